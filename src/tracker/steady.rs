//! The check of a tracked frame against the track's own recent frames.
//!
//! The check's thresholds are absolute and loose, so that right poses on
//! real video pass (a real cube's right poses show 69-100% of their
//! outline on edges): a wrong pose that keeps half of its outline on
//! edges passes them too. While an object is tracked its edge support is
//! steady: over the synthetic and real sequences of docs/accuracy.md, a
//! right pose never had less than 0.79 times the median of the frames
//! before it, where the one wrong pose a step made (the printed box on
//! the fast trajectory, its model merged, 18 degrees off) had 0.53. So a
//! frame that follows a tracked frame needs
//! [`super::VerifyConfig::edge_drop`] of that median; a refused frame
//! starts a loss, its recovery from the last pose is checked as every
//! start is, and the history starts again, so a lasting change (a hand
//! over the object) costs one frame.

use super::decision::{Decision, verified};
use super::result::Status;
use super::state::Tracker;
use super::verify::{Unverified, VerifyScores};

/// The tracked frames whose edge support the median is taken over.
pub(super) const HISTORY: usize = 10;

/// Tracked frames needed before the rule applies.
const LEAST_HISTORY: usize = 5;

/// The recent frames' edge supports; `None` where too few are known.
pub(super) fn recent_edges(history: &[f64]) -> Option<f64> {
    if history.len() < LEAST_HISTORY {
        return None;
    }
    let mut v: Vec<f64> = history[history.len().saturating_sub(HISTORY)..].to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// The rule alone: `Err` where `edge_support` is below `ratio` times the
/// median of `history` (the frames tracked before it, oldest first).
pub(super) fn judge_steady(
    edge_support: Option<f64>,
    history: &[f64],
    ratio: f64,
) -> Result<(), Unverified> {
    let (Some(edges), Some(recent)) = (edge_support, recent_edges(history)) else {
        return Ok(());
    };
    if ratio > 0.0 && edges < ratio * recent {
        return Err(Unverified::EdgeDrop {
            edge_support: edges,
            recent,
            ratio,
        });
    }
    Ok(())
}

impl Tracker {
    /// `d` of a frame that follows a tracked frame, whose check gave
    /// `scores` (module docs).
    pub(super) fn judge_steady(&self, d: Decision, scores: Option<&VerifyScores>) -> Decision {
        let cfg = &self.config.verify;
        if !cfg.enabled || d.status != Status::Tracking {
            return d;
        }
        let edges = scores.and_then(|s| s.edge_support);
        match judge_steady(edges, &self.edge_history, cfg.edge_drop) {
            Ok(()) => d,
            Err(why) => verified(d, Err(why)),
        }
    }

    /// Notes a frame's outcome in the history: a tracked frame's edge
    /// support is kept (the last [`HISTORY`]), a lost frame clears it.
    pub(super) fn note_steady(&mut self, status: Status, scores: Option<&VerifyScores>) {
        match (status, scores.and_then(|s| s.edge_support)) {
            (Status::Tracking, Some(e)) => {
                if self.edge_history.len() == HISTORY {
                    self.edge_history.remove(0);
                }
                self.edge_history.push(e);
            }
            (Status::Tracking, None) => {}
            (Status::Lost, _) => self.edge_history.clear(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_median_needs_five_frames_and_takes_the_last_ten() {
        assert_eq!(recent_edges(&[0.9; 4]), None);
        assert_eq!(recent_edges(&[0.9, 0.5, 0.7, 0.8, 0.6]), Some(0.7));
        assert_eq!(recent_edges(&[0.9, 0.5, 0.7, 0.8, 0.6, 1.0]), Some(0.75));
        let mut h = vec![0.1; 5];
        h.extend([0.9; 10]);
        assert_eq!(recent_edges(&h), Some(0.9));
    }

    #[test]
    fn a_sudden_drop_is_refused_and_a_steady_track_is_not() {
        let steady = [0.95, 0.97, 0.99, 1.0, 0.96, 0.98];
        // The wrong pose measured on the box: 0.52 after 0.95-1.0.
        let err = judge_steady(Some(0.522), &steady, 0.7).expect_err("a drop");
        assert!(
            matches!(err, Unverified::EdgeDrop { recent, .. } if (recent - 0.975).abs() < 1e-12)
        );
        // The lowest right pose measured: 0.79 of its median.
        assert!(judge_steady(Some(0.79 * 0.975), &steady, 0.7).is_ok());
        // Too little history, no edges, or the rule off: no verdict.
        assert!(judge_steady(Some(0.1), &steady[..4], 0.7).is_ok());
        assert!(judge_steady(None, &steady, 0.7).is_ok());
        assert!(judge_steady(Some(0.1), &steady, 0.0).is_ok());
    }
}
