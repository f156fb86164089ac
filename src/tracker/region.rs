//! Where the steps work: renders, reads, corners and NCC
//! windows are confined to the object's projected region instead of the
//! whole image, with the results the full image gives.
//!
//! - Renders go into a [`Window`] holding the projection of the model's
//!   bounding box (grown by its largest splat) plus a margin wider than a
//!   Harris support and an NCC window: every pixel the full render covers
//!   lies inside it, so reads and gathers there give the full render's
//!   values, and the empty margin keeps the novel view's corners and the
//!   check's contour away from the window's border. Window origins are
//!   aligned to the Harris grid cell so that corner selection picks the
//!   same corners. Targets are kept per window size (few sizes occur,
//!   since sizes are rounded up too) and reused.
//! - Harris on the live frame runs on the region of interest grown by the
//!   corners' support (the corners of the masked full frame).
//! - NCC matching runs on crops of both images around the features: the
//!   features of the first image grown by the search radius and the
//!   windows; no feature of the second image outside can be within the
//!   search radius, and mutual best matches only ever compare features
//!   within it.

use super::features_on::Matcher;
use crate::features::{
    Corner, FeatureError, FrameIntake, GpuGrey, GreyImage, Match, NccConfig, NccMatcher,
    Refinement, ResidentImage, ResidentMatch,
};
use crate::geometry::Pose;
use crate::splat::{Attributes, SplatTargets, Window};

/// Spare render targets kept (one per recent window size; a sequence
/// cycles through a few sizes, and a size not kept costs new targets).
pub(super) const SPARE_TARGETS: usize = 3;

/// A render kept for a later step: the check's render of the reported
/// pose (colour, geometry and predictors) is the render the next frame's
/// IT step needs (its previous pose), so the next frame does not render it
/// again.
pub(super) struct Kept {
    pub(super) pose: Pose,
    pub(super) window: Window,
    pub(super) targets: SplatTargets,
    /// The novel view those targets hold, if they hold one.
    pub(super) view: Option<ViewMade>,
}

/// The novel view the targets hold ([`super::Tracker::render_view_in`]'s
/// last render, while no other render or swap of targets came since): what
/// the pose check may score instead of rendering again.
#[derive(Debug, Clone, Copy)]
pub(super) struct ViewMade {
    pub(super) pose: Pose,
    pub(super) window: Window,
    /// The keyframe that textured it (`None`: the model's colours).
    pub(super) keyframe: Option<usize>,
    pub(super) attrs: Attributes,
    /// The pose the contour step's last rounds ended at, when they moved
    /// the points of this view no farther than
    /// [`super::ContourConfig::reproject_px`]: the check at that pose
    /// scores this view ([`super::Tracker::view_for_check`]).
    pub(super) stands_for: Option<Pose>,
}

impl Kept {
    /// The targets of the kept render.
    pub(super) fn targets(&self) -> &SplatTargets {
        &self.targets
    }
}

/// The frames' grey levels on the GPU: the frame being
/// tracked, uploaded once when its step starts and read by its IT and KF
/// matchings, and the previous frame's, kept for the next IT step. Used
/// only while `on` ([`super::Execution::resident_matching`]; on by default on
/// GPUs, off on CPU adapters, where the host path measured faster).
pub(super) struct Resident {
    pub(super) on: bool,
    /// The KF step's detection, matching and gather chained on the GPU
    /// ([`super::Execution::chained_kf`]).
    pub(super) chain_kf: bool,
    /// The frame's detection and IT's matching chained on the GPU
    /// ([`super::Execution::chained_it`]).
    pub(super) chain_it: bool,
    pub(super) images: [GpuGrey; 2],
    /// The frames' way in: their bytes uploaded, converted on the GPU
    /// (made on the first upload).
    pub(super) intake: Option<FrameIntake>,
    /// The slot of the frame being tracked (set by `upload`, cleared by
    /// `done`): a frame the steps see outside `track` (the search's) has
    /// none, and is matched on the host.
    pub(super) current: Option<usize>,
    /// The slot of the previous frame ([`Tracker::track`]'s `prev`).
    pub(super) previous: Option<usize>,
}

impl Resident {
    pub(super) fn new(on: bool) -> Self {
        Self {
            on,
            chain_kf: true,
            chain_it: true,
            images: [GpuGrey::new(), GpuGrey::new()],
            intake: None,
            current: None,
            previous: None,
        }
    }
}

