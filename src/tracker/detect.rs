//! Detection by features: the first path of the search for the object
//! in a whole frame ([`super::search`]), for textured objects.
//!
//! 1. Once per tracker (at the first search): each keyframe's textured
//!    view is splatted at its own pose; its Harris corners (never on
//!    empty pixels, so on the object) are lifted to model points by the
//!    splatted depth, as the KF step lifts its matches, and described
//!    ([`features`]: patches turned to their dominant gradient
//!    orientation, zero-mean and unit-norm) at several scales.
//! 2. Per search: up to [`DetectConfig::frame_corners`] Harris corners
//!    of the whole frame, described at one scale, matched to each
//!    keyframe's ([`matching`]: mutual best, a lowest NCC, the ratio
//!    test).
//! 3. Per keyframe with enough matches: a pose by PnP in RANSAC
//!    ([`crate::pose::solve_pnp_ransac`]), kept when it has
//!    [`DetectConfig::min_inliers`] inliers spread over
//!    [`DetectConfig::min_spread`] of the object's projected size.
//! 4. The best [`DetectConfig::candidates`] poses (by inliers) are refined
//!    by the KF step and judged by the check, as every candidate of the
//!    search is; the first to pass is the answer.

pub mod cache;
mod candidate;
pub mod config;
mod features;
mod matching;
#[cfg(test)]
mod tests;

use super::error::TrackError;
use super::features_on::CornerDetector;
use super::profile::Texture;
use super::result::{Refused, Source, StepError};
use super::state::{Frame, Tracker};
use crate::features::HarrisConfig;
use crate::geometry::Pose;
use crate::pose::{PnpRansacOptions, solve_pnp_ransac};
use crate::splat::{Attribute, Attributes, GatherMode, Window};
use cache::{Detector, KeyframeFeatures};
pub(super) use candidate::{Candidate, DETECT_REFINE_STEPS, Described};
pub use config::DetectConfig;
use features::{DescribeConfig, Descriptor, describe_all, smoothed};
use matching::{MatchConfig, match_descriptors};
use nalgebra::{Vector2, Vector3};
use std::time::Instant;

impl Tracker {
    /// Makes the detector (its keyframe features) where not yet made.
    pub(super) fn ensure_detector(&mut self) -> Result<(), TrackError> {
        let t = Instant::now();
        self.start_detector()?;
        let mut built = false;
        while let Some(k) = self.detector.as_ref().and_then(|d| d.unbuilt().next()) {
            self.build_detector_keyframe(k)?;
            built = true;
        }
        if let Some(d) = self.detector.as_ref().filter(|_| built) {
            log::debug!(
                "detector: keyframe features {:?} in {:.0} ms",
                d.keyframes
                    .iter()
                    .map(|k| k.points.len())
                    .collect::<Vec<_>>(),
                t.elapsed().as_secs_f64() * 1e3
            );
        }
        Ok(())
    }

    /// Makes the detector without its keyframes' features where not yet
    /// made ([`Tracker::build_detector_keyframe`] adds them one by one).
    pub(super) fn start_detector(&mut self) -> Result<(), TrackError> {
        if self.detector.is_some() {
            return Ok(());
        }
        let cfg = &self.config.init.detect;
        let hc = HarrisConfig {
            max_corners: cfg.frame_corners.max(cfg.keyframe_corners).max(1),
            relative_threshold: cfg.harris_threshold,
            ..self.config.harris.clone()
        };
        let harris = self.harris.like(&self.device, hc)?;
        let n = self.store.as_ref().map_or(0, |s| s.keyframes.len());
        self.detector = Some(Detector {
            harris,
            keyframes: vec![KeyframeFeatures::default(); n],
            built: vec![false; n],
            misses: 0,
        });
        Ok(())
    }

    /// Adds keyframe `k`'s features to the detector (started).
    pub(super) fn build_detector_keyframe(&mut self, k: usize) -> Result<(), TrackError> {
        let cfg = self.config.init.detect.clone();
        let pose = self
            .store
            .as_ref()
            .and_then(|s| s.keyframes.get(k))
            .map(|kf| kf.pose);
        let (Some(pose), Some(mut det)) = (pose, self.detector.take()) else {
            return Ok(());
        };
        let features = self.keyframe_features(&mut det.harris, k, &pose, &cfg);
        if let Ok(f) = &features {
            det.keyframes[k] = f.clone();
            det.built[k] = true;
        }
        self.detector = Some(det);
        features.map(|_| ())
    }

