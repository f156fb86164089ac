//! Occluders: other objects splatted into a render's visibility depth
//! buffer before the model, so that the model's attributes leave out the
//! pixels they hide ([`super::Splatter::set_occluders`]).
//!
//! An occluder is splatted at its own pose with the render's camera into
//! the same depth buffer, mapped over the *model's* depth range (its
//! culling near plane stays its own, so an occluder in front of the
//! model's range still hides it: its depth clamps to 0). Only the model's
//! splats go through the attribute pass.

use super::gpu_data::CameraUniform;
use super::{GpuModel, SplatError, SplatParams};
use crate::geometry::{Intrinsics, Pose};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// The most occluders a splatter takes (the host splatter lists each
/// object's splats in parts of its own, 64 in all).
pub const MAX_OCCLUDERS: usize = 16;

/// Another object hiding part of the model a splatter renders: its
/// uploaded model (made on the splatter's device) and its pose (object to
/// camera), the camera being the render's. Shared models are cheap to
/// hand on: a tracker's ([`crate::tracker::Tracker`]) can serve another's renders.
#[derive(Clone)]
pub struct Occluder {
    /// The occluding object's splats.
    pub model: Arc<GpuModel>,
    /// Its pose in the camera of the renders it occludes.
    pub pose: Pose,
}

impl std::fmt::Debug for Occluder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Occluder")
            .field("points", &self.model.len())
            .field("pose", &self.pose)
            .finish()
    }
}

/// Generations of occluder sets: unique across splatters, so that targets
/// rendered by one never match another's set.
static NEXT_GENERATION: AtomicU64 = AtomicU64::new(1);

/// A splatter's occluders and the generation that names the set: bumped
/// by every change, shared with the targets it renders into so that their
/// last view is forgotten once the set changes.
pub(super) struct OccluderSet {
    pub(super) list: Vec<Occluder>,
    pub(super) generation: Arc<AtomicU64>,
}

impl Default for OccluderSet {
    fn default() -> Self {
        Self {
            list: Vec::new(),
            // 0: the empty set a splatter starts with.
            generation: Arc::new(AtomicU64::new(0)),
        }
    }
}

/// What targets remember of the occluders of their last render: the
/// splatter's generation counter and its value then.
#[derive(Clone)]
pub(super) struct Stamp {
    source: Arc<AtomicU64>,
    pub(super) generation: u64,
}

impl Stamp {
    /// Whether the splatter still has the occluders of the render.
    pub(super) fn current(&self) -> bool {
        self.source.load(Ordering::Relaxed) == self.generation
    }
}

impl OccluderSet {
    /// Replaces the set; refused (the set unchanged) when an occluder's
    /// model is of the other device kind, a pose is not rigid, or there
    /// are more than [`MAX_OCCLUDERS`]. An equal set (the same models at
    /// the same poses) keeps its generation.
    pub(super) fn set(&mut self, on_cpu: bool, occluders: Vec<Occluder>) -> Result<(), SplatError> {
        if occluders.len() > MAX_OCCLUDERS {
            return Err(SplatError::Unsupported(format!(
                "{} occluders, at most {MAX_OCCLUDERS}",
                occluders.len()
            )));
        }
        for o in &occluders {
            if o.model.on_cpu() != on_cpu {
                return Err(SplatError::WrongDevice("an occluder's model"));
            }
            o.pose.validate()?;
        }
        let same = self.list.len() == occluders.len()
            && self
                .list
                .iter()
                .zip(&occluders)
                .all(|(a, b)| Arc::ptr_eq(&a.model, &b.model) && a.pose == b.pose);
        if !same {
            let g = NEXT_GENERATION.fetch_add(1, Ordering::Relaxed);
            self.generation.store(g, Ordering::Relaxed);
        }
        self.list = occluders;
        Ok(())
    }

    /// The generation of the set now (0: never set).
    pub(super) fn generation(&self) -> u64 {
        self.generation.load(Ordering::Relaxed)
    }

    /// The stamp a render leaves in its targets.
    pub(super) fn stamp(&self) -> Stamp {
        Stamp {
            source: self.generation.clone(),
            generation: self.generation(),
        }
    }

