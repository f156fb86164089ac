//! What the splatter keeps across resolves and gathers: grow-only
//! buffers, uniforms and the bind groups made on them.

use super::gpu_data::ResolveParams;
use crate::gpu::{BindCache, GpuContext, GrowBuffer, STORAGE_IN, STORAGE_OUT, Uniform};

/// Bind groups of resolves and gathers kept (one per recent targets and
/// output buffer).
pub(super) const KEPT_BINDS: usize = 4;
/// Render pass bind groups kept: those of resolves, and one per
/// occluder of a render behind a few.
const KEPT_RENDER_BINDS: usize = KEPT_BINDS + 8;

/// The buffers [`Splatter::read`](super::Splatter::read) and [`Splatter::gather`](super::Splatter::gather) reuse
/// (grow-only) and the bind groups made on them.
pub(super) struct Reuse {
    /// The uniform of each resolve kind (indexed by kind).
    pub(super) params: [Option<Uniform>; 6],
    pub(super) gather_params: Option<Uniform>,
    /// Indexed by [`Grown`].
    pub(super) buffers: [GrowBuffer; 3],
    pub(super) binds: Vec<(BindKey, wgpu::BindGroup)>,
    /// The render pass back end's, by camera uniform (the targets' or an
    /// occluder's), geometry and colours.
    pub(super) render_binds: BindCache<3>,
    /// The last gather, given back to the context at this mark: its
    /// points and parameters, written by `Queue::write_buffer`, must not
    /// be overwritten before it is submitted.
    pub(super) last_gather: Option<crate::gpu::SubmissionMark>,
}

#[derive(Clone, Copy)]
pub(super) enum Grown {
    Read = 0,
    Gather = 1,
    Points = 2,
}

pub(super) fn resolve_params(ctx: &GpuContext) -> Uniform {
    Uniform::new(
        ctx,
        "splat resolve params",
        std::mem::size_of::<ResolveParams>() as u64,
    )
}

/// What a kept resolve bind group binds.
#[derive(PartialEq)]
pub(super) struct BindKey {
    pub(super) view: wgpu::TextureView,
    pub(super) params: wgpu::Buffer,
    pub(super) out: wgpu::Buffer,
    pub(super) points: Option<wgpu::Buffer>,
}

impl Reuse {
    /// Nothing kept yet but the uniforms.
    pub(super) fn new(ctx: &GpuContext) -> Self {
        Reuse {
            params: std::array::from_fn(|_| Some(resolve_params(ctx))),
            gather_params: Some(resolve_params(ctx)),
            buffers: [
                GrowBuffer::new("splat image", STORAGE_OUT),
                GrowBuffer::new("gather out", STORAGE_OUT),
                GrowBuffer::new("gather points", STORAGE_IN),
            ],
            binds: Vec::new(),
            render_binds: BindCache::keeping(KEPT_RENDER_BINDS),
            last_gather: None,
        }
    }
}