    /// Keyframe `k`'s features: its view at its own pose (the tracker's
    /// camera, whole image), corners on it, lifted by the splatted depth.
    fn keyframe_features(
        &mut self,
        harris: &mut CornerDetector,
        k: usize,
        pose: &Pose,
        cfg: &DetectConfig,
    ) -> Result<KeyframeFeatures, TrackError> {
        let full = Window::full(&self.cam);
        let cam = self.use_window(full);
        self.splat(
            Texture::Keyframe(k),
            &cam,
            pose,
            Attributes::MOTION,
            "detect",
        )?;
        let c = self
            .splatter
            .read(&self.device, &self.targets, Attribute::Color)?;
        let grey =
            crate::features::GreyImage::from_rgb_f32(c.width as usize, c.height as usize, &c.data)
                .map_err(TrackError::from)?;
        let mut corners = harris.detect(&grey, None)?;
        corners.truncate(cfg.keyframe_corners);
        // The depth at each corner and a little around it: a corner on a
        // depth step (a fold, the outline) has no single model point. On
        // a surface the depth varies about linearly across the corner.
        const D: f32 = 1.5;
        let offsets = [[0.0, 0.0], [D, 0.0], [-D, 0.0], [0.0, D], [0.0, -D]];
        let pts: Vec<[f32; 2]> = corners
            .iter()
            .flat_map(|c| offsets.map(|o| [c.x + o[0], c.y + o[1]]))
            .collect();
        let samples =
            self.splatter
                .gather(&self.device, &self.targets, &pts, GatherMode::Bilinear)?;
        let step = 0.02 * self.radius;
        let inv = pose.inverse();
        let mut kept = Vec::new();
        let mut points = Vec::new();
        for (c, s) in corners.iter().zip(samples.chunks_exact(offsets.len())) {
            let d: Vec<f64> = s.iter().map(|x| x.depth as f64).collect();
            let valid = s.iter().all(|x| x.valid && x.depth.is_finite());
            let bend = (d[1] + d[2] - 2.0 * d[0])
                .abs()
                .max((d[3] + d[4] - 2.0 * d[0]).abs());
            let d0 = d[0];
            if valid && bend < step && d0 > 0.0 {
                let from = Vector2::new(c.x as f64, c.y as f64);
                points.push(inv.transform_point(&self.cam.unproject(&from, d0)));
                kept.push([c.x, c.y]);
            }
        }
        log::debug!(
            "detect: keyframe {k}: {} corners, {} on one surface",
            corners.len(),
            kept.len()
        );
        let dcfg = self.describe_config();
        let mut per_scale = Vec::new();
        for &s in &cfg.scales {
            let img = smoothed(&grey, dcfg.sigma_px * s);
            let mut d: Vec<Option<Descriptor>> = vec![None; kept.len()];
            for (i, x) in describe_all(&img, &kept, s, &dcfg) {
                d[i] = Some(x);
            }
            per_scale.push(d);
        }
        let mut out = KeyframeFeatures::default();
        for (i, p) in points.into_iter().enumerate() {
            let ds: Vec<Descriptor> = per_scale.iter().filter_map(|d| d[i]).collect();
            if ds.is_empty() {
                continue;
            }
            let owner = out.points.len();
            out.points.push(p);
            out.pixels.push(kept[i]);
            for d in ds {
                out.descriptors.push(d);
                out.owners.push(owner);
            }
        }
        Ok(out)
    }

    fn describe_config(&self) -> DescribeConfig {
        DescribeConfig {
            oriented: self.config.init.detect.oriented,
            ..DescribeConfig::default()
        }
    }

