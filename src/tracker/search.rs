//! The search for the object in a whole frame ([`super::init`]) by the
//! tracker: its viewpoints, templates, candidates and their refinement.

use super::decision::Decision;
use super::error::TrackError;
use super::init::{
    EdgeMap, Hit, TEMPLATE_POINTS, Template, axis_to, best_positions, shrink, sphere_directions,
    thinned,
};
use super::result::{LostReason, Refused, Source, Status, StepError};
use super::state::{Frame, Tracker};
use super::templates::{TemplateModels, TemplateSearch, ViewAndCover};
use super::verify::VerifyScores;
use crate::features::GreyImage;
use crate::geometry::{Pose, look_at, rotation_exp};
use crate::splat::{Attribute, Attributes, GpuModel, SplatTargets};
use nalgebra::{Matrix3, Vector3};
use std::collections::HashMap;

impl Tracker {
    /// The viewpoints of the search, the object's centre on the optical
    /// axis.
    fn init_viewpoints(&self) -> Vec<Pose> {
        let c = self.center;
        let fit = self.cam.fx.min(self.cam.fy) * 2.0 * self.radius
            / (self.cam.width.min(self.cam.height) as f64 / 3.0);
        let mut out = Vec::new();
        let mut dists = Vec::new();
        if let Some(store) = &self.store {
            for k in &store.keyframes {
                let z = k.pose.transform_point(&c).norm();
                dists.push(z);
                // The keyframe's view, re-centred on the axis.
                let ray = k.pose.transform_point(&c).normalize();
                let r = axis_to(&ray).transpose() * k.pose.rotation;
                out.push(centred(r, z, &c));
                // And tilted four ways: the object seen from a little off
                // the keyframe, still with its texture.
                let tilt = self.config.init.keyframe_tilt_deg.to_radians();
                if tilt > 0.0 {
                    for axis in [Vector3::x(), -Vector3::x(), Vector3::y(), -Vector3::y()] {
                        out.push(centred(rotation_exp(&(axis * tilt)) * r, z, &c));
                    }
                }
            }
        }
        dists.sort_by(f64::total_cmp);
        let d = dists
            .get(dists.len() / 2)
            .copied()
            .unwrap_or(fit)
            .max(self.radius * 1.5);
        let cfg = &self.config.init;
        for dir in sphere_directions(cfg.sphere) {
            let base = look_at(&(c + dir * d), &c, &Vector3::new(0.0, 0.0, 1.0));
            for k in 0..cfg.rolls.max(1) {
                let roll = rotation_exp(
                    &(Vector3::z() * std::f64::consts::TAU * k as f64 / cfg.rolls.max(1) as f64),
                );
                out.push(centred(roll * base.rotation, d, &c));
            }
        }
        out
    }

    /// Searches the whole frame for the object (module docs): the pose
    /// found, checked against the image, or `None`.
    pub fn find(&mut self, frame: &image::RgbImage) -> Result<Option<Pose>, TrackError> {
        self.search_refused = None;
        let mut grey_frame = Frame::new(frame.clone());
        // Features first; the templates where they found nothing, on a
        // textured object only now and then (they cost seconds).
        let cfg = self.config.init.detect.clone();
        let mut templates = true;
        let mut found = Ok(None);
        if cfg.enabled && self.store.is_some() {
            found = self.detect_in(&mut grey_frame);
            templates = self.detector.as_ref().is_none_or(|d| d.templates_now(&cfg));
        }
        if matches!(found, Ok(None)) && templates {
            let mask = self.search_mask();
            grey_frame.corners = self.harris.detect(grey_frame.grey(), mask.as_deref())?;
            found = self.find_in(&grey_frame, frame);
        }
        if self.config.modalities.contour {
            // The candidates' colours are not the object's: the first
            // tracked frame learns them afresh at its pose.
            self.contour.colours.reset();
        }
        found
    }

    /// The template search (module docs of [`super::init`]) in one go:
    /// the best candidate that passes the check, or `None`.
    pub(super) fn find_in(
        &mut self,
        frame: &Frame,
        rgb: &image::RgbImage,
    ) -> Result<Option<Pose>, TrackError> {
        let mut ts = self.template_search(frame)?;
        while !ts.views_done() {
            self.template_hits(&mut ts)?;
        }
        while !ts.candidates_done() {
            self.template_candidate(&mut ts, frame, rgb)?;
        }
        Ok(self.template_result(ts))
    }

