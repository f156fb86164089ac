//! The compute-shader back end of the splatter ([`super::Backend::Compute`]):
//! one thread per splat, or a workgroup per splat for footprints over
//! [`BIG_SPLAT_PIXELS`](super::gpu_data::BIG_SPLAT_PIXELS) pixels;
//! the passes of the render pass (visibility, attributes) as compute
//! kernels with atomics (shaders/splat_compute.wgsl says how), writing the
//! same accumulation targets, so that normalisation, gather and every
//! consumer of [`super::SplatTargets`] work on either back end.
//!
//! Why: a GPU with weak raster units (NVIDIA's compute parts, H100/H200)
//! splats far faster with atomics in a compute shader than through a render
//! pass (~14x measured on an H100, docs/performance.md); on lavapipe this
//! kernel halves a tracked frame with a 100k-point model, though the render
//! pass stays faster for sparse models of large splats (docs/benchmarks.md).
//!
//! A render is three compute passes, no clear and no indirect dispatch:
//! `finish` runs over the whole target, converting the sums inside the
//! splats' bounding box and writing zeros outside it (what the render
//! pass's clear leaves), and the large splats' passes run a fixed number
//! of workgroups striding over those pass 1 listed.

use super::gpu_data::{
    COMPUTE_BIG_MODEL, COMPUTE_BIG_OCCLUDER, COMPUTE_GEOMETRY, COMPUTE_MOTION, COMPUTE_OCCLUDED,
    COMPUTE_OCCLUDER_KEYS, CameraUniform, ComputeParams, RESOLVE_WORKGROUP,
};
use super::gpu_data::{TARGETS, compute_supported};
use super::scratch::{KEPT_BINDS, OccluderSlot, Scratch};
use super::{Attributes, GpuModel, SplatError, SplatTargets};
use crate::gpu::{
    GpuContext, GpuTimer, PassChain, WORKGROUP_1D, buffer_entry, compute_entry, storage, workgroups,
};

/// Workgroups of the large splats' passes on GPUs: each walks a listed
/// splat at a time, striding over the rest; those beyond the list's
/// length exit at once (the passes run whether or not a splat is large,
/// dispatched directly: no pass sizes them on the GPU first, one
/// dependent dispatch fewer a render).
const BIG_GROUPS_GPU: u32 = 512;
/// The same on CPU adapters, whose cores take a workgroup at a time.
const BIG_GROUPS_CPU: u32 = 16;

// `visibility_big` and the large splats' workgroups of `accumulate` lay a
// workgroup out as 8x8 lanes.
const _: () = assert!(WORKGROUP_1D == 64);

/// The pipelines of the compute back end.
pub(super) struct ComputeSplatter {
    layout: wgpu::BindGroupLayout,
    visibility: wgpu::ComputePipeline,
    accumulate: wgpu::ComputePipeline,
    visibility_big: wgpu::ComputePipeline,
    finish: wgpu::ComputePipeline,
    /// The last kernel of a depth-only render.
    finish_depth: wgpu::ComputePipeline,
    /// Workgroups of the large splats' passes ([`BIG_GROUPS_GPU`],
    /// [`BIG_GROUPS_CPU`]).
    big_groups: u32,
}

