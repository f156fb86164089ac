//! Verification of a pose against the image: before a frame is
//! reported `tracking`, the model is splatted at the pose and compared
//! with the frame. A pose passes when
//!
//! - enough of the object is in view (its points in front of the camera
//!   and inside the image: [`VerifyConfig::min_visible`]) and covers
//!   enough pixels ([`VerifyConfig::min_covered_px`]);
//! - its appearance agrees: the silhouette's contour is supported by
//!   edges of the frame (the fraction of contour pixels whose frame
//!   gradient along the contour's normal peaks within a few pixels and
//!   stands out from the level around it: [`edge_support`], adapted to
//!   the outline's contrast), and the textured novel view correlates with
//!   the frame over the object's pixels (dense ZNCC, blind to gain and
//!   offset). Both must hold where there is a texture (keyframes or model
//!   colours): a near-symmetric silhouette turned by 30 degrees keeps
//!   much of its contour on edges of a cluttered background, but its ZNCC
//!   falls to 0. Without any texture
//!   (IT mode, a model without colours) the contour alone decides, at a
//!   higher level ([`VerifyConfig::strong_edge_support`]): a weaker check.
//!   With the contour modality the same level passes a low ZNCC where the
//!   view has no texture of its own ([`VerifyScores::view_texture`],
//!   [`judge_with_contour`]): an untextured object's keyframes carry only
//!   shading, lit otherwise than the frame. On an object of shading
//!   only, a contour-alone pose with a loose fit needs more of its outline
//!   on edges ([`judge_contour_alone`]): over clutter the outline slips
//!   onto distractors of the object's colour, whose shading correlates.
//!
//! Where the view shows no texture of its own the check also fits the
//! frame's shading by the render's normals ([`VerifyScores::shading_rms`],
//! `tracker/shading.rs`), which the track holds to its recent level
//! (`tracker/steady.rs`).
//!
//! Measured at the right pose: ZNCC 0.87-0.99 on the synthetic blob, the
//! real cube and the (weakly textured) real dragon, whose keyframe
//! texture still carries its shading; edge support 0.76-0.97 on the real
//! cube, 0.63-0.84 on the dragon (docs/trust.md).
//!
//! This file holds the pure scoring ([`score`], testable without a GPU,
//! from a view, its coverage and the frame) and the rule ([`judge`]); the
//! tracker renders the view (`Tracker::verify_pose`).

use crate::features::GreyImage;
use std::fmt;

