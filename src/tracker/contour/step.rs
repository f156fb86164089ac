//! The contour step of the tracker: renders, outline, line searches and
//! solves (the iterations of the module docs).

use super::learner::Lesson;
use super::line::search_lines;
use super::normals::{ModelNormals, crease_radii};
use super::outline::{
    ContourPoint, extract_contour, inset_each, insets, limb_normals, limb_normals_with,
    straight_edge,
};
use super::rows::{GROUP_CONTOUR, GROUP_TEXTURE, Lifted, contour_predictors_at};
use crate::geometry::{Intrinsics, Pose};
use crate::pose::{Anchor, Observation, SolveError, irls_grouped};
use crate::splat::{Attribute, Attributes, Window};
use crate::tracker::decision::{Estimate, StepOutcome};
use crate::tracker::result::StepError;
use crate::tracker::state::Tracker;
use nalgebra::{Vector2, Vector6};

/// Outline points this close (pixels, along their normal) to an object
/// in front are left out: their lines would find that object's edge (half
/// the longest default line).
const OCCLUDED_EDGE_PX: f64 = 8.0;

impl Tracker {
    /// The contour step from `pose`: the iterations of the module docs,
    /// fused with `anchors` (texture matches of this frame, object point
    /// and live-frame position). `long`: no trusted texture estimate, so
    /// the lines reach farther. Leaves the last coverage mask in
    /// `self.contour.mask` for learning the colours.
    pub(in crate::tracker) fn contour_stage(
        &mut self,
        frame: &image::RgbImage,
        pose: &Pose,
        long: bool,
        anchors: &[Anchor],
    ) -> StepOutcome {
        StepOutcome::from_result(self.contour_step(frame, pose, long, anchors, None))
    }

    /// [`Self::contour_stage`] alone (no texture matches), every solve
    /// damped by `damping` (a fraction of the normal matrix's diagonal).
    pub(in crate::tracker) fn contour_stage_damped(
        &mut self,
        frame: &image::RgbImage,
        pose: &Pose,
        long: bool,
        damping: f64,
    ) -> StepOutcome {
        StepOutcome::from_result(self.contour_step(frame, pose, long, &[], Some(damping)))
    }

    fn contour_step(
        &mut self,
        frame: &image::RgbImage,
        start: &Pose,
        long: bool,
        anchors: &[Anchor],
        damping: Option<f64>,
    ) -> Result<Estimate, StepError> {
        let cfg = self.config.contour.clone();
        // Fused with a trusted KF step's matches, damping holds the solve
        // near that estimate (the prior the contour refines); from IT's
        // estimate (which drifts) or alone, nothing should hold it back.
        let damping = if let Some(d) = damping {
            d
        } else if anchors.is_empty() {
            cfg.damping
        } else {
            cfg.fused_damping
        };
        let mut pose = *start;
        // The last render's points and its pose, and the points of this
        // round (those, or them moved to the round's pose). A render the
        // targets already hold near `start` (the KF step's novel view)
        // seeds them: the first round then moves its points like a later
        // round does, instead of rendering.
        let mut rendered: Vec<Lifted> = Vec::new();
        let mut rendered_at = pose;
        if let Some((at, window)) = self.contour_seed(&pose) {
            let cam = window.camera(&self.cam);
            match self.contour_points_of_render(frame, &at, window, &cam) {
                Ok(points) => {
                    rendered = points;
                    rendered_at = at;
                }
                Err(e) => log::debug!("contour: the held render does not seed ({e})"),
            }
        }
        let mut moved: Vec<Lifted> = Vec::new();
        let mut last = None;
        self.contour.converged = false;
        for round in 0..cfg.rounds.max(1) {
            // The first round goes coarse to fine; later ones (at the
            // newest estimate) use the finest lines only.
            let levels = if round == 0 {
                &cfg.search_px[..]
            } else {
                &cfg.search_px[cfg.search_px.len() - 1..]
            };
            // After a small correction the outline is nearly the same
            // points of the surface: move them instead of rendering.
            let motion = pose.compose(&rendered_at.inverse());
            let twist = motion.log();
            let small = !rendered.is_empty()
                && cfg.reproject_px > 0.0
                && rendered
                    .iter()
                    .all(|l| (l.row.predictors * twist)[0].abs() <= cfg.reproject_px);
            if small {
                moved.clear();
                moved.extend(rendered.iter().filter_map(|l| l.moved(&motion, &self.cam)));
            } else {
                rendered = self.contour_points(frame, &pose)?;
                rendered_at = pose;
                self.contour.renders += 1;
            }
            let lifted: &[Lifted] = if small { &moved } else { &rendered };
            let step = self.contour_solve(
                frame,
                &pose,
                lifted,
                levels,
                long && round == 0,
                damping,
                anchors,
            )?;
            // How far this round moved the contour (to first order; the
            // mean of the points' motions along their normals).
            let twist = step.pose.compose(&pose.inverse()).log();
            let moved = lifted
                .iter()
                .map(|l| (l.row.predictors * twist)[0].abs())
                .sum::<f64>()
                / lifted.len().max(1) as f64;
            log::debug!("contour: round {round} moved the outline {moved:.2} px (mean)");
            self.contour.rounds += 1;
            pose = step.pose;
            last = Some(step);
            if round >= 1 && moved < cfg.converged_px {
                self.contour.converged = true;
                break;
            }
        }
        if let Some(step) = &last {
            self.note_view_ends_at(&rendered, &rendered_at, &step.pose);
        }
        last.ok_or(StepError::Solve(SolveError::TooFewMatches {
            got: 0,
            need: cfg.min_points,
        }))
    }