    /// A template search of `frame` (hits are scored on it), its
    /// viewpoints and candidates still to come ([`Tracker::template_hits`],
    /// [`Tracker::template_candidate`]).
    pub(super) fn template_search(&mut self, frame: &Frame) -> Result<TemplateSearch, TrackError> {
        let shading_only = self.shading_only()?;
        let (w, h) = (self.cam.width as usize, self.cam.height as usize);
        let views = self.init_viewpoints();
        let d0 = views
            .first()
            .map_or(1.0, |p| p.transform_point(&self.center).z);
        let diam_px = self.cam.fx.max(self.cam.fy) * 2.0 * self.radius / d0;
        let cfg = &self.config.init;
        let f = ((diam_px / cfg.template_px).floor() as usize).clamp(1, 16);
        let (coarse, cw, ch) = shrink(&frame.grey().data, w, h, f);
        let edges = EdgeMap::new(&coarse, cw, ch);
        // Templates rendered at twice the coarse size, then shrunk by 2:
        // pixel (i, j) of the result is centred where coarse pixel (i, j)
        // of the frame is ((u + 0.5) s - 0.5 with s = 1 / f).
        let small = self.cam.scaled(2.0 / f as f64);
        let targets = SplatTargets::new(&self.device, small.width, small.height);
        let (thin, idx) = thinned(&self.model, TEMPLATE_POINTS);
        let models = TemplateModels {
            geometry: GpuModel::new(&self.device, &thin)?,
            idx,
            textured: HashMap::new(),
        };
        Ok(TemplateSearch {
            shading_only,
            near: 0.25 * diam_px,
            places: Vec::new(),
            cap: cfg.candidates,
            views,
            f,
            coarse,
            cw,
            ch,
            edges,
            small,
            targets,
            models,
            hits: Vec::new(),
            next_view: 0,
            next_hit: None,
            best: None,
            refused: None,
        })
    }

    /// Scores the next viewpoint's templates over the search's frame.
    pub(super) fn template_hits(&mut self, ts: &mut TemplateSearch) -> Result<(), TrackError> {
        let Some(pose) = ts.views.get(ts.next_view).copied() else {
            return Ok(());
        };
        let vi = ts.next_view;
        ts.next_view += 1;
        let small = ts.small;
        let Some((view, cover)) =
            self.template_view(&pose, &small, &mut ts.targets, &mut ts.models)?
        else {
            return Ok(());
        };
        let (cw, ch) = (ts.cw, ts.ch);
        let (sw, sh) = (small.width as usize, small.height as usize);
        let (v, vw, vh) = shrink(&view, sw, sh, 2);
        let (c, _, _) = shrink(&cover, sw, sh, 2);
        for scale in [0.8, 1.0, 1.25] {
            let Some((t, origin)) = Template::new(&v, &c, vw, vh, scale) else {
                continue;
            };
            for (x, y, score) in best_positions(&t, &ts.coarse, &ts.edges, cw, ch, 2) {
                ts.hits.push(Hit {
                    view: vi,
                    scale,
                    x,
                    y,
                    score,
                    origin,
                });
            }
        }
        Ok(())
    }