/// The thresholds of the check. Calibrated on the synthetic sequences and
/// the real ViSP cube and dragon (docs/trust.md).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct VerifyConfig {
    /// Check every pose before reporting it `tracking` (default on).
    pub enabled: bool,
    /// Least fraction of the model's points in front of the camera and
    /// inside the image.
    pub min_visible: f64,
    /// Least number of covered pixels of the splatted view.
    pub min_covered_px: usize,
    /// Least ZNCC of the novel view against the frame over the object's
    /// inner pixels, where there is a texture.
    pub min_zncc: f64,
    /// Least contour edge support where there is a texture.
    pub min_edge_support: f64,
    /// Least contour edge support without any texture (no ZNCC).
    pub strong_edge_support: f64,
    /// Least contour edge support of a pose the contour alone made, on an
    /// object of shading only, where its fit is loose
    /// ([`VerifyConfig::shading_loose_px`]; [`judge_contour_alone`]): the
    /// view's ZNCC cannot tell the object from clutter of its colour.
    /// Measured on the untextured `plain` over clutter (contour only):
    /// 0.86-0.96 at most poses within 5 degrees, 0.62-0.82 at most poses
    /// 10-27 degrees off (docs/trust.md).
    pub shading_edge_support: f64,
    /// The contour fit's RMS residual (pixels) above which
    /// [`VerifyConfig::shading_edge_support`] applies: its lines found
    /// edges that disagree, as over clutter. Measured: 0.10-0.30 px for
    /// the untextured `plain` and `plainbox` on a plain background (where
    /// `plainbox`'s right poses have 72-77% of their outline on edges at
    /// some frames), 0.2-0.45 px at most right poses of `plain` over
    /// clutter, 0.9-1.7 px at most poses 10 degrees off or more.
    pub shading_loose_px: f64,
    /// A novel view whose own texture ([`VerifyScores::view_texture`]) is
    /// below this shows no more than shading: with the contour, strong
    /// edges may pass it despite a low ZNCC ([`judge_with_contour`]).
    /// Measured (`track --modalities texture,contour`, every frame, at
    /// 320x240 and 640x480): untextured synthetic objects 0.023-0.114,
    /// the textured blob 0.135-0.232, box 0.266-0.330, real cube
    /// 0.153-0.192, real dragon 0.077-0.098 (untextured by this measure;
    /// its ZNCC is high anyway).
    pub untextured_below: f64,
    /// Least ZNCC of a pose that starts a track of an object seen by its
    /// texture: the first frame's, and one that ends a loss (the
    /// recovering KF step's from the last pose or from one of the starts
    /// turned away from it, or from where the search found the object).
    /// A start has no motion to agree with, and the recovery's tries give
    /// a wrong pose many chances to pass [`VerifyConfig::min_zncc`].
    /// Measured: 0.77-0.99 at the right poses of the real cube and dragon
    /// and the synthetic objects; 0.48-0.54 at poses of the real cube 17
    /// and 69 degrees off reached from a start 50 degrees off, 0.45 at
    /// one of the dragon 12 degrees off.
    pub recovery_zncc: f64,
    /// Least frame gradient along the contour normal (grey levels 0..1 per
    /// pixel, Sobel / 8) that counts as an edge, however quiet the
    /// surroundings: the floor under [`VerifyConfig::edge_contrast`]'s
    /// local level (camera noise alone stays under it).
    pub edge_gradient: f32,
    /// How far along the normal an edge may lie from the contour, pixels.
    pub edge_search_px: usize,
    /// How many times the local level of the frame's gradient (along the
    /// normal, beyond the search: [`VerifyConfig::edge_band_px`]) an edge
    /// must stand out by: a faint outline on a plain surface counts, a
    /// random gradient in clutter does not ([`edge_support`]).
    pub edge_contrast: f32,
    /// The farthest the local level is sampled along the normal, pixels
    /// (from `edge_search_px + 2` on either side; no further than the
    /// search: a fixed threshold at [`VerifyConfig::edge_gradient`]).
    pub edge_band_px: usize,
    /// Least edge support of a frame that follows tracked frames, as a
    /// fraction of the median of the last ten (once five are known): a
    /// wrong pose that keeps half of its outline on edges passes the
    /// absolute thresholds, but not the track's own level. Measured: right
    /// poses at 0.79 of it or more over the synthetic and real sequences,
    /// a wrong pose 18 degrees off at 0.53 (docs/trust.md). 0: off.
    pub edge_drop: f64,
    /// Most RMS of the frame's shading left unexplained by the render's
    /// normals ([`VerifyScores::shading_rms`]) for a frame that follows
    /// tracked frames, as a multiple of the median of the last ten (once
    /// five are known), where the view shows no texture of its own. A
    /// near-symmetric untextured object that slips about its axis keeps
    /// its outline on edges; its shading does not follow. Measured: right
    /// poses at 1.46 times the recent level or less on fresh renders over
    /// the synthetic and real sequences, the slipping `plain` at 2.4 (6
    /// degrees off) and 2.9-4.9 (6-12 degrees off) (docs/trust.md). 0:
    /// off.
    pub shading_drop: f64,
}

impl VerifyConfig {
    /// How far from the contour the edge test reads the frame, pixels
    /// (a window of the frame this much wider than the view scores alike).
    pub fn edge_reach_px(&self) -> usize {
        self.edge_search_px.max(self.edge_band_px) + 1
    }
}

impl Default for VerifyConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            min_visible: 0.5,
            min_covered_px: 150,
            min_zncc: 0.4,
            min_edge_support: 0.4,
            strong_edge_support: 0.7,
            shading_edge_support: 0.85,
            shading_loose_px: 0.5,
            untextured_below: 0.125,
            recovery_zncc: 0.7,
            edge_gradient: 0.008,
            edge_search_px: 2,
            edge_contrast: 3.0,
            edge_band_px: 8,
            edge_drop: 0.7,
            shading_drop: 2.0,
        }
    }
}

