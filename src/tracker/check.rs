//! The check of a pose against the image on the tracker's renders
//! ([`super::verify`] gives the scores and the rules).

use super::region::Placed;
use super::shading::shading_rms;
use super::state::Frame;
use super::verify::{VerifyScores, score, texture_step};
use crate::features::GreyImage;

/// The rendering side: the model splatted at the pose, textured by the
/// closest keyframe where there is a store.
impl super::Tracker {
    /// The fraction of the model's points (up to 4096 of them, evenly
    /// strided) in front of the camera and inside the image at `pose`.
    pub(super) fn visible_fraction(&self, pose: &crate::geometry::Pose) -> f64 {
        let n = self.model.positions.len();
        if n == 0 {
            return 0.0;
        }
        let stride = n.div_ceil(4096);
        let (w, h) = (self.cam.width as f64, self.cam.height as f64);
        let (mut seen, mut all) = (0usize, 0usize);
        for p in self.model.positions.iter().step_by(stride) {
            all += 1;
            let c = pose.transform_point(&nalgebra::Vector3::new(
                p[0] as f64,
                p[1] as f64,
                p[2] as f64,
            ));
            if let Some(uv) = self.cam.project(&c).filter(|_| c.z > 0.0) {
                seen += usize::from(uv.x >= 0.0 && uv.y >= 0.0 && uv.x < w && uv.y < h);
            }
        }
        seen as f64 / all as f64
    }

    /// Scores `pose` against `frame` (module docs), and notes whether the
    /// view showed a texture of its own.
    pub(super) fn verify_scores(
        &mut self,
        frame: &Frame,
        pose: &crate::geometry::Pose,
    ) -> Result<VerifyScores, super::TrackError> {
        let (mut s, served) = self.score_pose(frame, pose, true)?;
        // A view made a pixel or so from the pose stands in for the
        // check's render; its normals sit as far off, which at a box's
        // creases lifts the shading's residual (measured: 1.8 times its
        // level at a right pose, where a fresh render left 1.0). A served
        // view whose shading the steady rule would refuse is rendered
        // again at the pose.
        if served
            && s.shading_rms
                .is_some_and(|rms| self.steady.refuses_shading(rms, &self.config.verify))
        {
            s = self.score_pose(frame, pose, false)?.0;
        }
        if s.covered_px > 0 {
            let below = self.config.verify.untextured_below;
            self.contour.plain_view = s.view_texture.is_none_or(|t| t < below);
        }
        Ok(s)
    }

