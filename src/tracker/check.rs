//! The check of a pose against the image on the tracker's renders
//! ([`super::verify`] gives the scores and the rules).

use super::region::Placed;
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
        let s = self.score_pose(frame, pose)?;
        if s.covered_px > 0 {
            let below = self.config.verify.untextured_below;
            self.contour.plain_view = s.view_texture.is_none_or(|t| t < below);
        }
        Ok(s)
    }

    fn score_pose(
        &mut self,
        frame: &Frame,
        pose: &crate::geometry::Pose,
    ) -> Result<VerifyScores, super::TrackError> {
        use crate::splat::{Attribute, Attributes};
        let visible = self.visible_fraction(pose);
        let step = texture_step(self.radius_px(pose));
        if visible < self.config.verify.min_visible {
            return Ok(VerifyScores {
                visible,
                ..Default::default()
            });
        }
        // With the predictors: the next frame's IT step needs this very
        // render (at its previous pose), and takes it over.
        let attrs = if self.config.windows {
            Attributes::MOTION
        } else {
            Attributes::COLOR
        };
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
        let (window, textured, rendered_at) = match self.view_for_check(pose, attrs) {
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
            // The render serves the next frame's IT step (after its
            // resolves were recorded).
            let t = check.take_timings();
            self.keep_render(rendered_at);
            self.note_timings("check score", t);
            return Ok(s);
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
        self.keep_render(rendered_at);
        Ok(score(
            &frame,
            &covered,
            view.as_deref(),
            visible,
            step,
            &self.config.verify,
        ))
    }
}
