//! The residual rows of contour points, and points lifted to move with a
//! pose.

use super::outline::ContourPoint;
use crate::geometry::Pose;
use crate::pose::Observation;
use nalgebra::{Matrix2x6, Vector2};

/// The residual row of a contour point whose predictors are `l` and
/// normal `n`, with the boundary found `d` pixels along the normal: the
/// first predictor row is `n^T L`, the second zero, so that
/// [`crate::pose::irls`] sees the scalar residual `n^T L a - d`.
pub fn contour_row(l: &Matrix2x6<f64>, n: &Vector2<f64>, d: f64) -> Observation {
    let row = n.transpose() * l;
    let mut predictors = Matrix2x6::zeros();
    predictors.set_row(0, &row);
    Observation {
        predictors,
        displacement: Vector2::new(d, 0.0),
    }
}

/// The rows of `points` with `d = 0` ([`contour_row`]), their predictors
/// `L` from the splatted depth `depth` (one channel, NaN where empty) at
/// each point's pixel, lifted to the camera-space point: the projection's
/// Jacobian that the splatter's motion targets hold there
/// (docs/how-it-works.md), without rendering them.
pub fn contour_predictors(
    cam: &crate::geometry::Intrinsics,
    depth: &crate::splat::SplatImage,
    points: &[ContourPoint],
) -> Vec<Observation> {
    let depths: Vec<f32> = points
        .iter()
        .map(|p| depth.pixel(p.pixel[0], p.pixel[1])[0])
        .collect();
    contour_predictors_at(cam, points, &depths)
}

/// [`contour_predictors`] with the depth at each point's pixel given.
pub(super) fn contour_predictors_at(
    cam: &crate::geometry::Intrinsics,
    points: &[ContourPoint],
    depths: &[f32],
) -> Vec<Observation> {
    points
        .iter()
        .zip(depths)
        .map(|(p, &z)| {
            let xc = cam.unproject(
                &Vector2::new(p.pixel[0] as f64, p.pixel[1] as f64),
                z as f64,
            );
            contour_row(&cam.motion_predictors(&xc), &p.normal, 0.0)
        })
        .collect()
}

/// The robust-scale groups of the fused solve.
pub(super) const GROUP_TEXTURE: u8 = 0;
pub(super) const GROUP_CONTOUR: u8 = 1;

/// A contour point found at some pose, with its row there and its edge
/// position lifted to that pose's camera frame (so that it can be moved
/// to a nearby pose without rendering again).
#[derive(Debug, Clone, Copy)]
pub(super) struct Lifted {
    /// Frame coordinates.
    pub(super) point: ContourPoint,
    /// The camera-space point of the edge position.
    pub(super) xc: nalgebra::Vector3<f64>,
    /// [`contour_row`] with `d = 0`.
    pub(super) row: Observation,
}

impl Lifted {
    /// The point moved by `motion` (camera frame to camera frame): its
    /// projection and row there; its image normal kept.
    pub(super) fn moved(&self, motion: &Pose, cam: &crate::geometry::Intrinsics) -> Option<Lifted> {
        let xc = motion.transform_point(&self.xc);
        let uv = cam.project(&xc)?;
        Some(Lifted {
            point: ContourPoint {
                position: uv,
                ..self.point
            },
            xc,
            row: contour_row(&cam.motion_predictors(&xc), &self.point.normal, 0.0),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contour_row_is_the_normal_part_of_the_motion() {
        let l = Matrix2x6::from_fn(|r, c| (r * 6 + c) as f64 - 3.0);
        let n = Vector2::new(0.6, -0.8);
        let o = contour_row(&l, &n, 1.5);
        let a = nalgebra::Vector6::new(0.1, -0.2, 0.3, 0.01, 0.02, -0.03);
        let r = (o.predictors * a - o.displacement).norm();
        assert!((r - (n.dot(&(l * a)) - 1.5).abs()).abs() < 1e-12);
    }
}
