//! The per-frame step: [`Tracker::track`] runs the steps in turn and
//! decides the frame.

use super::config::Modalities;
use super::decision::{Decision, FrameSteps, Rules, StepOutcome, decide, verified};
use super::error::TrackError;
use super::result::{LostReason, Refused, Source, StageTimes, Status, TrackResult};
use super::state::{Frame, Tracker};
use super::verify::{self, Unverified, VerifyScores};
use crate::geometry::Pose;
use crate::pose::Anchor;
use std::time::{Duration, Instant};

/// A lost frame's budget's measure before any frame was timed.
const LOST_FALLBACK: Duration = Duration::from_millis(50);

impl Tracker {
    /// Tracks one frame (RGB, undistorted, the camera's size): Harris
    /// corners, the IT step, the KF step(s), then [`decide`]. The tracker
    /// keeps a copy of the frame for the next one (in a buffer of its
    /// own); [`Tracker::track_owned`] keeps the frame itself instead.
    pub fn track(&mut self, frame: &image::RgbImage) -> Result<TrackResult, TrackError> {
        self.track_input(FrameInput::Borrowed(frame))
    }

    /// [`Tracker::track`] on a frame handed over: the tracker keeps it for
    /// the next frame instead of copying it (the same poses). A caller
    /// that fills a buffer itself (a decoder, a binding) takes it from
    /// [`Tracker::frame_buffer`], so that a frame is copied once on its
    /// way to the GPU.
    pub fn track_owned(&mut self, frame: image::RgbImage) -> Result<TrackResult, TrackError> {
        self.track_input(FrameInput::Owned(frame))
    }

    /// A buffer of the camera's size for the next frame of
    /// [`Tracker::track_owned`]: the one of a frame the tracker no longer
    /// needs where there is one (its bytes are stale), else a new one.
    pub fn frame_buffer(&mut self) -> image::RgbImage {
        match self.spare_frame.take() {
            Some(b) if b.dimensions() == (self.cam.width, self.cam.height) => b,
            _ => image::RgbImage::new(self.cam.width, self.cam.height),
        }
    }

