//! The keyframe step (KF, Dehais et al. 2010, section 4): the keyframe
//! whose viewpoint is closest textures the model; a novel view and its
//! motion predictors are splatted in one pass; corners of the novel view
//! matched to the frame's are solved for the correction.

use super::config::Mode;
use super::decision::StepOutcome;
use super::features_on::Matcher;
use super::region::{
    AFeatures, Bands, Placed, match_near, match_near_resident, placed, shifted, window_crop,
};
use super::result::StepError;
use super::state::{Frame, Tracker};
use super::workspace::estimate;
use crate::features::resident::MAX_REFINE_WINDOW;
use crate::features::{
    Corner, ExportPlace, GreyImage, Match, Refinement, ResidentImage, refine_match,
};
use crate::geometry::Pose;
use crate::gpu::PassChain;
use crate::pose::{Anchor, Correspondence, Refined};
use crate::splat::{Attribute, GatherMode, GatherSample, Window};
use nalgebra::Vector2;

/// A KF match: the view's corner, and where it lies in the frame
/// (`None`: its refinement failed).
type Found = (usize, Option<Vector2<f64>>);

/// How far the sub-pixel refinement of a match searches, pixels.
const REFINE_SHIFT: i32 = 2;

/// The KF step's detection, matching and gather chained on the GPU
/// ([`Tracker::kf_chained`]).
enum Chained {
    /// All done in one wait: the view's corners (window coordinates), the
    /// matches, and the samples at the corners.
    Done(Vec<Corner>, Vec<Found>, Vec<crate::splat::GatherSample>),
    /// The view's corners only (window coordinates): the GPU's selection
    /// was not final, or kept more corners than came back at once, so
    /// what was fed from it is void and done again from these.
    Corners(Vec<Corner>),
}

/// How far the KF step searches for matches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Search {
    /// From an IT estimate: the object is nearly where predicted.
    Refine,
    /// From the previous pose: as far as the object moves between frames.
    Motion,
    /// After a loss.
    Recover,
}

impl Tracker {
    /// The KF step(s), where the mode runs them (or the track is recovering)
    /// and there are keyframes. They start from `it_trusted`, IT's estimate
    /// when it is sound; without it the first step must search as far as
    /// frame-to-frame matching does, and after a loss farther. `anchors`
    /// (IT's inliers, when fusing) join the refinement. Returns the outcome
    /// and the keyframe last used.
    pub(super) fn kf_stage(
        &mut self,
        frame: &Frame,
        start_pose: &Pose,
        recovering: bool,
        it_trusted: Option<Pose>,
        anchors: &[Anchor],
    ) -> (StepOutcome, Option<usize>) {
        let mut outcome = StepOutcome::default();
        let mut keyframe = None;
        let use_kf = matches!(self.config.mode, Mode::Kf | Mode::KfIt)
            || (recovering && self.store.is_some());
        if !use_kf || self.store.is_none() {
            return (outcome, keyframe);
        }
        let (mut pose, first) = match (recovering, it_trusted) {
            (true, _) => (*start_pose, Search::Recover),
            (false, Some(p)) => (p, Search::Refine),
            (false, None) => (*start_pose, Search::Motion),
        };
        // Recovering, the wide step's outcome is refined once more: from
        // a start some degrees off the first step gets only part way.
        let iterations = self.config.kf_iterations.max(1 + usize::from(recovering));
        for it in 0..iterations {
            let search = if it == 0 { first } else { Search::Refine };
            match self.kf_step(frame, &pose, search, anchors) {
                Ok((step, k)) => {
                    pose = step.pose;
                    outcome.estimate = Some(estimate(&step));
                    self.kf_anchors = step.anchors;
                    keyframe = Some(k);
                }
                Err(e) => {
                    outcome.error = Some(e);
                    break;
                }
            }
        }
        (outcome, keyframe)
    }

