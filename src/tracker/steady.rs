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
//!
//! The same holds for the shading where the view shows no texture of its
//! own ([`super::VerifyConfig::shading_drop`]): what the render's normals
//! leave unexplained of the frame's brightness
//! ([`super::verify::VerifyScores::shading_rms`]) stays near its level
//! while the pose is right (at most 1.46 times the median of the frames
//! before on fresh renders, over the sequences of docs/trust.md) and rises
//! when a near-symmetric object slips about its axis (2.4 times at 6
//! degrees off, 2.9-4.9 times at 6-12 degrees). Its level from before a
//! loss holds the frames that end it (`recent::History::shading_level`).

use super::decision::{Decision, verified};
use super::recent::judge_steady;
use super::result::Status;
use super::state::Tracker;
use super::verify::VerifyScores;

impl Tracker {
    /// `d` of a frame that follows a tracked frame, whose check gave
    /// `scores` (module docs).
    pub(super) fn judge_steady(&self, d: Decision, scores: Option<&VerifyScores>) -> Decision {
        let cfg = &self.config.verify;
        let Some(s) = scores.filter(|_| cfg.enabled && d.status == Status::Tracking) else {
            return d;
        };
        match judge_steady(s, &self.steady, cfg.edge_drop, cfg.shading_drop) {
            Ok(()) => d,
            Err(why) => verified(d, Err(why)),
        }
    }

    /// Notes a frame's outcome in the history: a tracked frame's scores
    /// are kept, a lost frame clears it.
    pub(super) fn note_steady(&mut self, status: Status, scores: Option<&VerifyScores>) {
        match (status, scores) {
            (Status::Tracking, Some(s)) => self.steady.push(s),
            (Status::Tracking, None) => {}
            (Status::Lost, _) => self.steady.clear(),
        }
    }
}