impl Resident {
    /// Uploads the frame being tracked (when on), into the slot the
    /// previous frame does not hold: its RGB bytes, converted to grey and
    /// packed on the GPU ([`FrameIntake`]; the same pixels as the host's
    /// grey, packed).
    pub(super) fn upload(
        &mut self,
        ctx: &crate::gpu::GpuContext,
        frame: &image::RgbImage,
    ) -> Result<(), FeatureError> {
        if !self.on {
            return Ok(());
        }
        let slot = self.previous.map_or(0, |p| 1 - p);
        let intake = match &mut self.intake {
            Some(i) => i,
            None => self.intake.insert(FrameIntake::new(ctx)?),
        };
        intake.upload(frame, &mut self.images[slot])?;
        self.current = Some(slot);
        Ok(())
    }

    /// Packs the window `at` of the frame being tracked into Harris's
    /// input `out` ([`FrameIntake::pack_window`]).
    pub(super) fn pack_window(
        &mut self,
        at: [u32; 4],
        allowed: [u32; 4],
        out: &wgpu::Buffer,
    ) -> Result<(), FeatureError> {
        let (intake, frame) = self.taken_in()?;
        intake.pack_window(frame, at, allowed, out)
    }

    /// Records the writing of the window `at` of the frame being tracked
    /// into `out`, one f32 a pixel, as a stage of `passes`
    /// ([`FrameIntake::record_window_values`]).
    pub(super) fn record_window_values(
        &mut self,
        passes: &mut crate::gpu::PassChain,
        at: [u32; 4],
        out: &wgpu::Buffer,
    ) -> Result<(), FeatureError> {
        let (intake, frame) = self.taken_in()?;
        intake.record_window_values(passes, frame, at, out)
    }

    /// The intake and the frame being tracked, which it took in.
    fn taken_in(&mut self) -> Result<(&mut FrameIntake, ResidentImage<'_>), FeatureError> {
        let none = || FeatureError::Config("no frame on the GPU".into());
        let slot = self.current.ok_or_else(none)?;
        let intake = self.intake.as_mut().ok_or_else(none)?;
        let frame = self.images[slot].image().ok_or_else(none)?;
        Ok((intake, frame))
    }

    /// A frame starts: no frame is resident until `upload`.
    pub(super) fn begin(&mut self) {
        self.current = None;
    }

    /// The frame is done: it becomes the previous frame.
    pub(super) fn done(&mut self) {
        self.previous = self.current.take();
    }

    /// The frame being tracked and the previous frame, where resident.
    pub(super) fn frames(&self) -> (Option<ResidentImage<'_>>, Option<ResidentImage<'_>>) {
        let get = |s: Option<usize>| s.and_then(|s| self.images[s].image());
        (get(self.current), get(self.previous))
    }
}

/// An image placed in the frame: its pixel (0, 0) is pixel `at.x0, at.y0`
/// of the frame.
#[derive(Clone, Copy)]
pub(super) struct Placed<'a> {
    pub img: &'a GreyImage,
    pub at: Window,
}

impl<'a> Placed<'a> {
    /// A whole frame.
    pub fn full(img: &'a GreyImage) -> Self {
        Self {
            img,
            at: Window {
                x0: 0,
                y0: 0,
                width: img.width as u32,
                height: img.height as u32,
            },
        }
    }

    /// The pixels of window `w` (frame coordinates); NaN (invalid) where
    /// this image has none.
    pub fn crop(&self, w: &Window) -> GreyImage {
        if *w == self.at {
            return self.img.clone();
        }
        let (ww, wh) = (w.width as usize, w.height as usize);
        let mut data = vec![f32::NAN; ww * wh];
        let (ax0, ay0) = (self.at.x0 as i64, self.at.y0 as i64);
        let (aw, ah) = (self.img.width as i64, self.img.height as i64);
        for y in 0..wh {
            let sy = w.y0 as i64 + y as i64 - ay0;
            if !(0..ah).contains(&sy) {
                continue;
            }
            let sx0 = (w.x0 as i64 - ax0).max(0);
            let sx1 = (w.x0 as i64 + ww as i64 - ax0).min(aw);
            if sx0 >= sx1 {
                continue;
            }
            let dx0 = (sx0 + ax0 - w.x0 as i64) as usize;
            let row = sy as usize * self.img.width;
            data[y * ww + dx0..y * ww + dx0 + (sx1 - sx0) as usize]
                .copy_from_slice(&self.img.data[row + sx0 as usize..row + sx1 as usize]);
        }
        GreyImage {
            width: ww,
            height: wh,
            data,
        }
    }
}

