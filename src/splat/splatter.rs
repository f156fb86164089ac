//! The GPU splatter: pipelines for the three passes and the gather kernel
//! (the module docs of [`super`] say how it works).

use super::compute::ComputeSplatter;
use super::gpu_data::{
    CameraUniform, GATHER_BILINEAR, GATHER_NEAREST, GATHER_STRIDE, RESOLVE_DEPTH_MOTION,
    RESOLVE_WORKGROUP, ResolveParams,
};
use super::targets::{ACC_FORMAT, DEPTH_FORMAT, TARGETS, cleared_attachments, target_slots};
use super::{
    Attribute, Attributes, Backend, GatherMode, GatherSample, GpuModel, SplatError, SplatImage,
    SplatParams, SplatTargets,
};
use crate::geometry::{Intrinsics, Pose};
use crate::gpu::{
    BindCache, GpuContext, GpuTimer, GrowBuffer, PassChain, STORAGE_IN, STORAGE_OUT, Uniform,
    WORKGROUP_1D, buffer_entry, compute_entry, storage, texture_entry, workgroups,
};

/// The GPU splatter: pipelines for the three passes and the gather kernel.
/// Create once per device.
pub struct Splatter {
    params: SplatParams,
    render_layout: wgpu::BindGroupLayout,
    visibility: wgpu::RenderPipeline,
    /// The visibility pass of [`Splatter::render_depth`]: depth, and the
    /// nearest fragment's depth and unit weight into T1 and T0.
    visibility_depth: wgpu::RenderPipeline,
    /// Indexed by [`Attributes::index`].
    attribute: Vec<wgpu::RenderPipeline>,
    resolve_layout: wgpu::BindGroupLayout,
    resolve: wgpu::ComputePipeline,
    gather: wgpu::ComputePipeline,
    /// Bound where an entry point has no points to read.
    dummy_points: wgpu::Buffer,
    /// The back end that renders (never [`Backend::Auto`]).
    backend: Backend,
    /// The compute back end's pipelines, when it renders.
    compute: Option<ComputeSplatter>,
    /// `auto` on a CPU adapter: renders whose typical splat is wider than
    /// this (pixels, radius) go through the render pass
    /// ([`super::AUTO_CPU_RENDER_PASS_ABOVE_PX`]).
    render_pass_above_px: Option<f64>,
    /// Buffers and bind groups of `read`/`gather`, kept across calls.
    reuse: std::sync::Mutex<Reuse>,
    /// Held through a `read` or `gather`, whose kept buffers one call at a
    /// time may use.
    busy: std::sync::Mutex<()>,
}

/// Bind groups of resolves and gathers kept (one per recent targets and
/// output buffer).
const KEPT_BINDS: usize = 4;

/// The buffers [`Splatter::read`] and [`Splatter::gather`] reuse
/// (grow-only) and the bind groups made on them.
struct Reuse {
    /// The uniform of each resolve kind (indexed by kind).
    params: [Option<Uniform>; 6],
    gather_params: Option<Uniform>,
    /// Indexed by [`Grown`].
    buffers: [GrowBuffer; 3],
    binds: Vec<(BindKey, wgpu::BindGroup)>,
    /// The render pass back end's, by targets' uniform, geometry and
    /// colours.
    render_binds: BindCache<3>,
    /// The last gather, given back to the context at this mark: its
    /// points and parameters, written by `Queue::write_buffer`, must not
    /// be overwritten before it is submitted.
    last_gather: Option<crate::gpu::SubmissionMark>,
}

#[derive(Clone, Copy)]
enum Grown {
    Read = 0,
    Gather = 1,
    Points = 2,
}

fn resolve_params(ctx: &GpuContext) -> Uniform {
    Uniform::new(
        ctx,
        "splat resolve params",
        std::mem::size_of::<ResolveParams>() as u64,
    )
}

