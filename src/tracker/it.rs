//! The iterative step (IT, Dehais et al. 2010, section 4): the motion
//! predictors splatted at the previous pose; the previous frame's corners
//! that land on the object matched to the new ones by NCC; the predictors at
//! the old positions and the displacements solved for the update.

use super::config::Mode;
use super::decision::StepOutcome;
use super::error::TrackError;
use super::profile::Texture;
use super::region::{AFeatures, Placed, crop_window, match_near, match_near_resident, placed};
use super::result::StepError;
use super::state::{Frame, Tracker};
use super::workspace::estimate;
use crate::features::{Corner, ExportPlace, FeatureError, ResidentImage};
use crate::geometry::Pose;
use crate::gpu::PassChain;
use crate::pose::{Anchor, Correspondence, Refined};
use crate::splat::{Attributes, GatherSample, PendingGather, Window};
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

/// The frame's corners and what IT has of its work.
type WithCorners = (Vec<Corner>, Option<Result<ItEarly, StepError>>);

/// What IT has of its work before its step: its gather put off before
/// the frame's Harris ([`Tracker::it_gather_early`]), or with its matching
/// too, chained behind that Harris ([`Tracker::frame_corners_chained`]).
pub(super) enum ItEarly {
    Gather(PendingGather),
    Matched {
        /// The gather at every previous corner.
        samples: Vec<GatherSample>,
        /// (previous corner, frame corner) pairs.
        matches: Vec<(usize, usize)>,
    },
}