    /// Whether the contour's renders are the novel view the pose check
    /// scores (with the check's attributes, textured by the keyframe it
    /// would take, their visibility depth kept: the contour reads what a
    /// depth-only render gives) instead of depth-only ones. Where no
    /// texture step runs, the check then scores the contour's last render
    /// when the rounds after it moved its points within
    /// [`ContourConfig::reproject_px`] ([`Tracker::view_for_check`]), and
    /// the next frame's first round is seeded from it: a frame renders
    /// about once, not twice. Only while the check's views show no texture
    /// of their own (an untextured object's shading, which a pixel hardly
    /// changes; a printed texture's ZNCC falls by up to 0.14 a pixel off),
    /// and on the CPU device, whose full render keeps the visibility depth
    /// for one pass more of writes.
    pub(in crate::tracker) fn contour_view_serves_check(&self) -> bool {
        let c = &self.config;
        self.contour.plain_view
            && self.device.gpu().is_none()
            && c.verify.enabled
            && c.windows
            && !c.modalities.texture
            && self.contour_seed_px() > 0.0
    }

    /// How far (pixels, the model's bounding box) a held render may lie
    /// from the contour's start to seed its first round
    /// ([`Tracker::contour_seed`]); 0 where nothing seeds.
    pub(in crate::tracker) fn contour_seed_px(&self) -> f64 {
        let cfg = &self.config.contour;
        if cfg.seed_render && cfg.depth_only {
            4.0 * cfg.reproject_px
        } else {
            0.0
        }
    }

    /// Marks the view the targets hold, made at `rendered_at` (the source
    /// of the rounds' points `rendered`), as standing for the check at
    /// `end` where no point moved farther than
    /// [`ContourConfig::reproject_px`] along its normal from it to `end`
    /// (the rounds' own test for keeping a render) and the rounds
    /// converged: an unconverged step is stepped again, and the check
    /// compares the two by their edge support, which a view a pixel off
    /// would understate.
    fn note_view_ends_at(&mut self, rendered: &[Lifted], rendered_at: &Pose, end: &Pose) {
        let limit = self.config.contour.reproject_px;
        let serves = self.contour_view_serves_check();
        let held = self
            .targets
            .last_view()
            .is_some_and(|(p, _)| p == rendered_at);
        let Some(v) = self
            .view_made
            .as_mut()
            .filter(|v| held && v.pose == *rendered_at)
        else {
            return;
        };
        let twist = end.compose(&rendered_at.inverse()).log();
        let near = !rendered.is_empty()
            && rendered
                .iter()
                .all(|l| (l.row.predictors * twist)[0].abs() <= limit);
        v.stands_for = (near && self.contour.converged && serves).then_some(*end);
    }

    /// The render the targets hold, and its window, when it can stand for
    /// the contour's first render at `pose`: depth-only renders and the
    /// keyframe step's (whose depth comes from its predictors) show the
    /// same coverage; made in the current window, at a pose from which the
    /// model's bounding box moves at most `4 * reproject_px` pixels to
    /// `pose` (the rounds' own test, per point, then decides). Only with
    /// depth-only contour renders (whose limb normals come from the
    /// model's points).
    fn contour_seed(&self, pose: &Pose) -> Option<(Pose, Window)> {
        let reach = self.contour_seed_px();
        if reach <= 0.0 {
            return None;
        }
        let t = &self.targets;
        let readable = t.depth_only() || t.rendered().is_some_and(|r| r.motion || r.geometry);
        let (at, cam) = t.last_view()?;
        if !readable || *cam != self.window.camera(&self.cam) {
            return None;
        }
        let mut far = 0.0f64;
        for x in crate::splat::box_corners(&self.box_lo, &self.box_hi) {
            let a = self.cam.project(&at.transform_point(&x))?;
            let b = self.cam.project(&pose.transform_point(&x))?;
            far = far.max((a - b).norm());
        }
        log::debug!("contour: the held render's box moves {far:.2} px to the start");
        (far <= reach).then_some((*at, self.window))
    }