    /// Refines and judges the next best hit on `frame`, the search's own.
    pub(super) fn template_candidate(
        &mut self,
        ts: &mut TemplateSearch,
        frame: &Frame,
        rgb: &image::RgbImage,
    ) -> Result<(), TrackError> {
        if ts.next_hit.is_none() {
            ts.hits.sort_by(|a, b| b.score.total_cmp(&a.score));
        }
        // The next hit at a place refined at most once before: a place is
        // refined at most twice, so that a distractor whose look matches
        // many views does not take every candidate.
        let ff = ts.f as f64;
        let (pu, pv) = (
            (self.cam.cx + 0.5) / ff - 0.5,
            (self.cam.cy + 0.5) / ff - 0.5,
        );
        let mut next = ts.next_hit.unwrap_or(0);
        let found = loop {
            let Some(hit) = ts.hits.get(next).copied() else {
                break None;
            };
            next += 1;
            let (x0, y0) = hit.origin;
            // Where the template's centre (the principal point) lands, in
            // coarse pixels, then full-size ones (a coarse pixel centre u
            // is full-size (u + 0.5) f - 0.5).
            let u = (hit.x as f64 + (pu - x0 as f64) * hit.scale + 0.5) * ff - 0.5;
            let vv = (hit.y as f64 + (pv - y0 as f64) * hit.scale + 0.5) * ff - 0.5;
            let seen = ts
                .places
                .iter()
                .filter(|p| (p.0 - u).hypot(p.1 - vv) < ts.near)
                .count();
            if seen < 2 {
                ts.places.push((u, vv));
                break Some((hit, u, vv));
            }
        };
        ts.next_hit = Some(next);
        let Some((hit, u, vv)) = found else {
            return Ok(());
        };
        let pose = &ts.views[hit.view];
        let ray = Vector3::new(
            (u - self.cam.cx) / self.cam.fx,
            (vv - self.cam.cy) / self.cam.fy,
            1.0,
        )
        .normalize();
        let r = axis_to(&ray);
        let z = pose.transform_point(&self.center).z / hit.scale;
        let rot = r * pose.rotation;
        let start = Pose::new(rot, ray * z - rot * self.center)?;
        let Some((refined, by_contour)) = self.refine_candidate(frame, rgb, start)? else {
            return Ok(());
        };
        let s = self.verify_scores(frame, &refined)?;
        log::debug!("init candidate {hit:?} (contour: {by_contour}): {s:?}");
        // Refined by its outline (no texture step held), the edges
        // decide; on an object of shading only, strictly (distractors
        // of its colour and other shapes pass the plain rule).
        let judged = if by_contour && ts.shading_only {
            super::verify::judge_outline_candidate(&s, &self.config.verify)
        } else if by_contour {
            super::verify::judge_with_contour(&s, &self.config.verify)
        } else {
            super::verify::judge(&s, &self.config.verify)
        };
        let z = s.zncc.unwrap_or(s.edge_support.unwrap_or(0.0));
        if judged.is_ok() {
            if ts.best.is_none_or(|b| z > b.0) {
                ts.best = Some((z, refined, by_contour));
            }
        } else if ts.refused.as_ref().is_none_or(|b| z > b.0) {
            let pose = refined;
            ts.refused = Some((
                z,
                Refused {
                    pose,
                    source: Source::Search,
                    inliers: 0,
                    residual_px: f64::NAN,
                    scores: Some(s),
                },
            ));
        }
        Ok(())
    }

    /// The template search's answer: its best candidate that passed, and
    /// its best refused one kept for the report.
    pub(super) fn template_result(&mut self, ts: TemplateSearch) -> Option<Pose> {
        // Kept where the templates refused nothing (the features may have).
        if let Some(r) = ts.refused {
            self.search_refused = Some(r.1);
        }
        self.found_by_outline = ts.shading_only && ts.best.is_some_and(|b| b.2);
        ts.best.map(|b| b.1)
    }

    /// Holds a start found by the outline alone (module docs of
    /// [`super::init`]): `d`, the frame's decision from `from` with the
    /// check's `scores`, unless a start is being confirmed. While one is,
    /// a frame that tracks within [`super::InitConfig::confirm_max_turn_deg`]
    /// of `from` and passes the search's check
    /// ([`super::verify::judge_outline_candidate`]) counts towards it and
    /// is reported `lost` (`confirming`) until the last; one that does not
    /// ends it (`unconfirmed`) and the search runs again. Returns the
    /// decision the tracker keeps and, for a held frame, the reason it is
    /// reported `lost`.
    pub(super) fn confirm_start(
        &mut self,
        d: Decision,
        scores: Option<&VerifyScores>,
        from: &Pose,
    ) -> (Decision, Option<LostReason>) {
        if self.confirm_left == 0 {
            return (d, None);
        }
        if d.status != Status::Tracking {
            self.confirm_left = 0;
            self.searching = true;
            self.pose = self.confirm_report;
            return (d, None);
        }
        let pose = d.pose.unwrap_or(*from);
        let turn_deg = pose.rotation_error_deg(from);
        let check = scores
            .and_then(|s| super::verify::judge_outline_candidate(s, &self.config.verify).err());
        if turn_deg > self.config.init.confirm_max_turn_deg || check.is_some() {
            log::debug!("start not confirmed: turned {turn_deg:.1} deg, check {check:?}");
            self.confirm_left = 0;
            self.searching = true;
            self.pose = self.confirm_report;
            let lost = Decision {
                status: Status::Lost,
                pose: None,
                reason: Some(LostReason::Unconfirmed { turn_deg, check }),
                it_only_streak: 0,
                ..d
            };
            return (lost, None);
        }
        self.confirm_left -= 1;
        let held = (self.confirm_left > 0).then_some(LostReason::Confirming {
            left: self.confirm_left,
        });
        (d, held)
    }

