//! The GPU side of the splatter ([`GpuSplatter`]): pipelines for the
//! three passes and the gather kernel (the module docs of [`super`] say
//! how it works; the public [`super::Splatter`] dispatches to it or to the
//! host's, in `host`). The render pass back
//! end's passes are in `render`, normalisation (resolves, reads, gathers)
//! in `resolve`, the compute back end in `compute`.

use super::Attributes;
use super::compute::ComputeSplatter;
use super::error::SplatError;
use super::gpu_data::TARGETS;
use super::model::GpuModel;
use super::params::{AUTO_CPU_RENDER_PASS_ABOVE_PX, Backend, SPLATTER_ENV, SplatParams};
use super::reuse::Reuse;
use super::targets::{ACC_FORMAT, DEPTH_FORMAT, target_slots};
use crate::geometry::{Intrinsics, Pose};
use crate::gpu::{GpuContext, buffer_entry, compute_entry, storage, texture_entry};

/// The GPU splatter: pipelines for the three passes and the gather kernel.
pub(super) struct GpuSplatter {
    pub(super) params: SplatParams,
    pub(super) render_layout: wgpu::BindGroupLayout,
    pub(super) visibility: wgpu::RenderPipeline,
    /// The visibility pass of [`Splatter::render_depth`]: depth, and the
    /// nearest fragment's depth and unit weight into T1 and T0.
    pub(super) visibility_depth: wgpu::RenderPipeline,
    /// The occluders' draws in that pass: depth alone (the targets'
    /// writes masked), so that where an occluder is nearest the model's
    /// cleared values stay.
    pub(super) visibility_depth_occluder: wgpu::RenderPipeline,
    /// Indexed by [`Attributes::index`].
    pub(super) attribute: Vec<wgpu::RenderPipeline>,
    pub(super) resolve_layout: wgpu::BindGroupLayout,
    pub(super) resolve: wgpu::ComputePipeline,
    pub(super) gather: wgpu::ComputePipeline,
    /// Bound where an entry point has no points to read.
    pub(super) dummy_points: wgpu::Buffer,
    /// The back end that renders (never [`Backend::Auto`]).
    pub(super) backend: Backend,
    /// The compute back end's pipelines, when it renders.
    pub(super) compute: Option<ComputeSplatter>,
    /// `auto` on a CPU adapter: renders whose typical splat is wider than
    /// this (pixels, radius) go through the render pass
    /// ([`super::AUTO_CPU_RENDER_PASS_ABOVE_PX`]).
    pub(super) render_pass_above_px: Option<f64>,
    /// Buffers and bind groups of `read`/`gather`, kept across calls.
    pub(super) reuse: std::sync::Mutex<Reuse>,
    /// Held through a `read` or `gather`, whose kept buffers one call at a
    /// time may use.
    pub(super) busy: std::sync::Mutex<()>,
}

impl GpuSplatter {
    /// A splatter with `params`; its back end is resolved on this adapter
    /// ([`SplatError::Unsupported`] where none works).
    pub fn with_params(ctx: &GpuContext, params: SplatParams) -> Result<Self, SplatError> {
        let backend = params.backend.resolve(ctx)?;
        let compute = match backend {
            Backend::Compute => Some(ComputeSplatter::new(ctx)?),
            _ => None,
        };
        let forced = std::env::var(SPLATTER_ENV)
            .ok()
            .and_then(|v| Backend::parse(&v))
            .is_some_and(|b| b != Backend::Auto);
        let render_pass_above_px = (params.backend == Backend::Auto
            && !forced
            && backend == Backend::Compute
            && ctx.is_cpu())
        .then_some(AUTO_CPU_RENDER_PASS_ABOVE_PX);
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
        let masked = Some(wgpu::ColorTargetState {
            format: ACC_FORMAT,
            blend: None,
            write_mask: wgpu::ColorWrites::empty(),
        });
        let visibility_depth_occluder = pipeline(
            "splat visibility depth occluder",
            "fs_visibility_depth",
            true,
            &target_slots(Attributes::GEOMETRY).map(|on| if on { masked.clone() } else { None }),
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
            visibility_depth_occluder,
            attribute,
            resolve_layout,
            resolve,
            gather,
            dummy_points,
            backend,
            compute,
            render_pass_above_px,
            reuse: std::sync::Mutex::new(Reuse::new(ctx)),
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

    /// The back end that renders: [`Backend::RenderPass`] or
    /// [`Backend::Compute`] (what [`Backend::Auto`] chose on this adapter;
    /// on a CPU adapter `auto` still sends renders of large splats through
    /// the render pass: [`Splatter::backend_for`]).
    pub fn backend(&self) -> Backend {
        self.backend
    }
}
