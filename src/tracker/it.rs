//! The iterative step (IT, Dehais et al. 2010, section 4): the motion
//! predictors splatted at the previous pose; the previous frame's corners
//! that land on the object matched to the new ones by NCC; the predictors at
//! the old positions and the displacements solved for the update.

use super::profile::Texture;
use super::view::{Placed, match_near, match_near_resident};
use super::{Frame, Mode, StepError, StepOutcome, Tracker, estimate};
use crate::features::Corner;
use crate::geometry::Pose;
use crate::pose::{Anchor, Correspondence, Refined};
use crate::splat::Attributes;
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
    pub(super) fn it_stage(
        &mut self,
        frame: &Frame,
        pose: &Pose,
        recovering: bool,
    ) -> (StepOutcome, Vec<Anchor>) {
        if !matches!(self.config.mode, Mode::It | Mode::KfIt) || recovering {
            return (StepOutcome::default(), Vec::new());
        }
        let Some(prev) = self.prev.take() else {
            return (StepOutcome::default(), Vec::new());
        };
        match self.it_step(&prev, frame, pose) {
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

    /// Frame-to-frame step from the previous frame's corners.
    fn it_step(&mut self, prev: &Frame, frame: &Frame, pose: &Pose) -> Result<Refined, StepError> {
        let t = std::time::Instant::now();
        let window = self.view_window(pose);
        // The render (where the check of the previous frame did not make
        // it already) goes with the gather's readback.
        let _batch = self.ctx.batch();
        if !self.reuse_render(pose, window) {
            let cam = self.use_window(window);
            self.splat(Texture::None, &cam, pose, Attributes::MOTION, "IT")?;
        }
        let pts: Vec<[f32; 2]> = prev.corners.iter().map(|c| [c.x, c.y]).collect();
        let samples = self.gather_frame(&pts)?;
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
                let full = Placed::full(&prev.grey).at;
                match_near_resident(
                    &mut self.it_matcher,
                    (before, full),
                    &src,
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
                Placed::full(&prev.grey),
                &src,
                &frame.grey,
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