    /// The feature path of the search: the pose found and checked, or
    /// `None`. `frame.corners` become the detector's corners of the whole
    /// frame (the refinement matches against them too).
    pub(super) fn detect_in(&mut self, frame: &mut Frame) -> Result<Option<Pose>, TrackError> {
        let cfg = self.config.init.detect.clone();
        let t0 = Instant::now();
        self.ensure_detector()?;
        let Some(described) = self.describe_frame(frame)? else {
            return Ok(None);
        };
        let candidates = self.candidates(&described, &cfg);
        let t_match = t0.elapsed();
        let mut result = None;
        // The refused candidate the check scored best, for `--refused`.
        let mut refused: Option<(f64, Refused)> = None;
        for c in candidates.iter().take(cfg.candidates) {
            match self.judge_candidate(frame, c)? {
                Ok(p) => {
                    result = Some(p);
                    break;
                }
                Err(Some((z, r))) if refused.as_ref().is_none_or(|b| z > b.0) => {
                    refused = Some((z, r));
                }
                Err(_) => {}
            }
        }
        if result.is_none() {
            self.search_refused = refused.map(|r| r.1);
        }
        self.count_detection(result.is_some());
        log::debug!(
            "detect: {} candidates; matching {:.0} ms, total {:.0} ms",
            candidates.len(),
            t_match.as_secs_f64() * 1e3,
            t0.elapsed().as_secs_f64() * 1e3
        );
        Ok(result)
    }

    /// Counts a detection that found the object or not
    /// ([`Detector::templates_now`]).
    pub(super) fn count_detection(&mut self, found: bool) {
        if let Some(d) = self.detector.as_mut() {
            d.misses = if found { 0 } else { d.misses + 1 };
        }
    }

    /// The detector's corners of `frame` (they become `frame.corners`),
    /// described; `None` without a detector.
    pub(super) fn describe_frame(
        &mut self,
        frame: &mut Frame,
    ) -> Result<Option<Described>, TrackError> {
        let t0 = Instant::now();
        let mask = self.search_mask();
        let Some(det) = self.detector.as_mut() else {
            return Ok(None);
        };
        let c = det.harris.detect(frame.grey(), mask.as_deref())?;
        log::debug!(
            "detect: {} frame corners in {:.0} ms",
            c.len(),
            t0.elapsed().as_secs_f64() * 1e3
        );
        frame.corners = c;
        let dcfg = self.describe_config();
        let img = smoothed(frame.grey(), dcfg.sigma_px);
        let pts: Vec<[f32; 2]> = frame.corners.iter().map(|c| [c.x, c.y]).collect();
        let described = describe_all(&img, &pts, 1.0, &dcfg);
        let descs = described.iter().map(|d| d.1).collect();
        Ok(Some(Described {
            pts,
            described,
            descs,
        }))
    }

    /// Refines candidate `c` on `frame` (the frame it came from) by KF
    /// steps and judges it: the pose where it passes, else the refused
    /// pose with its score for ranking (`None` where it was not refined).
    pub(super) fn judge_candidate(
        &mut self,
        frame: &Frame,
        c: &Candidate,
    ) -> Result<Result<Pose, Option<(f64, Refused)>>, TrackError> {
        let mut pose = c.pose;
        for _ in 0..DETECT_REFINE_STEPS {
            match self.refine_detected(frame, &pose)? {
                Some(p) => pose = p,
                None => {
                    log::debug!("detect: keyframe {} candidate not refined", c.keyframe);
                    return Ok(Err(None));
                }
            }
        }
        self.check_candidate(frame, c, pose)
    }

    /// Candidate `c`, refined to `refined`, checked on `frame`: the pose
    /// where it passes, else the refused pose with its score for ranking.
    pub(super) fn check_candidate(
        &mut self,
        frame: &Frame,
        c: &Candidate,
        refined: Pose,
    ) -> Result<Result<Pose, Option<(f64, Refused)>>, TrackError> {
        let s = self.verify_scores(frame, &refined)?;
        let judged = super::verify::judge(&s, &self.config.verify);
        log::debug!(
            "detect: keyframe {} candidate ({} inliers, spread {:.2}): {s:?} {judged:?}",
            c.keyframe,
            c.inliers,
            c.spread
        );
        if judged.is_ok() {
            return Ok(Ok(refined));
        }
        let z = s.zncc.unwrap_or(s.edge_support.unwrap_or(0.0));
        let r = Refused {
            pose: refined,
            source: Source::Search,
            inliers: c.inliers,
            residual_px: f64::NAN,
            scores: Some(s),
        };
        Ok(Err(Some((z, r))))
    }