    /// The occluders that can hide part of a render of `model_view` (the
    /// model's uniform) with `cam`, each with its own uniform over the
    /// model's depth range; those that cannot reach the image, or lie
    /// wholly behind the model's far end, are left out (they would write
    /// nothing that a depth test lets through).
    pub(super) fn views(
        &self,
        cam: &Intrinsics,
        params: &SplatParams,
        model_view: &CameraUniform,
    ) -> Result<Vec<(&GpuModel, CameraUniform)>, SplatError> {
        let (near, far) = (model_view.size[2], model_view.size[3]);
        let mut out = Vec::new();
        for o in &self.list {
            if o.model.is_empty() || !reaches(&o.model, &o.pose, cam, params, far as f64) {
                continue;
            }
            let view = o.model.bounds.view(cam, &o.pose, params)?;
            out.push((&*o.model, view.with_depth_range(near, far)));
        }
        Ok(out)
    }
}

/// Whether any splat of `model` at `pose` may cover a pixel of `cam`'s
/// image in front of camera-space depth `far`: its bounding sphere (grown
/// as [`super::ModelBounds::view`] grows it, and by the low-pass disc and
/// the quads' half-pixel margin at the image's edges) is in front of the
/// camera, nearer than `far`, and not wholly outside one of the four
/// planes through the camera and the image's edges.
fn reaches(
    model: &GpuModel,
    pose: &Pose,
    cam: &Intrinsics,
    params: &SplatParams,
    far: f64,
) -> bool {
    let b = &model.bounds;
    let c = pose.transform_point(&b.center);
    let r = b.radius + (2.0 + params.epsilon as f64) * b.max_splat_radius;
    if c.z + r <= 0.0 || c.z - r >= far {
        return false;
    }
    // Pixels beyond the image a splat's quad may still reach it from.
    let m = params.lowpass_px as f64 + 2.0;
    let (x0, x1) = (-0.5 - m, cam.width as f64 - 0.5 + m);
    let (y0, y1) = (-0.5 - m, cam.height as f64 - 0.5 + m);
    // Inside: f X + (c - e) Z >= 0 for the low edges, <= 0 for the high.
    let plane = |f: f64, along: f64, e: f64, centre: f64, low: bool| {
        let (a, b) = (f, centre - e);
        let d = (a * along + b * c.z) / (a * a + b * b).sqrt();
        if low { d >= -r } else { d <= r }
    };
    plane(cam.fx, c.x, x0, cam.cx, true)
        && plane(cam.fx, c.x, x1, cam.cx, false)
        && plane(cam.fy, c.y, y0, cam.cy, true)
        && plane(cam.fy, c.y, y1, cam.cy, false)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Device;
    use crate::model::shapes;
    use nalgebra::Vector3;

    fn model() -> GpuModel {
        let m = shapes::sphere(glam::Vec3::ZERO, 0.1, 200, 1.5);
        GpuModel::new(&Device::Cpu, &m).expect("model")
    }

    #[test]
    fn spheres_off_the_image_or_behind_the_model_are_left_out() {
        let cam = Intrinsics::new(64, 48, 60.0, 60.0, 31.5, 23.5);
        let p = SplatParams::default();
        let m = model();
        let at = |x: f64, y: f64, z: f64| {
            Pose::new(nalgebra::Matrix3::identity(), Vector3::new(x, y, z)).expect("pose")
        };
        assert!(reaches(&m, &at(0.0, 0.0, 1.0), &cam, &p, 10.0));
        // Just past the right edge: the sphere (radius ~0.1) still reaches.
        assert!(reaches(&m, &at(0.55, 0.0, 1.0), &cam, &p, 10.0));
        assert!(!reaches(&m, &at(1.0, 0.0, 1.0), &cam, &p, 10.0));
        assert!(!reaches(&m, &at(-1.0, 0.0, 1.0), &cam, &p, 10.0));
        assert!(!reaches(&m, &at(0.0, 1.0, 1.0), &cam, &p, 10.0));
        assert!(!reaches(&m, &at(0.0, -1.0, 1.0), &cam, &p, 10.0));
        assert!(!reaches(&m, &at(0.0, 0.0, -1.0), &cam, &p, 10.0));
        // Behind the far end of the model's range.
        assert!(!reaches(&m, &at(0.0, 0.0, 3.0), &cam, &p, 2.0));
        assert!(reaches(&m, &at(0.0, 0.0, 2.05), &cam, &p, 2.0));
    }
}