    fn track_input(&mut self, input: FrameInput<'_>) -> Result<TrackResult, TrackError> {
        let frame = input.image();
        if frame.width() != self.cam.width || frame.height() != self.cam.height {
            return Err(TrackError::FrameSize {
                got_w: frame.width(),
                got_h: frame.height(),
                want_w: self.cam.width,
                want_h: self.cam.height,
            });
        }
        let t0 = Instant::now();
        let read0 = self.device.stats();
        self.resident.begin();
        self.pending_gpu.clear();
        self.contour.begin_frame();
        let mut times = StageTimes::default();
        self.stages = StageTimes::default();
        // No pose yet: search the whole frame. Lost for a while: a slice
        // of that search (its budget leaves room for the frame's steps).
        let every = self.config.init.redetect_after_lost;
        let seeded = std::mem::take(&mut self.lost.seeded);
        let lost_search = !self.searching && every > 0 && self.lost_streak >= every && !seeded;
        // A pose the search found this frame or the last is where this
        // frame starts; else a recovering frame picks its start.
        let mut found_start = seeded;
        let target = self
            .lost
            .frame_target(self.config.init.lost_frame_budget, LOST_FALLBACK);
        if self.searching || lost_search {
            let found = if self.searching {
                self.find(frame)?
            } else {
                let budget = target.saturating_sub(self.lost.steps_time());
                self.lost_search_slice(frame, budget)?
            };
            times.search = t0.elapsed();
            times.waits.search = self
                .device
                .stats()
                .wait_time
                .saturating_sub(read0.wait_time);
            // The search's KF-like steps are its own time ("search"), not
            // the KF stage's parts, which would otherwise exceed it (the
            // passes' GPU times stay, under their own labels).
            let s = &mut self.stages;
            for part in [
                &mut s.it_render,
                &mut s.it_ncc,
                &mut s.kf_render,
                &mut s.kf_harris,
                &mut s.kf_ncc,
            ] {
                *part = Duration::ZERO;
            }
            let no_time = lost_search && t0.elapsed() + self.lost.steps_time() > target;
            let stop = match found {
                // Tracked from it on the next frame (a wide KF step).
                Some(p) if no_time => {
                    log::info!("object found by search (tracked from the next frame)");
                    self.hold_outline_start();
                    self.pose = p;
                    self.lost.reset();
                    self.lost.seeded = true;
                    true
                }
                // Its frame is older than this one (the round's first): a
                // wide KF step from it and the check on this frame.
                Some(p) if lost_search => {
                    log::info!("object found by search");
                    self.hold_outline_start();
                    self.pose = p;
                    self.lost.reset();
                    found_start = true;
                    false
                }
                Some(p) => {
                    log::info!("object found by search");
                    self.hold_outline_start();
                    self.pose = p;
                    self.searching = false;
                    self.lost_streak = 0;
                    self.it_only_streak = 0;
                    self.prev = None;
                    false
                }
                None => self.searching || no_time,
            };
            if stop {
                if !self.searching {
                    self.lost_streak += 1;
                }
                let refused = self.search_refused.take();
                let pose = self.pose;
                self.drift.lost();
                return Ok(self.lost_without_steps(pose, LostReason::NotFound, times, t0, refused));
            }
        }
        let t_features = Instant::now();
        let w_features = self.device.stats().wait_time;
        // The frame kept for the next one, in the buffer of the frame
        // before the last where it fits.
        let kept = match input {
            FrameInput::Owned(img) => img,
            FrameInput::Borrowed(rgb) => match self.spare_frame.take() {
                Some(mut b) if b.dimensions() == rgb.dimensions() => {
                    b.copy_from_slice(rgb);
                    b
                }
                _ => rgb.clone(),
            },
        };
        let mut frame = Frame::new(kept);
        let rgb = &frame.rgb;
        let frozen = self
            .prev
            .as_ref()
            .is_some_and(|p| p.rgb.as_raw() == rgb.as_raw());
        if frozen && self.config.verify.enabled {
            // Nothing new to see: lost at once, whatever a step would make
            // of the same image again. The next frame is tracked as if this
            // one had not come (a video's duplicated frames do not start a
            // recovery): from the same pose and previous frame (here and on
            // the GPU), the lost streak unchanged.
            self.spare_frame = Some(frame.rgb);
            let pose = self.reported_pose();
            let why = LostReason::Unverified(Unverified::FrozenFrame);
            return Ok(self.lost_without_steps(pose, why, times, t0, None));
        }
        let texture = self.config.modalities.texture;
        let recovering = self.lost_streak > 0;
        // A frame identical to the last (unchecked) starts from the last
        // pose: the recovery's starts wait for a frame that can show where
        // the object went.
        let pick = recovering && texture && !found_start && !frozen;
        let mut start_pose = if pick {
            self.recovery_first()
        } else {
            self.pose
        };
        // A start turned away from the last pose is tried by the texture
        // alone: from a wrong turn the outline of a smooth object still
        // finds edges to fit (the real dragon's passed the check 12
        // degrees off), while the keyframes' texture does not correlate.
        let mut turned = start_pose != self.pose;
        // The frame's intake and its window's packing go to the GPU with
        // Harris's first readback (their parameters have buffers of their
        // own), and so do IT's render and gather, which do not need the
        // frame: that readback brings the gather's samples too.
        let intake = self.device.batch();
        let t_early = Instant::now();
        let it_early = if texture {
            self.it_gather_early(&start_pose, recovering)
        } else {
            None
        };
        let it_early_time = t_early.elapsed();
        if texture {
            if let Some(ctx) = self.device.gpu() {
                self.resident.upload(ctx, rgb)?;
            }
        }
        // With IT's matching chained behind the frame's Harris where it
        // can be (one wait for both).
        let it_early = if texture {
            let (corners, early) = self.frame_corners_chained(&frame, &start_pose, it_early)?;
            frame.corners = corners;
            early
        } else {
            None
        };
        drop(intake);
        // IT's early render and gather count as IT's.
        times.features = t_features.elapsed().saturating_sub(it_early_time);
        times.waits.features = self.device.stats().wait_time.saturating_sub(w_features);

        let rules = Rules::of(&self.config);
        let first_frame = self.prev.is_none() && !recovering;
        let t_it = Instant::now();
        let w_it = self.device.stats().wait_time;
        let (it, it_anchors) = if texture {
            self.it_stage(&frame, &start_pose, recovering, it_early)
        } else {
            (StepOutcome::default(), Vec::new())
        };
        times.it = t_it.elapsed() + it_early_time;
        times.waits.it = self.device.stats().wait_time.saturating_sub(w_it);
        let t_kf = Instant::now();
        let w_kf = self.device.stats().wait_time;
        let it_trusted = it.estimate.filter(|e| rules.trusted(e)).map(|e| e.pose);
        self.kf_anchors.clear();
        let (mut kf, mut keyframe) = if texture {
            let fused: &[Anchor] = if self.config.fuse { &it_anchors } else { &[] };
            self.kf_stage(&frame, &start_pose, recovering, it_trusted, fused)
        } else {
            (StepOutcome::default(), None)
        };
        // Recovering, a second start where the first gave nothing to
        // trust and the frame's budget has room for it (IT does not run).
        let room = target.saturating_sub(t0.elapsed()) > t_kf.elapsed();
        if pick && room && !kf.estimate.is_some_and(|e| rules.trusted(&e)) {
            let second = self.recovery_second();
            let (k2, kf2) = self.kf_stage(&frame, &second, recovering, None, &[]);
            if k2.estimate.is_some_and(|e| rules.trusted(&e)) {
                (kf, keyframe, start_pose) = (k2, kf2, second);
                turned = start_pose != self.pose;
            }
        }
        times.kf = t_kf.elapsed();
        times.waits.kf = self.device.stats().wait_time.saturating_sub(w_kf);
        let t_contour = Instant::now();
        let w_contour = self.device.stats().wait_time;
        if self.config.modalities.contour && self.stages.renders == 0.0 {
            // Nothing rendered yet this frame: the previous check's render,
            // made at the pose this frame starts from, seeds the contour's
            // first round instead of a render of its own.
            let window = self.view_window(&start_pose);
            let near = self.contour_seed_px();
            self.reuse_render(&start_pose, window, false, near);
        }
        let contour = if self.config.modalities.contour {
            // From the best texture estimate, fused with its inliers; else
            // from the previous pose with longer lines.
            let kf_trusted = kf.estimate.filter(|e| rules.trusted(e)).map(|e| e.pose);
            let anchors = std::mem::take(&mut self.kf_anchors);
            match (kf_trusted, it_trusted) {
                // A trusted KF step: the outline only refines it where
                // configured ([`ContourConfig::refine_texture`]).
                (Some(_), _) if !self.config.contour.refine_texture => StepOutcome::default(),
                (Some(p), _) => self.contour_stage(rgb, &p, false, &anchors),
                // IT's matches are not fused: they carry its drift (on the
                // real dragon they pulled the fused pose 20 degrees off).
                (None, Some(p)) => self.contour_stage(rgb, &p, false, &[]),
                (None, None) if turned => StepOutcome::default(),
                (None, None) => self.contour_stage(rgb, &start_pose, true, &[]),
            }
        } else {
            StepOutcome::default()
        };
        times.contour = t_contour.elapsed();
        times.waits.contour = self.device.stats().wait_time.saturating_sub(w_contour);

        let texture_held = kf.estimate.is_some_and(|e| rules.trusted(&e))
            || it.estimate.is_some_and(|e| rules.trusted(&e));
        let contour_held = contour.estimate.is_some_and(|e| rules.trusted(&e));
        let d = decide(
            &rules,
            &FrameSteps {
                it,
                kf,
                contour,
                first_frame,
                it_only_streak: self.it_only_streak,
            },
        );
        // What a lost frame refuses: the decision's estimate, else (a
        // first frame with nothing to track against) the initial pose.
        let proposed = match d.estimate {
            Some((stage, e)) => Some((Source::from(stage), e.pose, e.inliers, e.residual_px)),
            None => (d.status == Status::Tracking).then_some((
                Source::Initial,
                d.pose.unwrap_or(start_pose),
                0,
                f64::NAN,
            )),
        };
        // Every pose reported `tracking` is checked against the image.
        let mut scores = None;
        let mut texture_set_aside = false;
        let mut contour_again = false;
        let t_verify = Instant::now();
        let w_verify = self.device.stats().wait_time;
        let mut d = d;
        if d.status == Status::Tracking && self.config.verify.enabled {
            let check = {
                let s = self.verify_scores(&frame, &d.pose.unwrap_or(start_pose))?;
                scores = Some(s);
                log::debug!("verify: {s:?}");
                // Without a trusted texture step the object shows no
                // texture to correlate (an untextured object's shading):
                // the contour's edges decide.
                if self.config.modalities.contour && !texture_held {
                    let loose = d.residual_px;
                    let shading_only = self.shading_only_for(&s, loose)?;
                    verify::judge_contour_alone(&s, &self.config.verify, shading_only, loose)
                } else {
                    verify::judge(&s, &self.config.verify)
                }
            };
            // A trusted texture step whose pose does not look like the
            // frame matched something the keyframes do not show (on an
            // untextured object, the shading of a moving light): set the
            // texture aside and let the contour alone solve from that
            // pose, checked as when no texture step is trusted.
            // Without a trusted texture step the contour alone made the
            // pose: where it failed, or passed without converging (still
            // drifting after its last round), a second step from the
            // previous pose is damped ([`ContourConfig::retry_damping`]);
            // the check takes it where it passes, and over a pose that
            // passed where its edges support it better.
            let retry = self.config.contour.retry_damping;
            let again = self.config.modalities.contour && !texture_held && retry > 0.0 && !turned;
            let edges = |s: &VerifyScores| s.edge_support.unwrap_or(0.0);
            let aside = match (&check, d.pose) {
                (Err(Unverified::Appearance { .. }), Some(from))
                    if self.config.modalities.contour && texture_held && !turned =>
                {
                    self.contour_alone(&rules, &frame, rgb, (from, false, None), first_frame)?
                }
                (Err(Unverified::Appearance { .. } | Unverified::ShadingOnly { .. }), _)
                    if again =>
                {
                    let from = (start_pose, true, Some(retry));
                    self.contour_alone(&rules, &frame, rgb, from, first_frame)?
                }
                (Ok(()), _) if again && contour_held && !self.contour.converged => {
                    let first = scores.as_ref().map_or(0.0, edges);
                    let from = (start_pose, true, Some(retry));
                    self.contour_alone(&rules, &frame, rgb, from, first_frame)?
                        .filter(|(_, s)| edges(s) > first)
                }
                _ => None,
            };
            match aside {
                Some((alone, s)) => {
                    scores = Some(s);
                    texture_set_aside = texture_held;
                    contour_again = true;
                    d = alone;
                }
                None => d = verified(d, check),
            }
        }
        times.verify = t_verify.elapsed();
        times.waits.verify = self.device.stats().wait_time.saturating_sub(w_verify);
        if recovering || first_frame {
            d = self.judge_start(d, scores.as_ref());
        }
        // After a loss only the shading's level from before applies
        // (`recent::History::shading_level`).
        d = self.judge_steady(d, scores.as_ref());
        let (d, held) = self.confirm_start(d, scores.as_ref(), &start_pose);
        let (status, reason) = match held {
            Some(why) => (Status::Lost, Some(why)),
            None => (d.status, d.reason.clone()),
        };
        self.note_steady(status, scores.as_ref());
        if let Some(why) = &d.kf_passed_over {
            log::debug!("KF step not used ({why}); keeping the IT estimate");
        }
        self.it_only_streak = d.it_only_streak;
        if d.status == Status::Tracking {
            self.pose = d.pose.unwrap_or(start_pose);
            self.drift.tracked(self.pose.transform_point(&self.center));
            self.lost_streak = 0;
            self.recovery_turn = 0;
            self.recovery_next = None;
            self.recovery_hidden = false;
            self.lost.reset();
            if self.config.modalities.contour {
                let pose = self.pose;
                self.learn_colours(rgb, &pose);
            }
        } else {
            // Keep the last good pose: never report a pose that failed.
            self.drift.lost();
            if self.lost_streak == 0 {
                self.recovery_tracked = !first_frame;
            }
            self.lost_streak += 1;
        }
        if let Some(old) = self.prev.replace(frame) {
            self.spare_frame = Some(old.rgb);
        }
        self.resident.done();
        self.collect_frame_times(&mut times, &read0);
        times.total = t0.elapsed();
        // The lost frames' budget is measured in these times: a tracked
        // frame's (not the first, which makes its buffers), and a lost
        // frame's own steps.
        if recovering {
            self.lost.steps(times.total.saturating_sub(times.search));
        } else if status == Status::Tracking && !first_frame && times.search.is_zero() {
            self.lost.tracked(times.total);
        }
        let refused = proposed.filter(|_| status == Status::Lost).map(
            |(source, pose, inliers, residual_px)| Refused {
                pose,
                source,
                inliers,
                residual_px,
                scores,
            },
        );
        Ok(TrackResult {
            pose: self.reported_pose(),
            inliers: d.inliers,
            residual_px: d.residual_px,
            status,
            reason,
            keyframe,
            times,
            verify: scores,
            texture_set_aside,
            cues: match status {
                Status::Tracking if contour_again => Modalities::CONTOUR,
                Status::Tracking => Modalities {
                    texture: texture_held,
                    contour: contour_held,
                },
                Status::Lost => Modalities::NONE,
            },
            refused,
        })
    }