/// Corners found in a window's pixels placed in the image's: moved by the
/// window's `origin` (one f32 addition each, as the export on the GPU
/// moves them: `ExportPlace`).
pub(super) fn placed(corners: &[Corner], origin: [f32; 2]) -> Vec<Corner> {
    corners
        .iter()
        .map(|c| Corner {
            x: c.x + origin[0],
            y: c.y + origin[1],
            score: c.score,
        })
        .collect()
}

/// Moves a corner by `-origin`.
pub(super) fn shifted(c: &Corner, origin: [f32; 2]) -> Corner {
    Corner {
        x: c.x - origin[0],
        y: c.y - origin[1],
        score: c.score,
    }
}

/// Mutual NCC matches of the features `a` of `img_a` with `b` of the
/// frame `img_b` (all in frame coordinates), computed on crops around `a`
/// grown by `margin` (at least the search radius plus a window): the
/// matches `matcher` gives on the whole images. `None`: on the whole
/// images. Also returns the two crops
/// and their window (for refinements that work near the matches).
pub(super) fn match_near(
    matcher: &mut Matcher,
    img_a: Placed,
    a: &[Corner],
    img_b: &GreyImage,
    b: &[Corner],
    margin: Option<f64>,
) -> Result<(Vec<Match>, Window, GreyImage, GreyImage), FeatureError> {
    let full = Placed::full(img_b).at;
    if a.is_empty() || b.is_empty() {
        return Ok((
            Vec::new(),
            full,
            GreyImage::filled(0, 0, 0.0),
            GreyImage::filled(0, 0, 0.0),
        ));
    }
    let w = crop_window(matcher.config(), a, margin, full);
    let o = w.origin();
    let inside = |c: &Corner| {
        c.x >= o[0] && c.y >= o[1] && c.x < o[0] + w.width as f32 && c.y < o[1] + w.height as f32
    };
    let a_w: Vec<Corner> = a.iter().map(|c| shifted(c, o)).collect();
    let b_idx: Vec<usize> = (0..b.len()).filter(|&i| inside(&b[i])).collect();
    let b_w: Vec<Corner> = b_idx.iter().map(|&i| shifted(&b[i], o)).collect();
    let crop_a = img_a.crop(&w);
    let crop_b = Placed::full(img_b).crop(&w);
    let matches = matcher
        .match_features(&crop_a, &a_w, &crop_b, &b_w)?
        .into_iter()
        .map(|m| Match { b: b_idx[m.b], ..m })
        .collect();
    Ok((matches, w, crop_a, crop_b))
}

/// The window of the frame `full` that [`match_near`] crops: the box of
/// the features `a` grown by `margin`, or the whole frame (no search
/// radius, no margin, or no box).
pub(super) fn crop_window(
    matcher: &NccConfig,
    a: &[Corner],
    margin: Option<f64>,
    full: Window,
) -> Window {
    let (x0, y0, x1, y1) = a.iter().fold(
        (
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ),
        |(x0, y0, x1, y1), c| {
            let (x, y) = (c.x as f64, c.y as f64);
            (x0.min(x), y0.min(y), x1.max(x), y1.max(y))
        },
    );
    match (matcher.search_radius, margin) {
        (Some(_), Some(m)) => {
            Window::around([x0, y0, x1, y1], m, 1, full.width, full.height).unwrap_or(full)
        }
        _ => full,
    }
}

