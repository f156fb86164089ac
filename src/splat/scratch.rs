//! The compute back end's per-size scratch, kept in the targets it
//! renders into ([`SplatTargets`](super::SplatTargets)).

use super::error::SplatError;
use super::gpu_data::{ACC_STRIDE, ComputeParams};
use crate::gpu::{GpuContext, GrowBuffer, Uniform};

/// Per-size scratch of the compute back end, kept in [`SplatTargets`](super::SplatTargets):
/// the depth keys, the fixed-point sums and the parameters.
pub(super) struct Scratch {
    pub(super) depth: wgpu::Buffer,
    pub(super) acc: wgpu::Buffer,
    pub(super) params: Uniform,
    /// The splats' pixel bounding box and the count of large splats, in
    /// two halves of 8 u32: a render uses one and its last pass zeroes
    /// the other for the next (no clear between renders).
    pub(super) bounds: wgpu::Buffer,
    /// The half the next render uses.
    pub(super) slot: u32,
    /// The list of large splats (one u32 per splat of the largest model).
    pub(super) big: GrowBuffer,
    /// The splat's bind groups by the buffers that vary (the model's
    /// geometry and colours, the list of large splats), most recent
    /// first: the frame loop's renders (a keyframe's colours, the bare
    /// geometry) bind anew only when a model or the list changes.
    pub(super) binds: Vec<([wgpu::Buffer; 3], wgpu::BindGroup)>,
    /// One per occluder of the most occluded render here.
    pub(super) occluders: Vec<OccluderSlot>,
}

/// An occluder's own buffers in a [`Scratch`]: its camera uniform and
/// parameters (written before the submission, so one per occluder), and
/// its bind group by the buffers that vary (as [`Scratch::binds`]).
pub(super) struct OccluderSlot {
    pub(super) uniform: wgpu::Buffer,
    pub(super) params: Uniform,
    pub(super) bind: Option<([wgpu::Buffer; 3], wgpu::BindGroup)>,
}

impl OccluderSlot {
    pub(super) fn new(ctx: &GpuContext) -> Self {
        Self {
            uniform: super::gpu_data::camera_buffer(ctx),
            params: params_uniform(ctx),
            bind: None,
        }
    }
}

fn params_uniform(ctx: &GpuContext) -> Uniform {
    Uniform::new(
        ctx,
        "compute splat params",
        std::mem::size_of::<ComputeParams>() as u64,
    )
}

/// Bind groups a [`Scratch`] keeps: the frame loop's two models (each
/// keeps its buffers alive, so no more: a keyframe's colours dropped
/// from the cache are freed at the next change).
pub(super) const KEPT_BINDS: usize = 2;

impl Scratch {
    pub(super) fn new(ctx: &GpuContext, width: u32, height: u32) -> Result<Self, SplatError> {
        let pixels = width as u64 * height as u64;
        let acc_bytes = pixels * ACC_STRIDE as u64 * 4;
        let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        ctx.check_buffer_size("compute splatter sums", acc_bytes, usage)?;
        Ok(Self {
            depth: ctx.buffer("compute splat depth", pixels * 4, usage),
            acc: ctx.buffer("compute splat sums", acc_bytes, usage),
            params: params_uniform(ctx),
            bounds: ctx.buffer("compute splat bounds", 64, usage),
            slot: 0,
            big: GrowBuffer::new("compute splat large splats", wgpu::BufferUsages::STORAGE),
            binds: Vec::new(),
            occluders: Vec::new(),
        })
    }
}

impl Scratch {
    /// GPU bytes of this scratch: the depth keys (4 a pixel), the sums
    /// (4 * ACC_STRIDE a pixel), the list of large splats (4 a splat of the
    /// largest model rendered) and the small buffers.
    pub(super) fn gpu_bytes(&self) -> u64 {
        [&self.depth, &self.acc, self.params.buffer(), &self.bounds]
            .iter()
            .map(|b| b.size())
            .sum::<u64>()
            + self.big.size()
            + self
                .occluders
                .iter()
                .map(|o| o.uniform.size() + o.params.buffer().size())
                .sum::<u64>()
    }
}