/// What the check measured at a pose.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct VerifyScores {
    /// Fraction of the model's points in front of the camera and inside
    /// the image.
    pub visible: f64,
    /// Covered pixels of the splatted view.
    pub covered_px: usize,
    /// ZNCC of the novel view against the frame over the object's inner
    /// pixels; `None` without a texture or without enough pixels or
    /// contrast.
    pub zncc: Option<f64>,
    /// Fraction of the silhouette's contour supported by frame edges;
    /// `None` without a contour.
    pub edge_support: Option<f64>,
    /// The novel view's own texture: the RMS of its grey Laplacian at a
    /// step of [`texture_step`] pixels (`4 v - ` the four pixels that far,
    /// grey levels 0..1) over the ZNCC's pixels whose four are covered;
    /// `None` without a view or under 50 such pixels. Smooth shading has
    /// little, a printed texture a lot: where this is low the ZNCC has
    /// nothing but shading to correlate.
    #[serde(default)]
    pub view_texture: Option<f64>,
    /// The RMS (grey levels 0..1) of the frame's brightness over the
    /// view's inner pixels left after the best fit by the render's normals
    /// (nine spherical-harmonic terms: any distant light and ambient;
    /// `tracker/shading.rs`). Measured only where the view shows no texture
    /// of its own (neither keyframes nor model colours, or the last
    /// check's view untextured); `None` elsewhere and under 100 such
    /// pixels.
    #[serde(default)]
    pub shading_rms: Option<f64>,
}

/// Why a pose failed the check.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Unverified {
    /// Too little of the object in front of the camera and in the image.
    NotInView {
        /// [`VerifyScores::visible`].
        visible: f64,
        /// [`VerifyConfig::min_visible`].
        min: f64,
    },
    /// The splatted object covers too few pixels.
    TooSmall {
        /// [`VerifyScores::covered_px`].
        covered_px: usize,
        /// [`VerifyConfig::min_covered_px`].
        min: usize,
    },
    /// The model at the pose does not look like the frame.
    Appearance {
        /// [`VerifyScores::zncc`].
        zncc: Option<f64>,
        /// [`VerifyScores::edge_support`].
        edge_support: Option<f64>,
    },
    /// A pose the contour alone made, whose view shows shading only, has
    /// too little of its outline on frame edges: the shading's ZNCC does
    /// not tell the object from clutter of its colour
    /// ([`judge_contour_alone`]).
    ShadingOnly {
        /// [`VerifyScores::zncc`].
        zncc: Option<f64>,
        /// [`VerifyScores::edge_support`].
        edge_support: Option<f64>,
        /// [`VerifyConfig::shading_edge_support`].
        min: f64,
    },
    /// A pose that starts a track (the first frame's, or one after a
    /// loss) correlates too little with the frame
    /// ([`VerifyConfig::recovery_zncc`]).
    Recovery {
        /// [`VerifyScores::zncc`].
        zncc: Option<f64>,
        /// [`VerifyConfig::recovery_zncc`].
        min: f64,
    },
    /// The frame is identical to the previous one (a frozen feed: a real
    /// camera's noise changes every frame), so nothing says where the
    /// object is now.
    FrozenFrame,
    /// The pose's outline is on far fewer edges than the track's recent
    /// frames' ([`VerifyConfig::edge_drop`]).
    EdgeDrop {
        /// [`VerifyScores::edge_support`].
        edge_support: f64,
        /// The median edge support of the recent tracked frames.
        recent: f64,
        /// [`VerifyConfig::edge_drop`].
        ratio: f64,
    },
    /// The render's normals explain the frame's shading far worse than
    /// at the track's recent frames ([`VerifyConfig::shading_drop`]).
    ShadingDrop {
        /// [`VerifyScores::shading_rms`].
        shading_rms: f64,
        /// The level it was held to: the median of the recent tracked
        /// frames', or during a loss's first frames the one from before
        /// it.
        recent: f64,
        /// [`VerifyConfig::shading_drop`].
        ratio: f64,
    },
}