/// A's features in a resident matching ([`match_near_resident`]).
#[derive(Clone, Copy)]
pub(super) enum AFeatures<'a> {
    /// In the frame's pixels: the crop is cut around them ([`crop_window`]).
    InFrame(&'a [Corner]),
    /// In A's own pixels (a novel view's window, whose corners Harris
    /// found there): the crop is the window grown by the margin
    /// ([`window_crop`]), as the chained KF step cuts it.
    InWindow(&'a [Corner]),
}

/// The bands of a resident matching on the crop `w` of the frame: B's
/// features inside it (and their indices in `b`), the rows of A (placed
/// at `at`) within it, and its own rows.
pub(super) struct Bands {
    pub b_idx: Vec<usize>,
    pub b_in: Vec<Corner>,
    pub a_rows: std::ops::Range<usize>,
    pub b_rows: std::ops::Range<usize>,
}

impl Bands {
    /// `None` where A has no row in the crop.
    pub(super) fn new(at: Window, b: &[Corner], w: Window) -> Option<Self> {
        let o = w.origin();
        let inside = |c: &Corner| {
            c.x >= o[0]
                && c.y >= o[1]
                && c.x < o[0] + w.width as f32
                && c.y < o[1] + w.height as f32
        };
        let b_idx: Vec<usize> = (0..b.len()).filter(|&i| inside(&b[i])).collect();
        let b_in: Vec<Corner> = b_idx.iter().map(|&i| b[i]).collect();
        let a_rows = (w.y0.max(at.y0) - at.y0) as usize
            ..((w.y0 + w.height).min(at.y0 + at.height)).saturating_sub(at.y0) as usize;
        let b_rows = w.y0 as usize..(w.y0 + w.height) as usize;
        (a_rows.start < a_rows.end).then_some(Self {
            b_idx,
            b_in,
            a_rows,
            b_rows,
        })
    }
}

/// The crop of a matching of features inside the window `at` (a novel
/// view's): `at` grown by `margin` where the matcher has a search radius
/// (else the whole frame, as [`crop_window`]). It holds the crop
/// [`match_near`] cuts around any features inside `at`, and the features
/// of B it adds lie farther than the search radius from all of them: the
/// matches are the same.
pub(super) fn window_crop(
    matcher: &NccConfig,
    at: Window,
    margin: Option<f64>,
    full: Window,
) -> Window {
    let o = at.origin();
    let rect = [
        o[0] as f64,
        o[1] as f64,
        (at.x0 + at.width) as f64,
        (at.y0 + at.height) as f64,
    ];
    match (matcher.search_radius, margin) {
        (Some(_), Some(m)) => Window::around(rect, m, 1, full.width, full.height).unwrap_or(full),
        _ => full,
    }
}

/// [`match_near`] on images resident on the GPU: `img_a` placed at window
/// `at` of the frame (the whole frame, or a novel view's window), the
/// frame `img_b`; each takes part with the rows of the crop
/// [`match_near`] would cut (its features outside the crop left out, as
/// there), so the matches are the same. With `refine`, each match carries
/// B's refined point (frame coordinates; `None` where the refinement
/// fails), as [`crate::features::refine_match`] on the crops gives it.
/// A's features given in its own pixels ([`AFeatures::InWindow`]) are
/// matched on the crop the chained KF step cuts ([`window_crop`]): the
/// same matches, B's points and windows within f32 rounding of its band's
/// rows.
pub(super) fn match_near_resident(
    matcher: &mut NccMatcher,
    img_a: (ResidentImage, Window),
    a: AFeatures,
    img_b: ResidentImage,
    b: &[Corner],
    margin: Option<f64>,
    refine: Option<Refinement>,
) -> Result<Vec<ResidentMatch>, FeatureError> {
    let full = Window {
        x0: 0,
        y0: 0,
        width: img_b.width as u32,
        height: img_b.height as u32,
    };
    let (img, at) = img_a;
    let (list, w) = match a {
        AFeatures::InFrame(a) => (a, crop_window(matcher.config(), a, margin, full)),
        AFeatures::InWindow(a) => (a, window_crop(matcher.config(), at, margin, full)),
    };
    if list.is_empty() || b.is_empty() {
        return Ok(Vec::new());
    }
    let Some(bands) = Bands::new(at, b, w) else {
        return Ok(Vec::new());
    };
    // A's features in its own pixels.
    let a_own: Vec<Corner> = match a {
        AFeatures::InFrame(a) => a.iter().map(|c| shifted(c, at.origin())).collect(),
        AFeatures::InWindow(a) => a.to_vec(),
    };
    let Bands {
        b_idx,
        b_in,
        a_rows,
        b_rows,
    } = bands;
    Ok(matcher
        .match_resident(
            img,
            a_rows,
            &a_own,
            img_b,
            b_rows,
            &b_in,
            [-(at.x0 as i32), -(at.y0 as i32)],
            refine,
        )?
        .into_iter()
        .map(|m| ResidentMatch { b: b_idx[m.b], ..m })
        .collect())
}
