//! Where the steps work: the windows of renders, the targets kept for
//! them, the frame's corners in its window, and what the steps share
//! (the textured render at a pose, a match as a correspondence, the
//! robust solve). The types are in [`super::region`].

use super::decision::Estimate;
use super::error::TrackError;
use super::profile;
use super::region::{Kept, Placed, SPARE_TARGETS, ViewMade, placed};
use super::result::StepError;
use super::state::{Frame, Tracker};
use crate::features::{Corner, FeatureError};
use crate::geometry::{Intrinsics, Pose};
use crate::pose::{Anchor, Correspondence, Observation, Refined, Refiner};
use crate::splat::{
    Attribute, Attributes, GatherMode, GatherSample, SplatError, SplatTargets, Window,
};
use nalgebra::Vector2;

impl Tracker {
    /// Matches on GPU-resident images or on host crops
    /// ([`super::Execution::resident_matching`]).
    pub(super) fn set_resident_matching(&mut self, on: bool) {
        self.resident.on = on;
        if !on {
            self.resident.current = None;
            self.resident.previous = None;
        }
    }

    /// Every kernel choice a GPU's or a CPU adapter's
    /// ([`super::Execution::gpu_kernels`]).
    pub(super) fn set_gpu_kernels(&mut self, gpu: bool) {
        self.harris.set_tiled_selection(gpu);
        self.it_matcher.set_tiled(gpu);
        self.kf_matcher.set_tiled(gpu);
        self.recover_matcher.set_tiled(gpu);
        if let Some(c) = self.check.as_mut() {
            c.set_tiled(gpu);
        }
    }

    /// The window a render of the model at `pose` needs: every pixel it
    /// can cover, plus `margin` pixels.
    pub(super) fn view_window(&self, pose: &Pose) -> Window {
        let full = Window::full(&self.cam);
        if !self.config.windows {
            return full;
        }
        // The low-pass filter spreads a splat by up to 3 x 0.75 px beyond
        // its radius (shaders/splat.wgsl); 4 px more for rounding.
        let margin = self.window_margin() + 4.0;
        // Origins on the Harris grid and on the contour's cells.
        let (a, b) = (
            self.config.harris.grid_cell.max(1),
            self.config.contour.spacing_px.max(1),
        );
        let gcd = |mut x: u32, mut y: u32| {
            while y != 0 {
                (x, y) = (y, x % y);
            }
            x
        };
        let align = (a / gcd(a, b)).saturating_mul(b);
        Window::of_box(&self.cam, pose, &self.box_lo, &self.box_hi, margin, align).unwrap_or(full)
    }

    /// The margin around what a step looks at that keeps Harris supports,
    /// sub-pixel refinements and the check's edge test (its search and
    /// the level beyond it) inside a window.
    pub(super) fn window_margin(&self) -> f64 {
        let h = &self.config.harris;
        let v = &self.config.verify;
        (h.support_radius() + h.refine_radius as usize + 4 + v.edge_search_px)
            .max(v.edge_reach_px()) as f64
    }

    /// The margin of the NCC crops for a search radius `r` (`None`: no
    /// crops, windows off).
    pub(super) fn match_margin(&self, r: f32) -> Option<f64> {
        self.config.windows.then_some(
            (r + self.config.ncc.patch as f32 + self.config.refine_patch as f32 + 4.0) as f64,
        )
    }

    /// Makes the tracker's targets the size of `w` (reusing spare ones)
    /// and records `w` as the window of the next render; returns the
    /// window's camera.
    pub(super) fn use_window(&mut self, w: Window) -> Intrinsics {
        if (self.targets.width(), self.targets.height()) != (w.width, w.height) {
            let fresh = self.spare_targets(w);
            let old = std::mem::replace(&mut self.targets, fresh);
            self.put_spare(old);
        }
        self.window = w;
        self.view_made = None;
        w.camera(&self.cam)
    }

    /// Targets of `w`'s size: a spare one, else new ones.
    fn spare_targets(&mut self, w: Window) -> SplatTargets {
        match self
            .spare
            .iter()
            .position(|t| (t.width(), t.height()) == (w.width, w.height))
        {
            Some(i) => self.spare.remove(i),
            None => SplatTargets::new(&self.device, w.width, w.height).motion_depth(),
        }
    }

    fn put_spare(&mut self, t: SplatTargets) {
        self.spare.insert(0, t);
        self.spare.truncate(SPARE_TARGETS);
    }