    /// One step against the novel view of the closest keyframe: the refined
    /// solve and the keyframe's index.
    pub(super) fn kf_step(
        &mut self,
        frame: &Frame,
        pose: &Pose,
        search: Search,
        anchors: &[Anchor],
    ) -> Result<(Refined, usize), StepError> {
        if self.store.is_none() {
            return Err(StepError::NoKeyframes);
        }
        let t = std::time::Instant::now();
        // The render and the resolve go with Harris's first readback.
        let batch = self.device.batch();
        let window = self.view_window(pose);
        let k = self
            .render_view_in(pose, self.view_attrs(true), window, "KF")?
            .ok_or(StepError::NoKeyframes)?;
        self.stages.kf_render += t.elapsed();
        // The novel view of the window only (its corners in window
        // coordinates, then in the frame's): its colour is resolved into
        // Harris's input on the GPU, and only its grey levels come back
        // (for the NCC windows and the refinement).
        let t = std::time::Instant::now();
        let (w, h) = (window.width as usize, window.height as usize);
        // On the CPU device the view is on the host already: its colour,
        // read, gives the grey levels.
        let host_view = match self.device.gpu() {
            Some(ctx) => {
                let target = self.harris.gpu()?.colour_target(w, h)?;
                self.splatter
                    .resolve_into(ctx, &self.targets, Attribute::Color, &target)?;
                None
            }
            None => {
                let c = self
                    .splatter
                    .read(&self.device, &self.targets, Attribute::Color)?;
                Some(GreyImage::from_rgb_f32(w, h, &c.data)?)
            }
        };
        let margin = self.match_margin(match search {
            Search::Recover => self.config.recover_search_px,
            Search::Motion => self.config.it_search_px,
            Search::Refine => self.config.kf_search_px,
        });
        // Resident (the default): the view stays on the GPU for NCC and
        // the refinement; else its grey levels come back for host crops.
        let resident =
            self.resident.frames().0.is_some() && self.config.refine_patch <= MAX_REFINE_WINDOW;
        // Chained (resident, by default): the detection, the matching and
        // the gather go to the GPU together, and one wait brings them.
        let chained = if resident && self.resident.chain_kf && !self.harris.host() {
            self.kf_chained(window, &frame.corners, search, margin)?
        } else {
            None
        };
        let mut done = None;
        let mut matching = std::time::Duration::ZERO;
        let (corners, view) = match chained {
            Some((Chained::Done(corners, found, samples), d)) => {
                done = Some((found, samples));
                matching = d;
                (corners, None)
            }
            Some((Chained::Corners(corners), d)) => {
                matching = d;
                (corners, None)
            }
            None if resident => (self.harris.gpu()?.detect_resolved_resident(w, h)?, None),
            None => match host_view {
                Some(v) => (self.harris.detect_view(&v)?, Some(v)),
                None => {
                    let (c, v) = self.harris.gpu()?.detect_resolved(w, h)?;
                    (c, Some(v))
                }
            },
        };
        let o = window.origin();
        let view_corners = placed(&corners, o);
        drop(batch);
        self.note_harris("KF");
        // A chained step's matching and wait count as matching.
        self.stages.kf_harris += t.elapsed().saturating_sub(matching);
        self.stages.kf_ncc += matching;
        let t = std::time::Instant::now();
        let (found, all) = match done {
            Some(d) => d,
            None => {
                // The predictors at every view corner, gathered now and
                // read back with the matching's readback (one submission
                // and one wait for both; a corner's sample does not depend
                // on the others).
                // Resident, at the corners in the window's pixels (as the
                // chained step gathers and matches: the same samples and
                // matches); else at the corners in the frame's.
                let batch = self.device.batch();
                let (found, gathered): (Vec<Found>, _) = match view {
                    None => {
                        let pts: Vec<[f32; 2]> = corners.iter().map(|c| [c.x, c.y]).collect();
                        let gathered = self.splatter.gather_later(
                            &self.device,
                            &self.targets,
                            &pts,
                            GatherMode::Bilinear,
                        )?;
                        let found = self.kf_match_resident(
                            window,
                            &corners,
                            &frame.corners,
                            search,
                            margin,
                        )?;
                        (found, gathered)
                    }
                    Some(view) => {
                        let pts: Vec<[f32; 2]> = view_corners.iter().map(|c| [c.x, c.y]).collect();
                        let gathered = self.gather_frame_later(&pts)?;
                        let found = self.kf_match_host(
                            window,
                            &view,
                            &view_corners,
                            frame,
                            search,
                            margin,
                        )?;
                        (found, gathered)
                    }
                };
                drop(batch);
                (found, gathered.wait(&self.device)?)
            }
        };
        let timings = self.matcher(search).take_timings();
        self.note_timings("KF ncc", timings);
        let obs: Vec<Correspondence> = found
            .iter()
            .map(|f| (f, &all[f.0]))
            .filter(|(_, s)| s.valid)
            .filter_map(|((a, to), s)| {
                let a = &view_corners[*a];
                Some(self.correspondence(s, Vector2::new(a.x as f64, a.y as f64), (*to)?, pose))
            })
            .collect();
        self.stages.kf_ncc += t.elapsed();
        self.refine(&obs, pose, anchors).map(|s| (s, k))
    }

