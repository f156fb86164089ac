//! The iterative step (IT, Dehais et al. 2010, section 4): the motion
//! predictors splatted at the previous pose; the previous frame's corners
//! that land on the object matched to the new ones by NCC; the predictors at
//! the old positions and the displacements solved for the update.

use super::profile::Texture;
use super::view::{AFeatures, Placed, match_near, match_near_resident};
use super::{Frame, Mode, StepError, StepOutcome, Tracker, estimate};
use crate::features::Corner;
use crate::geometry::Pose;
use crate::pose::{Anchor, Correspondence, Refined};
use crate::splat::{Attributes, PendingGather};
use nalgebra::Vector2;

/// Where `it_interior_px` probes around a corner, in units of that distance.
const RING: [(f32, f32); 8] = [
    (-1.0, -1.0),
    (0.0, -1.0),
    (1.0, -1.0),
    (-1.0, 0.0),
    (1.0, 0.0),
    (-1.0, 1.0),
    (0.0, 1.0),
    (1.0, 1.0),
];

impl Tracker {
    /// IT, where the mode runs it and there is a previous frame (never
    /// while recovering): its outcome and, when fusing, its inliers.
    /// `early`: the gather [`Tracker::it_gather_early`] put off, if any.
    pub(super) fn it_stage(
        &mut self,
        frame: &Frame,
        pose: &Pose,
        recovering: bool,
        early: Option<Result<PendingGather, StepError>>,
    ) -> (StepOutcome, Vec<Anchor>) {
        if !self.it_runs(recovering) {
            return (StepOutcome::default(), Vec::new());
        }
        let Some(prev) = self.prev.take() else {
            return (StepOutcome::default(), Vec::new());
        };
        match self.it_step(&prev, frame, pose, early) {
            Ok(step) => {
                let outcome = StepOutcome::from_result(Ok(estimate(&step)));
                let anchors = if self.config.fuse || self.config.modalities.contour {
                    step.anchors
                } else {
                    Vec::new()
                };
                (outcome, anchors)
            }
            Err(e) => (StepOutcome::from_result(Err(e)), Vec::new()),
        }
    }

    /// Whether the IT step runs this frame (where the mode runs it, never
    /// while recovering, and with a previous frame).
    fn it_runs(&self, recovering: bool) -> bool {
        matches!(self.config.mode, Mode::It | Mode::KfIt) && !recovering && self.prev.is_some()
    }

    /// IT's render at `pose` (where the check of the previous frame did
    /// not make it already) and its gather at the previous frame's
    /// corners, the gather's readback put off: before the frame's Harris,
    /// both go with its readback (neither needs the frame). `None` where
    /// IT does not run.
    pub(super) fn it_gather_early(
        &mut self,
        pose: &Pose,
        recovering: bool,
    ) -> Option<Result<PendingGather, StepError>> {
        if !self.it_runs(recovering) {
            return None;
        }
        let t = std::time::Instant::now();
        let pts: Vec<[f32; 2]> = self
            .prev
            .as_ref()?
            .corners
            .iter()
            .map(|c| [c.x, c.y])
            .collect();
        let r = self.it_render_and_gather(pose, &pts);
        self.stages.it_render += t.elapsed();
        Some(r)
    }

    /// IT's render and gather at `pts` (module docs of `it_gather_early`).
    fn it_render_and_gather(
        &mut self,
        pose: &Pose,
        pts: &[[f32; 2]],
    ) -> Result<PendingGather, StepError> {
        let window = self.view_window(pose);
        // The render goes with the gather's readback.
        let _batch = self.ctx.batch();
        if !self.reuse_render(pose, window) {
            let cam = self.use_window(window);
            self.splat(Texture::None, &cam, pose, Attributes::MOTION, "IT")?;
        }
        Ok(self.gather_frame_later(pts)?)
    }

    /// Frame-to-frame step from the previous frame's corners (their
    /// gather `early`, if put off before the frame's Harris).
    fn it_step(
        &mut self,
        prev: &Frame,
        frame: &Frame,
        pose: &Pose,
        early: Option<Result<PendingGather, StepError>>,
    ) -> Result<Refined, StepError> {
        let t = std::time::Instant::now();
        let pending = match early {
            Some(p) => p?,
            None => {
                let pts: Vec<[f32; 2]> = prev.corners.iter().map(|c| [c.x, c.y]).collect();
                self.it_render_and_gather(pose, &pts)?
            }
        };
        let samples = pending.wait(&self.ctx)?;
        // Only corners on the object take part; with `it_interior_px`, only
        // those whose surroundings are on the object too (see the field).
        let mut on_object: Vec<usize> = (0..samples.len()).filter(|&i| samples[i].valid).collect();
        let r = self.config.it_interior_px;
        if r > 0.0 && !on_object.is_empty() {
            let probes: Vec<[f32; 2]> = on_object
                .iter()
                .flat_map(|&i| {
                    let c = prev.corners[i];
                    RING.iter()
                        .map(move |(dx, dy)| [c.x + dx * r, c.y + dy * r])
                })
                .collect();
            let ring = self.gather_frame(&probes)?;
            on_object = on_object
                .iter()
                .zip(ring.chunks(RING.len()))
                .filter(|(_, ring)| ring.iter().all(|s| s.valid))
                .map(|(&i, _)| i)
                .collect();
        }
        self.stages.it_render += t.elapsed();
        let t = std::time::Instant::now();
        let src: Vec<Corner> = on_object.iter().map(|&i| prev.corners[i]).collect();
        let margin = self.match_margin(self.config.it_search_px);
        let matches = match self.resident.frames() {
            (Some(now), Some(before)) => {
                let full = prev.whole();
                match_near_resident(
                    &mut self.it_matcher,
                    (before, full),
                    AFeatures::InFrame(&src),
                    now,
                    &frame.corners,
                    margin,
                    None,
                )?
                .into_iter()
                .map(|m| (m.a, m.b))
                .collect::<Vec<_>>()
            }
            _ => match_near(
                &mut self.it_matcher,
                Placed::full(prev.grey()),
                &src,
                frame.grey(),
                &frame.corners,
                margin,
            )?
            .0
            .into_iter()
            .map(|m| (m.a, m.b))
            .collect(),
        };
        let timings = self.it_matcher.last_timings().clone();
        self.note_ncc("IT", timings);
        self.stages.it_ncc += t.elapsed();
        let obs: Vec<Correspondence> = matches
            .iter()
            .map(|&(ia, ib)| {
                let a = &src[ia];
                // Frame-to-frame, both images are equally sharp: the
                // detected corners are unbiased against each other.
                let b = &frame.corners[ib];
                self.correspondence(
                    &samples[on_object[ia]],
                    Vector2::new(a.x as f64, a.y as f64),
                    Vector2::new(b.x as f64, b.y as f64),
                    pose,
                )
            })
            .collect();
        self.refine(&obs, pose, &[])
    }
}