    /// Keeps the last render (made at `pose` with the predictors and the
    /// model's geometry) for [`Tracker::reuse_render`].
    pub(super) fn keep_render(&mut self, pose: Pose) {
        if !self.config.windows {
            return;
        }
        let view = self.view_made.take().filter(|v| v.pose == pose);
        let fresh = self.spare_targets(self.window);
        let targets = std::mem::replace(&mut self.targets, fresh);
        let kept = Kept {
            pose,
            window: self.window,
            targets,
            view,
        };
        if let Some(old) = self.kept.replace(kept) {
            self.put_spare(old.targets);
        }
    }

    /// Whether a render at `at` can stand for one at `pose`: no corner of
    /// the model's bounding box moves more than `limit_px` between them
    /// (windows on; 0: never).
    pub(super) fn near_render(&self, at: &Pose, pose: &Pose, limit_px: f64) -> bool {
        if !self.config.windows || limit_px <= 0.0 {
            return false;
        }
        let mut far = 0.0f64;
        for x in crate::splat::box_corners(&self.box_lo, &self.box_hi) {
            let (Some(a), Some(b)) = (
                self.cam.project(&at.transform_point(&x)),
                self.cam.project(&pose.transform_point(&x)),
            ) else {
                return false;
            };
            far = far.max((a - b).norm());
        }
        far <= limit_px
    }

    /// The novel view the targets hold when the pose check at `pose`
    /// may score it instead of rendering: it has `attrs`, was textured by
    /// the keyframe a render at `pose` would be, and was made
    /// [`Tracker::near_render`] to `pose` (within
    /// [`super::TrackerConfig::reuse_render_px`]), or it is the view the
    /// contour step's rounds ended at `pose` from ([`ViewMade::stands_for`]).
    pub(super) fn view_for_check(&self, pose: &Pose, attrs: Attributes) -> Option<ViewMade> {
        let v = self.view_made?;
        let held = self.targets.last_view().is_some_and(|(p, _)| *p == v.pose);
        let keyframe = self.store.as_ref().map(|s| s.closest(pose));
        let near = v.stands_for == Some(*pose)
            || self.near_render(&v.pose, pose, self.config.reuse_render_px as f64);
        (held
            && v.window == self.window
            && v.attrs.contains(attrs)
            && v.keyframe == keyframe
            && near)
            .then_some(v)
    }

    /// The kept render and its window, when it was made at `pose`.
    pub(super) fn kept_at(&self, pose: &Pose) -> Option<(&SplatTargets, Window)> {
        self.kept
            .as_ref()
            .filter(|k| k.pose == *pose)
            .map(|k| (&k.targets, k.window))
    }

    /// Makes the kept render current when it was made at `pose` in window
    /// `w` (the render [`Tracker::use_window`] and a render at `pose` would
    /// give), or at a pose [`Tracker::near_render`] to `pose` within
    /// `limit_px` (in its own window, which holds every pixel it covers);
    /// whether it was, and the view it holds is the current one again
    /// (not for `previous_frame`). For
    /// `previous_frame` (IT's view of the frame before, the kept render's
    /// own frame) a render behind other occluders serves too: it shows
    /// that frame's objects where they were then.
    pub(super) fn reuse_render(
        &mut self,
        pose: &Pose,
        w: Window,
        previous_frame: bool,
        limit_px: f64,
    ) -> bool {
        match self.kept.take() {
            // Otherwise not when the splatter's occluders changed since it
            // was made.
            Some(k)
                if (previous_frame || k.targets.last_view().is_some())
                    && ((k.pose == *pose && k.window == w)
                        || self.near_render(&k.pose, pose, limit_px)) =>
            {
                let old = std::mem::replace(&mut self.targets, k.targets);
                self.put_spare(old);
                self.window = k.window;
                // The previous frame's view, for this frame's contour
                // seed (IT takes the render for its predictors alone).
                self.view_made = k.view.filter(|_| !previous_frame).map(|v| ViewMade {
                    stands_for: None,
                    ..v
                });
                true
            }
            Some(k) => {
                self.put_spare(k.targets);
                false
            }
            None => false,
        }
    }

    /// Predictors and depth of the last render at `points` (frame
    /// coordinates).
    pub(super) fn gather_frame(
        &self,
        points: &[[f32; 2]],
    ) -> Result<Vec<GatherSample>, SplatError> {
        self.gather_frame_later(points)?.wait(&self.device)
    }

    /// [`Tracker::gather_frame`], its readback put off to go with the
    /// next one ([`crate::splat::Splatter::gather_later`]).
    pub(super) fn gather_frame_later(
        &self,
        points: &[[f32; 2]],
    ) -> Result<crate::splat::PendingGather, SplatError> {
        let o = self.window.origin();
        let local: Vec<[f32; 2]> = points.iter().map(|p| [p[0] - o[0], p[1] - o[1]]).collect();
        self.splatter
            .gather_later(&self.device, &self.targets, &local, GatherMode::Bilinear)
    }