    /// The matcher of a search.
    fn matcher(&mut self, search: Search) -> &mut Matcher {
        match search {
            Search::Recover => &mut self.recover_matcher,
            Search::Motion => &mut self.it_matcher,
            Search::Refine => &mut self.kf_matcher,
        }
    }

    /// The KF step's detection on the view resolved into Harris's input,
    /// its matching against the resident frame and the gather of the
    /// predictors at its corners, chained on the GPU: the corners go from
    /// Harris to NCC and the gather there
    /// ([`crate::features::Harris::export_corners`]), and one wait brings
    /// the corners, the matches and the samples (instead of one for the
    /// corners, then one for the rest). The matching's crop is the
    /// window grown by the margin ([`window_crop`]), which it can cut
    /// before the corners are known: the same matches. `None` where it
    /// cannot run (no frame corner in the crop, no resident frame): the
    /// caller detects and matches apart. With the outcome, the time spent
    /// from the detection's recording on (the matching's and the wait's).
    fn kf_chained(
        &mut self,
        window: Window,
        frame_corners: &[Corner],
        search: Search,
        margin: Option<f64>,
    ) -> Result<Option<(Chained, std::time::Duration)>, StepError> {
        let (w, h) = (window.width as usize, window.height as usize);
        let Some(now) = self.resident.frames().0 else {
            return Ok(None);
        };
        let (now_pixels, nw, nh) = (now.pixels.clone(), now.width, now.height);
        let full = Window {
            x0: 0,
            y0: 0,
            width: nw as u32,
            height: nh as u32,
        };
        let crop = window_crop(self.matcher(search).config(), window, margin, full);
        let bands = match Bands::new(window, frame_corners, crop) {
            Some(b) if w > 0 && h > 0 && !b.b_in.is_empty() => b,
            _ => return Ok(None),
        };
        let refine = (self.config.refine_patch > 0).then_some(Refinement {
            patch: self.config.refine_patch,
            max_shift: REFINE_SHIFT as u32,
            min_score: self.config.ncc.min_score * 0.8,
        });
        let pending = self.harris.gpu()?.detect_resolved_resident_later(w, h)?;
        let t = std::time::Instant::now();
        let points = self
            .splatter
            .gather_points(self.gpu_ctx()?, pending.slots())?;
        let view_pixels = self.harris.gpu()?.resident_view(w, h)?.pixels.clone();
        let band_y0 = bands.a_rows.start as f32;
        let harris = self.harris.gpu()?;
        let matcher = match search {
            Search::Recover => &mut self.recover_matcher,
            Search::Motion => &mut self.it_matcher,
            Search::Refine => &mut self.kf_matcher,
        }
        .gpu()?;
        let matching = {
            let mut export = |passes: &mut PassChain, positions: &wgpu::Buffer| {
                harris.export_corners(
                    passes,
                    &pending,
                    ExportPlace::band(band_y0),
                    positions,
                    Some(&points),
                )
            };
            matcher.match_resident_exported(
                ResidentImage {
                    pixels: &view_pixels,
                    width: w,
                    height: h,
                },
                bands.a_rows.clone(),
                pending.slots(),
                &mut export,
                ResidentImage {
                    pixels: &now_pixels,
                    width: nw,
                    height: nh,
                },
                bands.b_rows.clone(),
                &bands.b_in,
                [-(window.x0 as i32), -(window.y0 as i32)],
                refine,
                pending.rows(),
            )?
        };
        let gathered = self.splatter.gather_written_later(
            self.gpu_ctx()?,
            &self.targets,
            pending.rows(),
            GatherMode::Bilinear,
        )?;
        // The one wait.
        let detected = self.harris.gpu()?.finish_later(pending)?;
        if !detected.exported {
            log::trace!("KF: the chained matching is done again from the host's corners");
            return Ok(Some((Chained::Corners(detected.corners), t.elapsed())));
        }
        let kept = detected.corners.len();
        let matcher = match search {
            Search::Recover => &mut self.recover_matcher,
            Search::Motion => &mut self.it_matcher,
            Search::Refine => &mut self.kf_matcher,
        }
        .gpu()?;
        let found = matcher
            .finish_exported(matching, kept)?
            .into_iter()
            .map(|m| (m.a, m.at.map(|p| Vector2::new(p[0], p[1]))))
            .collect();
        let mut samples: Vec<GatherSample> = gathered.wait(&self.device)?;
        samples.truncate(kept);
        Ok(Some((
            Chained::Done(detected.corners, found, samples),
            t.elapsed(),
        )))
    }