    /// The pose a frame reports: the last one, or while a start found by
    /// the outline alone is held, the one before it.
    fn reported_pose(&self) -> Pose {
        if self.confirm_left > 0 {
            self.confirm_report
        } else {
            self.pose
        }
    }

    /// A `lost` frame that ran no step: the search's alone, or a frozen
    /// frame.
    fn lost_without_steps(
        &mut self,
        pose: Pose,
        reason: LostReason,
        mut times: StageTimes,
        t0: Instant,
        refused: Option<Refused>,
    ) -> TrackResult {
        times.renders = self.stages.renders;
        times.total = t0.elapsed();
        TrackResult {
            pose,
            inliers: 0,
            residual_px: f64::NAN,
            status: Status::Lost,
            reason: Some(reason),
            keyframe: None,
            times,
            verify: None,
            texture_set_aside: false,
            cues: Modalities::NONE,
            refused,
        }
    }

    /// The frame's sub-stage times and device counters since `read0`
    /// into `times`.
    fn collect_frame_times(&mut self, times: &mut StageTimes, read0: &crate::gpu::GpuStats) {
        self.collect_gpu_times();
        let sub = std::mem::take(&mut self.stages);
        times.it_render = sub.it_render;
        times.it_ncc = sub.it_ncc;
        times.kf_render = sub.kf_render;
        times.kf_harris = sub.kf_harris;
        times.kf_ncc = sub.kf_ncc;
        times.renders = sub.renders;
        times.gpu = sub.gpu;
        times.gpu_timeline = sub.gpu_timeline;
        let done = self.device.stats().since(read0);
        times.readback_bytes = done.bytes_read as f64;
        times.readbacks = done.readbacks as f64;
        times.submissions = done.submissions as f64;
        times.command_buffers = done.command_buffers as f64;
        times.uploads = done.uploads as f64;
        times.uploads_skipped = done.uploads_skipped as f64;
        times.passes = done.passes as f64;
        times.passes_untimed = done.passes_untimed as f64;
        times.gpu_wait = done.wait_time;
        times.gpu_finish = done.finish_time;
        times.gpu_submit = done.submit_time;
        times.contour_rounds = self.contour.rounds as f64;
        times.contour_renders = self.contour.renders as f64;
        (times.colour_learning, times.colour_wait) = self.contour.colours.take_times();
    }