    /// The window of `frame` Harris looks in at `pose` (the region of
    /// interest grown by the corners' support) and the region of interest
    /// (`x0, y0, x1, y1`, inclusive); `None` where the object is not in
    /// view.
    pub(super) fn frame_window(&self, frame: &Frame, pose: &Pose) -> Option<(Window, [usize; 4])> {
        let (x0, y0, x1, y1) = self.roi(pose)?;
        let full = frame.whole();
        let w = if self.config.windows {
            Window::around(
                [x0 as f64, y0 as f64, x1 as f64, y1 as f64],
                self.window_margin(),
                self.config.harris.grid_cell,
                full.width,
                full.height,
            )
            .unwrap_or(full)
        } else {
            full
        };
        Some((w, [x0, y0, x1, y1]))
    }

    /// Packs the resident frame's window `w` for Harris on the GPU, the
    /// region of interest `roi` allowed (as the host packs the crop), and
    /// returns its size.
    pub(super) fn pack_frame_window(
        &mut self,
        w: Window,
        roi: [usize; 4],
    ) -> Result<(usize, usize), FeatureError> {
        let (ww, wh) = (w.width as usize, w.height as usize);
        let target = self.harris.gpu()?.input_target(ww, wh)?;
        let (ox, oy) = (w.x0 as usize, w.y0 as usize);
        let [x0, y0, x1, y1] = roi;
        let allowed = [x0 - ox, y0 - oy, x1 - ox, y1 - oy].map(|v| v as u32);
        self.resident
            .pack_window([w.x0, w.y0, w.width, w.height], allowed, &target)?;
        Ok((ww, wh))
    }

    /// Harris corners of `frame` within the region of interest at `pose`
    /// (frame coordinates), detected on the region grown by the corners'
    /// support only.
    pub(super) fn frame_corners(
        &mut self,
        frame: &Frame,
        pose: &Pose,
    ) -> Result<Vec<Corner>, FeatureError> {
        let Some((w, [x0, y0, x1, y1])) = self.frame_window(frame, pose) else {
            return Ok(Vec::new());
        };
        let (ww, wh) = (w.width as usize, w.height as usize);
        let o = w.origin();
        let corners = if !self.harris.host() && self.resident.frames().0.is_some() {
            // The frame is on the GPU: its window is packed there.
            self.pack_frame_window(w, [x0, y0, x1, y1])?;
            self.harris.gpu()?.detect_packed(ww, wh)?
        } else {
            let mut mask = vec![false; ww * wh];
            for y in y0..=y1 {
                let row = (y - w.y0 as usize) * ww;
                mask[row + x0 - w.x0 as usize..=row + x1 - w.x0 as usize].fill(true);
            }
            let crop = Placed::full(frame.grey()).crop(&w);
            self.harris.detect(&crop, Some(&mask))?
        };
        self.note_harris("features");
        Ok(placed(&corners, o))
    }
}

impl Tracker {
    /// The model's coverage mask at `pose` (for overlays and the live
    /// view): one flag per pixel of the frame. Only the window the model
    /// can cover at `pose` is splatted and read back (the whole frame with
    /// windows off), the rest is uncovered; at the pose the last frame's
    /// check rendered (a tracked frame's), that render's coverage is read
    /// instead of splatting again.
    pub fn silhouette(&mut self, pose: &Pose) -> Result<Vec<bool>, TrackError> {
        let (weight, window) = match self.kept_at(pose) {
            Some((targets, window)) => (
                self.splatter
                    .read(&self.device, targets, Attribute::Weight)?,
                window,
            ),
            None => {
                let window = self.view_window(pose);
                let cam = self.use_window(window);
                self.splatter.render(
                    &self.device,
                    &self.geometry,
                    &cam,
                    pose,
                    Attributes::COLOR,
                    &mut self.targets,
                )?;
                let weight = self
                    .splatter
                    .read(&self.device, &self.targets, Attribute::Weight)?;
                (weight, window)
            }
        };
        let (fw, fh) = (self.cam.width as usize, self.cam.height as usize);
        let (x0, y0, ww) = (
            window.x0 as usize,
            window.y0 as usize,
            window.width as usize,
        );
        let mut mask = vec![false; fw * fh];
        for (y, row) in weight.data.chunks(ww.max(1)).enumerate() {
            let at = (y0 + y) * fw + x0;
            for (m, v) in mask[at..at + row.len()].iter_mut().zip(row) {
                *m = *v > 0.0 && !v.is_nan();
            }
        }
        Ok(mask)
    }
}