impl fmt::Display for Unverified {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let opt = |v: &Option<f64>| v.map_or("n/a".to_string(), |v| format!("{v:.2}"));
        match self {
            Unverified::NotInView { visible, min } => write!(
                f,
                "object not in view: {:.0}% of it in front of the camera and in the image (need {:.0}%)",
                100.0 * visible,
                100.0 * min
            ),
            Unverified::TooSmall { covered_px, min } => {
                write!(f, "object covers {covered_px} px (need {min})")
            }
            Unverified::Appearance { zncc, edge_support } => write!(
                f,
                "model does not match the image: ZNCC {}, contour edge support {}",
                opt(zncc),
                opt(edge_support)
            ),
            Unverified::ShadingOnly {
                zncc,
                edge_support,
                min,
            } => write!(
                f,
                "outline not on the image's edges: contour edge support {} (need {min:.2} where \
                 the view shows shading only: its ZNCC {} cannot tell the object from clutter)",
                opt(edge_support),
                opt(zncc)
            ),
            Unverified::Recovery { zncc, min } => write!(
                f,
                "a start unlike the frame: ZNCC {} (need {min:.2} to start a track)",
                opt(zncc)
            ),
            Unverified::FrozenFrame => f.write_str("frame identical to the previous one (frozen)"),
            Unverified::EdgeDrop {
                edge_support,
                recent,
                ratio,
            } => write!(
                f,
                "contour edge support {edge_support:.2} fell below {ratio:.2} of the recent frames' {recent:.2}"
            ),
            Unverified::ShadingDrop {
                shading_rms,
                recent,
                ratio,
            } => write!(
                f,
                "shading unlike the model's at this pose: {shading_rms:.3} RMS left by its normals, over {ratio:.1} times the recent frames' {recent:.3}"
            ),
        }
    }
}

/// Scores a view against `frame`: `covered` the view's coverage per pixel,
/// `view` its grey levels where there is a texture, `visible` the fraction
/// of the model in view (computed by the caller from the pose).
pub fn score(
    frame: &GreyImage,
    covered: &[bool],
    view: Option<&[f32]>,
    visible: f64,
    texture_step: usize,
    cfg: &VerifyConfig,
) -> VerifyScores {
    let (w, h) = (frame.width, frame.height);
    debug_assert_eq!(covered.len(), w * h);
    let covered_px = covered.iter().filter(|c| **c).count();
    let inner = |x: usize, y: usize| inner_pixel(covered, w, h, x, y);
    let zncc = view.and_then(|v| {
        let pairs = (0..h).flat_map(|y| (0..w).map(move |x| (x, y)));
        zncc_of(
            pairs
                .filter(|&(x, y)| inner(x, y))
                .map(|(x, y)| (v[y * w + x] as f64, frame.data[y * w + x] as f64)),
        )
    });
    let view_texture = view.and_then(|v| view_texture(v, covered, w, h, texture_step));
    VerifyScores {
        visible,
        covered_px,
        zncc,
        edge_support: edge_support(frame, covered, cfg),
        view_texture,
        shading_rms: None,
    }
}

/// Whether pixel `(x, y)` and its four neighbours are covered (inside
/// the image).
fn inner_pixel(covered: &[bool], w: usize, h: usize, x: usize, y: usize) -> bool {
    x > 0
        && y > 0
        && x + 1 < w
        && y + 1 < h
        && covered[y * w + x]
        && covered[y * w + x - 1]
        && covered[y * w + x + 1]
        && covered[(y - 1) * w + x]
        && covered[(y + 1) * w + x]
}

/// [`VerifyScores::view_texture`] of a `w` x `h` view (grey levels) and
/// its coverage, at a step of `texture_step` pixels; `None` under 50
/// pixels.
pub fn view_texture(
    view: &[f32],
    covered: &[bool],
    w: usize,
    h: usize,
    texture_step: usize,
) -> Option<f64> {
    let d = texture_step.max(1);
    let (mut n, mut sum) = (0usize, 0.0f64);
    for y in d..h.saturating_sub(d) {
        for x in d..w.saturating_sub(d) {
            let i = y * w + x;
            let around = [i - d, i + d, i - d * w, i + d * w];
            if inner_pixel(covered, w, h, x, y) && around.iter().all(|&j| covered[j]) {
                let lap =
                    4.0 * view[i] as f64 - around.iter().map(|&j| view[j] as f64).sum::<f64>();
                n += 1;
                sum += lap * lap;
            }
        }
    }
    laplacian_rms(n as f64, sum)
}

/// The step of [`VerifyScores::view_texture`]'s Laplacian for an object
/// whose bounding sphere projects to a circle of `radius_px` pixels: one
/// step per [`PIXELS_PER_TEXTURE_STEP`], 1 to 8, so that the measure is
/// the same for an object seen nearer or at a finer resolution (a
/// Laplacian at a fixed step grows 4x for the shading of an object half
/// as large). At a step of 1 the keyframes' noise (baked into the points'
/// colours) weighs as much as a texture.
pub fn texture_step(radius_px: f64) -> usize {
    if radius_px.is_finite() {
        (radius_px / PIXELS_PER_TEXTURE_STEP)
            .round()
            .clamp(1.0, 8.0) as usize
    } else {
        1
    }
}