/// What a kept resolve bind group binds.
#[derive(PartialEq)]
struct BindKey {
    view: wgpu::TextureView,
    params: wgpu::Buffer,
    out: wgpu::Buffer,
    points: Option<wgpu::Buffer>,
}

impl Splatter {
    pub fn new(ctx: &GpuContext) -> Result<Self, SplatError> {
        Self::with_params(ctx, SplatParams::default())
    }

    pub fn with_params(ctx: &GpuContext, params: SplatParams) -> Result<Self, SplatError> {
        let backend = params.backend.resolve(ctx)?;
        let compute = match backend {
            Backend::Compute => Some(ComputeSplatter::new(ctx)?),
            _ => None,
        };
        let forced = std::env::var(super::SPLATTER_ENV)
            .ok()
            .and_then(|v| Backend::parse(&v))
            .is_some_and(|b| b != Backend::Auto);
        let render_pass_above_px = (params.backend == Backend::Auto
            && !forced
            && backend == Backend::Compute
            && ctx.is_cpu())
        .then_some(super::AUTO_CPU_RENDER_PASS_ABOVE_PX);
        let need = TARGETS as u32 * 16;
        if ctx.limits.max_color_attachments < TARGETS as u32
            || ctx.limits.max_color_attachment_bytes_per_sample < need
        {
            return Err(SplatError::Unsupported(format!(
                "{} colour attachments of {need} bytes per sample needed, the adapter allows {} and {}",
                TARGETS,
                ctx.limits.max_color_attachments,
                ctx.limits.max_color_attachment_bytes_per_sample
            )));
        }
        let device = &ctx.device;
        let render_layout = ctx.bind_group_layout(
            "splat",
            &[
                buffer_entry(
                    0,
                    wgpu::ShaderStages::VERTEX_FRAGMENT,
                    wgpu::BufferBindingType::Uniform,
                ),
                buffer_entry(1, wgpu::ShaderStages::VERTEX, storage(true)),
                buffer_entry(2, wgpu::ShaderStages::VERTEX, storage(true)),
            ],
        );
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("splat"),
            bind_group_layouts: &[Some(&render_layout)],
            immediate_size: 0,
        });
        let module = ctx.shader(&super::gpu_data::SPLAT_SHADER)?;
        let pipeline =
            |label: &str, entry: &str, write: bool, targets: &[Option<wgpu::ColorTargetState>]| {
                ctx.catch(label, || {
                    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                        label: Some(label),
                        layout: Some(&layout),
                        vertex: wgpu::VertexState {
                            module: &module,
                            entry_point: Some("vs_splat"),
                            compilation_options: Default::default(),
                            buffers: &[],
                        },
                        primitive: wgpu::PrimitiveState {
                            topology: wgpu::PrimitiveTopology::TriangleStrip,
                            ..Default::default()
                        },
                        depth_stencil: Some(wgpu::DepthStencilState {
                            format: DEPTH_FORMAT,
                            depth_write_enabled: Some(write),
                            depth_compare: Some(if write {
                                wgpu::CompareFunction::Less
                            } else {
                                wgpu::CompareFunction::LessEqual
                            }),
                            stencil: Default::default(),
                            bias: Default::default(),
                        }),
                        multisample: Default::default(),
                        fragment: Some(wgpu::FragmentState {
                            module: &module,
                            entry_point: Some(entry),
                            compilation_options: Default::default(),
                            targets,
                        }),
                        multiview_mask: None,
                        cache: None,
                    })
                })
            };
        let visibility = pipeline("splat visibility", "fs_visibility", true, &[])?;
        // No blending: the fragment that passes the depth test last (the
        // nearest) leaves its values.
        let replace = Some(wgpu::ColorTargetState {
            format: ACC_FORMAT,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        });
        let visibility_depth = pipeline(
            "splat visibility depth",
            "fs_visibility_depth",
            true,
            &target_slots(Attributes::GEOMETRY).map(|on| if on { replace.clone() } else { None }),
        )?;
        let additive = Some(wgpu::ColorTargetState {
            format: ACC_FORMAT,
            blend: Some(wgpu::BlendState {
                color: wgpu::BlendComponent {
                    src_factor: wgpu::BlendFactor::One,
                    dst_factor: wgpu::BlendFactor::One,
                    operation: wgpu::BlendOperation::Add,
                },
                alpha: wgpu::BlendComponent {
                    src_factor: wgpu::BlendFactor::One,
                    dst_factor: wgpu::BlendFactor::One,
                    operation: wgpu::BlendOperation::Add,
                },
            }),
            write_mask: wgpu::ColorWrites::ALL,
        });
        let mut attribute = Vec::new();
        for index in 0..4 {
            let attrs = Attributes {
                geometry: index & 1 != 0,
                motion: index & 2 != 0,
            };
            let targets = target_slots(attrs).map(|on| if on { additive.clone() } else { None });
            let entry = ["fs_attr_c", "fs_attr_cg", "fs_attr_cm", "fs_attr_cgm"][index];
            attribute.push(pipeline(entry, entry, false, &targets)?);
        }

        let tex = |binding| texture_entry(binding, wgpu::ShaderStages::COMPUTE);
        let resolve_layout = ctx.bind_group_layout(
            "splat resolve",
            &[
                compute_entry(0, wgpu::BufferBindingType::Uniform),
                tex(1),
                tex(2),
                tex(3),
                tex(4),
                tex(5),
                compute_entry(6, storage(false)),
                compute_entry(7, storage(true)),
            ],
        );
        let [resolve, gather]: [wgpu::ComputePipeline; 2] = ctx
            .compute_pipelines(
                &super::gpu_data::RESOLVE_SHADER,
                &resolve_layout,
                &["resolve", "gather"],
            )?
            .try_into()
            .expect("two pipelines");
        let dummy_points = ctx.buffer("no points", 16, wgpu::BufferUsages::STORAGE);
        Ok(Self {
            params,
            render_layout,
            visibility,
            visibility_depth,
            attribute,
            resolve_layout,
            resolve,
            gather,
            dummy_points,
            backend,
            compute,
            render_pass_above_px,
            reuse: std::sync::Mutex::new(Reuse {
                params: std::array::from_fn(|_| Some(resolve_params(ctx))),
                gather_params: Some(resolve_params(ctx)),
                buffers: [
                    GrowBuffer::new("splat image", STORAGE_OUT),
                    GrowBuffer::new("gather out", STORAGE_OUT),
                    GrowBuffer::new("gather points", STORAGE_IN),
                ],
                binds: Vec::new(),
                render_binds: BindCache::keeping(KEPT_BINDS),
                last_gather: None,
            }),
            busy: std::sync::Mutex::new(()),
        })
    }

    /// The back end that renders `model` at `pose`: [`Splatter::backend`],
    /// except for `auto` on a CPU adapter, where renders whose typical
    /// splat (the median radius at the depth of the model's centre) is
    /// wider than [`super::AUTO_CPU_RENDER_PASS_ABOVE_PX`] pixels go
    /// through the render pass. Both write the same targets.
    pub fn backend_for(&self, model: &GpuModel, cam: &Intrinsics, pose: &Pose) -> Backend {
        if self.compute.is_none() {
            return Backend::RenderPass;
        }
        if let Some(limit) = self.render_pass_above_px {
            let z = pose.transform_point(&model.bounds.center).z;
            let px = cam.fx.max(cam.fy) * model.bounds.median_splat_radius / z;
            if z > 0.0 && px > limit {
                return Backend::RenderPass;
            }
        }
        Backend::Compute
    }

    pub fn params(&self) -> &SplatParams {
        &self.params
    }

    /// The back end that renders: [`Backend::RenderPass`] or
    /// [`Backend::Compute`] (what [`Backend::Auto`] chose on this adapter;
    /// on a CPU adapter `auto` still sends renders of large splats through
    /// the render pass: [`Splatter::backend_for`]).
    pub fn backend(&self) -> Backend {
        self.backend
    }

    /// Splats `model` at `pose` into `targets` (whose size must be the
    /// camera's). Submits the work and returns without waiting.
    pub fn render(
        &self,
        ctx: &GpuContext,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        attrs: Attributes,
        targets: &mut SplatTargets,
    ) -> Result<(), SplatError> {
        self.render_timed(ctx, model, cam, pose, attrs, targets, None)
    }

    /// [`Splatter::render`] with GPU timestamps for the passes "visibility"
    /// and "attributes" (resolved into `timer`; read it after the submit).
    #[allow(clippy::too_many_arguments)]
    pub fn render_timed(
        &self,
        ctx: &GpuContext,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        attrs: Attributes,
        targets: &mut SplatTargets,
        mut timer: Option<&mut GpuTimer>,
    ) -> Result<(), SplatError> {
        let uniform = self.checked_view(model, cam, pose, targets)?;
        targets.view = None;
        if let Some(compute) = &self.compute
            && self.backend_for(model, cam, pose) == Backend::Compute
        {
            compute.render(ctx, model, &uniform, attrs, false, targets, timer)?;
            targets.rendered = Some(attrs);
            targets.depth_only = false;
            targets.view = Some((*pose, *cam));
            return Ok(());
        }
        let bind = self.render_bind(ctx, model, targets, &uniform);
        let mut enc = ctx.encoder();
        // Two render passes: the visibility, the attributes.
        ctx.count_passes(2);
        self.visibility_pass(
            &mut enc,
            (&self.visibility, "splat visibility", &[]),
            &bind,
            model,
            targets,
            timer.as_deref_mut(),
        );
        {
            let colors = cleared_attachments(targets, attrs);
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("splat attributes"),
                color_attachments: &colors,
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &targets.depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Load,
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: timer
                    .as_deref_mut()
                    .and_then(|t| t.render_pass("attributes")),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.attribute[attrs.index()]);
            pass.set_bind_group(0, &bind, &[]);
            pass.draw(0..4, 0..model.count);
        }
        if let Some(t) = timer {
            t.resolve(&mut enc);
        }
        ctx.submit(enc);
        targets.rendered = Some(attrs);
        targets.depth_only = false;
        targets.view = Some((*pose, *cam));
        Ok(())
    }

    /// A depth-only render: the visibility pass alone (one pass over the
    /// splats instead of two, no attribute sums). Afterwards
    /// [`Splatter::read`] gives [`Attribute::Depth`], the depth of the
    /// nearest surface pushed back by the visibility epsilon (`epsilon *
    /// r` along the ray, [`SplatParams::epsilon`]: what the attribute pass
    /// tests against, within a splat radius behind the averaged depth of a
    /// full render), and [`Attribute::Weight`], 1 where covered; the
    /// coverage is exactly a full render's (a pixel is covered when a
    /// splat's kernel reaches it, and the nearest such splat passes the
    /// attribute pass's test). Other reads fail with
    /// [`SplatError::NotRendered`]. [`cpu::visibility_depth`](super::cpu::visibility_depth)
    /// is the reference. Timed as "visibility" (and, on the compute back
    /// end, "depth": its large splats and the conversion).
    #[allow(clippy::too_many_arguments)]
    pub fn render_depth(
        &self,
        ctx: &GpuContext,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        targets: &mut SplatTargets,
        mut timer: Option<&mut GpuTimer>,
    ) -> Result<(), SplatError> {
        let uniform = self.checked_view(model, cam, pose, targets)?;
        targets.view = None;
        if let Some(compute) = &self.compute
            && self.backend_for(model, cam, pose) == Backend::Compute
        {
            compute.render(
                ctx,
                model,
                &uniform,
                Attributes::GEOMETRY,
                true,
                targets,
                timer,
            )?;
            targets.rendered = None;
            targets.depth_only = true;
            targets.view = Some((*pose, *cam));
            return Ok(());
        }
        let bind = self.render_bind(ctx, model, targets, &uniform);
        let mut enc = ctx.encoder();
        ctx.count_passes(1);
        let colors = cleared_attachments(targets, Attributes::GEOMETRY);
        self.visibility_pass(
            &mut enc,
            (&self.visibility_depth, "splat visibility depth", &colors),
            &bind,
            model,
            targets,
            timer.as_deref_mut(),
        );
        if let Some(t) = timer {
            t.resolve(&mut enc);
        }
        ctx.submit(enc);
        targets.rendered = None;
        targets.depth_only = true;
        targets.view = Some((*pose, *cam));
        Ok(())
    }

    /// The camera uniform of a render of `model` at `pose`, once `targets`
    /// are checked to be the camera's size.
    fn checked_view(
        &self,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        targets: &SplatTargets,
    ) -> Result<CameraUniform, SplatError> {
        if targets.width != cam.width || targets.height != cam.height {
            return Err(SplatError::SizeMismatch {
                got_w: targets.width,
                got_h: targets.height,
                want_w: cam.width,
                want_h: cam.height,
            });
        }
        model.bounds.view(cam, pose, &self.params)
    }

    /// The render pass back end's bind group, with `uniform` written to
    /// the targets' uniform buffer; kept for the targets and model of the
    /// last few renders.
    fn render_bind(
        &self,
        ctx: &GpuContext,
        model: &GpuModel,
        targets: &SplatTargets,
        uniform: &CameraUniform,
    ) -> wgpu::BindGroup {
        ctx.write_buffer(&targets.uniform, 0, bytemuck::bytes_of(uniform));
        let bufs = [
            targets.uniform.clone(),
            model.geometry.clone(),
            model.colors.clone(),
        ];
        let mut reuse = self.reuse.lock().unwrap_or_else(|p| p.into_inner());
        let made = reuse.render_binds.get(bufs, |b| {
            Ok(ctx.bind_group(&wgpu::BindGroupDescriptor {
                label: Some("splat"),
                layout: &self.render_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: b[0].as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: b[1].as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: b[2].as_entire_binding(),
                    },
                ],
            }))
        });
        let Ok::<_, std::convert::Infallible>(bind) = made;
        bind.clone()
    }

    /// The render pass back end's visibility pass into a cleared depth
    /// buffer: `pipeline`, its label and colour attachments (none for a
    /// full render's first pass, the depth-only render's targets for
    /// [`Splatter::render_depth`]); timed as "visibility".
    fn visibility_pass(
        &self,
        enc: &mut wgpu::CommandEncoder,
        (pipeline, label, colors): (
            &wgpu::RenderPipeline,
            &str,
            &[Option<wgpu::RenderPassColorAttachment<'_>>],
        ),
        bind: &wgpu::BindGroup,
        model: &GpuModel,
        targets: &SplatTargets,
        timer: Option<&mut GpuTimer>,
    ) {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(label),
            color_attachments: colors,
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: timer.and_then(|t| t.render_pass("visibility")),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bind, &[]);
        pass.draw(0..4, 0..model.count);
    }

    /// The bind group of a resolve or gather into `out` from `targets`,
    /// with its uniform set to `params` (written now). Each kind of
    /// resolve, and the gather, has a uniform of its own: a batch of
    /// submissions ([`GpuContext::batch`]) may hold one of each. Kept per
    /// (targets, out, points) and reused (no allocation per
    /// frame).
    fn resolve_bind(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        params: ResolveParams,
        out: &wgpu::Buffer,
        points: Option<&wgpu::Buffer>,
    ) -> wgpu::BindGroup {
        let mut reuse = self.reuse.lock().unwrap_or_else(|p| p.into_inner());
        let slot = params.kind as usize % reuse.params.len();
        let uniform = if points.is_some() {
            reuse
                .gather_params
                .get_or_insert_with(|| resolve_params(ctx))
        } else {
            reuse.params[slot].get_or_insert_with(|| resolve_params(ctx))
        };
        uniform.write(ctx, bytemuck::bytes_of(&params));
        let pbuf = uniform.buffer().clone();
        let key = BindKey {
            view: targets.acc_views[0].clone(),
            params: pbuf.clone(),
            out: out.clone(),
            points: points.cloned(),
        };
        if let Some(i) = reuse.binds.iter().position(|(k, _)| *k == key) {
            let hit = reuse.binds.remove(i);
            let bind = hit.1.clone();
            reuse.binds.insert(0, hit);
            return bind;
        }
        let mut entries = vec![wgpu::BindGroupEntry {
            binding: 0,
            resource: pbuf.as_entire_binding(),
        }];
        for (i, v) in targets.acc_views.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 1 + i as u32,
                resource: wgpu::BindingResource::TextureView(v),
            });
        }
        entries.push(wgpu::BindGroupEntry {
            binding: 6,
            resource: out.as_entire_binding(),
        });
        entries.push(wgpu::BindGroupEntry {
            binding: 7,
            resource: points.unwrap_or(&self.dummy_points).as_entire_binding(),
        });
        let bind = ctx.bind_group(&wgpu::BindGroupDescriptor {
            label: Some("splat resolve"),
            layout: &self.resolve_layout,
            entries: &entries,
        });
        reuse.binds.insert(0, (key, bind.clone()));
        reuse.binds.truncate(KEPT_BINDS);
        bind
    }

    /// Normalises one attribute of the last render on the GPU into `out`
    /// (at least width x height x channels floats, `STORAGE`), where it
    /// stays: nothing is read back. Submitted at once.
    pub fn resolve_into(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        attribute: Attribute,
        out: &wgpu::Buffer,
    ) -> Result<(), SplatError> {
        let enc = self.encode_resolve(ctx, targets, attribute, out)?;
        ctx.submit(enc);
        Ok(())
    }

    /// Records [`Splatter::resolve_into`]'s pass (its parameters queued)
    /// for the caller to submit, with a readback behind it, say.
    fn encode_resolve(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        attribute: Attribute,
        out: &wgpu::Buffer,
    ) -> Result<crate::gpu::Encoder, SplatError> {
        let mut enc = ctx.encoder();
        self.record_resolve(
            ctx,
            &mut PassChain::new(ctx, &mut enc),
            targets,
            attribute,
            out,
        )?;
        Ok(enc)
    }

    /// [`Splatter::resolve_into`] recorded as a stage of `passes` (its
    /// parameters queued), for the caller to submit with the stages
    /// around it: in one compute pass with them where untimed. Resolves
    /// of different attributes may share a submission (each kind has
    /// its parameters).
    pub fn record_resolve(
        &self,
        ctx: &GpuContext,
        passes: &mut PassChain,
        targets: &SplatTargets,
        attribute: Attribute,
        out: &wgpu::Buffer,
    ) -> Result<(), SplatError> {
        targets.check(attribute.needs(), attribute)?;
        let (w, h) = (targets.width, targets.height);
        let n = w as u64 * h as u64 * attribute.channels() as u64;
        if out.size() < n * 4 {
            return Err(SplatError::Unsupported(format!(
                "resolve_into: a {}-byte buffer for {} bytes",
                out.size(),
                n * 4
            )));
        }
        let bind = self.resolve_bind(
            ctx,
            targets,
            ResolveParams {
                width: w,
                height: h,
                kind: if attribute == Attribute::Depth && targets.depth_from_motion() {
                    RESOLVE_DEPTH_MOTION
                } else {
                    attribute.kind()
                },
                mode: GATHER_NEAREST,
                fx: targets.fx(),
                ..Default::default()
            },
            out,
            None,
        );
        let pass = passes.stage("resolve", None);
        pass.set_pipeline(&self.resolve);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(
            workgroups(w, RESOLVE_WORKGROUP),
            workgroups(h, RESOLVE_WORKGROUP),
            1,
        );
        Ok(())
    }

    /// Normalises one attribute of the last render on the GPU and reads the
    /// whole image back (for the CLI and tests; the tracker uses
    /// [`Splatter::gather`]).
    pub fn read(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        attribute: Attribute,
    ) -> Result<SplatImage, SplatError> {
        targets.check(attribute.needs(), attribute)?;
        let (w, h) = (targets.width, targets.height);
        let n = w as usize * h as usize * attribute.channels();
        let _busy = self.busy.lock().unwrap_or_else(|p| p.into_inner());
        let out = self.grown(ctx, Grown::Read, (n * 4) as u64);
        let enc = self.encode_resolve(ctx, targets, attribute, &out)?;
        let data = ctx.read_buffer_after::<f32>(enc, &out, n)?;
        Ok(SplatImage {
            width: w,
            height: h,
            channels: attribute.channels(),
            data,
        })
    }

    /// A kept buffer of at least `size` bytes (grow-only).
    fn grown(&self, ctx: &GpuContext, which: Grown, size: u64) -> wgpu::Buffer {
        let mut reuse = self.reuse.lock().unwrap_or_else(|p| p.into_inner());
        let b = &mut reuse.buffers[which as usize];
        b.ensure(ctx, size);
        b.get().clone()
    }

    /// Motion predictors, depth and validity at `points` (OpenCV pixel
    /// coordinates) from the last render, which must include the motion
    /// predictors ([`Attributes::MOTION`] or [`Attributes::ALL`]). The depth
    /// comes from the predictors (`fx / (du/dtx)`: the harmonic mean of the
    /// fragments' depths, eq. 5), so no geometry needs rendering. Reads
    /// back 14 floats per point only.
    pub fn gather(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        points: &[[f32; 2]],
        mode: GatherMode,
    ) -> Result<Vec<GatherSample>, SplatError> {
        self.gather_later(ctx, targets, points, mode)?.wait(ctx)
    }

    /// [`Splatter::gather`] without waiting: the gather is recorded and
    /// submitted (within a batch, put off with it) and its readback goes
    /// with the calling thread's next one ([`GpuContext::read_buffer_later`]);
    /// [`PendingGather::wait`] returns the samples. The next gather
    /// submits a put-off one first (they share the points' buffer).
    pub fn gather_later(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        points: &[[f32; 2]],
        mode: GatherMode,
    ) -> Result<PendingGather, SplatError> {
        self.gather_at(ctx, targets, Points::Host(points), mode)
    }

    /// The buffer of points [`Splatter::gather_written_later`] gathers
    /// at, grown to hold `n` (8 bytes each: x, y as f32), for work on the
    /// GPU to write into (such as [`crate::features::Harris::export_corners`]).
    /// The next [`Splatter::gather_later`] overwrites it.
    pub fn gather_points(&self, ctx: &GpuContext, n: usize) -> Result<wgpu::Buffer, SplatError> {
        let bytes = (n.max(1) * 8) as u64;
        ctx.check_buffer_size("gather points", bytes, STORAGE_IN)?;
        Ok(self.grown(ctx, Grown::Points, bytes))
    }

    /// The buffer the last gather wrote its samples into
    /// ([`GATHER_STRIDE`] floats a point, its validity last), for work on
    /// the GPU fed from them (such as
    /// [`crate::features::NccMatcher::match_resident_exported_b`]'s gate),
    /// recorded after that gather; the next gather overwrites it.
    pub fn gathered_samples(&self, ctx: &GpuContext) -> wgpu::Buffer {
        self.grown(ctx, Grown::Gather, 0)
    }

    /// [`Splatter::gather_later`] at the first `n` points written on the
    /// GPU into [`Splatter::gather_points`] (recorded before this call).
    pub fn gather_written_later(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        n: usize,
        mode: GatherMode,
    ) -> Result<PendingGather, SplatError> {
        self.gather_at(ctx, targets, Points::Written(n), mode)
    }

    fn gather_at(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        points: Points,
        mode: GatherMode,
    ) -> Result<PendingGather, SplatError> {
        targets.check(Attributes::MOTION, Attribute::Motion)?;
        let count = match points {
            Points::Host(p) => p.len(),
            Points::Written(n) => n,
        };
        if count == 0 {
            return Ok(PendingGather { read: None, n: 0 });
        }
        let size = (count * 8) as u64;
        let _busy = self.busy.lock().unwrap_or_else(|p| p.into_inner());
        ctx.check_buffer_size("gather points", size, STORAGE_IN)?;
        let last = self
            .reuse
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .last_gather
            .take();
        // Only where the last gather is still put off: a readback since
        // submitted it (as IT's chain does before KF's gather) leaves
        // nothing to flush, and no submission of its own.
        if last.is_some_and(|m| !ctx.submitted_since(m)) {
            ctx.flush();
        }
        let pbuf = match points {
            Points::Host(p) => {
                let pbuf = self.grown(ctx, Grown::Points, size);
                ctx.write_buffer(&pbuf, 0, bytemuck::cast_slice(p));
                pbuf
            }
            Points::Written(_) => {
                let pbuf = self.grown(ctx, Grown::Points, 0);
                if pbuf.size() < size {
                    return Err(SplatError::Gpu(crate::gpu::GpuError::Readback(format!(
                        "a gather at {count} written points of a {}-byte buffer",
                        pbuf.size()
                    ))));
                }
                pbuf
            }
        };
        let n = count * GATHER_STRIDE;
        let out = self.grown(ctx, Grown::Gather, (n * 4) as u64);
        let bind = self.resolve_bind(
            ctx,
            targets,
            ResolveParams {
                width: targets.width,
                height: targets.height,
                kind: count as u32,
                mode: match mode {
                    GatherMode::Nearest => GATHER_NEAREST,
                    GatherMode::Bilinear => GATHER_BILINEAR,
                },
                fx: targets.fx(),
                ..Default::default()
            },
            &out,
            Some(&pbuf),
        );
        let mut enc = ctx.encoder();
        {
            let mut passes = PassChain::new(ctx, &mut enc);
            let pass = passes.stage("gather", None);
            pass.set_pipeline(&self.gather);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(workgroups(count as u32, WORKGROUP_1D), 1, 1);
        }
        let read = ctx.read_buffer_later(enc, &out, (n * 4) as u64)?;
        self.reuse
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .last_gather = Some(ctx.submission_mark());
        Ok(PendingGather {
            read: Some(read),
            n: count,
        })
    }

    /// One-shot convenience: upload, render and read one attribute.
    pub fn render_image(
        &self,
        ctx: &GpuContext,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        attribute: Attribute,
    ) -> Result<SplatImage, SplatError> {
        let mut targets = SplatTargets::new(ctx, cam.width, cam.height);
        self.render(ctx, model, cam, pose, attribute.needs(), &mut targets)?;
        self.read(ctx, &targets, attribute)
    }
}

/// Where a gather's points come from.
#[derive(Clone, Copy)]
enum Points<'p> {
    /// Uploaded.
    Host(&'p [[f32; 2]]),
    /// The first n of the points' buffer, written on the GPU.
    Written(usize),
}

/// A gather whose readback is put off ([`Splatter::gather_later`]).
#[must_use = "a pending gather is only useful waited for"]
pub struct PendingGather {
    read: Option<crate::gpu::PendingRead>,
    /// Points gathered.
    n: usize,
}

impl PendingGather {
    /// The samples, one a point: at once when a readback since brought
    /// them, else after a readback of their own.
    pub fn wait(self, ctx: &GpuContext) -> Result<Vec<GatherSample>, SplatError> {
        let Some(read) = self.read else {
            return Ok(Vec::new());
        };
        let bytes = read.wait(ctx)?;
        let data: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes);
        debug_assert_eq!(data.len(), self.n * GATHER_STRIDE);
        Ok(data
            .chunks(GATHER_STRIDE)
            .map(GatherSample::from_floats)
            .collect())
    }
}