    /// One render at `pose`: the contour points, each with its row
    /// (predictors from the splatted depth) and its edge position lifted
    /// to the camera frame.
    fn contour_points(
        &mut self,
        frame: &image::RgbImage,
        pose: &Pose,
    ) -> Result<Vec<Lifted>, StepError> {
        // The object's window only (every covered pixel, with a margin
        // wider than the contour's normal window).
        let window = self.view_window(pose);
        let cam = self.use_window(window);
        let t0 = std::time::Instant::now();
        // The render goes with its depth's readback.
        let _batch = self.device.batch();
        let depth_only = self.config.contour.depth_only;
        if self.contour_view_serves_check() {
            // The check's view (its attributes, textured by the keyframe
            // it would take), its visibility depth kept: the points are a
            // depth-only render's.
            let attrs = self.view_attrs(true);
            self.render_view_keeping_depth(pose, attrs, window)?;
        } else if depth_only {
            self.splatter.render_depth(
                &self.device,
                &self.geometry,
                &cam,
                pose,
                &mut self.targets,
                self.gpu_timer.as_mut(),
            )?;
            self.note_splat("contour splat");
        } else {
            self.splat(
                crate::tracker::profile::Texture::None,
                &cam,
                pose,
                Attributes::GEOMETRY,
                "contour",
            )?;
        }
        let points = self.contour_points_of_render(frame, pose, window, &cam)?;
        log::debug!(
            "contour: render, read, extract, gather {:.1} ms",
            t0.elapsed().as_secs_f64() * 1e3
        );
        Ok(points)
    }

