//! A point model checked, packed ([`pack_model`]) and uploaded
//! ([`GpuModel`]): its geometry once, its colours in a small buffer of
//! their own that models textured by other keyframes replace
//! ([`GpuModel::with_colors`]).

use super::gpu_data::{SplatGpu, pack_color};
use super::{ModelBounds, SplatError, SplatParams};
use crate::gpu::GpuContext;
use crate::model::PointModel;

/// A model as the splatter reads it: the geometry of each splat and its
/// colour ([`pack_color`]).
#[derive(Debug, Clone, PartialEq)]
pub struct PackedModel {
    pub splats: Vec<SplatGpu>,
    pub colors: Vec<u32>,
}

/// Checks a model and packs it for the GPU (and the CPU reference).
pub fn pack_model(model: &PointModel, params: &SplatParams) -> Result<PackedModel, SplatError> {
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
    let mut colors = Vec::with_capacity(n);
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
        });
        colors.push(pack_color(c));
    }
    Ok(PackedModel {
        splats: out,
        colors,
    })
}

/// A point model uploaded to the GPU: the geometry (32 bytes a point),
/// shared by every recoloured copy, and the colours (4 bytes a point).
pub struct GpuModel {
    pub(super) geometry: wgpu::Buffer,
    pub(super) colors: wgpu::Buffer,
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
        let n = packed.splats.len();
        let bytes = (n * std::mem::size_of::<SplatGpu>()) as u64;
        let limit = ctx
            .limits
            .max_storage_buffer_binding_size
            .min(ctx.limits.max_buffer_size);
        if bytes > limit || n > u32::MAX as usize {
            return Err(SplatError::TooLarge {
                points: n,
                bytes,
                limit,
            });
        }
        let geometry = ctx.buffer_init(
            "splats",
            &packed.splats,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        );
        Ok(Self {
            geometry,
            colors: Self::color_buffer(ctx, &packed.colors),
            count: n as u32,
            bounds: ModelBounds::of(model),
        })
    }

    fn color_buffer(ctx: &GpuContext, colors: &[u32]) -> wgpu::Buffer {
        ctx.buffer_init(
            "splat colours",
            colors,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        )
    }

    /// The same geometry with other colours (one per point, linear RGB
    /// 0..1, e.g. a keyframe's): only a colour buffer of 4 bytes a point is
    /// uploaded; the geometry buffer is shared.
    pub fn with_colors(&self, ctx: &GpuContext, colors: &[[f32; 3]]) -> Result<Self, SplatError> {
        if colors.len() != self.len() {
            return Err(SplatError::Inconsistent {
                what: "colours",
                got: colors.len(),
                expected: self.len(),
            });
        }
        let packed: Vec<u32> = colors.iter().map(|&c| pack_color(c)).collect();
        Ok(Self {
            geometry: self.geometry.clone(),
            colors: Self::color_buffer(ctx, &packed),
            count: self.count,
            bounds: self.bounds,
        })
    }

    /// GPU bytes of the colours alone (what a recoloured copy adds).
    pub fn color_bytes(&self) -> u64 {
        self.colors.size()
    }

    /// GPU bytes of this model: geometry and colours (36 bytes a point).
    pub fn gpu_bytes(&self) -> u64 {
        self.geometry_bytes() + self.color_bytes()
    }

    /// GPU bytes of the geometry (shared by recoloured copies).
    pub fn geometry_bytes(&self) -> u64 {
        self.geometry.size()
    }

    pub fn len(&self) -> usize {
        self.count as usize
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
}