    /// One KF step from a candidate's pose on its frame (close already:
    /// the short search of a tracked frame): the refined pose, or `None`
    /// when the step fails. A candidate takes [`DETECT_REFINE_STEPS`] of
    /// them.
    pub(super) fn refine_detected(
        &mut self,
        frame: &Frame,
        pose: &Pose,
    ) -> Result<Option<Pose>, TrackError> {
        if self.roi(pose).is_none() {
            return Ok(None);
        }
        match self.kf_step(frame, pose, super::kf::Search::Refine, &[]) {
            Ok((step, _)) => Ok(Some(step.pose)),
            Err(StepError::Gpu(e)) => Err(TrackError::Search(e)),
            Err(_) => Ok(None),
        }
    }

    /// The candidate poses of the frame's corners against each keyframe,
    /// most inliers first.
    fn candidates(&self, described: &Described, cfg: &DetectConfig) -> Vec<Candidate> {
        let Some(det) = self.detector.as_ref() else {
            return Vec::new();
        };
        let mut out: Vec<Candidate> = (0..det.keyframes.len())
            .filter_map(|k| self.keyframe_candidate(k, described, cfg))
            .collect();
        out.sort_by_key(|c| std::cmp::Reverse(c.inliers));
        out
    }

    /// The candidate pose of the frame's described corners against
    /// keyframe `k`'s features, if any.
    pub(super) fn keyframe_candidate(
        &self,
        k: usize,
        described: &Described,
        cfg: &DetectConfig,
    ) -> Option<Candidate> {
        let kf = self.detector.as_ref()?.keyframes.get(k)?;
        let t = Instant::now();
        let mcfg = MatchConfig {
            min_score: cfg.min_score,
            ratio: cfg.ratio,
        };
        let opts = PnpRansacOptions {
            threshold_px: cfg.inlier_px,
            min_inliers: cfg.min_inliers.max(4),
            ..PnpRansacOptions::default()
        };
        let m = match_descriptors(
            &described.descs,
            &kf.descriptors,
            &kf.owners,
            kf.points.len(),
            &mcfg,
        );
        if m.len() < cfg.min_inliers.max(4) {
            log::debug!("detect: keyframe {k}: {} matches", m.len());
            return None;
        }
        let points: Vec<Vector3<f64>> = m.iter().map(|x| kf.points[x.corner]).collect();
        let pixels: Vec<Vector2<f64>> = m
            .iter()
            .map(|x| {
                let p = described.pts[described.described[x.frame].0];
                Vector2::new(p[0] as f64, p[1] as f64)
            })
            .collect();
        let Ok(sol) = solve_pnp_ransac(&points, &pixels, &self.cam, &opts) else {
            log::debug!("detect: keyframe {k}: {} matches, no pose", m.len());
            return None;
        };
        let spread = spread(&sol.inliers.iter().map(|&i| pixels[i]).collect::<Vec<_>>())
            / (2.0 * self.radius_px(&sol.pose)).max(1.0);
        log::debug!(
            "detect: keyframe {k}: {} matches, {} inliers ({:.2} px), spread {spread:.2}, \
             {:.0} ms",
            m.len(),
            sol.inliers.len(),
            sol.rms_px,
            t.elapsed().as_secs_f64() * 1e3
        );
        (sol.inliers.len() >= cfg.min_inliers
            && spread >= cfg.min_spread
            && self.roi(&sol.pose).is_some())
        .then_some(Candidate {
            keyframe: k,
            pose: sol.pose,
            inliers: sol.inliers.len(),
            spread,
        })
    }
}

/// The larger side of the bounding box of `pixels`.
fn spread(pixels: &[Vector2<f64>]) -> f64 {
    if pixels.is_empty() {
        return 0.0;
    }
    let (mut lo, mut hi) = (pixels[0], pixels[0]);
    for p in pixels {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (hi - lo).max()
}
