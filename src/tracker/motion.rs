//! An object's recent motion, to say where it is while another object
//! hides it ([`Motion`]).

use crate::geometry::{Pose, rotation_exp, rotation_log};
use nalgebra::{Matrix3, Vector3};
use std::collections::VecDeque;

/// Tracked poses (consecutive frames) the velocity is measured over.
const SPAN: usize = 4;

/// Frames a prediction runs for at most: past them the object is looked
/// for where it was last seen (a constant velocity held longer is a guess).
const MAX_PREDICTED: usize = 60;

/// An object's motion: its last tracked poses, consecutive, and while it
/// is not tracked (hidden), where its last velocity would have taken it.
/// The velocity is the object's own: its centre's shift and its turn
/// about its centre, per frame, averaged over the last few frames, so
/// that a prediction moves the object along its path rather than swinging
/// it about the camera.
pub(super) struct Motion {
    /// The object's centre, model coordinates.
    center: Vector3<f64>,
    history: VecDeque<Pose>,
    /// The velocity measured when the track stopped: the centre's shift
    /// (camera frame) and the turn (rotation vector), per frame.
    velocity: Option<(Vector3<f64>, Vector3<f64>)>,
    /// The predicted pose, and frames predicted.
    predicted: Option<(Pose, usize)>,
}

impl Motion {
    pub(super) fn new(center: Vector3<f64>) -> Self {
        Self {
            center,
            history: VecDeque::with_capacity(SPAN),
            velocity: None,
            predicted: None,
        }
    }

    /// A frame tracked at `pose`.
    pub(super) fn tracked(&mut self, pose: Pose) {
        if self.history.len() == SPAN {
            self.history.pop_front();
        }
        self.history.push_back(pose);
        self.velocity = None;
        self.predicted = None;
    }

    /// A frame not tracked: the prediction moves one frame on (from the
    /// last tracked pose at the first such frame). `None` when there is
    /// no velocity (fewer than two tracked frames) or the prediction has
    /// run its course; the history is cleared either way (the next
    /// tracked frame does not follow the last).
    pub(super) fn untracked(&mut self) -> Option<Pose> {
        let (from, frames) = match self.predicted {
            Some((p, n)) => (p, n),
            None => {
                let (first, last) = (*self.history.front()?, *self.history.back()?);
                let steps = (self.history.len() - 1) as f64;
                if steps < 1.0 {
                    self.history.clear();
                    return None;
                }
                let c0 = first.transform_point(&self.center);
                let c1 = last.transform_point(&self.center);
                let turn = rotation_log(&(last.rotation * first.rotation.transpose())) / steps;
                self.velocity = Some(((c1 - c0) / steps, turn));
                self.history.clear();
                (last, 0)
            }
        };
        if frames >= MAX_PREDICTED {
            return None;
        }
        let (shift, turn) = self.velocity?;
        let rotation: Matrix3<f64> = rotation_exp(&turn) * from.rotation;
        let centre = from.transform_point(&self.center) + shift;
        let next = Pose::new(rotation, centre - rotation * self.center)
            .ok()?
            .orthonormalized();
        self.predicted = Some((next, frames + 1));
        Some(next)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_steady_motion_is_carried_on() {
        // An object turning 1 degree a frame about its own centre (off
        // the origin of its coordinates) while its centre moves.
        let center = Vector3::new(0.05, -0.02, 0.01);
        let axis = Vector3::new(0.3, 1.0, -0.2).normalize();
        let at = |k: f64| {
            let r = rotation_exp(&(axis * (k * 1f64.to_radians())));
            let c = Vector3::new(0.01 * k, -0.004 * k, 0.6 + 0.002 * k);
            Pose::new(r, c - r * center).unwrap()
        };
        let mut m = Motion::new(center);
        assert!(m.untracked().is_none(), "no velocity yet");
        for k in 0..6 {
            m.tracked(at(k as f64));
        }
        for k in 6..12 {
            let p = m.untracked().expect("a prediction");
            let truth = at(k as f64);
            assert!(p.rotation_error_deg(&truth) < 1e-6, "frame {k}");
            assert!((p.translation - truth.translation).norm() < 1e-9, "frame {k}");
        }
        // Tracked again: the prediction stops, and a single tracked pose
        // gives none.
        m.tracked(at(20.0));
        assert!(m.untracked().is_none());
    }

    #[test]
    fn a_prediction_runs_its_course() {
        let mut m = Motion::new(Vector3::zeros());
        for k in 0..3 {
            m.tracked(Pose::new(Matrix3::identity(), Vector3::new(0.001 * k as f64, 0.0, 1.0)).unwrap());
        }
        let n = std::iter::from_fn(|| m.untracked()).count();
        assert_eq!(n, MAX_PREDICTED);
    }
}
