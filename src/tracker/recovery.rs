//! Where a recovering frame's wide KF step starts: the last pose, that
//! pose turned by [`RING_TURN_DEG`] about [`RING_AXES`] axes in the image
//! plane, and each keyframe's view of the object seen from where the
//! object was last (its rotation carried to that line of sight, its
//! centre there), in turn; two a frame where the first gives nothing to
//! trust and the frame's budget has room. During a short loss of a
//! tracked object the last pose is each frame's first start, the cycle's
//! the second: an object lost to a blur or a passing hand most often
//! shows again where it was.
//!
//! An object lost while it turned (hidden by another, or moved too fast)
//! or started from a wrong pose is seldom found again from the last pose
//! alone: the KF step matches a view of the object as it was, and after
//! 20 degrees of turning its patches no longer correlate. Among the
//! turns and the keyframes' views one is near however the object turned.
//! Each start costs what the step from the last pose costs; the pose
//! check judges each outcome, more strictly than a tracked frame's
//! ([`super::verify::VerifyConfig::recovery_zncc`]).
//!
//! An object hidden by another moves on while out of sight: its rounds of
//! starts turn about where its drift ([`super::drift::Drift`]) carries
//! the last pose and about the last pose, in turn.

use super::decision::{Decision, verified};
use super::result::Status;
use super::state::Tracker;
use super::verify::{Unverified, VerifyScores};
use crate::geometry::Pose;
use nalgebra::{Rotation3, Vector3};

/// A keyframe's start closer than this to the last pose's rotation adds
/// nothing to the start from the last pose (the KF step's reach), degrees.
const SAME_START_DEG: f64 = 8.0;

/// Axes in the image plane the last pose is turned about, evenly spaced.
const RING_AXES: usize = 8;

/// How far the last pose is turned about each, degrees.
const RING_TURN_DEG: f64 = 20.0;

/// Lost frames, after a tracked one, that start from the last pose first.
const SHORT_LOSS: usize = 10;

impl Tracker {
    /// The first start of a recovering frame's KF step. In the first
    /// [`SHORT_LOSS`] frames of a loss that followed a tracked frame (a
    /// blur, a glitch, a hand passing; not a loss from the first frame
    /// nor one hidden by another object): a pose a turned start reached
    /// that passed only the usual check, else the last pose, where such
    /// an object most often shows again. Else the cycle's next start
    /// ([`Self::recovery_start`]).
    pub(super) fn recovery_first(&mut self) -> Pose {
        if self.short_loss() {
            return self.recovery_next.take().unwrap_or(self.pose);
        }
        self.recovery_start()
    }

    /// The second start of a recovering frame (where the first gave
    /// nothing to trust and the budget has room): the cycle's next start,
    /// passing over the last pose where the first start was that.
    pub(super) fn recovery_second(&mut self) -> Pose {
        let p = self.recovery_start();
        if self.short_loss() && p == self.pose {
            return self.recovery_start();
        }
        p
    }

    /// Whether the last pose is each recovering frame's first start: the
    /// loss is short and followed a tracked frame, not a hiding.
    fn short_loss(&self) -> bool {
        self.recovery_tracked && !self.recovery_hidden && self.lost_streak <= SHORT_LOSS
    }

    /// Where an object lost while hidden by another is expected: the last
    /// pose moved by its drift ([`super::drift::Drift::carried`]); the
    /// last pose for any other loss.
    pub(super) fn expected_pose(&self) -> Pose {
        match self.drift.carried().filter(|_| self.recovery_hidden) {
            Some(d) => Pose {
                rotation: self.pose.rotation,
                translation: self.pose.translation + d,
            },
            None => self.pose,
        }
    }

    /// The start of the next recovering frame's KF step (module docs): a
    /// pose a turned start reached that passed only the usual check, else
    /// the last pose, then each other start, then round again. An object
    /// lost while hidden by another takes its rounds about where its drift
    /// takes it and about the last pose in turn.
    pub(super) fn recovery_start(&mut self) -> Pose {
        if let Some(p) = self.recovery_next.take() {
            return p;
        }
        // Rounds are counted by the starts about the last pose; those
        // about the expected one are made only where it differs.
        let about_last = self.recovery_starts(&self.pose);
        let round = self.recovery_turn / (about_last.len() + 1);
        let base = if round.is_multiple_of(2) {
            self.expected_pose()
        } else {
            self.pose
        };
        let starts = if base == self.pose {
            about_last
        } else {
            self.recovery_starts(&base)
        };
        let i = self.recovery_turn % (starts.len() + 1);
        self.recovery_turn += 1;
        let p = if i == 0 { base } else { starts[i - 1] };
        log::debug!("recovery: start {i} of {}", starts.len() + 1);
        p
    }

    /// `d` of a frame that starts a track (the first, or one ending a
    /// loss), whose check gave `scores`: an object seen by its texture
    /// needs [`super::verify::VerifyConfig::recovery_zncc`] besides the
    /// usual check; a pose that passes only that is where the next frame
    /// starts.
    pub(super) fn judge_start(&mut self, d: Decision, scores: Option<&VerifyScores>) -> Decision {
        let cfg = &self.config;
        if !cfg.modalities.texture || !cfg.verify.enabled || d.status != Status::Tracking {
            return d;
        }
        let zncc = scores.and_then(|s| s.zncc);
        let min = cfg.verify.recovery_zncc;
        if zncc.is_some_and(|z| z >= min) {
            return d;
        }
        self.recovery_next = d.pose;
        verified(d, Err(Unverified::Recovery { zncc, min }))
    }

    /// The other starts about `last`: its turns and the keyframes' starts
    /// (nearest first), taken in turn; the turns first after the object
    /// was hidden by another (it turned while out of sight, most often by
    /// less than a keyframe's spacing).
    fn recovery_starts(&self, last: &Pose) -> Vec<Pose> {
        let Some(store) = self.store.as_ref() else {
            return Vec::new();
        };
        let last = *last;
        let at = last.transform_point(&store.center);
        // A rotation of the object with its centre where it was last.
        let centred = |rotation: nalgebra::Matrix3<f64>| Pose {
            rotation,
            translation: at - rotation * store.center,
        };
        let mut starts: Vec<(f64, Pose)> = store
            .keyframes
            .iter()
            .filter_map(|k| {
                let seen = k.pose.transform_point(&store.center);
                let turn =
                    Rotation3::rotation_between(&seen, &at).unwrap_or_else(Rotation3::identity);
                let pose = centred(turn.matrix() * k.pose.rotation);
                let d = pose.rotation_error_deg(&last);
                (d > SAME_START_DEG).then_some((d, pose))
            })
            .collect();
        starts.sort_by(|a, b| a.0.total_cmp(&b.0));
        // Turns of the last pose about its centre.
        let ring = (0..RING_AXES).map(|i| {
            let a = i as f64 * std::f64::consts::TAU / RING_AXES as f64;
            let axis = nalgebra::Unit::new_normalize(Vector3::new(a.cos(), a.sin(), 0.0));
            centred(
                Rotation3::from_axis_angle(&axis, RING_TURN_DEG.to_radians()).matrix()
                    * last.rotation,
            )
        });
        let mut kf = starts.into_iter().map(|(_, p)| p);
        if self.recovery_hidden {
            return ring.chain(kf).collect();
        }
        let mut out = Vec::new();
        for r in ring {
            out.push(r);
            out.extend(kf.next());
        }
        out.extend(kf);
        out
    }
}