impl ComputeSplatter {
    pub(super) fn new(ctx: &GpuContext) -> Result<Self, SplatError> {
        if !compute_supported(ctx) {
            return Err(SplatError::Unsupported(format!(
                "the compute splatter writes {TARGETS} storage textures, the adapter allows {}",
                ctx.limits.max_storage_textures_per_shader_stage
            )));
        }
        // `finish` runs a thread a pixel of the target: within the limit
        // for any target the adapter can make.
        let widest = ctx
            .limits
            .max_texture_dimension_2d
            .div_ceil(RESOLVE_WORKGROUP);
        if widest > ctx.limits.max_compute_workgroups_per_dimension {
            return Err(SplatError::Unsupported(format!(
                "targets of {} pixels a side need {widest} workgroups a dimension, the adapter allows {}",
                ctx.limits.max_texture_dimension_2d,
                ctx.limits.max_compute_workgroups_per_dimension
            )));
        }
        let texture = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::StorageTexture {
                access: wgpu::StorageTextureAccess::WriteOnly,
                format: super::targets::ACC_FORMAT,
                view_dimension: wgpu::TextureViewDimension::D2,
            },
            count: None,
        };
        let uniform = wgpu::BufferBindingType::Uniform;
        let layout = ctx.bind_group_layout(
            "splat compute",
            &[
                buffer_entry(0, wgpu::ShaderStages::COMPUTE, uniform),
                compute_entry(1, uniform),
                compute_entry(2, storage(true)),
                compute_entry(3, storage(false)),
                compute_entry(4, storage(false)),
                texture(5),
                texture(6),
                texture(7),
                texture(8),
                texture(9),
                compute_entry(10, storage(false)),
                compute_entry(11, storage(false)),
                compute_entry(12, storage(true)),
            ],
        );
        let module = ctx.shader(&super::gpu_data::COMPUTE_SHADER)?;
        let pipeline = |entry: &str, layouts: &[Option<&wgpu::BindGroupLayout>]| {
            ctx.catch(&format!("splat_compute::{entry}"), || {
                let pl = ctx
                    .device
                    .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some(entry),
                        bind_group_layouts: layouts,
                        immediate_size: 0,
                    });
                ctx.device
                    .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(entry),
                        layout: Some(&pl),
                        module: &module,
                        entry_point: Some(entry),
                        compilation_options: Default::default(),
                        cache: None,
                    })
            })
        };
        let one = [Some(&layout)];
        Ok(Self {
            visibility: pipeline("visibility", &one)?,
            accumulate: pipeline("accumulate", &one)?,
            visibility_big: pipeline("visibility_big", &one)?,
            finish: pipeline("finish", &one)?,
            finish_depth: pipeline("finish_depth", &one)?,
            layout,
            big_groups: if ctx.is_cpu() {
                BIG_GROUPS_CPU
            } else {
                BIG_GROUPS_GPU
            },
        })
    }

    /// Passes 1 and 2 of `model` with its `uniform` behind `occluders`
    /// (each with its uniform) into `targets` (checked by the caller to be
    /// the camera's size), timed as "visibility" and "attributes" like the
    /// render pass (the conversion into the targets counts as attributes;
    /// the occluders' pass 1 counts as visibility). `depth_only`: pass 1
    /// only, then `finish_depth` (timed as "depth") writes the visibility
    /// depth and a unit weight ([`super::Splatter::render_depth`]);
    /// `attrs` is then ignored.
    pub(super) fn render(
        &self,
        ctx: &GpuContext,
        (model, uniform, occluders): (&GpuModel, &CameraUniform, &[(&GpuModel, CameraUniform)]),
        attrs: Attributes,
        depth_only: bool,
        targets: &mut SplatTargets,
        mut timer: Option<&mut GpuTimer>,
    ) -> Result<(), SplatError> {
        let attrs = if depth_only {
            // The targets a depth-only render writes: T0 and T1.
            Attributes::GEOMETRY
        } else {
            attrs
        };
        let (width, height) = (targets.width, targets.height);
        let g = targets.g_mut();
        if g.compute.is_none() {
            g.compute = Some(Scratch::new(ctx, width, height)?);
        }
        let scratch = g.compute.as_mut().expect("just made");
        // One list of large splats serves every object in turn.
        let most = occluders
            .iter()
            .map(|(m, _)| m.count)
            .fold(model.count, u32::max);
        ctx.check_buffer_size(
            "compute splatter list of large splats",
            most as u64 * 4,
            wgpu::BufferUsages::STORAGE,
        )?;
        scratch.big.ensure(ctx, most as u64 * 4);
        let params = ComputeParams {
            width,
            height,
            count: model.count,
            flags: if depth_only {
                if occluders.is_empty() {
                    0
                } else {
                    COMPUTE_OCCLUDED
                }
            } else {
                (if attrs.geometry { COMPUTE_GEOMETRY } else { 0 })
                    | (if attrs.motion { COMPUTE_MOTION } else { 0 })
            },
            slot: scratch.slot,
            big_at: COMPUTE_BIG_MODEL,
            clear_big: 0,
            pad0: 0,
        };
        while scratch.occluders.len() < occluders.len() {
            scratch.occluders.push(OccluderSlot::new(ctx));
        }
        for (k, ((m, u), o)) in occluders.iter().zip(&mut scratch.occluders).enumerate() {
            let k = k as u32;
            let p = ComputeParams {
                count: m.count,
                flags: if depth_only { COMPUTE_OCCLUDER_KEYS } else { 0 },
                big_at: COMPUTE_BIG_OCCLUDER + (k & 1),
                clear_big: if k == 0 {
                    0
                } else {
                    COMPUTE_BIG_OCCLUDER + ((k + 1) & 1)
                },
                ..params
            };
            ctx.write_buffer(&o.uniform, 0, bytemuck::bytes_of(u));
            o.params.write(ctx, bytemuck::bytes_of(&p));
        }
        scratch.slot ^= 1;
        ctx.write_buffer(&g.uniform, 0, bytemuck::bytes_of(uniform));
        scratch.params.write(ctx, bytemuck::bytes_of(&params));
        let bind = self.cached_bind(ctx, targets, model);
        let hidden: Vec<(wgpu::BindGroup, u32)> = occluders
            .iter()
            .enumerate()
            .map(|(k, (m, _))| (self.occluder_bind(ctx, targets, k, m), m.count))
            .collect();
        // Splats per dispatch row: at most 65535 workgroups in x.
        let groups = workgroups(model.count, WORKGROUP_1D);
        let gx = groups.clamp(1, 65_535);
        let gy = groups.div_ceil(gx);
        // `finish` runs a thread a pixel of the whole target.
        let (fx, fy) = (
            workgroups(targets.width, RESOLVE_WORKGROUP),
            workgroups(targets.height, RESOLVE_WORKGROUP),
        );
        let mut enc = ctx.encoder();
        // The depth keys, sums and this render's half of the bounds are
        // zero: made so (wgpu zeroes new buffers), and `finish` clears
        // every pixel it reads and the other half of the bounds. The
        // targets need no clear: `finish` writes zeros where no splat
        // reached, as the render pass's clear leaves them. One compute
        // pass, two where timed.
        let mut passes = PassChain::new(ctx, &mut enc);
        // Pass 1, the large splats' visibility after the others' (a fixed
        // number of workgroups striding over those listed), each
        // occluder's before the model's.
        let pass = passes.stage("visibility", timer.as_deref_mut());
        for (b, n) in &hidden {
            let groups = workgroups(*n, WORKGROUP_1D);
            let gx = groups.clamp(1, 65_535);
            pass.set_bind_group(0, b, &[]);
            pass.set_pipeline(&self.visibility);
            pass.dispatch_workgroups(gx, groups.div_ceil(gx), 1);
            pass.set_pipeline(&self.visibility_big);
            pass.dispatch_workgroups(self.big_groups, 1, 1);
        }
        pass.set_pipeline(&self.visibility);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(gx, gy, 1);
        pass.set_pipeline(&self.visibility_big);
        pass.dispatch_workgroups(self.big_groups, 1, 1);
        if depth_only {
            // The depth into the targets.
            let pass = passes.stage("depth", timer.as_deref_mut());
            pass.set_bind_group(0, &bind, &[]);
            pass.set_pipeline(&self.finish_depth);
            pass.dispatch_workgroups(fx, fy, 1);
        } else {
            let pass = passes.stage("attributes", timer.as_deref_mut());
            pass.set_bind_group(0, &bind, &[]);
            // The splats' workgroups, then the large splats' (one
            // dependent dispatch fewer than two passes: both only add).
            let all = groups + self.big_groups;
            let ax = all.min(65_535);
            pass.set_pipeline(&self.accumulate);
            pass.dispatch_workgroups(ax, all.div_ceil(ax), 1);
            pass.set_pipeline(&self.finish);
            pass.dispatch_workgroups(fx, fy, 1);
        }
        drop(passes);
        if let Some(t) = timer {
            t.resolve(&mut enc);
        }
        ctx.submit(enc);
        Ok(())
    }

    /// The bind group of a render of `model` into `targets` (whose
    /// scratch is made): the one kept for these buffers, else a new one,
    /// kept.
    fn cached_bind(
        &self,
        ctx: &GpuContext,
        targets: &mut SplatTargets,
        model: &GpuModel,
    ) -> wgpu::BindGroup {
        let (geometry, colors) = model.gpu_buffers();
        let scratch = targets.g().compute.as_ref().expect("scratch made");
        let key = [geometry.clone(), colors.clone(), scratch.big.get().clone()];
        match scratch.binds.iter().position(|(k, _)| *k == key) {
            Some(i) => targets
                .g_mut()
                .compute
                .as_mut()
                .expect("scratch made")
                .binds[..=i]
                .rotate_right(1),
            None => {
                let own = (&targets.g().uniform, scratch.params.buffer());
                let bind = self.bind(ctx, targets, scratch, model, own);
                let binds = &mut targets
                    .g_mut()
                    .compute
                    .as_mut()
                    .expect("scratch made")
                    .binds;
                binds.truncate(KEPT_BINDS - 1);
                binds.insert(0, (key, bind));
            }
        }
        targets.g().compute.as_ref().expect("scratch made").binds[0]
            .1
            .clone()
    }

    /// The bind group of occluder `k` (`model`) in a render into
    /// `targets`: its slot's, made anew when its buffers change.
    fn occluder_bind(
        &self,
        ctx: &GpuContext,
        targets: &mut SplatTargets,
        k: usize,
        model: &GpuModel,
    ) -> wgpu::BindGroup {
        let (geometry, colors) = model.gpu_buffers();
        let scratch = targets.g().compute.as_ref().expect("scratch made");
        let key = [geometry.clone(), colors.clone(), scratch.big.get().clone()];
        let slot = &scratch.occluders[k];
        if let Some((held, bind)) = &slot.bind
            && *held == key
        {
            return bind.clone();
        }
        let own = (&slot.uniform, slot.params.buffer());
        let bind = self.bind(ctx, targets, scratch, model, own);
        targets
            .g_mut()
            .compute
            .as_mut()
            .expect("scratch made")
            .occluders[k]
            .bind = Some((key, bind.clone()));
        bind
    }

    /// A new bind group of a render of `model` into `targets`, with its
    /// camera uniform and parameters (`own`: the targets' and the
    /// scratch's for the model, a slot's for an occluder).
    fn bind(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        scratch: &Scratch,
        model: &GpuModel,
        (uniform, params): (&wgpu::Buffer, &wgpu::Buffer),
    ) -> wgpu::BindGroup {
        let mut entries = vec![
            wgpu::BindGroupEntry {
                binding: 0,
                resource: uniform.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: params.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: model.gpu_buffers().0.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: scratch.depth.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 4,
                resource: scratch.acc.as_entire_binding(),
            },
        ];
        for (i, v) in targets.g().acc_views.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 5 + i as u32,
                resource: wgpu::BindingResource::TextureView(v),
            });
        }
        entries.push(wgpu::BindGroupEntry {
            binding: 10,
            resource: scratch.bounds.as_entire_binding(),
        });
        entries.push(wgpu::BindGroupEntry {
            binding: 11,
            resource: scratch.big.get().as_entire_binding(),
        });
        entries.push(wgpu::BindGroupEntry {
            binding: 12,
            resource: model.gpu_buffers().1.as_entire_binding(),
        });
        ctx.bind_group(&wgpu::BindGroupDescriptor {
            label: Some("splat compute"),
            layout: &self.layout,
            entries: &entries,
        })
    }
}