    /// The contour points of the render the targets hold, made at `pose`
    /// in `window` (whose camera is `cam`).
    fn contour_points_of_render(
        &mut self,
        frame: &image::RgbImage,
        pose: &Pose,
        window: Window,
        cam: &Intrinsics,
    ) -> Result<Vec<Lifted>, StepError> {
        let (w, h) = (self.cam.width as usize, self.cam.height as usize);
        let depth_only = self.config.contour.depth_only;
        let (ww, wh) = (window.width as usize, window.height as usize);
        let (x0, y0) = (window.x0 as usize, window.y0 as usize);
        let spacing = self.config.contour.spacing_px;
        // The splatted depth gives the coverage (NaN: empty) and, lifted
        // to the camera-space point, the motion predictors L there: the
        // projection's Jacobian (docs/how-it-works.md), what the motion
        // targets would hold, without rendering them. On the GPU
        // (depth-only renders, whose normals come from the model): the
        // outline found there, a few integers a point and the coverage's
        // bits read back; else the depth read back and the outline found
        // here. The same points either way.
        let gpu_outline = self
            .outline
            .as_mut()
            .filter(|o| depth_only && o.resident() && o.fits(window.width, window.height))
            .zip(self.device.gpu());
        let (points, depths, depth) = if let Some((gpu_outline, ctx)) = gpu_outline {
            let _batch = ctx.batch();
            let target = gpu_outline.depth_target(window.width, window.height);
            self.splatter
                .resolve_into(ctx, &self.targets, Attribute::Depth, &target)?;
            let outline = gpu_outline
                .extract(window.width, window.height, spacing)
                .map_err(crate::splat::SplatError::from)?;
            let t = gpu_outline.take_timings();
            self.note_timings("contour outline", t);
            self.fill_contour_mask(w, h, window, |x, y| outline.covered(x as u32, y as u32));
            (outline.points, outline.depths, None)
        } else {
            let depth = self
                .splatter
                .read(&self.device, &self.targets, Attribute::Depth)?;
            let local: Vec<bool> = depth.data.iter().map(|v| v.is_finite()).collect();
            self.fill_contour_mask(w, h, window, |x, y| local[y * ww + x]);
            // Window coordinates (the window's origin is a multiple of the
            // spacing: the same cells as the whole image), then the frame's.
            let points = extract_contour(&local, ww, wh, spacing as usize);
            let depths = points
                .iter()
                .map(|p| depth.pixel(p.pixel[0], p.pixel[1])[0])
                .collect();
            (points, depths, Some(depth))
        };
        // Points near a corner of the outline out, when asked (both ways
        // alike, from the coverage kept in the mask), with their depths.
        let drop_corners = self.config.contour.drop_corners;
        let (mut points, depths) = {
            let mask = &self.contour.mask;
            let at = |x: i64, y: i64| {
                let (fx, fy) = (x + x0 as i64, y + y0 as i64);
                x < 0
                    || y < 0
                    || x >= ww as i64
                    || y >= wh as i64
                    || mask[fy as usize * w + fx as usize]
            };
            points
                .into_iter()
                .zip(depths)
                .filter(|(p, _)| !drop_corners || straight_edge(p, at))
                .unzip::<_, _, Vec<_>, Vec<_>>()
        };
        let cfg = &self.config.contour;
        if !self.contour.colours.model().is_learned()
            && let Some(rect) = self.roi(pose)
            && let Some(centre) = self.centre_px(pose)
        {
            // Needed at once: learnt here.
            let lesson = Lesson {
                rect,
                margin: cfg.learn_margin_px,
                rate: cfg.learning_rate,
                centre: Some(centre),
            };
            self.contour
                .colours
                .learn_here(frame, &self.contour.mask, lesson);
        }
        let mut creases = Vec::new();
        if depth_only {
            if self.contour.normals.is_none() {
                self.contour.normals = ModelNormals::new(&self.model);
            }
            if let Some(grid) = &self.contour.normals {
                let inv = pose.inverse();
                let eye = inv.translation;
                let eye = glam::Vec3::new(eye.x as f32, eye.y as f32, eye.z as f32);
                let rot = pose.rotation;
                // Each point's normal on its own: over the cores.
                let at: Vec<([u32; 2], f32)> = points
                    .iter()
                    .map(|p| p.pixel)
                    .zip(depths.iter().copied())
                    .collect();
                let normals = crate::par::flat_map_split(&at, 64, |part| {
                    part.iter()
                        .map(|&(pixel, z)| {
                            let px = Vector2::new(pixel[0] as f64, pixel[1] as f64);
                            let xo = inv.transform_point(&cam.unproject(&px, z as f64));
                            let n = grid.normal_at(
                                glam::Vec3::new(xo.x as f32, xo.y as f32, xo.z as f32),
                                eye,
                            )?;
                            let n = nalgebra::Vector3::new(n.x as f64, n.y as f64, n.z as f64);
                            (n.norm() > 0.0).then(|| (rot * n).normalize())
                        })
                        .collect()
                });
                let mut normals = normals.into_iter();
                creases = limb_normals_with(cam, &mut points, true, |_| {
                    normals.next().expect("a normal a point")
                });
            }
        } else {
            let normals = self
                .splatter
                .read(&self.device, &self.targets, Attribute::Normal)?;
            creases = limb_normals(cam, &normals, &mut points);
        }
        drop(depth);
        // Limbs by the configured inset, creases by what their splats'
        // size in pixels (the radius at the point's depth) gives.
        if self.contour.crease_radii.is_none() {
            if self.contour.normals.is_none() {
                self.contour.normals = ModelNormals::new(&self.model);
            }
            let radii = crease_radii(&self.model, self.contour.normals.as_ref());
            self.contour.crease_radii = Some(radii);
        }
        let radii = self.contour.crease_radii.expect("set above");
        let lowpass = self.splatter.params().lowpass_px as f64;
        let by = insets(&creases, &depths, radii, cam.fx, cfg.inset_px, lowpass);
        inset_each(&mut points, &by);
        let rows = contour_predictors_at(cam, &points, &depths);
        let origin = Vector2::new(x0 as f64, y0 as f64);
        let mut lifted: Vec<Lifted> = points
            .iter()
            .zip(rows)
            .zip(&depths)
            .map(|((p, row), &z)| Lifted {
                xc: cam.unproject(&p.position, z as f64),
                point: ContourPoint {
                    pixel: [p.pixel[0] + x0 as u32, p.pixel[1] + y0 as u32],
                    position: p.position + origin,
                    normal: p.normal,
                },
                row,
            })
            .collect();
        if let Some(hidden) = &self.hidden {
            // Where another object in front cuts the outline, the edge in
            // the image is that object's: it does not move with this one.
            lifted.retain(|l| {
                let p = &l.point;
                !hidden.near_edge(p.position, p.normal, l.xc.z as f32, OCCLUDED_EDGE_PX)
            });
        }
        Ok(lifted)
    }

