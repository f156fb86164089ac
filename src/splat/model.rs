//! A point model checked, packed ([`pack_model`]) and uploaded
//! ([`GpuModel`]).

use super::gpu_data::SplatGpu;
use super::{ModelBounds, SplatError, SplatParams};
use crate::gpu::GpuContext;
use crate::model::PointModel;

/// Checks a model and packs it for the GPU (and the CPU reference).
pub fn pack_model(model: &PointModel, params: &SplatParams) -> Result<Vec<SplatGpu>, SplatError> {
    let n = model.positions.len();
    if n == 0 {
        return Err(SplatError::EmptyModel);
    }
    let check = |what, got| {
        if got == n {
            Ok(())
        } else {
            Err(SplatError::Inconsistent {
                what,
                got,
                expected: n,
            })
        }
    };
    check("normals", model.normals.len())?;
    check("radii", model.radii.len())?;
    if let Some(c) = &model.colors {
        check("colours", c.len())?;
    }
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let (p, nrm, r) = (model.positions[i], model.normals[i], model.radii[i]);
        let len = nrm.length();
        if !(p.is_finite() && nrm.is_finite() && len > 0.0 && r > 0.0 && r.is_finite()) {
            return Err(SplatError::BadPoint { index: i });
        }
        let nrm = nrm / len;
        let c = model.colors.as_ref().map_or(params.default_color, |c| c[i]);
        out.push(SplatGpu {
            pos_radius: [p.x, p.y, p.z, r],
            normal: [nrm.x, nrm.y, nrm.z, 0.0],
            color: [c[0], c[1], c[2], 1.0],
        });
    }
    Ok(out)
}

/// A point model uploaded to the GPU.
pub struct GpuModel {
    pub(super) buffer: wgpu::Buffer,
    pub(super) count: u32,
    pub bounds: ModelBounds,
}

impl GpuModel {
    pub fn new(ctx: &GpuContext, model: &PointModel) -> Result<Self, SplatError> {
        Self::with_params(ctx, model, &SplatParams::default())
    }

    pub fn with_params(
        ctx: &GpuContext,
        model: &PointModel,
        params: &SplatParams,
    ) -> Result<Self, SplatError> {
        let packed = pack_model(model, params)?;
        let bytes = (packed.len() * std::mem::size_of::<SplatGpu>()) as u64;
        let limit = ctx
            .limits
            .max_storage_buffer_binding_size
            .min(ctx.limits.max_buffer_size);
        if bytes > limit || packed.len() > u32::MAX as usize {
            return Err(SplatError::TooLarge {
                points: packed.len(),
                bytes,
                limit,
            });
        }
        let buffer = ctx.buffer_init(
            "splats",
            &packed,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        );
        Ok(Self {
            buffer,
            count: packed.len() as u32,
            bounds: ModelBounds::of(model),
        })
    }

    pub fn len(&self) -> usize {
        self.count as usize
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
}