impl Tracker {
    /// IT, where the mode runs it and there is a previous frame (never
    /// while recovering): its outcome and, when fusing, its inliers.
    /// `early`: the gather [`Tracker::it_gather_early`] put off, if any.
    pub(super) fn it_stage(
        &mut self,
        frame: &Frame,
        pose: &Pose,
        recovering: bool,
        early: Option<Result<ItEarly, StepError>>,
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

    /// The frame's corners ([`Tracker::frame_corners`]) and, where IT
    /// chains on the GPU ([`super::Execution::chained_it`]), IT's matching
    /// recorded behind their detection, with one wait for both and IT's
    /// `early` gather; elsewhere the corners alone and the gather handed
    /// on for IT's step.
    pub(super) fn frame_corners_chained(
        &mut self,
        frame: &Frame,
        pose: &Pose,
        early: Option<Result<PendingGather, StepError>>,
    ) -> Result<WithCorners, TrackError> {
        let plan = match &early {
            Some(Ok(_)) => self.it_chain_plan(frame, pose),
            _ => None,
        };
        match (plan, early) {
            (Some(plan), Some(Ok(gather))) => self.it_chained(plan, gather),
            (_, early) => {
                let corners = self.frame_corners(frame, pose)?;
                Ok((corners, early.map(|r| r.map(ItEarly::Gather))))
            }
        }
    }

    /// What the chain needs, where it applies: resident frames, Harris
    /// and matching on the GPU, no interior probes, previous corners and a
    /// region of interest.
    fn it_chain_plan(&self, frame: &Frame, pose: &Pose) -> Option<ChainPlan> {
        if !self.resident.chain_it || self.harris.host() || self.config.it_interior_px > 0.0 {
            return None;
        }
        let (Some(now), Some(_)) = self.resident.frames() else {
            return None;
        };
        let prev = self.prev.as_ref()?;
        if prev.corners.is_empty() {
            return None;
        }
        let (window, roi) = self.frame_window(frame, pose)?;
        if window.width == 0 || window.height == 0 {
            return None;
        }
        let full = Window {
            x0: 0,
            y0: 0,
            width: now.width as u32,
            height: now.height as u32,
        };
        let margin = self.match_margin(self.config.it_search_px);
        let crop = crop_window(self.it_matcher.config(), &prev.corners, margin, full);
        (crop.width > 0 && crop.height > 0).then(|| ChainPlan {
            window,
            roi,
            crop,
            a: prev.corners.clone(),
        })
    }

    /// The chain ([`Tracker::frame_corners_chained`]): the frame's window
    /// packed and detected, its corners exported as B's features of IT's
    /// matching on the crop (the previous frame's corners as A's, gated
    /// by `gather`), one wait.
    fn it_chained(
        &mut self,
        plan: ChainPlan,
        gather: PendingGather,
    ) -> Result<WithCorners, TrackError> {
        let ChainPlan {
            window,
            roi,
            crop,
            a,
        } = plan;
        let t = std::time::Instant::now();
        let (ww, wh) = self.pack_frame_window(window, roi)?;
        let pending = self.harris.gpu()?.detect_packed_later(ww, wh)?;
        let (Some(now), Some(before)) = self.resident.frames() else {
            return Err(FeatureError::Config("IT's chain without resident frames".into()).into());
        };
        let (now_pixels, before_pixels) = (now.pixels.clone(), before.pixels.clone());
        let (nw, nh, bw, bh) = (now.width, now.height, before.width, before.height);
        let gate = self.splatter.gathered_samples(self.gpu_ctx()?)?;
        let o = window.origin();
        let c = crop.origin();
        let rows = crop.y0 as usize..(crop.y0 + crop.height) as usize;
        let place = ExportPlace {
            origin: o,
            clip: Some([
                c[0],
                c[1],
                c[0] + crop.width as f32,
                c[1] + crop.height as f32,
            ]),
            band_y0: rows.start as f32,
            first: a.len(),
        };
        let harris = self.harris.gpu()?;
        let it_matcher = self.it_matcher.gpu()?;
        let matching = {
            let mut export = |passes: &mut PassChain, positions: &wgpu::Buffer| {
                harris.export_corners(passes, &pending, place, positions, None)
            };
            it_matcher.match_resident_exported_b(
                ResidentImage {
                    pixels: &before_pixels,
                    width: bw,
                    height: bh,
                },
                rows.clone(),
                &a,
                Some(&gate),
                ResidentImage {
                    pixels: &now_pixels,
                    width: nw,
                    height: nh,
                },
                rows,
                pending.slots(),
                &mut export,
                [0, 0],
                None,
            )
        };
        self.stages.it_ncc += t.elapsed();
        // The one wait.
        let detected = self.harris.gpu()?.finish_later(pending)?;
        self.note_harris("features");
        let corners = placed(&detected.corners, o);
        let matching = match matching {
            Ok(m) => m,
            Err(e) => return Ok((corners, Some(Err(e.into())))),
        };
        if !detected.exported {
            log::trace!("IT: the chained matching is done again from the host's corners");
            drop(matching);
            return Ok((corners, Some(Ok(ItEarly::Gather(gather)))));
        }
        let t = std::time::Instant::now();
        let early = self
            .it_matcher
            .gpu()
            .map_err(StepError::from)
            .and_then(|m| Ok(m.finish_exported(matching, a.len())?))
            .and_then(|found| {
                let matches = found
                    .into_iter()
                    .filter(|m| m.b < corners.len())
                    .map(|m| (m.a, m.b))
                    .collect();
                let samples = gather.wait(&self.device)?;
                Ok(ItEarly::Matched { samples, matches })
            });
        let timings = self.it_matcher.take_timings();
        self.note_timings("IT ncc", timings);
        self.stages.it_ncc += t.elapsed();
        Ok((corners, Some(early)))
    }

    /// IT's render and gather at `pts` (module docs of `it_gather_early`).
    fn it_render_and_gather(
        &mut self,
        pose: &Pose,
        pts: &[[f32; 2]],
    ) -> Result<PendingGather, StepError> {
        let window = self.view_window(pose);
        // The render goes with the gather's readback.
        let _batch = self.device.batch();
        let near = self.config.reuse_render_px as f64;
        if !self.reuse_render(pose, window, true, near) {
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
        early: Option<Result<ItEarly, StepError>>,
    ) -> Result<Refined, StepError> {
        let t = std::time::Instant::now();
        let pending = match early {
            Some(Ok(ItEarly::Matched { samples, matches })) => {
                self.stages.it_render += t.elapsed();
                let obs: Vec<Correspondence> = matches
                    .iter()
                    .map(|&(ia, ib)| {
                        let (a, b) = (&prev.corners[ia], &frame.corners[ib]);
                        self.correspondence(
                            &samples[ia],
                            Vector2::new(a.x as f64, a.y as f64),
                            Vector2::new(b.x as f64, b.y as f64),
                            pose,
                        )
                    })
                    .collect();
                return self.refine(&obs, pose, &[]);
            }
            Some(Ok(ItEarly::Gather(p))) => p,
            Some(Err(e)) => return Err(e),
            None => {
                let pts: Vec<[f32; 2]> = prev.corners.iter().map(|c| [c.x, c.y]).collect();
                self.it_render_and_gather(pose, &pts)?
            }
        };
        let samples = pending.wait(&self.device)?;
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
                    self.it_matcher.gpu()?,
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
        let timings = self.it_matcher.take_timings();
        self.note_timings("IT ncc", timings);
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

/// The chain's plan ([`Tracker::it_chain_plan`]): the frame's window for
/// Harris and its region of interest, the matching's crop, the previous
/// frame's corners.
struct ChainPlan {
    window: Window,
    roi: [usize; 4],
    crop: Window,
    a: Vec<Corner>,
}
