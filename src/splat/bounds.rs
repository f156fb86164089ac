//! The one bounding-sphere computation of the crate, and the depth range
//! it gives at a pose.

use super::gpu_data::CameraUniform;
use super::{SplatError, SplatParams};
use crate::geometry::{Intrinsics, Pose};
use crate::model::PointModel;
use nalgebra::Vector3;

/// A bounding sphere of points: the centre of their bounding box and the
/// distance to the farthest point from it.
pub fn bounding_sphere(points: impl Iterator<Item = Vector3<f64>> + Clone) -> (Vector3<f64>, f64) {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for p in points.clone() {
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    let center = (lo + hi) / 2.0;
    let radius = points.map(|p| (p - center).norm()).fold(0.0, f64::max);
    (center, radius)
}

/// The bounding sphere and largest radius of a model: enough to choose the
/// depth range at any pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelBounds {
    /// Centre of the bounding sphere, in model coordinates.
    pub center: Vector3<f64>,
    /// Radius of the bounding sphere (model units).
    pub radius: f64,
    /// The largest splat radius (model units).
    pub max_splat_radius: f64,
    /// The median splat radius (model units; 0 for no points): how large
    /// a typical splat is (`Splatter::backend_for`).
    pub median_splat_radius: f64,
}

impl ModelBounds {
    /// Bounds of a checked model (the centre of the bounding box, the
    /// farthest point from it).
    pub fn of(model: &PointModel) -> Self {
        let (center, radius) = bounding_sphere(
            model
                .positions
                .iter()
                .map(|p| Vector3::new(p.x as f64, p.y as f64, p.z as f64)),
        );
        let max_splat_radius = model.radii.iter().fold(0.0f64, |m, &r| m.max(r as f64));
        let median_splat_radius = {
            let mut r = model.radii.clone();
            let mid = r.len() / 2;
            if r.is_empty() {
                0.0
            } else {
                *r.select_nth_unstable_by(mid, f32::total_cmp).1 as f64
            }
        };
        Self {
            center,
            radius,
            max_splat_radius,
            median_splat_radius,
        }
    }

    /// The uniform of a view: near and far planes from the bounding sphere at
    /// the pose (grown by the largest splat and its push-back).
    pub fn view(
        &self,
        cam: &Intrinsics,
        pose: &Pose,
        params: &SplatParams,
    ) -> Result<CameraUniform, SplatError> {
        cam.validate().map_err(SplatError::Camera)?;
        pose.validate()?;
        let zc = pose.transform_point(&self.center).z;
        let rr = self.radius + (2.0 + params.epsilon as f64) * self.max_splat_radius;
        let far = zc + rr;
        if far.is_nan() || far <= 0.0 {
            return Err(SplatError::BehindCamera { far });
        }
        let near = (zc - rr).max(far * 1e-4);
        Ok(CameraUniform::new(
            cam,
            pose,
            near as f32,
            far as f32,
            params.epsilon,
            params.lowpass_px,
        ))
    }
}