    /// The KF step from `start`, wide search first: the refined pose, or
    /// `None` when a step fails. Where a KF step fails (too few corners on
    /// a weakly textured object) and the contour modality is on, the
    /// outline refines the candidate instead ([`Tracker::contour_candidate`]);
    /// the flag says so.
    fn refine_candidate(
        &mut self,
        frame: &Frame,
        rgb: &image::RgbImage,
        start: Pose,
    ) -> Result<Option<(Pose, bool)>, TrackError> {
        let mut pose = start;
        for i in 0..self.config.init.refine_steps.max(1) {
            if self.roi(&pose).is_none() {
                return Ok(None);
            }
            let search = if i == 0 {
                super::kf::Search::Recover
            } else {
                super::kf::Search::Refine
            };
            match self.kf_step(frame, &pose, search, &[]) {
                Ok((step, _)) => pose = step.pose,
                Err(StepError::Gpu(e)) => return Err(TrackError::Search(e)),
                Err(_) if self.config.modalities.contour => {
                    return self.contour_candidate(rgb, start);
                }
                Err(_) => return Ok(None),
            }
        }
        Ok(Some((pose, false)))
    }

    /// The contour step from `start` (colours learnt at `start`, long lines
    /// first), `refine_steps` times: the refined pose, or `None` when a
    /// step fails or is not trusted.
    fn contour_candidate(
        &mut self,
        rgb: &image::RgbImage,
        start: Pose,
    ) -> Result<Option<(Pose, bool)>, TrackError> {
        self.contour.colours.reset();
        let rules = super::decision::Rules::of(&self.config);
        let mut pose = start;
        for i in 0..self.config.init.refine_steps.max(1) {
            if self.roi(&pose).is_none() {
                return Ok(None);
            }
            let step = self.contour_stage(rgb, &pose, i == 0, &[]);
            if let Some(StepError::Gpu(e)) = step.error {
                return Err(TrackError::Search(e));
            }
            match step.estimate.filter(|e| rules.trusted(e)) {
                Some(e) => pose = e.pose,
                None => return Ok(None),
            }
        }
        Ok(Some((pose, true)))
    }

    /// The textured view (grey) and coverage (0/1) at `pose` of the
    /// thinned model seen by `cam` (a scaled copy of the tracker's camera)
    /// in `targets` (its size), textured by the closest keyframe; `None`
    /// without any texture.
    fn template_view(
        &mut self,
        pose: &Pose,
        cam: &crate::geometry::Intrinsics,
        targets: &mut SplatTargets,
        models: &mut TemplateModels,
    ) -> Result<Option<ViewAndCover>, TrackError> {
        let Some(store) = self.store.as_ref() else {
            return Ok(None);
        };
        let k = store.closest(pose);
        let gm = match models.textured.entry(k) {
            std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::hash_map::Entry::Vacant(e) => {
                let colors: Vec<[f32; 3]> = models
                    .idx
                    .iter()
                    .map(|&i| store.keyframes[k].colors[i])
                    .collect();
                e.insert(models.geometry.with_colors(&self.device, &colors)?)
            }
        };
        self.splatter
            .render(&self.device, gm, cam, pose, Attributes::COLOR, targets)?;
        let weight = self
            .splatter
            .read(&self.device, targets, Attribute::Weight)?;
        let c = self
            .splatter
            .read(&self.device, targets, Attribute::Color)?;
        let grey = GreyImage::from_rgb_f32(c.width as usize, c.height as usize, &c.data)?;
        let cover: Vec<f32> = weight
            .data
            .iter()
            .map(|v| f32::from(u8::from(*v > 0.0 && !v.is_nan())))
            .collect();
        // Empty pixels hold no colour (NaN): zero, so shrinking mixes none in.
        let view = grey
            .data
            .iter()
            .zip(&cover)
            .map(|(g, c)| if *c > 0.0 && g.is_finite() { *g } else { 0.0 })
            .collect();
        Ok(Some((view, cover)))
    }
}

/// The pose with rotation `r` and the object's centre `c` at distance `d`
/// on the optical axis.
fn centred(r: Matrix3<f64>, d: f64, c: &Vector3<f64>) -> Pose {
    Pose {
        rotation: r,
        translation: Vector3::new(0.0, 0.0, d) - r * c,
    }
}