    /// The whole frame's coverage (`w x h`) in `self.contour.mask`, the buffer
    /// of the last render, from `covered(x, y)` over `window` (window
    /// pixels); nothing outside it.
    fn fill_contour_mask(
        &mut self,
        w: usize,
        h: usize,
        window: Window,
        covered: impl Fn(usize, usize) -> bool,
    ) {
        let (ww, wh) = (window.width as usize, window.height as usize);
        let (x0, y0) = (window.x0 as usize, window.y0 as usize);
        let coverage = &mut self.contour.mask;
        coverage.clear();
        coverage.resize(w * h, false);
        for y in 0..wh {
            let row = &mut coverage[(y0 + y) * w + x0..(y0 + y) * w + x0 + ww];
            for (x, c) in row.iter_mut().enumerate() {
                *c = covered(x, y);
            }
        }
        self.contour.mask_fresh = true;
    }

    /// One search and solve per line length of `levels` from the points
    /// `found` at `pose`, each searching where the previous solve moved
    /// the contour (to first order: by `n^T L a`), all linearised at
    /// `pose`.
    #[allow(clippy::too_many_arguments)]
    fn contour_solve(
        &mut self,
        frame: &image::RgbImage,
        pose: &Pose,
        found: &[Lifted],
        levels: &[f32],
        long: bool,
        damping: f64,
        anchors: &[Anchor],
    ) -> Result<Estimate, StepError> {
        let cfg = &self.config.contour;
        let t0 = std::time::Instant::now();
        let texture: Vec<Observation> = anchors
            .iter()
            .filter_map(|a| {
                let xc = pose.transform_point(&a.point);
                let uv = self.cam.project(&xc)?;
                Some(Observation {
                    predictors: self.cam.motion_predictors(&xc),
                    displacement: a.target - uv,
                })
            })
            .collect();
        let mut twist = Vector6::zeros();
        let mut last = None;
        for &half in levels {
            let half = if long { half * cfg.long_factor } else { half };
            let centre = self.centre_px(pose).unwrap_or_default();
            let mut obs = search_lines(
                frame,
                self.contour.colours.model(),
                centre,
                found,
                &twist,
                half,
                cfg.slope_px,
            );
            obs.reserve(texture.len());
            let n_contour = obs.len();
            log::debug!(
                "contour: {n_contour} of {} points, half-length {half} px, {:.1} ms",
                found.len(),
                t0.elapsed().as_secs_f64() * 1e3
            );
            if n_contour < cfg.min_points {
                return Err(StepError::Solve(SolveError::TooFewMatches {
                    got: n_contour,
                    need: cfg.min_points,
                }));
            }
            obs.extend_from_slice(&texture);
            let mut groups = vec![GROUP_CONTOUR; n_contour];
            groups.resize(obs.len(), GROUP_TEXTURE);
            let s = irls_grouped(&obs, &groups, damping, &self.config.irls)?;
            let contour_inliers = s.inliers[..n_contour].iter().filter(|&&i| i).count();
            let need = (cfg.min_inlier_fraction * n_contour as f64).ceil() as usize;
            if contour_inliers < need {
                return Err(StepError::Solve(SolveError::TooFewInliers {
                    got: contour_inliers,
                    total: n_contour,
                    need,
                }));
            }
            twist = s.twist;
            last = Some(Estimate {
                pose: pose.apply_twist(&twist).orthonormalized(),
                inliers: s.inlier_count,
                residual_px: s.residual_rms_px,
                scale_px: s.scale_px,
            });
        }
        last.ok_or(StepError::Solve(SolveError::TooFewMatches {
            got: 0,
            need: cfg.min_points,
        }))
    }

    /// Learns the colours of `frame` at the last contour render (after a
    /// tracked frame): on the colour learner's thread (see
    /// [`crate::tracker::Execution::background_learning`]).
    pub(in crate::tracker) fn learn_colours(&mut self, frame: &image::RgbImage, pose: &Pose) {
        let fresh = std::mem::take(&mut self.contour.mask_fresh);
        if let (true, Some(rect), Some(centre)) = (fresh, self.roi(pose), self.centre_px(pose)) {
            let c = &self.config.contour;
            let lesson = Lesson {
                rect,
                margin: c.learn_margin_px,
                rate: c.learning_rate,
                centre: Some(centre),
            };
            self.contour
                .colours
                .learn(frame, &mut self.contour.mask, lesson);
        }
    }

    /// The projection of the model's centre at `pose`: the origin of the
    /// colour sectors' directions.
    fn centre_px(&self, pose: &Pose) -> Option<Vector2<f64>> {
        self.cam.project(&pose.transform_point(&self.center))
    }
}
