//! An object's motion before a loss ([`Drift`]), for the recovery's
//! starts and the visibility of an object hidden by others.

use nalgebra::Vector3;

/// Tracked frames in a row the object's drift is measured over.
const DRIFT_FRAMES: usize = 5;

/// The most lost frames a drift is carried over.
const DRIFT_CARRY: usize = 60;

/// The object's motion over its last tracked frames, carried on while it
/// is lost: an object hidden by another most often moves on as it moved
/// (the default `hide` scene's box passes behind the blob), and comes out
/// where its drift takes it, not where it went in.
#[derive(Debug, Default, Clone)]
pub(super) struct Drift {
    /// The object's centre (camera frame) at the last tracked frames in a
    /// row, oldest first.
    centres: Vec<Vector3<f64>>,
    /// Lost frames since the last tracked one.
    since: usize,
}

impl Drift {
    /// A tracked frame with the object's centre at `centre`.
    pub(super) fn tracked(&mut self, centre: Vector3<f64>) {
        if self.since > 0 {
            self.centres.clear();
        }
        if self.centres.len() == DRIFT_FRAMES {
            self.centres.remove(0);
        }
        self.centres.push(centre);
        self.since = 0;
    }

    /// A lost frame.
    pub(super) fn lost(&mut self) {
        self.since += 1;
    }

    /// How far the centre has moved since the last tracked frame at the
    /// mean velocity of the tracked frames before it (camera frame), for
    /// at most [`DRIFT_CARRY`] frames; `None` while tracked, or with
    /// fewer than three tracked frames in a row to measure.
    pub(super) fn carried(&self) -> Option<Vector3<f64>> {
        let n = self.centres.len();
        if n < 3 || self.since == 0 {
            return None;
        }
        let velocity = (self.centres[n - 1] - self.centres[0]) / (n - 1) as f64;
        Some(velocity * self.since.min(DRIFT_CARRY) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drift_carries_the_mean_motion_of_the_last_tracked_frames() {
        let mut d = Drift::default();
        let at = |x: f64| Vector3::new(x, 0.0, 0.5);
        d.tracked(at(0.0));
        d.tracked(at(0.01));
        d.lost();
        // Two tracked frames: no velocity yet.
        assert_eq!(d.carried(), None);
        // A loss breaks the row: it starts again.
        for x in [0.10, 0.12, 0.13, 0.15, 0.16, 0.18] {
            d.tracked(at(x));
        }
        assert_eq!(d.carried(), None, "tracked: nothing carried");
        d.lost();
        d.lost();
        // The last five: 0.12 to 0.18 in 4 frames, 0.015 a frame, 2 frames.
        let c = d.carried().expect("a drift");
        assert!((c - Vector3::new(0.03, 0.0, 0.0)).norm() < 1e-12, "{c}");
        for _ in 0..100 {
            d.lost();
        }
        let c = d.carried().expect("a drift");
        assert!((c.x - 0.015 * DRIFT_CARRY as f64).abs() < 1e-12, "{c}");
    }
}