    /// The scores of `pose` on its render, or on a view made near it
    /// where `serve`; and whether such a view (not made at `pose`) served.
    fn score_pose(
        &mut self,
        frame: &Frame,
        pose: &crate::geometry::Pose,
        serve: bool,
    ) -> Result<(VerifyScores, bool), super::TrackError> {
        use crate::splat::Attribute;
        let visible = self.visible_fraction(pose);
        let step = texture_step(self.radius_px(pose));
        if visible < self.config.verify.min_visible {
            let s = VerifyScores {
                visible,
                ..Default::default()
            };
            return Ok((s, false));
        }
        // With the predictors: the next frame's IT step needs this very
        // render (at its previous pose), and takes it over.
        let fit = self.fits_shading();
        let attrs = self.view_attrs(self.config.windows);
        // The render, its resolves and the frame's window go with the
        // scores' readback (or the view's).
        let _batch = self.device.batch();
        // A novel view made this frame within a pixel or so of the pose
        // (the KF step's, when its correction was small) is scored
        // instead of rendering again: the edge test searches 2 px along
        // the outline's normal, and the ZNCC falls little for a sub-pixel
        // shift. Else the window holds every covered pixel with a margin
        // wider than the edge search, so the scores are those of the
        // whole image.
        let served = self.view_for_check(pose, attrs).filter(|_| serve);
        let near = served.is_some_and(|v| v.pose != *pose);
        let (window, textured, rendered_at) = match served {
            Some(v) => (v.window, v.keyframe.is_some(), v.pose),
            None => {
                let window = self.view_window(pose);
                let k = self.render_view_in(pose, attrs, window, "check")?;
                (window, k.is_some(), *pose)
            }
        };
        let gpu_check = self
            .check
            .as_mut()
            .filter(|c| c.resident() && c.fits(window.width, window.height))
            .zip(self.device.gpu());
        if let Some((check, ctx)) = gpu_check {
            // Resident: the view is resolved into the check's buffers and
            // scored there; CHECK_SUMS floats come back.
            let (wb, cb) = check.targets(window.width, window.height);
            let (wb, cb) = (wb.clone(), cb.clone());
            // The frame's window: cut from the resident frame on the GPU
            // where there is one (the same values), else uploaded.
            let (w, h) = (window.width, window.height);
            let on_gpu = self.resident.frames().0.is_some();
            let s = if on_gpu {
                // The view's resolves, the frame's window and the scores:
                // one compute pass where untimed.
                let target = check.frame_target(w, h);
                let (splatter, targets) = (&self.splatter, &self.targets);
                let resident = &mut self.resident;
                let at = [window.x0, window.y0, w, h];
                check.score_prepared(
                    w,
                    h,
                    textured,
                    visible,
                    step,
                    &self.config.verify,
                    |passes| {
                        splatter.record_resolve(ctx, passes, targets, Attribute::Weight, &wb)?;
                        if textured {
                            splatter.record_resolve(ctx, passes, targets, Attribute::Color, &cb)?;
                        }
                        resident.record_window_values(passes, at, &target)?;
                        Ok::<_, super::TrackError>(())
                    },
                )?
            } else {
                self.splatter
                    .resolve_into(ctx, &self.targets, Attribute::Weight, &wb)?;
                if textured {
                    self.splatter
                        .resolve_into(ctx, &self.targets, Attribute::Color, &cb)?;
                }
                let frame = Placed::full(frame.grey()).crop(&window);
                check
                    .score(&frame, textured, visible, step, &self.config.verify)
                    .map_err(crate::splat::SplatError::from)?
            };
            let t = check.take_timings();
            let s = if fit {
                let frame = Placed::full(frame.grey()).crop(&window);
                self.with_shading(s, &frame)?
            } else {
                s
            };
            // The render serves the next frame's IT step (after its
            // resolves were recorded).
            self.keep_render(rendered_at);
            self.note_timings("check score", t);
            return Ok((s, near));
        }
        let frame = Placed::full(frame.grey()).crop(&window);
        let weight = self
            .splatter
            .read(&self.device, &self.targets, Attribute::Weight)?;
        let covered: Vec<bool> = weight
            .data
            .iter()
            .map(|v| *v > 0.0 && !v.is_nan())
            .collect();
        let view = if textured {
            let c = self
                .splatter
                .read(&self.device, &self.targets, Attribute::Color)?;
            Some(GreyImage::from_rgb_f32(c.width as usize, c.height as usize, &c.data)?.data)
        } else {
            None
        };
        let s = score(
            &frame,
            &covered,
            view.as_deref(),
            visible,
            step,
            &self.config.verify,
        );
        let s = if fit {
            self.with_shading(s, &frame)?
        } else {
            s
        };
        self.keep_render(rendered_at);
        Ok((s, near))
    }

    /// Whether the check fits the frame's shading by the render's normals
    /// ([`super::shading`]): where the view shows no texture of its own
    /// (neither keyframes nor model colours, or the last check's view
    /// untextured), so that its ZNCC cannot vouch for the pose.
    pub(crate) fn fits_shading(&self) -> bool {
        let v = &self.config.verify;
        v.enabled && v.shading_drop > 0.0 && (self.store.is_none() || self.contour.plain_view)
    }

    /// The attributes of a view the check may score: the predictors where
    /// `motion`, and the normals where the check fits the shading (so that
    /// the KF step's and the contour's views still serve it).
    pub(crate) fn view_attrs(&self, motion: bool) -> crate::splat::Attributes {
        crate::splat::Attributes {
            geometry: self.fits_shading(),
            motion,
        }
    }

    /// `s` with [`VerifyScores::shading_rms`] of the render the targets
    /// hold against `frame` (its window's grey levels). The normals are
    /// read (on a GPU, read back: the check's sums leave the fit out) and
    /// give the coverage too: NaN where no splat reaches (and where the
    /// splats' normals cancel, which leaves no normal to fit either).
    fn with_shading(
        &mut self,
        mut s: VerifyScores,
        frame: &GreyImage,
    ) -> Result<VerifyScores, super::TrackError> {
        if s.covered_px > 0 {
            let normals =
                self.splatter
                    .read(&self.device, &self.targets, crate::splat::Attribute::Normal)?;
            s.shading_rms = shading_rms(frame, &normals.data);
        }
        Ok(s)
    }
}