    /// The KF matches on the GPU of the view's `corners` (in its window's
    /// pixels): the view Harris left there against the resident frame,
    /// on the crop the chained step cuts, the mutual check and the
    /// refinement there too.
    fn kf_match_resident(
        &mut self,
        window: Window,
        corners: &[Corner],
        frame_corners: &[Corner],
        search: Search,
        margin: Option<f64>,
    ) -> Result<Vec<Found>, StepError> {
        let refine = (self.config.refine_patch > 0).then_some(Refinement {
            patch: self.config.refine_patch,
            max_shift: REFINE_SHIFT as u32,
            min_score: self.config.ncc.min_score * 0.8,
        });
        let (w, h) = (window.width as usize, window.height as usize);
        let view = self.harris.gpu()?.resident_view(w, h)?;
        let Some(now) = self.resident.frames().0 else {
            return Ok(Vec::new());
        };
        let matcher = match search {
            Search::Recover => &mut self.recover_matcher,
            Search::Motion => &mut self.it_matcher,
            Search::Refine => &mut self.kf_matcher,
        }
        .gpu()?;
        let matches = match_near_resident(
            matcher,
            (view, window),
            AFeatures::InWindow(corners),
            now,
            frame_corners,
            margin,
            refine,
        )?;
        Ok(matches
            .into_iter()
            .map(|m| (m.a, m.at.map(|p| Vector2::new(p[0], p[1]))))
            .collect())
    }

    /// The KF matches on host crops (the view's grey levels read back),
    /// refined on the host.
    fn kf_match_host(
        &mut self,
        window: Window,
        view: &GreyImage,
        view_corners: &[Corner],
        frame: &Frame,
        search: Search,
        margin: Option<f64>,
    ) -> Result<Vec<Found>, StepError> {
        let placed = Placed {
            img: view,
            at: window,
        };
        let (matches, mw, view_m, frame_m) = match_near(
            self.matcher(search),
            placed,
            view_corners,
            frame.grey(),
            &frame.corners,
            margin,
        )?;
        let mo = mw.origin();
        let local = |c: &Corner| shifted(c, mo);
        Ok(matches
            .iter()
            .map(|m: &Match| {
                let a = &view_corners[m.a];
                let to = self
                    .match_target(&view_m, &local(a), &frame_m, &local(&frame.corners[m.b]))
                    .map(|p| p + Vector2::new(mo[0] as f64, mo[1] as f64));
                (m.a, to)
            })
            .collect())
    }

    /// Where the corner `a` of image `src` lies in the live frame: the
    /// matched corner `b`, moved to the NCC peak when refinement is on;
    /// `None` drops a match whose refinement fails.
    fn match_target(
        &self,
        src: &GreyImage,
        a: &Corner,
        live: &GreyImage,
        b: &Corner,
    ) -> Option<Vector2<f64>> {
        if self.config.refine_patch == 0 {
            return Some(Vector2::new(b.x as f64, b.y as f64));
        }
        let (p, _) = refine_match(
            src,
            [a.x, a.y],
            live,
            [b.x, b.y],
            self.config.refine_patch,
            REFINE_SHIFT,
            self.config.ncc.min_score * 0.8,
        )?;
        Some(Vector2::new(p[0] as f64, p[1] as f64))
    }
}