    /// A start found by the outline alone is held until confirmed
    /// ([`Tracker::confirm_start`]); call before the pose found replaces
    /// the one to report meanwhile.
    fn hold_outline_start(&mut self) {
        if self.found_by_outline && self.config.init.confirm_frames > 0 {
            self.confirm_left = self.config.init.confirm_frames + 1;
            self.confirm_report = self.pose;
        }
    }

    /// The contour alone from `from` (the pose of a decision whose
    /// texture steps were trusted but whose check failed on appearance; or
    /// the previous pose, when the contour alone made that decision), with
    /// long lines or not and damped as given (`None`: as configured),
    /// decided as if no texture step had run and checked by the contour's
    /// edges ([`verify::judge_contour_alone`]): the decision and its scores
    /// when that pose passes, `None` when it does not (the frame stays
    /// lost).
    fn contour_alone(
        &mut self,
        rules: &Rules,
        frame: &Frame,
        rgb: &image::RgbImage,
        (from, long, damping): (Pose, bool, Option<f64>),
        first_frame: bool,
    ) -> Result<Option<(Decision, VerifyScores)>, TrackError> {
        let contour = match damping {
            Some(damping) => self.contour_stage_damped(rgb, &from, long, damping),
            None => self.contour_stage(rgb, &from, long, &[]),
        };
        let alone = decide(
            rules,
            &FrameSteps {
                it: StepOutcome::default(),
                kf: StepOutcome::default(),
                contour,
                first_frame,
                it_only_streak: 0,
            },
        );
        let Some(pose) = alone.pose.filter(|_| alone.status == Status::Tracking) else {
            return Ok(None);
        };
        let s = self.verify_scores(frame, &pose)?;
        log::debug!("verify (contour alone): {s:?}");
        let loose = alone.residual_px;
        let shading_only = self.shading_only_for(&s, loose)?;
        match verify::judge_contour_alone(&s, &self.config.verify, shading_only, loose) {
            Ok(()) => {
                log::debug!(
                    "the contour alone passes: {:.2} deg from where it started",
                    pose.rotation_error_deg(&from)
                );
                Ok(Some((alone, s)))
            }
            Err(why) => {
                log::debug!("the contour alone does not pass either: {why}");
                Ok(None)
            }
        }
    }
}

/// The frame [`Tracker::track`] or [`Tracker::track_owned`] was given.
enum FrameInput<'a> {
    Borrowed(&'a image::RgbImage),
    Owned(image::RgbImage),
}

impl FrameInput<'_> {
    fn image(&self) -> &image::RgbImage {
        match self {
            FrameInput::Borrowed(img) => img,
            FrameInput::Owned(img) => img,
        }
    }
}