/// See [`texture_step`]. Measured (`track --modalities texture,contour`,
/// every frame, 320x240 and 640x480): the untextured synthetic objects at
/// most 0.114, the textured ones at least 0.135 (blob), 0.153 (real
/// cube), 0.266 (box); with a fixed step of 4 the untextured object at
/// 320x240 reached 0.171, next to the blob at 640x480 (0.178), and a step of
/// 2 at 640x480 left 0.070 against 0.097.
pub const PIXELS_PER_TEXTURE_STEP: f64 = 30.0;

/// [`VerifyScores::view_texture`] from the count of inner pixels and the
/// sum of their squared Laplacians; `None` under 50 pixels.
pub fn laplacian_rms(n: f64, sum_sq: f64) -> Option<f64> {
    (n >= 50.0).then(|| (sum_sq / n).sqrt())
}

/// ZNCC of paired samples ([`zncc_of_sums`]'s rules).
pub fn zncc_of(pairs: impl Iterator<Item = (f64, f64)>) -> Option<f64> {
    let (mut n, mut sa, mut sb, mut saa, mut sbb, mut sab) = (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (a, b) in pairs {
        n += 1.0;
        sa += a;
        sb += b;
        saa += a * a;
        sbb += b * b;
        sab += a * b;
    }
    zncc_of_sums([n, sa, sb, saa, sbb, sab])
}

/// ZNCC of paired samples from their sums `[n, Σa, Σb, Σa², Σb², Σab]`
/// (the GPU check reduces to these); `None` under 50 pairs or where `a`
/// (the view) has no contrast, 0 where only `b` (the frame) has none: a
/// frame that shows nothing of the view's texture does not match it (an
/// outline alone would otherwise decide, as for an untextured view).
pub fn zncc_of_sums([n, sa, sb, saa, sbb, sab]: [f64; 6]) -> Option<f64> {
    if n < 50.0 {
        return None;
    }
    let va = saa - sa * sa / n;
    let vb = sbb - sb * sb / n;
    let cov = sab - sa * sb / n;
    // Below 1e-4 grey levels of standard deviation there is no texture.
    let floor = n * 1e-8;
    match (va > floor, vb > floor) {
        (true, true) => Some(cov / (va * vb).sqrt()),
        (true, false) => Some(0.0),
        (false, _) => None,
    }
}

/// The fraction of the silhouette's contour pixels (covered, with an
/// uncovered 4-neighbour inside the image) on an edge of the frame; `None`
/// under 20 contour pixels. Along the contour's normal (the mask's Sobel
/// direction), at whole-pixel steps rounded to the nearest pixel, the
/// frame's gradient along that normal (|Sobel / 8|, grey levels per
/// pixel) is read within [`VerifyConfig::edge_search_px`] of the contour
/// (the peak) and, from `edge_search_px + 2` to
/// [`VerifyConfig::edge_band_px`] on either side, the local level: the
/// mean on each side, the quieter side's (an outline separates its
/// object's texture from a plain background, or the reverse). A pixel is
/// supported when its peak is at least [`VerifyConfig::edge_gradient`]
/// and [`VerifyConfig::edge_contrast`] times that level ([`edge_hit`]):
/// an outline of little contrast on a plain surface (a white box on a
/// white table) counts, while in clutter only an edge that stands out
/// from its surroundings does.
pub fn edge_support(frame: &GreyImage, covered: &[bool], cfg: &VerifyConfig) -> Option<f64> {
    let (w, h) = (frame.width, frame.height);
    if w < 3 || h < 3 {
        return None;
    }
    let m = |x: usize, y: usize| f64::from(u8::from(covered[y * w + x]));
    let p = |x: usize, y: usize| frame.data[y * w + x] as f64;
    let sobel = |f: &dyn Fn(usize, usize) -> f64, x: usize, y: usize| {
        let gx = (f(x + 1, y - 1) + 2.0 * f(x + 1, y) + f(x + 1, y + 1))
            - (f(x - 1, y - 1) + 2.0 * f(x - 1, y) + f(x - 1, y + 1));
        let gy = (f(x - 1, y + 1) + 2.0 * f(x, y + 1) + f(x + 1, y + 1))
            - (f(x - 1, y - 1) + 2.0 * f(x, y - 1) + f(x + 1, y - 1));
        (gx / 8.0, gy / 8.0)
    };
    let (mut contour, mut supported) = (0usize, 0usize);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            if !covered[y * w + x]
                || (covered[y * w + x - 1]
                    && covered[y * w + x + 1]
                    && covered[(y - 1) * w + x]
                    && covered[(y + 1) * w + x])
            {
                continue;
            }
            let (nx, ny) = sobel(&m, x, y);
            let norm = (nx * nx + ny * ny).sqrt();
            if norm < 1e-9 {
                continue;
            }
            let (nx, ny) = (nx / norm, ny / norm);
            contour += 1;
            let along = |s: i64| {
                let s = s as f64;
                let (qx, qy) = ((x as f64 + s * nx).round(), (y as f64 + s * ny).round());
                if qx < 1.0 || qy < 1.0 || qx >= (w - 1) as f64 || qy >= (h - 1) as f64 {
                    return None;
                }
                let (gx, gy) = sobel(&p, qx as usize, qy as usize);
                Some((gx * nx + gy * ny).abs())
            };
            supported += usize::from(edge_hit(along, cfg));
        }
    }
    (contour >= 20).then(|| supported as f64 / contour as f64)
}