impl Tracker {
    /// The novel view at `pose` over the whole frame: the model textured
    /// by the keyframe closest to `pose` (by the model's colours without
    /// keyframes), as the KF step sees it, with its depth and coverage.
    pub fn novel_view(&mut self, pose: &Pose) -> Result<super::result::NovelView, TrackError> {
        pose.validate()?;
        let window = Window::full(&self.cam);
        let keyframe = self.render_view_in(pose, Attributes::GEOMETRY, window, "view")?;
        let read = |t: &mut Self, a| t.splatter.read(&t.device, &t.targets, a);
        let color = read(self, Attribute::Color)?;
        let depth = read(self, Attribute::Depth)?;
        let weight = read(self, Attribute::Weight)?;
        let mask: Vec<bool> = weight.data.iter().map(|v| *v > 0.0).collect();
        let color = color
            .data
            .chunks_exact(3)
            .zip(&mask)
            .flat_map(|(c, &m)| {
                c.iter().map(move |v| {
                    if m {
                        (v.clamp(0.0, 1.0) * 255.0).round() as u8
                    } else {
                        0
                    }
                })
            })
            .collect();
        let depth = depth
            .data
            .iter()
            .zip(&mask)
            .map(|(&d, &m)| if m { d } else { f32::NAN })
            .collect();
        Ok(super::result::NovelView {
            width: self.cam.width,
            height: self.cam.height,
            color,
            depth,
            mask,
            keyframe,
        })
    }
}

/// What the steps share: the view of the model at a pose, turning a match
/// into a correspondence, and the robust solve.
impl Tracker {
    /// Splats `attrs` of the model at `pose` into window `w` of the image
    /// (the tracker's targets for that size), textured by the keyframe
    /// closest to `pose` (its index is returned), or untextured when there
    /// is no keyframe store (`None`); its GPU passes are timed under
    /// `stage`.
    pub(super) fn render_view_in(
        &mut self,
        pose: &Pose,
        attrs: Attributes,
        w: Window,
        stage: &str,
    ) -> Result<Option<usize>, crate::splat::SplatError> {
        self.render_view(pose, attrs, w, stage, false)
    }

    /// [`Tracker::render_view_in`] for the contour, the render's
    /// visibility depth kept (CPU device:
    /// [`crate::splat::Splatter::render_keeping_depth`]).
    pub(super) fn render_view_keeping_depth(
        &mut self,
        pose: &Pose,
        attrs: Attributes,
        w: Window,
    ) -> Result<Option<usize>, crate::splat::SplatError> {
        self.render_view(pose, attrs, w, "contour", true)
    }

    fn render_view(
        &mut self,
        pose: &Pose,
        attrs: Attributes,
        w: Window,
        stage: &str,
        keep_depth: bool,
    ) -> Result<Option<usize>, crate::splat::SplatError> {
        let cam = self.use_window(w);
        let k = self.store.as_ref().map(|s| s.closest(pose));
        let texture = k.map_or(profile::Texture::None, profile::Texture::Keyframe);
        self.splat_with(texture, &cam, pose, attrs, stage, keep_depth)?;
        self.view_made = Some(ViewMade {
            pose: *pose,
            window: w,
            keyframe: k,
            attrs,
            stands_for: None,
        });
        Ok(k)
    }

    /// The match of pixel `from` of the view splatted at `pose` (`s`: its
    /// predictors and depth there) with `to` in the live frame: its row of
    /// the linear solve, and the object point seen at `from` (lifted with
    /// the splatted depth) for the refinement.
    pub(super) fn correspondence(
        &self,
        s: &GatherSample,
        from: Vector2<f64>,
        to: Vector2<f64>,
        pose: &Pose,
    ) -> Correspondence {
        Correspondence {
            observation: Observation {
                predictors: s.matrix(),
                displacement: to - from,
            },
            anchor: Anchor {
                point: pose
                    .inverse()
                    .transform_point(&self.cam.unproject(&from, s.depth as f64)),
                target: to,
            },
        }
    }

    /// The linear solve of `obs` from `pose`, then the Gauss-Newton
    /// refinements, with `extra` anchors from another step.
    pub(super) fn refine(
        &self,
        obs: &[Correspondence],
        pose: &Pose,
        extra: &[Anchor],
    ) -> Result<Refined, StepError> {
        let refiner = Refiner {
            cam: &self.cam,
            irls: &self.config.irls,
            iterations: self.config.refine_iterations,
            extra_weight: self.config.fuse_weight,
        };
        Ok(refiner.solve(obs, pose, extra)?)
    }
}

/// A step's estimate from its refined solve.
pub(super) fn estimate(r: &Refined) -> Estimate {
    Estimate {
        pose: r.pose,
        inliers: r.solve.inlier_count,
        residual_px: r.solve.residual_rms_px,
        scale_px: r.solve.scale_px,
    }
}