/// The rule of [`edge_support`] for one contour pixel, given the frame's
/// gradient along its normal at `s` whole pixels along it (`None` outside
/// the image): the peak within the search against the floor and against
/// the quieter side's mean level beyond it (0 where neither side has a
/// sample in the image).
pub fn edge_hit(along: impl Fn(i64) -> Option<f64>, cfg: &VerifyConfig) -> bool {
    let r = cfg.edge_search_px as i64;
    let peak = (-r..=r).filter_map(&along).fold(0.0f64, f64::max);
    if peak < cfg.edge_gradient as f64 {
        return false;
    }
    let side = |sign: i64| {
        let (n, sum) = (r + 2..=cfg.edge_band_px as i64)
            .filter_map(|s| along(sign * s))
            .fold((0usize, 0.0f64), |(n, sum), g| (n + 1, sum + g));
        (n > 0).then(|| sum / n as f64)
    };
    let level = match (side(-1), side(1)) {
        (Some(a), Some(b)) => a.min(b),
        (a, b) => a.or(b).unwrap_or(0.0),
    };
    peak >= cfg.edge_contrast as f64 * level
}

/// [`judge`] for a frame that the contour modality tracked while no
/// texture step was trusted (or one was and its pose failed on
/// appearance): a pose whose outline the frame's edges support strongly
/// (the rule without any texture) also passes where the novel view's ZNCC
/// is low, provided that the view has no texture of its own
/// ([`VerifyScores::view_texture`] under [`VerifyConfig::untextured_below`]):
/// an untextured object shows only its shading there, which keyframes lit
/// otherwise do not share (the synthetic `plain` object under its moving
/// light: ZNCC 0.24 at poses within 4 degrees, edge support 0.92). Where
/// the view is textured the ZNCC keeps its veto (the textured blob turned
/// by 60 degrees keeps 89% of its outline on edges, ZNCC 0.15).
pub fn judge_with_contour(s: &VerifyScores, cfg: &VerifyConfig) -> Result<(), Unverified> {
    let untextured = s.view_texture.is_none_or(|t| t < cfg.untextured_below);
    judge(s, cfg).or_else(|e| match e {
        Unverified::Appearance { .. }
            if untextured && s.edge_support.unwrap_or(0.0) >= cfg.strong_edge_support =>
        {
            Ok(())
        }
        e => Err(e),
    })
}

/// [`judge_with_contour`] for a pose the contour alone made (no trusted
/// texture step, or one set aside) with an RMS residual of `residual_px`,
/// and `shading_only` whether the
/// object's views show shading only (`cues::SHADING_ONLY_BELOW`, measured
/// once on the keyframes' views: the synthetic `plain` and `plainbox`,
/// not the real dragon). On such an object, where the novel view is
/// textured (by keyframes or the model's colours, so that it has a ZNCC)
/// and shows shading only ([`VerifyScores::view_texture`] under
/// [`VerifyConfig::untextured_below`]) and the fit is loose (its residual
/// over [`VerifyConfig::shading_loose_px`]), the outline also needs
/// [`VerifyConfig::shading_edge_support`]. Over clutter its contour slips
/// onto edges of distractors of its colour, where the shading still
/// correlates: `plain` 10-27 degrees off kept ZNCC 0.44-0.87 with 62-82%
/// of its outline on edges, which [`judge`]'s levels (and the strong edge
/// support's 70%) pass. Without any texture (no ZNCC) the strong edge
/// support alone decides, as before.
pub fn judge_contour_alone(
    s: &VerifyScores,
    cfg: &VerifyConfig,
    shading_only: bool,
    residual_px: f64,
) -> Result<(), Unverified> {
    judge_with_contour(s, cfg)?;
    if shading_only && shading_rule_applies(s, cfg, residual_px) {
        return Err(Unverified::ShadingOnly {
            zncc: s.zncc,
            edge_support: s.edge_support,
            min: cfg.shading_edge_support,
        });
    }
    Ok(())
}

/// Whether [`judge_contour_alone`] refuses scores `s` and a fit of RMS
/// `residual_px` for an object whose views show shading only: a view that
/// correlates (a ZNCC) without texture of its own, a loose fit, and too
/// little of the outline on edges.
pub fn shading_rule_applies(s: &VerifyScores, cfg: &VerifyConfig, residual_px: f64) -> bool {
    let shading = s.zncc.is_some() && s.view_texture.is_none_or(|t| t < cfg.untextured_below);
    // A NaN residual (no solve) is not loose: nothing says so.
    let loose = residual_px > cfg.shading_loose_px;
    shading && loose && s.edge_support.unwrap_or(0.0) < cfg.shading_edge_support
}

/// The least ZNCC by which a novel view without texture of its own vouches
/// for a search candidate whose outline is not strongly supported
/// ([`judge_outline_candidate`]). Measured over clutter: distractors of
/// the object's colour at most 0.79; the real dragon at its pose 0.87-0.99.
pub const SHADING_ZNCC: f64 = 0.85;

/// [`judge_with_contour`] for a pose the search (or the frames that
/// confirm its start) found by the outline alone, on an object whose views
/// show shading only (`cues::SHADING_ONLY_BELOW`). Where the view has no
/// texture of its own its ZNCC correlates shading only, and over clutter
/// the object's own colours shaded on a distractor of another shape pass
/// [`judge`]'s levels (the untextured `plain` and `plainbox` over
/// `--background clutter`: ZNCC 0.36-0.79, edge support 0.39-0.65, 40-150
/// degrees off): such a pose needs the strong edge support, or a ZNCC of
/// [`SHADING_ZNCC`]. Textured views keep [`judge`].
pub fn judge_outline_candidate(s: &VerifyScores, cfg: &VerifyConfig) -> Result<(), Unverified> {
    judge_with_contour(s, cfg)?;
    let untextured = s.view_texture.is_none_or(|t| t < cfg.untextured_below);
    let strong = s.edge_support.unwrap_or(0.0) >= cfg.strong_edge_support;
    let shading = s.zncc.unwrap_or(0.0) >= SHADING_ZNCC;
    if untextured && !strong && !shading {
        return Err(Unverified::Appearance {
            zncc: s.zncc,
            edge_support: s.edge_support,
        });
    }
    Ok(())
}

/// The rule: in view, large enough, and looking like the frame (module
/// docs). `Ok` when the pose passes.
pub fn judge(s: &VerifyScores, cfg: &VerifyConfig) -> Result<(), Unverified> {
    if s.visible.is_nan() || s.visible < cfg.min_visible {
        return Err(Unverified::NotInView {
            visible: s.visible,
            min: cfg.min_visible,
        });
    }
    if s.covered_px < cfg.min_covered_px {
        return Err(Unverified::TooSmall {
            covered_px: s.covered_px,
            min: cfg.min_covered_px,
        });
    }
    let edges = s.edge_support.unwrap_or(0.0);
    let pass = match s.zncc {
        Some(zncc) => zncc >= cfg.min_zncc && edges >= cfg.min_edge_support,
        None => edges >= cfg.strong_edge_support,
    };
    if pass {
        Ok(())
    } else {
        Err(Unverified::Appearance {
            zncc: s.zncc,
            edge_support: s.edge_support,
        })
    }
}

#[cfg(test)]
mod tests;
