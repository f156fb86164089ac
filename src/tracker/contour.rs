//! The contour modality (beyond the paper; DESIGN.md section 3, "Contour
//! residuals"): the object's silhouette, splatted at the predicted pose, is
//! searched for along its normals in the live frame, and each contour point
//! gives one residual row that joins the texture rows in one robust solve.
//!
//! How it works, per iteration (coarse to fine: long lines first, then
//! shorter ones, each iteration re-rendered at the newest estimate):
//! 1. The model is splatted at the pose, depth only (the visibility pass
//!    alone: coverage and depth, [`crate::splat::Splatter::render_depth`];
//!    the predictors follow from the depth, the limb normals from the
//!    model's points, [`ModelNormals`]); the
//!    covered pixels with an uncovered 4-neighbour are the silhouette. One
//!    point per `spacing_px` cell is kept ([`extract_contour`]); its outward
//!    normal is the gradient of the coverage over an 11x11 window, and its edge
//!    position is moved off the pixel centre by the covered fraction of
//!    that window (a straight edge through the window cuts it in proportion
//!    to its offset), so the contour is sub-pixel, then inward by the width
//!    the splatter's low-pass filter adds to the silhouette ([`inset`]).
//! 2. Along each normal, the frame is sampled every pixel and each sample's
//!    colour turned into the probability that it shows the object
//!    ([`ColourModel`]: foreground and background colour histograms learnt
//!    online at the tracked pose, away from the outline, as region
//!    trackers such as RBOT, SRT3D and M3T do). The boundary position `d`
//!    along the line is the mean of its posterior under a smooth-step
//!    model of the line ([`search_line`]).
//! 3. A twist `a` moves the contour point by `L(x_c) a` (the splatted motion
//!    predictors gathered at the contour pixel), of which the normal part
//!    is observable: the residual is `n^T L(x_c) a - d`, one row of 6
//!    ([`contour_row`]). The rows are solved with the texture matches of
//!    the frame (re-projected at the current estimate) by
//!    [`crate::pose::irls_grouped`], each modality with its own robust
//!    scale; undamped alone, damped towards a trusted KF estimate it
//!    refines ([`ContourConfig::fused_damping`]).
//! 4. The finest lines are searched again at the newest estimate while a
//!    round still moves the outline ([`ContourConfig::converged_px`]; two
//!    rounds at least, at most [`ContourConfig::rounds`]): a large jump is
//!    not reached from one linearisation. A round renders again unless
//!    the last render's points moved little since
//!    ([`ContourConfig::reproject_px`]: then they are moved instead).

use super::{ConfigError, Estimate, StepError, StepOutcome, Tracker};
use crate::geometry::{Intrinsics, Pose};
use crate::pose::{Anchor, Observation, SolveError, irls_grouped};
use crate::splat::{Attribute, Attributes, Window};
use nalgebra::{Matrix2x6, Vector2, Vector3, Vector6};

/// Settings of the contour modality.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct ContourConfig {
    /// Half-length of the search lines, pixels, one entry per iteration
    /// (coarse to fine).
    pub search_px: Vec<f32>,
    /// Lines are this many times longer when the contour starts without a
    /// trusted texture estimate (contour alone, a failed texture step, or
    /// recovering).
    pub long_factor: f32,
    /// One contour point per cell of this side, pixels.
    pub spacing_px: u32,
    /// Colour histogram bins per channel.
    pub bins: u32,
    /// Weight of the newest frame in the online colour histograms.
    pub learning_rate: f32,
    /// Pixels this close to the outline (either side) are not learnt.
    pub learn_margin_px: usize,
    /// The splatted silhouette is this much wider than the object, pixels
    /// (the splatter's 0.75 px low-pass disc around each splat): contour
    /// points are moved this far inward.
    pub inset_px: f64,
    /// Width of the smooth step of the line model, pixels.
    pub slope_px: f32,
    /// Fewer usable contour points than this: the step fails.
    pub min_points: usize,
    /// Most rounds per frame, each a render (or the last render's points
    /// moved, [`Self::reproject_px`]), line searches and a solve: the
    /// first searches every line length of `search_px`, later ones (at the
    /// newest estimate) the finest only.
    pub rounds: usize,
    /// From the second round on, a round whose correction moved the
    /// contour points less than this along their normals (mean, pixels)
    /// ends the step: a frame whose pose has converged stops, one that
    /// moved far (the first estimate linearised too far from it) searches
    /// again, up to [`Self::rounds`]. 0: always `rounds` rounds.
    pub converged_px: f64,
    /// Levenberg-Marquardt damping of each solve, as a fraction of the
    /// normal matrix's diagonal: it keeps a motion the silhouette hardly
    /// sees (a rotation of a nearly symmetric outline) from jumping, but
    /// holds it back where the object really makes it (0 by default: 0.01
    /// left the synthetic `plain` object 26 degrees behind its tilt).
    pub damping: f64,
    /// [`Self::damping`] when the step refines a trusted KF estimate, fused
    /// with its matches: it holds the fused solve near that estimate, so that the
    /// outline refines a textured object's pose instead of pulling it
    /// (the real cube fused: 1.01 degrees undamped, 0.50 at 0.1, against
    /// 0.35 with texture alone; 1 spoils the real dragon).
    pub fused_damping: f64,
    /// Whether a trusted KF step is refined by the contour (fused with its
    /// matches); else the contour runs only where the KF step fails. Off,
    /// the real cube keeps texture's 0.34 degrees but the real dragon,
    /// whose few trusted KF steps are wrong, goes from 3.3 to 10.7.
    pub refine_texture: bool,
    /// Fewer contour inliers than this fraction of the usable points: the
    /// step fails (the silhouette does not fit the frame).
    pub min_inlier_fraction: f64,
    /// Whether the contour's renders are depth-only
    /// ([`crate::splat::Splatter::render_depth`]: the visibility pass
    /// alone, a third of a depth and normal render), the limb normals then
    /// taken from the model's points ([`ModelNormals`]); else depth and
    /// normals are splatted (the former way, for comparison).
    pub depth_only: bool,
    /// A later round moves the last render's contour points to the newest
    /// estimate (lifted to 3-D at their depth, projected again) instead of
    /// rendering, when no point's normal motion since that render exceeds
    /// this many pixels (0: always render). After a small correction the
    /// outline is nearly the same points of the surface; keeping them also
    /// keeps the points' sampling of the frame (a new render picks other
    /// pixels of the outline, whose line noise moves the weakly seen
    /// rotations; README "Contour": the real dragon fused 98.8% to 100%).
    pub reproject_px: f64,
    /// Sectors of directions around the object's projected centre, each
    /// with its own colour histograms (learnt from the pixels in its
    /// directions, its lines weighed with them): what lies behind an object
    /// changes along its outline. 0: one pair of histograms for the whole
    /// object (README "Contour": measured 0, 4, 6, 8, 12).
    pub sectors: usize,
    /// Whether a render the targets already hold near the step's start
    /// (the KF step's novel view, whose depth comes from its predictors;
    /// or the last contour render) stands for the first round's render:
    /// its points are moved to the start as a later round's are (same
    /// [`Self::reproject_px`] test), and the round renders only when they
    /// moved too far. Off: the first round always renders.
    pub seed_render: bool,
}

impl Default for ContourConfig {
    fn default() -> Self {
        Self {
            search_px: vec![16.0, 8.0, 5.0],
            long_factor: 2.0,
            spacing_px: 4,
            bins: 16,
            learning_rate: 0.2,
            learn_margin_px: 2,
            inset_px: 0.65,
            slope_px: 1.0,
            min_points: 24,
            rounds: 4,
            converged_px: 0.25,
            damping: 0.0,
            fused_damping: 0.1,
            refine_texture: true,
            min_inlier_fraction: 0.5,
            depth_only: true,
            reproject_px: 1.0,
            seed_render: true,
            sectors: 8,
        }
    }
}

impl ContourConfig {
    /// Checks the ranges (part of [`super::TrackerConfig::validate`]).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |field, value: String, rule| Err(ConfigError::OutOfRange { field, value, rule });
        if self.search_px.is_empty()
            || self
                .search_px
                .iter()
                .any(|v| !(v.is_finite() && *v >= 2.0 && *v <= 200.0))
        {
            return bad(
                "contour.search_px",
                format!("{:?}", self.search_px),
                "a non-empty list of half-lengths in [2, 200]",
            );
        }
        if !(self.long_factor.is_finite() && (1.0..=10.0).contains(&self.long_factor)) {
            return bad(
                "contour.long_factor",
                self.long_factor.to_string(),
                "in [1, 10]",
            );
        }
        if !(1..=256).contains(&self.spacing_px) {
            return bad(
                "contour.spacing_px",
                self.spacing_px.to_string(),
                "in [1, 256]",
            );
        }
        if !(2..=64).contains(&self.bins) {
            return bad("contour.bins", self.bins.to_string(), "in [2, 64]");
        }
        if !(self.learning_rate > 0.0 && self.learning_rate <= 1.0) {
            return bad(
                "contour.learning_rate",
                self.learning_rate.to_string(),
                "in (0, 1]",
            );
        }
        if !(self.inset_px.is_finite() && (-2.0..=2.0).contains(&self.inset_px)) {
            return bad("contour.inset_px", self.inset_px.to_string(), "in [-2, 2]");
        }
        if self.learn_margin_px > 32 {
            return bad(
                "contour.learn_margin_px",
                self.learn_margin_px.to_string(),
                "in [0, 32]",
            );
        }
        if !(self.slope_px.is_finite() && self.slope_px > 0.0) {
            return bad("contour.slope_px", self.slope_px.to_string(), "> 0");
        }
        if self.sectors > 64 {
            return bad("contour.sectors", self.sectors.to_string(), "in [0, 64]");
        }
        if !(1..=10).contains(&self.rounds) {
            return bad("contour.rounds", self.rounds.to_string(), "in [1, 10]");
        }
        if !(self.converged_px.is_finite() && self.converged_px >= 0.0) {
            return bad(
                "contour.converged_px",
                self.converged_px.to_string(),
                ">= 0",
            );
        }
        if !(self.damping.is_finite() && self.damping >= 0.0) {
            return bad("contour.damping", self.damping.to_string(), ">= 0");
        }
        if !(self.fused_damping.is_finite() && self.fused_damping >= 0.0) {
            return bad(
                "contour.fused_damping",
                self.fused_damping.to_string(),
                ">= 0",
            );
        }
        if !(self.reproject_px.is_finite() && (0.0..=100.0).contains(&self.reproject_px)) {
            return bad(
                "contour.reproject_px",
                self.reproject_px.to_string(),
                "in [0, 100]",
            );
        }
        if !(0.0..=1.0).contains(&self.min_inlier_fraction) {
            return bad(
                "contour.min_inlier_fraction",
                self.min_inlier_fraction.to_string(),
                "in [0, 1]",
            );
        }
        Ok(())
    }
}

/// A point of the splatted silhouette.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContourPoint {
    /// The covered pixel on the silhouette (where the predictors are read).
    pub pixel: [u32; 2],
    /// The sub-pixel edge position, OpenCV pixel coordinates.
    pub position: Vector2<f64>,
    /// The unit image normal, pointing out of the object.
    pub normal: Vector2<f64>,
}

/// Half-width of the window giving a contour point's normal and offset.
const WINDOW: i64 = super::outline_gpu::OUTLINE_WINDOW as i64;

/// The silhouette of a coverage mask (`width x height`, row-major), one
/// point per `spacing x spacing` cell (the first silhouette pixel of the
/// cell in raster order). Pixels beyond the image count as covered, so an
/// object cut by the image border has no contour there (that edge is not
/// the object's).
pub fn extract_contour(
    coverage: &[bool],
    width: usize,
    height: usize,
    spacing: usize,
) -> Vec<ContourPoint> {
    assert_eq!(coverage.len(), width * height, "coverage size");
    let spacing = spacing.max(1);
    let at = |x: i64, y: i64| -> bool {
        if x < 0 || y < 0 || x >= width as i64 || y >= height as i64 {
            true
        } else {
            coverage[y as usize * width + x as usize]
        }
    };
    let (cw, ch) = (width.div_ceil(spacing), height.div_ceil(spacing));
    let mut taken = vec![false; cw * ch];
    let mut out = Vec::new();
    for y in 0..height as i64 {
        for x in 0..width as i64 {
            if !at(x, y) || (at(x - 1, y) && at(x + 1, y) && at(x, y - 1) && at(x, y + 1)) {
                continue;
            }
            let cell = (y as usize / spacing) * cw + x as usize / spacing;
            if taken[cell] {
                continue;
            }
            let (mut gx, mut gy, mut covered) = (0i64, 0i64, 0u32);
            for dy in -WINDOW..=WINDOW {
                for dx in -WINDOW..=WINDOW {
                    if at(x + dx, y + dy) {
                        gx += dx;
                        gy += dy;
                        covered += 1;
                    }
                }
            }
            // |g| < the least (exact in integers): a thin part or a corner,
            // whose normal is unreliable.
            let least = super::outline_gpu::OUTLINE_MIN_GRADIENT as i64;
            if gx * gx + gy * gy < least * least {
                continue;
            }
            taken[cell] = true;
            out.push(contour_point(x as u32, y as u32, gx, gy, covered));
        }
    }
    out
}

/// The contour point of silhouette pixel `(x, y)` whose window
/// ([`extract_contour`]'s, `WINDOW` pixels either side) holds `covered`
/// covered pixels, their offsets from `(x, y)` summing to `(gx, gy)`: the
/// normal is the sums' direction, turned outward, and the covered fraction
/// of the window locates a straight edge along it (its chord at the centre
/// is side / max(|nx|, |ny|)).
pub(crate) fn contour_point(x: u32, y: u32, gx: i64, gy: i64, covered: u32) -> ContourPoint {
    let (gx, gy) = (gx as f64, gy as f64);
    let g = (gx * gx + gy * gy).sqrt();
    let normal = Vector2::new(-gx / g, -gy / g);
    let side = (2 * WINDOW + 1) as f64;
    let offset = (covered as f64 / (side * side) - 0.5) * side * normal.x.abs().max(normal.y.abs());
    ContourPoint {
        pixel: [x, y],
        position: Vector2::new(x as f64, y as f64) + normal * offset,
        normal,
    }
}

/// Foreground (object) and background colour histograms, learnt online
/// from frames at their tracked poses: one pair over the whole object and,
/// where configured ([`ContourConfig::sectors`]), one pair per sector of
/// directions around the object's projected centre. What lies behind an
/// object changes along its outline (the real dragon's head stands
/// against an orange model, its tail against the white table): a line
/// then weighs its colours against the background seen on its side
/// (localised statistics, as RBOT's do around contour points).
#[derive(Debug, Clone, PartialEq)]
pub struct ColourModel {
    bins: u32,
    global: Histograms,
    sectors: Vec<Histograms>,
    scratch: LearnScratch,
}

/// The counts [`ColourModel::learn_around`] gathers from one frame, kept
/// between frames so that learning allocates nothing once the window and
/// sectors have been seen (the sectors' counts are 8 x 4096 bins a side).
/// Not part of the model: any two compare equal, and it prints as nothing.
#[derive(Clone, Default)]
struct LearnScratch {
    fg: Vec<f32>,
    bg: Vec<f32>,
    sectors_fg: Vec<f32>,
    sectors_bg: Vec<f32>,
    integral: Vec<u32>,
    /// A row's directions from the centre ([`turns_of_row`]).
    turns: Vec<f64>,
}

impl PartialEq for LearnScratch {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl std::fmt::Debug for LearnScratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("LearnScratch")
    }
}

/// `v` cleared and filled with `n` copies of `x` (its allocation kept).
fn refill<T: Copy>(v: &mut Vec<T>, n: usize, x: T) {
    v.clear();
    v.resize(n, x);
}

/// One pair of normalised histograms, with the per-bin terms the line
/// search reads.
#[derive(Debug, Clone, PartialEq)]
pub struct Histograms {
    foreground: Vec<f32>,
    background: Vec<f32>,
    learned: bool,
    /// Per bin: the object probability `p` (as
    /// [`ColourModel::foreground_probability`]), `ln p` and `ln (1 - p)`,
    /// kept up to date by every update (the line search needs the
    /// logarithms of every sample).
    terms: Vec<[f64; 3]>,
}

impl Histograms {
    fn new(n: usize) -> Self {
        let mut h = Self {
            foreground: vec![0.0; n],
            background: vec![0.0; n],
            learned: false,
            terms: Vec::new(),
        };
        h.update_terms();
        h
    }

    fn probability_of_bin(&self, b: usize) -> f32 {
        let (f, g) = (self.foreground[b], self.background[b]);
        if f + g <= 0.0 {
            0.5
        } else {
            (f / (f + g)).clamp(0.02, 0.98)
        }
    }

    fn update_terms(&mut self) {
        // A scene's colours fill few of the bins: the empty ones (0.5)
        // share one value, computed once.
        // Refilled in place: no allocation after the first.
        let half = [0.5, 0.5f64.ln(), 0.5f64.ln()];
        let mut terms = std::mem::take(&mut self.terms);
        terms.clear();
        terms.extend((0..self.foreground.len()).map(|b| {
            if self.foreground[b] + self.background[b] <= 0.0 {
                return half;
            }
            let p = self.probability_of_bin(b) as f64;
            [p, p.ln(), (1.0 - p).ln()]
        }));
        self.terms = terms;
    }

    /// Blends in one frame's counts (`rate`; the first time they are
    /// taken whole) when each side holds at least `least` pixels.
    fn blend(&mut self, fg: &[f32], bg: &[f32], least: f32, rate: f32) {
        let (nf, nb) = (fg.iter().sum::<f32>(), bg.iter().sum::<f32>());
        if nf < least.max(f32::MIN_POSITIVE) || nb < least.max(f32::MIN_POSITIVE) {
            return;
        }
        let rate = if self.learned { rate } else { 1.0 };
        for (h, v) in self.foreground.iter_mut().zip(fg) {
            *h = (1.0 - rate) * *h + rate * v / nf;
        }
        for (h, v) in self.background.iter_mut().zip(bg) {
            *h = (1.0 - rate) * *h + rate * v / nb;
        }
        self.learned = true;
        self.update_terms();
    }
}

/// A sector learns from a frame only where each side of it holds at least
/// this many pixels (weights: a pixel counts towards its two nearest
/// sectors); until then its lines use the whole object's histograms.
pub const SECTOR_LEAST_PX: f32 = 200.0;

/// The direction of `d` as a fraction of a full turn, in [0, 1), from +x
/// towards +y (clockwise on the screen, whose y points down), to within
/// 6e-4 turns (0.22 degrees: a polynomial approximation of the
/// arctangent; the sectors' weights need no more, and it is several times
/// cheaper than `atan2` over a window's pixels). 0 for a zero vector and
/// for one with a component not finite (no histogram learns a NaN weight).
pub fn turn_of(d: Vector2<f64>) -> f64 {
    let (ax, ay) = (d.x.abs(), d.y.abs());
    if (ax == 0.0 && ay == 0.0) || !(ax.is_finite() && ay.is_finite()) {
        return 0.0;
    }
    // atan(t) / (2 pi) for t in [0, 1] (|error| < 6e-4 turns).
    let t = ax.min(ay) / ax.max(ay);
    let mut a = t * (0.25 * std::f64::consts::PI + 0.273 * (1.0 - t)) / std::f64::consts::TAU;
    if ay > ax {
        a = 0.25 - a;
    }
    if d.x < 0.0 {
        a = 0.5 - a;
    }
    if d.y < 0.0 {
        a = 1.0 - a;
    }
    if a >= 1.0 { 0.0 } else { a }
}

/// A run of pixels that [`ColourModel::learn_around`] counts into the same
/// bins: side (covered), bin and sector `k`; `near` and `far` are the
/// sums of sector `k`'s and sector `k + 1`'s bin (the same when there is
/// one sector), started from their values in memory.
#[derive(Default)]
struct Run {
    key: (bool, usize, usize),
    count: u32,
    near: f32,
    far: f32,
}

impl Run {
    /// Starts a run of `key`, reading its sector bins from `sides`.
    fn start(&mut self, key: (bool, usize, usize), sides: &[f32], nbins: usize, ns: usize) {
        let (_, b, k) = key;
        self.key = key;
        self.count = 0;
        if ns > 0 {
            self.near = sides[k * nbins + b];
            self.far = sides[(k + 1) % ns * nbins + b];
        }
    }

    /// Writes the run's sums back (a count of pixels is exact in f32 up to
    /// 2^24: adding it at once is adding 1 that many times).
    fn flush(
        &mut self,
        fg: &mut [f32],
        bg: &mut [f32],
        sfg: &mut [f32],
        sbg: &mut [f32],
        nbins: usize,
        ns: usize,
    ) {
        if self.count == 0 {
            return;
        }
        let (covered, b, k) = self.key;
        let (side, sides) = if covered { (fg, sfg) } else { (bg, sbg) };
        side[b] += self.count as f32;
        if ns > 0 {
            if ns > 1 {
                sides[(k + 1) % ns * nbins + b] = self.far;
            }
            sides[k * nbins + b] = self.near;
        }
        self.count = 0;
    }
}

/// [`turn_of`]`((x0 + i - cx, dy))` into `out[i]`, bit for bit (the same
/// operations in the same order), for a row of pixels at once, with
/// selects instead of branches (the baseline x86-64 build keeps the
/// divisions scalar; a build for wider vectors may vectorise them).
/// `x0 + i` must fit an `i32`.
fn turns_of_row(x0: i32, cx: f64, dy: f64, out: &mut [f64]) {
    let ay = dy.abs();
    let (quarter, turn) = (0.25 * std::f64::consts::PI, std::f64::consts::TAU);
    for (i, o) in out.iter_mut().enumerate() {
        let dx = (x0 + i as i32) as f64 - cx;
        let ax = dx.abs();
        // min and max: equal to f64's where neither is NaN (the result is
        // then 0 below).
        let (lo, hi) = if ax < ay { (ax, ay) } else { (ay, ax) };
        let t = lo / hi;
        let a = t * (quarter + 0.273 * (1.0 - t)) / turn;
        let a = if ay > ax { 0.25 - a } else { a };
        let a = if dx < 0.0 { 0.5 - a } else { a };
        let a = if dy < 0.0 { 1.0 - a } else { a };
        // Zero and non-finite vectors: hi is 0, infinite or NaN.
        let valid = hi > 0.0 && hi < f64::INFINITY;
        *o = if valid && a < 1.0 { a } else { 0.0 };
    }
}

impl ColourModel {
    /// Empty histograms of `bins` bins per channel, over the whole object
    /// only.
    pub fn new(bins: u32) -> Self {
        Self::with_sectors(bins, 0)
    }

    /// Empty histograms of `bins` bins per channel, over the whole object
    /// and for each of `sectors` sectors of directions around it (0: none;
    /// sector `k` centred on the direction `k / sectors` of a turn from
    /// +x, towards +y).
    pub fn with_sectors(bins: u32, sectors: usize) -> Self {
        let n = (bins * bins * bins) as usize;
        Self {
            bins,
            global: Histograms::new(n),
            sectors: vec![Histograms::new(n); sectors],
            scratch: LearnScratch::default(),
        }
    }

    /// The number of sectors.
    pub fn sectors(&self) -> usize {
        self.sectors.len()
    }

    /// Whether any frame has been learnt.
    pub fn is_learned(&self) -> bool {
        self.global.learned
    }

    /// Whether sector `k` has learnt from a frame.
    pub fn sector_learned(&self, k: usize) -> bool {
        self.sectors.get(k).is_some_and(|h| h.learned)
    }

    fn bin(&self, c: [u8; 3]) -> usize {
        let q = |v: u8| (v as u32 * self.bins / 256) as usize;
        let b = self.bins as usize;
        (q(c[0]) * b + q(c[1])) * b + q(c[2])
    }

    /// The sector whose centre is nearest the direction `d` from the
    /// object's centre (`None` without sectors).
    pub fn sector_toward(&self, d: Vector2<f64>) -> Option<usize> {
        let n = self.sectors.len();
        (n > 0).then(|| ((turn_of(d) * n as f64).round() as usize) % n)
    }

    /// The histograms a line in direction `d` from the object's centre
    /// weighs its colours with: its sector's where learnt, else the whole
    /// object's.
    pub fn histograms_toward(&self, d: Vector2<f64>) -> &Histograms {
        match self.sector_toward(d) {
            Some(k) if self.sectors[k].learned => &self.sectors[k],
            _ => &self.global,
        }
    }

    /// The whole object's histograms.
    pub fn global(&self) -> &Histograms {
        &self.global
    }

    /// Learns from `frame` with the object covering `coverage` (row-major,
    /// the frame's size): covered pixels are foreground, uncovered ones
    /// inside `rect` (x0, y0, x1, y1, inclusive) background, except those
    /// within `margin` pixels (a square window) of the other side: the
    /// pixels across the outline mix both colours (and the splatted
    /// coverage is a little wider than the object), and learnt as either
    /// they would pull every boundary found toward that side. The first call
    /// sets the histograms, later ones blend in with weight `rate`. The
    /// whole object's histograms only; [`Self::learn_around`] learns the
    /// sectors too.
    pub fn learn(
        &mut self,
        frame: &image::RgbImage,
        coverage: &[bool],
        rect: (usize, usize, usize, usize),
        margin: usize,
        rate: f32,
    ) {
        self.learn_around(frame, coverage, rect, margin, rate, None);
    }

    /// [`Self::learn`], and with `centre` (the object's projected centre)
    /// each sector from the pixels in its directions around it: a pixel
    /// counts towards its two nearest sectors, by how near (linearly in
    /// angle).
    pub fn learn_around(
        &mut self,
        frame: &image::RgbImage,
        coverage: &[bool],
        rect: (usize, usize, usize, usize),
        margin: usize,
        rate: f32,
        centre: Option<Vector2<f64>>,
    ) {
        let w = frame.width() as usize;
        let h = frame.height() as usize;
        let nbins = self.global.foreground.len();
        let ns = if centre.is_some() {
            self.sectors.len()
        } else {
            0
        };
        let mut scratch = std::mem::take(&mut self.scratch);
        let LearnScratch {
            fg,
            bg,
            sectors_fg: sfg,
            sectors_bg: sbg,
            integral,
            turns,
        } = &mut scratch;
        refill(fg, nbins, 0.0);
        refill(bg, nbins, 0.0);
        refill(sfg, nbins * ns, 0.0);
        refill(sbg, nbins * ns, 0.0);
        let (x0, y0) = (rect.0.min(w - 1), rect.1.min(h - 1));
        let (x1, y1) = (rect.2.min(w - 1).max(x0), rect.3.min(h - 1).max(y0));
        // Covered counts over the rectangle grown by the margin (clamped to
        // the image), as an integral image: a pixel is kept when its window
        // is all covered or all empty.
        let (gx0, gy0) = (x0.saturating_sub(margin), y0.saturating_sub(margin));
        let (gx1, gy1) = ((x1 + margin).min(w - 1), (y1 + margin).min(h - 1));
        let gw = gx1 - gx0 + 2;
        refill(integral, gw * (gy1 - gy0 + 2), 0);
        for y in gy0..=gy1 {
            let mut run = 0u32;
            for x in gx0..=gx1 {
                run += u32::from(coverage[y * w + x]);
                let k = (y - gy0 + 1) * gw + (x - gx0 + 1);
                integral[k] = integral[k - gw] + run;
            }
        }
        let window = |x: usize, y: usize| {
            let (a, b) = (
                x.saturating_sub(margin).max(gx0),
                y.saturating_sub(margin).max(gy0),
            );
            let (c, d) = ((x + margin).min(gx1), (y + margin).min(gy1));
            let at = |x: usize, y: usize| integral[(y - gy0) * gw + (x - gx0)];
            let n = ((c - a + 1) * (d - b + 1)) as u32;
            let sum = at(c + 1, d + 1) + at(a, b) - at(a, d + 1) - at(c + 1, b);
            (sum, n)
        };
        let centre = centre.unwrap_or_default();
        let raw = frame.as_raw();
        // Pixel coordinates as i32 for the row's directions; a frame
        // wider than that learns without sectors rather than wrongly.
        let ns = if x1 < i32::MAX as usize { ns } else { 0 };
        refill(turns, if ns > 0 { x1 - x0 + 1 } else { 0 }, 0.0);
        // A run of pixels on one side in one bin (and sector) keeps its
        // sums in registers: the same additions in the same order as bin
        // by bin through memory (so the same sums bit for bit), without
        // waiting on each store when neighbours share a colour.
        let mut run = Run::default();
        for y in y0..=y1 {
            if ns > 0 {
                turns_of_row(x0 as i32, centre.x, y as f64 - centre.y, turns);
            }
            for x in x0..=x1 {
                let (sum, n) = window(x, y);
                let covered = coverage[y * w + x];
                if (covered && sum != n) || (!covered && sum != 0) {
                    continue;
                }
                let p = (y * w + x) * 3;
                let b = self.bin([raw[p], raw[p + 1], raw[p + 2]]);
                let (k, f) = if ns > 0 {
                    let t = turns[x - x0] * ns as f64;
                    let k = (t as usize).min(ns - 1);
                    (k, (t - k as f64) as f32)
                } else {
                    (0, 0.0)
                };
                if run.count == 0 || run.key != (covered, b, k) {
                    run.flush(fg, bg, sfg, sbg, nbins, ns);
                    run.start(
                        (covered, b, k),
                        if covered { &*sfg } else { &*sbg },
                        nbins,
                        ns,
                    );
                }
                run.count += 1;
                if ns > 0 {
                    run.near += 1.0 - f;
                    if ns == 1 {
                        run.near += f;
                    } else {
                        run.far += f;
                    }
                }
            }
        }
        run.flush(fg, bg, sfg, sbg, nbins, ns);
        self.global.blend(fg, bg, 1.0, rate);
        for (k, hist) in self.sectors.iter_mut().enumerate().take(ns) {
            let r = k * nbins..(k + 1) * nbins;
            hist.blend(&sfg[r.clone()], &sbg[r], SECTOR_LEAST_PX, rate);
        }
        self.scratch = scratch;
    }

    /// The probability that a pixel of colour `c` shows the object (equal
    /// priors), kept within [0.02, 0.98] so that one pixel cannot veto a
    /// boundary position; 0.5 for a colour never seen. The whole object's
    /// histograms.
    pub fn foreground_probability(&self, c: [u8; 3]) -> f32 {
        self.global.probability_of_bin(self.bin(c))
    }
}

impl Histograms {
    /// [`ColourModel::foreground_probability`] `p` of bin `b`, with `ln p`
    /// and `ln (1 - p)`.
    fn terms(&self, b: usize) -> [f64; 3] {
        self.terms[b]
    }
}

/// The boundary along one line: from `position` along the outward `normal`,
/// samples every pixel within `half_len`; returns the offset `d` (pixels,
/// positive outward) where the object ends, the mean of its posterior
/// under a smooth step of width `slope` (the object's probability
/// `hf(o - d) = (1 - tanh((o - d) / slope)) / 2` at offset `o`), or `None`
/// when the line leaves the image, shows no boundary (a flat posterior) or
/// puts it at the line's ends. The colours are weighed with the whole
/// object's histograms ([`search_line_toward`]: a sector's).
pub fn search_line(
    frame: &image::RgbImage,
    colours: &ColourModel,
    position: Vector2<f64>,
    normal: Vector2<f64>,
    half_len: f32,
    slope: f32,
) -> Option<f64> {
    let h = colours.global();
    LINE_SCRATCH.with_borrow_mut(|s| {
        search_line_in(s, frame, colours, h, position, normal, half_len, slope)
    })
}

/// [`search_line`] with the histograms of the sector the line lies in,
/// `direction` from the object's centre
/// ([`ColourModel::histograms_toward`]).
#[allow(clippy::too_many_arguments)]
pub fn search_line_toward(
    frame: &image::RgbImage,
    colours: &ColourModel,
    direction: Vector2<f64>,
    position: Vector2<f64>,
    normal: Vector2<f64>,
    half_len: f32,
    slope: f32,
) -> Option<f64> {
    let h = colours.histograms_toward(direction);
    LINE_SCRATCH.with_borrow_mut(|s| {
        search_line_in(s, frame, colours, h, position, normal, half_len, slope)
    })
}

/// The buffers of [`search_line`], kept per thread between lines (a
/// frame searches hundreds of them).
#[derive(Default)]
struct LineScratch {
    /// The object probability of each sample.
    pf: Vec<f64>,
    /// Prefix sums of `ln pf` and `ln (1 - pf)`.
    inside: Vec<f64>,
    outside: Vec<f64>,
    /// The smooth step on the 1/8 px grid, for `steps_slope`.
    steps: Vec<f64>,
    steps_slope: f64,
    /// Log-likelihoods of the half-pixel candidates.
    ll: Vec<f64>,
}

thread_local! {
    static LINE_SCRATCH: std::cell::RefCell<LineScratch> = std::cell::RefCell::default();
}

#[allow(clippy::too_many_arguments)]
fn search_line_in(
    s: &mut LineScratch,
    frame: &image::RgbImage,
    colours: &ColourModel,
    hist: &Histograms,
    position: Vector2<f64>,
    normal: Vector2<f64>,
    half_len: f32,
    slope: f32,
) -> Option<f64> {
    let l = half_len.round().max(2.0) as i64;
    let n = (2 * l + 1) as usize;
    s.pf.clear();
    s.inside.clear();
    s.outside.clear();
    s.inside.push(0.0);
    s.outside.push(0.0);
    for k in -l..=l {
        let p = position + normal * k as f64;
        let c = crate::geometry::sample_bilinear_rgb(frame, p.x as f32, p.y as f32)?;
        let [p, ln_p, ln_q] = hist.terms(colours.bin(c.0));
        s.pf.push(p);
        let i = s.pf.len() - 1;
        s.inside.push(s.inside[i] + ln_p);
        s.outside.push(s.outside[i] + ln_q);
    }
    // Beyond 4 slopes the step is 0 or 1 to within 3e-4: those samples
    // count as plainly inside (ln pf) or outside (ln (1 - pf)), summed by
    // prefix sums; only the samples near `d` need the smooth step.
    let slope = slope as f64;
    let reach = (4.0 * slope).ceil() as i64;
    // The smooth step at every offset o - d the searches below meet: d
    // lies on a grid of 1/8 px and |o - d| <= reach, so the step is
    // tabulated once (per slope) at o - d = m / 8 (m / 8 is exact).
    if s.steps_slope != slope || s.steps.is_empty() {
        s.steps.clear();
        s.steps.extend(
            (-8 * reach..=8 * reach).map(|m| 0.5 * (1.0 - ((m as f64 / 8.0) / slope).tanh())),
        );
        s.steps_slope = slope;
    }
    let (pf, inside, outside, steps) = (&s.pf, &s.inside, &s.outside, &s.steps);
    let loglik = |d: f64| {
        // d in eighths of a pixel (exact: d lies on that grid).
        let d8 = (d * 8.0) as i64;
        debug_assert_eq!(d8 as f64, d * 8.0, "d off the 1/8 px grid");
        // Samples i with offset o = i - l: plainly inside when o < d - reach.
        let lo =
            ((d8 - 8 * reach).div_euclid(8) + i64::from((d8 - 8 * reach).rem_euclid(8) != 0) + l)
                .clamp(0, n as i64) as usize;
        let hi = ((d8 + 8 * reach).div_euclid(8) + l + 1).clamp(0, n as i64) as usize;
        // The samples near d: one logarithm of their likelihoods' product
        // (at least 0.02 each, at most 9 of them for a 1 px slope: no
        // underflow) instead of one per sample. Sample i is at o - d =
        // (8 (i - l) - d8) / 8, the step's entry m of that.
        let mut near = 1.0;
        let mut m = 8 * (lo as i64 - l) - d8 + 8 * reach;
        for p in &pf[lo..hi.max(lo)] {
            let hf = steps[m as usize];
            near *= hf * p + (1.0 - hf) * (1.0 - p);
            m += 8;
        }
        inside[lo] + (outside[n] - outside[hi]) + near.ln()
    };
    // Candidates every half pixel, away from the line's ends: d = h / 2.
    let candidate = |h: i64| h as f64 * 0.5;
    let (h0, h1) = (-(2 * l - 2), 2 * l - 2);
    s.ll.clear();
    s.ll.extend((h0..=h1).map(|h| loglik(candidate(h))));
    let ll = &s.ll;
    let (k, best) = ll
        .iter()
        .copied()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    // A boundary the line cannot place (a flat posterior: no transition,
    // or several alike) is no evidence.
    let (mut sw, mut sd, mut sdd) = (0.0, 0.0, 0.0);
    for (j, v) in ll.iter().enumerate() {
        let w = (v - best).exp();
        let d = candidate(h0 + j as i64);
        sw += w;
        sd += w * d;
        sdd += w * d * d;
    }
    let mean = sd / sw;
    let var = (sdd / sw - mean * mean).max(0.0);
    if var.sqrt() > (0.15 * l as f64).max(1.5) || k == 0 || k + 1 == ll.len() {
        return None;
    }
    // Sub-pixel, first to about half a pixel: the posterior mean on a
    // finer grid near the maximum (a boundary pixel of mixed colour, never
    // learnt, leaves the likelihood flat across it: its mean, not a
    // parabola's vertex, is unbiased); then within the pixels by their
    // colours ([`mixed_boundary`]).
    let dk = candidate(h0 + k as i64);
    let fine = (-12..=12)
        .map(|q| dk + q as f64 * 0.125)
        .filter(|d| d.abs() <= (l - 1) as f64);
    let fl: [Option<(f64, f64)>; 25] = {
        let mut a = [None; 25];
        for (slot, d) in a.iter_mut().zip(fine) {
            *slot = Some((d, loglik(d)));
        }
        a
    };
    let top = fl
        .iter()
        .flatten()
        .map(|p| p.1)
        .fold(f64::NEG_INFINITY, f64::max);
    let (mut sw, mut sd) = (0.0, 0.0);
    for (d, v) in fl.iter().flatten() {
        let w = (v - top).exp();
        sw += w;
        sd += w * d;
    }
    let d0 = sd / sw;
    Some(mixed_boundary(frame, position, normal, pf, l, d0).unwrap_or(d0))
}

/// Samples either side of the boundary that stand for the pure colours in
/// [`mixed_boundary`], pixels from the posterior's estimate.
const MIX_REACH: i64 = 2;

/// Spacing of [`mixed_boundary`]'s samples along the line, pixels.
const MIX_STEP: f64 = 0.25;

/// A sample farther than this fraction of the two colours' distance from
/// its mix of them (on the segment between them, or of the object's shade
/// and the background) shows a third colour: no mixed boundary.
const MIX_OFF_SEGMENT: f64 = 0.25;

/// A shade of the object's side is told from the background's share
/// when the background's colour lies at least this fraction of the two
/// colours' distance from every shade of the object's (else its share
/// would be noisier than on the segment between them).
const MIX_MIN_SHADE_DISTANCE: f64 = 0.5;

/// Colours closer than this (RGB distance, 0..255 units) do not place the
/// boundary within a pixel: image noise would.
const MIX_MIN_CONTRAST: f64 = 30.0;

/// The boundary within its pixels. The colour models place it to about half
/// a pixel only (a sample's colour is object or background by the
/// histograms; the samples across the boundary mix both and are in
/// neither). But a mixed sample shows the boundary's place: camera pixels
/// (and anti-aliased renders) average the colours of the two sides over
/// their area, so its colour lies between the object's and the
/// background's in proportion to the object's share `alpha`. With the
/// samples [`MIX_REACH`] pixels either side of `d0` (the posterior's
/// estimate, offsets along the line from `position`) standing for the
/// pure colours, each sample between is split into its shares of them
/// (the object's side scaled by a free shade where the background lies
/// away from its shades: a limb darkens towards the outline; else on the
/// segment between them),
/// and the boundary is where a sharp step of the same area lies:
/// for samples every `h` from `a` to `b`, `alpha(a) = 1`, `alpha(b) = 0`,
/// a step at `e` covers `h sum alpha = e - a + h / 2`. (Fine steps make
/// this hold for any blur across the boundary, a pixel's footprint seen
/// along a slanted line included; at one pixel it would not.) `pf`: the
/// object probabilities of the line's samples at offsets `-l..=l`. `None`
/// (keep `d0`) where the line is too short, the two colours are too alike,
/// the colour model does not put them on their sides, a sample between is
/// no mix of them, or the result leaves `d0`'s pixel.
fn mixed_boundary(
    frame: &image::RgbImage,
    position: Vector2<f64>,
    normal: Vector2<f64>,
    pf: &[f64],
    l: i64,
    d0: f64,
) -> Option<f64> {
    let c = d0.round() as i64;
    let (a, b) = (c - MIX_REACH, c + MIX_REACH);
    if a < -l || b > l {
        return None;
    }
    if !(pf[(a + l) as usize] > 0.5 && pf[(b + l) as usize] < 0.5) {
        return None;
    }
    let colour = |o: f64| {
        let p = position + normal * o;
        crate::geometry::sample_bilinear_rgb(frame, p.x as f32, p.y as f32)
            .map(|v| Vector3::new(v.0[0] as f64, v.0[1] as f64, v.0[2] as f64))
    };
    let (inside, outside) = (colour(a as f64)?, colour(b as f64)?);
    let span = inside - outside;
    let len2 = span.norm_squared();
    if len2 < MIX_MIN_CONTRAST * MIX_MIN_CONTRAST {
        return None;
    }
    // The object's side darkens towards a limb (its surface turns away
    // from the light): a mixed sample is then `s inside` and the
    // background over their shares, with an unknown shade `s`. Where the
    // background's colour lies away from every shade of the object's (the
    // ray through `inside`), `v = p inside + q outside` is solved for
    // (p, q) by least squares and the object's share is `1 - q` (the
    // background's share is what the shade cannot change). The standard
    // deviation of `q` is the noise over that distance, against the noise
    // over the colours' distance on the segment: nearer than
    // [`MIX_MIN_SHADE_DISTANCE`] of it (colours apart in brightness
    // more than in hue), the shade and the share are told apart too
    // poorly, and the sample is placed on the segment between them.
    let gram = nalgebra::Matrix2::new(
        inside.norm_squared(),
        inside.dot(&outside),
        inside.dot(&outside),
        outside.norm_squared(),
    );
    let off_shades2 = gram.determinant() / gram[(0, 0)].max(1e-9);
    let shaded = (off_shades2 >= MIX_MIN_SHADE_DISTANCE * MIX_MIN_SHADE_DISTANCE * len2)
        .then(|| gram.try_inverse())
        .flatten();
    let steps = ((b - a) as f64 / MIX_STEP).round() as i64;
    let mut area = 1.0; // alpha(a)
    for j in 1..steps {
        let o = a as f64 + j as f64 * MIX_STEP;
        let c = colour(o)?;
        let (t, off) = match &shaded {
            Some(inv) => {
                let pq = inv * nalgebra::Vector2::new(inside.dot(&c), outside.dot(&c));
                let (p, q) = (pq[0].max(0.0), pq[1].clamp(0.0, 1.0));
                (1.0 - q, c - inside * p - outside * q)
            }
            None => {
                let v = c - outside;
                let t = v.dot(&span) / len2;
                (t, v - span * t)
            }
        };
        // A third colour (texture, clutter) is not a mix of the two.
        if off.norm_squared() > MIX_OFF_SEGMENT * MIX_OFF_SEGMENT * len2 {
            return None;
        }
        area += t.clamp(0.0, 1.0);
    }
    let e = a as f64 - 0.5 * MIX_STEP + MIX_STEP * area;
    ((e - d0).abs() <= 1.0).then_some(e)
}

/// Moves each point `px` pixels inward along its normal: the splatted
/// coverage extends past the object's outline by about the splatter's
/// low-pass radius (measured 0.65 px on the synthetic `plain` object
/// against its exact rasterised outline, and on the analytic sphere of
/// tests/contour.rs).
pub fn inset(points: &mut [ContourPoint], px: f64) {
    for p in points {
        p.position -= p.normal * px;
    }
}

/// The residual row of a contour point whose predictors are `l` and
/// normal `n`, with the boundary found `d` pixels along the normal: the
/// first predictor row is `n^T L`, the second zero, so that
/// [`crate::pose::irls`] sees the scalar residual `n^T L a - d`.
pub fn contour_row(l: &Matrix2x6<f64>, n: &Vector2<f64>, d: f64) -> Observation {
    let row = n.transpose() * l;
    let mut predictors = Matrix2x6::zeros();
    predictors.set_row(0, &row);
    Observation {
        predictors,
        displacement: Vector2::new(d, 0.0),
    }
}

/// Replaces the coverage-gradient normal of each point on an occluding
/// contour (a limb: the splatted surface normal `N` there is nearly
/// perpendicular to the viewing ray) by the exact one: the surface's
/// tangent plane there contains the ray, so it projects onto the contour's
/// tangent line, whose image normal is `(N_x / f_x, N_y / f_y)`. Crease
/// outlines (a box's edges, where `N` faces the camera) keep theirs.
/// `normals`: the splatted normals (3 channels, NaN where empty).
pub fn limb_normals(
    cam: &crate::geometry::Intrinsics,
    normals: &crate::splat::SplatImage,
    points: &mut [ContourPoint],
) {
    limb_normals_with(cam, points, false, |p| {
        let nv = normals.pixel(p.pixel[0], p.pixel[1]);
        Some(nalgebra::Vector3::new(
            nv[0] as f64,
            nv[1] as f64,
            nv[2] as f64,
        ))
    });
}

/// [`limb_normals`] with the camera-space surface normal at each point
/// given by `normal_at` (`None`: keep the point's normal). `perpendicular`:
/// a limb's normal is taken perpendicular to the ray (the part along the
/// ray removed), as it is by definition: a mean of the normals around the
/// limb ([`ModelNormals`]) leans towards the camera, which would tilt the
/// image normal towards or away from the principal point.
pub fn limb_normals_with(
    cam: &crate::geometry::Intrinsics,
    points: &mut [ContourPoint],
    perpendicular: bool,
    mut normal_at: impl FnMut(&ContourPoint) -> Option<nalgebra::Vector3<f64>>,
) {
    for p in points {
        let Some(n3) = normal_at(p) else {
            continue;
        };
        if !n3.iter().all(|v| v.is_finite()) || n3.norm() < 0.5 {
            continue;
        }
        let ray = cam
            .unproject(&Vector2::new(p.pixel[0] as f64, p.pixel[1] as f64), 1.0)
            .normalize();
        if n3.normalize().dot(&ray).abs() > 0.3 {
            continue;
        }
        let n3 = if perpendicular {
            n3 - ray * n3.dot(&ray)
        } else {
            n3
        };
        let img = Vector2::new(n3.x / cam.fx, n3.y / cam.fy);
        if img.norm() < 1e-12 {
            continue;
        }
        let img = img.normalize();
        // Only a refinement: a normal far from the outline's is a sign of
        // a mixed pixel, keep the coverage's then.
        if img.dot(&p.normal) > 0.9 {
            p.normal = img;
        }
    }
}

/// The model's normals near a point, for the limb normals of a depth-only
/// render (which splats no normals): the points in a uniform grid of
/// cells of twice the median splat radius, and at a query the
/// kernel-weighted mean normal (`exp(-2 (d / r)^2)`, as the splatter
/// weights a splat `d` away from its centre) of the points facing the
/// camera within twice their radius, as the splatted normal averages the
/// visible splats covering the pixel.
#[derive(Debug, Clone)]
pub struct ModelNormals {
    cell: f32,
    lo: glam::Vec3,
    dims: [usize; 3],
    /// Points of cell `c`: `points[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    /// The model's points that can count (a positive radius), in cell
    /// order and, within a cell, in the model's: a query reads its cells'
    /// points from one place instead of three arrays at random.
    points: Vec<GridPoint>,
    /// Per cell, the largest radius of its points (0 when empty): a cell
    /// farther than twice that from a query holds no point near it.
    reach: Vec<f32>,
}

/// A model point as [`ModelNormals`] keeps it.
#[derive(Debug, Clone, Copy)]
struct GridPoint {
    position: glam::Vec3,
    normal: glam::Vec3,
    radius: f32,
}

impl ModelNormals {
    /// The grid of `model`'s points (`None` for an empty model, or one
    /// without a positive radius).
    pub fn new(model: &crate::model::PointModel) -> Option<Self> {
        if model.positions.is_empty() {
            return None;
        }
        let mut radii: Vec<f32> = model.radii.iter().copied().filter(|r| *r > 0.0).collect();
        if radii.is_empty() {
            return None;
        }
        let mid = radii.len() / 2;
        let median = *radii.select_nth_unstable_by(mid, f32::total_cmp).1;
        let (mut lo, mut hi) = (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN));
        for p in &model.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        // At most about 2^24 cells: a model of a few far-apart points
        // gets larger cells, not a huge grid.
        let extent = (hi - lo).max_element().max(1e-9);
        let cell = (2.0 * median).max(extent / 256.0);
        let dims = [0, 1, 2].map(|k| ((hi[k] - lo[k]) / cell) as usize + 1);
        let n = dims[0] * dims[1] * dims[2];
        let index = |p: &glam::Vec3| {
            let c = ((*p - lo) / cell).as_uvec3();
            let c = [0, 1, 2].map(|k| (c[k] as usize).min(dims[k] - 1));
            (c[2] * dims[1] + c[1]) * dims[0] + c[0]
        };
        // Points with a NaN or non-positive radius never count
        // (`normal_at`): left out.
        let counted = |i: usize| model.radii[i] > 0.0;
        let mut start = vec![0u32; n + 1];
        let mut reach = vec![0f32; n];
        for (i, p) in model.positions.iter().enumerate() {
            if counted(i) {
                let c = index(p);
                start[c + 1] += 1;
                reach[c] = reach[c].max(model.radii[i]);
            }
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let empty = GridPoint {
            position: glam::Vec3::ZERO,
            normal: glam::Vec3::ZERO,
            radius: 0.0,
        };
        let mut points = vec![empty; start[n] as usize];
        for (i, p) in model.positions.iter().enumerate() {
            if counted(i) {
                let c = index(p);
                points[fill[c] as usize] = GridPoint {
                    position: *p,
                    normal: model.normals[i],
                    radius: model.radii[i],
                };
                fill[c] += 1;
            }
        }
        Some(Self {
            cell,
            lo,
            dims,
            start,
            points,
            reach,
        })
    }

    /// The weighted mean normal (object frame, not normalised) at the
    /// object-frame point `x` of the points whose normal faces `eye` (the
    /// camera centre, object frame); `None` when no point is near. The
    /// sums run over the points of the 27 cells around `x` in a fixed
    /// order, skipping the cells too far to hold a point within twice its
    /// radius (which would add nothing).
    pub fn normal_at(&self, x: glam::Vec3, eye: glam::Vec3) -> Option<glam::Vec3> {
        let c = ((x - self.lo) / self.cell).floor();
        let mut sum = glam::Vec3::ZERO;
        let mut wsum = 0.0f32;
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let q = c + glam::Vec3::new(dx as f32, dy as f32, dz as f32);
                    if q.min_element() < 0.0 {
                        continue;
                    }
                    let q = [q.x as usize, q.y as usize, q.z as usize];
                    if (0..3).any(|k| q[k] >= self.dims[k]) {
                        continue;
                    }
                    let k = (q[2] * self.dims[1] + q[1]) * self.dims[0] + q[0];
                    if self.beyond_reach(k, q, x) {
                        continue;
                    }
                    for g in &self.points[self.start[k] as usize..self.start[k + 1] as usize] {
                        let (p, n, r) = (g.position, g.normal, g.radius);
                        if n.dot(eye - p) <= 0.0 {
                            continue;
                        }
                        let d2 = (x - p).length_squared() / (r * r);
                        if d2 > 4.0 {
                            continue;
                        }
                        let w = (-2.0 * d2).exp();
                        sum += n * w;
                        wsum += w;
                    }
                }
            }
        }
        (wsum > 0.0).then_some(sum)
    }

    /// Whether cell `k` (at `q`) lies farther from `x` than twice its
    /// largest radius, with a margin: well beyond f32 rounding in the
    /// cell's bounds (the points on the grid's far faces are clamped into
    /// its last cells) and in `normal_at`'s test, so no point that would
    /// count is skipped.
    fn beyond_reach(&self, k: usize, q: [usize; 3], x: glam::Vec3) -> bool {
        let slack = 1e-3 * self.cell;
        let mut d2 = 0.0f32;
        for a in 0..3 {
            let lo = self.lo[a] + q[a] as f32 * self.cell - slack;
            let hi = self.lo[a] + (q[a] + 1) as f32 * self.cell + slack;
            let d = (lo - x[a]).max(x[a] - hi).max(0.0);
            d2 += d * d;
        }
        let reach = 2.0 * self.reach[k] * 1.001;
        d2 > reach * reach
    }
}

/// The rows of `points` with `d = 0` ([`contour_row`]), their predictors
/// `L` from the splatted depth `depth` (one channel, NaN where empty) at
/// each point's pixel, lifted to the camera-space point: the projection's
/// Jacobian that the splatter's motion targets hold there (DESIGN.md
/// section 3), without rendering them.
pub fn contour_predictors(
    cam: &crate::geometry::Intrinsics,
    depth: &crate::splat::SplatImage,
    points: &[ContourPoint],
) -> Vec<Observation> {
    let depths: Vec<f32> = points
        .iter()
        .map(|p| depth.pixel(p.pixel[0], p.pixel[1])[0])
        .collect();
    contour_predictors_at(cam, points, &depths)
}

/// [`contour_predictors`] with the depth at each point's pixel given.
fn contour_predictors_at(
    cam: &crate::geometry::Intrinsics,
    points: &[ContourPoint],
    depths: &[f32],
) -> Vec<Observation> {
    points
        .iter()
        .zip(depths)
        .map(|(p, &z)| {
            let xc = cam.unproject(
                &Vector2::new(p.pixel[0] as f64, p.pixel[1] as f64),
                z as f64,
            );
            contour_row(&cam.motion_predictors(&xc), &p.normal, 0.0)
        })
        .collect()
}

/// The contour rows of `found` at `twist`: each line searched where the
/// twist moved its point (to first order, `n^T L twist` along the normal),
/// in order, the lines without a boundary left out. The lines are
/// independent: long lists are split over the CPU's cores (the results
/// are the same as in one thread, in the same order).
fn search_lines(
    frame: &image::RgbImage,
    colours: &ColourModel,
    centre: Vector2<f64>,
    found: &[Lifted],
    twist: &Vector6<f64>,
    half: f32,
    slope: f32,
) -> Vec<Observation> {
    let one = |l: &Lifted| {
        let (p, row) = (&l.point, &l.row);
        let moved = (row.predictors * twist)[0];
        search_line_toward(
            frame,
            colours,
            p.position - centre,
            p.position + p.normal * moved,
            p.normal,
            half,
            slope,
        )
        .map(|d| Observation {
            displacement: Vector2::new(moved + d, 0.0),
            ..*row
        })
    };
    crate::par::flat_map_split(found, 64, |part| part.iter().filter_map(one).collect())
}

/// The robust-scale groups of the fused solve.
const GROUP_TEXTURE: u8 = 0;
const GROUP_CONTOUR: u8 = 1;

/// A contour point found at some pose, with its row there and its edge
/// position lifted to that pose's camera frame (so that it can be moved
/// to a nearby pose without rendering again).
#[derive(Debug, Clone, Copy)]
struct Lifted {
    /// Frame coordinates.
    point: ContourPoint,
    /// The camera-space point of the edge position.
    xc: nalgebra::Vector3<f64>,
    /// [`contour_row`] with `d = 0`.
    row: Observation,
}

impl Lifted {
    /// The point moved by `motion` (camera frame to camera frame): its
    /// projection and row there; its image normal kept.
    fn moved(&self, motion: &Pose, cam: &crate::geometry::Intrinsics) -> Option<Lifted> {
        let xc = motion.transform_point(&self.xc);
        let uv = cam.project(&xc)?;
        Some(Lifted {
            point: ContourPoint {
                position: uv,
                ..self.point
            },
            xc,
            row: contour_row(&cam.motion_predictors(&xc), &self.point.normal, 0.0),
        })
    }
}

impl Tracker {
    /// The contour step from `pose`: the iterations of the module docs,
    /// fused with `anchors` (texture matches of this frame, object point
    /// and live-frame position). `long`: no trusted texture estimate, so
    /// the lines reach farther. Leaves the last coverage mask in
    /// `self.contour_mask` for learning the colours.
    pub(super) fn contour_stage(
        &mut self,
        frame: &image::RgbImage,
        pose: &Pose,
        long: bool,
        anchors: &[Anchor],
    ) -> StepOutcome {
        StepOutcome::from_result(self.contour_step(frame, pose, long, anchors))
    }

    fn contour_step(
        &mut self,
        frame: &image::RgbImage,
        start: &Pose,
        long: bool,
        anchors: &[Anchor],
    ) -> Result<Estimate, StepError> {
        let cfg = self.config.contour.clone();
        // Fused with a trusted KF step's matches, damping holds the solve
        // near that estimate (the prior the contour refines); from IT's
        // estimate (which drifts) or alone, nothing should hold it back.
        let damping = if anchors.is_empty() {
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
                self.contour_renders += 1;
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
            self.contour_rounds += 1;
            pose = step.pose;
            last = Some(step);
            if round >= 1 && moved < cfg.converged_px {
                break;
            }
        }
        last.ok_or(StepError::Solve(SolveError::TooFewMatches {
            got: 0,
            need: cfg.min_points,
        }))
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
        let cfg = &self.config.contour;
        if !cfg.seed_render || !cfg.depth_only || cfg.reproject_px <= 0.0 {
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
        (far <= 4.0 * cfg.reproject_px).then_some((*at, self.window))
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
        let _batch = self.ctx.batch();
        let depth_only = self.config.contour.depth_only;
        if depth_only {
            self.splatter.render_depth(
                &self.ctx,
                &self.geometry,
                &cam,
                pose,
                &mut self.targets,
                self.gpu_timer.as_mut(),
            )?;
            self.note_splat("contour splat");
        } else {
            self.splat(
                super::profile::Texture::None,
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
        // projection's Jacobian of DESIGN.md section 3, what the motion
        // targets would hold, without rendering them. On the GPU
        // (depth-only renders, whose normals come from the model): the
        // outline found there, a few integers a point and the coverage's
        // bits read back; else the depth read back and the outline found
        // here. The same points either way.
        let resident =
            depth_only && self.outline.resident() && self.outline.fits(window.width, window.height);
        let (mut points, depths, depth) = if resident {
            let _batch = self.ctx.batch();
            let target = self.outline.depth_target(window.width, window.height);
            self.splatter
                .resolve_into(&self.ctx, &self.targets, Attribute::Depth, &target)?;
            let outline = self
                .outline
                .extract(window.width, window.height, spacing)
                .map_err(crate::splat::SplatError::from)?;
            let t = self.outline.take_timings();
            self.note_timings("contour outline", t);
            self.fill_contour_mask(w, h, window, |x, y| outline.covered(x as u32, y as u32));
            (outline.points, outline.depths, None)
        } else {
            let depth = self
                .splatter
                .read(&self.ctx, &self.targets, Attribute::Depth)?;
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
        let cfg = &self.config.contour;
        if !self.colours.model().is_learned()
            && let Some(rect) = self.roi(pose)
            && let Some(centre) = self.centre_px(pose)
        {
            // Needed at once: learnt here.
            let lesson = super::learner::Lesson {
                rect,
                margin: cfg.learn_margin_px,
                rate: cfg.learning_rate,
                centre: Some(centre),
            };
            self.colours.learn_here(frame, &self.contour_mask, lesson);
        }
        if depth_only {
            if self.model_normals.is_none() {
                self.model_normals = ModelNormals::new(&self.model);
            }
            if let Some(grid) = &self.model_normals {
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
                limb_normals_with(cam, &mut points, true, |_| {
                    normals.next().expect("a normal a point")
                });
            }
        } else {
            let normals = self
                .splatter
                .read(&self.ctx, &self.targets, Attribute::Normal)?;
            limb_normals(cam, &normals, &mut points);
        }
        drop(depth);
        inset(&mut points, cfg.inset_px);
        let rows = contour_predictors_at(cam, &points, &depths);
        let origin = Vector2::new(x0 as f64, y0 as f64);
        let lifted = points
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
        Ok(lifted)
    }

    /// The whole frame's coverage (`w x h`) in `contour_mask`, the buffer
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
        let coverage = &mut self.contour_mask;
        coverage.clear();
        coverage.resize(w * h, false);
        for y in 0..wh {
            let row = &mut coverage[(y0 + y) * w + x0..(y0 + y) * w + x0 + ww];
            for (x, c) in row.iter_mut().enumerate() {
                *c = covered(x, y);
            }
        }
        self.contour_mask_fresh = true;
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
                self.colours.model(),
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

    /// Whether the contour learns a tracked frame's colours on a thread of
    /// its own while the next frame's texture steps run (`true`, the
    /// default), or on the calling thread before [`Tracker::track`]
    /// returns (for profiling, or an embedding that wants no thread). The
    /// colours, and so the poses, are the same either way.
    pub fn set_background_learning(&mut self, on: bool) {
        self.colours.set_background(on);
    }

    /// Finds the contour's outline on the GPU (`true`, the default on
    /// GPUs) or on the host from a readback of the window's depth (the
    /// default on CPU adapters): [`super::outline_gpu::GpuOutline::resident`].
    /// Only for depth-only contour renders; the points, and so the poses,
    /// are the same.
    pub fn set_resident_outline(&mut self, on: bool) {
        self.outline.set_resident(on);
    }

    /// Learns the colours of `frame` at the last contour render (after a
    /// tracked frame): on the colour learner's thread (see
    /// [`Tracker::set_background_learning`]).
    pub(super) fn learn_colours(&mut self, frame: &image::RgbImage, pose: &Pose) {
        let fresh = std::mem::take(&mut self.contour_mask_fresh);
        if let (true, Some(rect), Some(centre)) = (fresh, self.roi(pose), self.centre_px(pose)) {
            let c = &self.config.contour;
            let lesson = super::learner::Lesson {
                rect,
                margin: c.learn_margin_px,
                rate: c.learning_rate,
                centre: Some(centre),
            };
            self.colours.learn(frame, &mut self.contour_mask, lesson);
        }
    }

    /// The projection of the model's centre at `pose`: the origin of the
    /// colour sectors' directions.
    fn centre_px(&self, pose: &Pose) -> Option<Vector2<f64>> {
        self.cam.project(&pose.transform_point(&self.center))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A disc of radius 40 centred at (60.3, 50.7) in a 128x100 mask.
    fn disc() -> (Vec<bool>, usize, usize, Vector2<f64>, f64) {
        let (w, h) = (128, 100);
        let c = Vector2::new(60.3, 50.7);
        let r = 40.0;
        let m = (0..w * h)
            .map(|i| (Vector2::new((i % w) as f64, (i / w) as f64) - c).norm() <= r)
            .collect();
        (m, w, h, c, r)
    }

    #[test]
    fn contour_of_a_disc_lies_on_its_circle_with_radial_normals() {
        let (m, w, h, c, r) = disc();
        let pts = extract_contour(&m, w, h, 6);
        assert!(pts.len() > 30, "{} points", pts.len());
        let mut err = 0.0f64;
        let mut worst_angle = 0.0f64;
        for p in &pts {
            let radial = (p.position - c).normalize();
            worst_angle = worst_angle.max(radial.dot(&p.normal).clamp(-1.0, 1.0).acos());
            err += ((p.position - c).norm() - r).abs();
        }
        err /= pts.len() as f64;
        assert!(err < 0.3, "mean distance to the circle {err:.3} px");
        assert!(worst_angle < 0.2, "normal off by {worst_angle:.3} rad");
    }

    #[test]
    fn the_image_border_is_not_a_contour() {
        let (w, h) = (40, 40);
        // The object covers the left half, cut by the image's left border.
        let m: Vec<bool> = (0..w * h).map(|i| i % w < 20).collect();
        let pts = extract_contour(&m, w, h, 1);
        assert!(!pts.is_empty());
        assert!(pts.iter().all(|p| p.pixel[0] == 19), "{pts:?}");
        // Away from the corners, the normal is +x and the edge lies half-way
        // between the last covered pixel and the first empty one.
        let inner: Vec<_> = pts
            .iter()
            .filter(|p| p.pixel[1] > 5 && p.pixel[1] < 34)
            .collect();
        assert!(!inner.is_empty());
        assert!(
            inner
                .iter()
                .all(|p| (p.normal - Vector2::new(1.0, 0.0)).norm() < 1e-9)
        );
        assert!(inner.iter().all(|p| (p.position.x - 19.5).abs() < 1e-9));
    }

    #[test]
    fn colours_are_not_learnt_near_the_outline() {
        // Object red on the left half, background blue, and a mixed purple
        // column on the boundary that belongs to neither.
        let (w, h) = (20u32, 10u32);
        let frame = image::RgbImage::from_fn(w, h, |x, _| match x {
            0..=9 => image::Rgb([250, 10, 10]),
            10 => image::Rgb([130, 10, 130]),
            _ => image::Rgb([10, 10, 250]),
        });
        let coverage: Vec<bool> = (0..w * h).map(|i| i % w <= 10).collect();
        let rect = (0, 0, w as usize - 1, h as usize - 1);
        let mut near = ColourModel::new(8);
        near.learn(&frame, &coverage, rect, 0, 1.0);
        assert!(near.foreground_probability([130, 10, 130]) > 0.9);
        let mut away = ColourModel::new(8);
        away.learn(&frame, &coverage, rect, 2, 1.0);
        assert_eq!(away.foreground_probability([130, 10, 130]), 0.5);
        assert!(away.foreground_probability([250, 10, 10]) > 0.9);
        assert!(away.foreground_probability([10, 10, 250]) < 0.1);
    }

    /// A frame whose object is the half-plane `n . (p - p0) < 0`, each pixel
    /// the area average of the object's and the background's colours (as a
    /// camera integrates them), plus noise; and its coverage at the pixel
    /// centres.
    fn half_plane(
        n: Vector2<f64>,
        p0: Vector2<f64>,
        rng: &mut crate::rng::Rng,
    ) -> (image::RgbImage, Vec<bool>) {
        half_plane_shaded(n, p0, 0.0, rng)
    }

    /// [`half_plane`] with the object's colour darkened towards its edge,
    /// as a limb is: by `darken` at the edge, `darken / e` a pixel inside.
    fn half_plane_shaded(
        n: Vector2<f64>,
        p0: Vector2<f64>,
        darken: f64,
        rng: &mut crate::rng::Rng,
    ) -> (image::RgbImage, Vec<bool>) {
        let (w, h) = (64u32, 64u32);
        let (fg, bg) = ([200.0, 160.0, 40.0], [60.0, 40.0, 120.0]);
        let depth = |x: f64, y: f64| -n.dot(&(Vector2::new(x, y) - p0));
        let inside = |x: f64, y: f64| depth(x, y) > 0.0;
        let mut frame = image::RgbImage::new(w, h);
        for (x, y, px) in frame.enumerate_pixels_mut() {
            let s = 16;
            let mut sum = [0.0; 3];
            for i in 0..s {
                for j in 0..s {
                    let u = x as f64 - 0.5 + (i as f64 + 0.5) / s as f64;
                    let v = y as f64 - 0.5 + (j as f64 + 0.5) / s as f64;
                    let d = depth(u, v);
                    for k in 0..3 {
                        sum[k] += if d > 0.0 {
                            fg[k] * (1.0 - darken * (-d).exp())
                        } else {
                            bg[k]
                        };
                    }
                }
            }
            let mut c =
                |k: usize| (sum[k] / (s * s) as f64 + 2.0 * rng.normal()).clamp(0.0, 255.0) as u8;
            *px = image::Rgb([c(0), c(1), c(2)]);
        }
        let coverage = (0..w * h)
            .map(|i| inside((i % w) as f64, (i / w) as f64))
            .collect();
        (frame, coverage)
    }

    /// Straight edges at random angles and sub-pixel places (darkened by
    /// `darken` towards the edge, [`half_plane_shaded`]), searched from a
    /// point a known distance off: every offset found is within `most` px
    /// of that distance; returns their rms error.
    fn edge_search_rms(seed: u64, darken: f64, most: f64) -> f64 {
        let mut rng = crate::rng::Rng::new(seed);
        let mut sq = 0.0;
        let trials = 40;
        for _ in 0..trials {
            let a = rng.uniform(0.0, std::f64::consts::TAU);
            let n = Vector2::new(a.cos(), a.sin());
            let p0 = Vector2::new(rng.uniform(30.0, 34.0), rng.uniform(30.0, 34.0));
            let (frame, coverage) = half_plane_shaded(n, p0, darken, &mut rng);
            let mut colours = ColourModel::new(16);
            colours.learn(&frame, &coverage, (0, 0, 63, 63), 2, 1.0);
            let off = rng.uniform(-2.0, 2.0);
            let d = search_line(&frame, &colours, p0 - n * off, n, 8.0, 1.0).unwrap();
            let err = d - off;
            assert!(
                err.abs() < most,
                "angle {a:.2}, offset {off:.2}: found {d:.3}"
            );
            sq += err * err;
        }
        (sq / trials as f64).sqrt()
    }

    /// [`search_line`]'s model in its plainest arithmetic: each
    /// candidate's log-likelihood a sum of one logarithm per sample (the
    /// step taken as 0 or 1 beyond 4 slopes, as there), the probabilities
    /// from [`ColourModel::foreground_probability`], fresh buffers.
    fn search_line_reference(
        frame: &image::RgbImage,
        colours: &ColourModel,
        position: Vector2<f64>,
        normal: Vector2<f64>,
        half_len: f32,
        slope: f32,
    ) -> Option<f64> {
        let l = half_len.round().max(2.0) as i64;
        let mut pf = Vec::new();
        for k in -l..=l {
            let p = position + normal * k as f64;
            let c = crate::geometry::sample_bilinear_rgb(frame, p.x as f32, p.y as f32)?;
            pf.push(colours.foreground_probability(c.0) as f64);
        }
        let slope = slope as f64;
        let reach = (4.0 * slope).ceil();
        let loglik = |d: f64| {
            let mut v = 0.0;
            for (i, p) in pf.iter().enumerate() {
                let o = (i as i64 - l) as f64;
                v += if o < d - reach {
                    p.ln()
                } else if o > d + reach {
                    (1.0 - p).ln()
                } else {
                    let hf = 0.5 * (1.0 - ((o - d) / slope).tanh());
                    (hf * p + (1.0 - hf) * (1.0 - p)).ln()
                };
            }
            v
        };
        let candidates: Vec<f64> = (-(2 * l - 2)..=(2 * l - 2))
            .map(|h| h as f64 * 0.5)
            .collect();
        let ll: Vec<f64> = candidates.iter().map(|&d| loglik(d)).collect();
        let (k, best) = ll
            .iter()
            .copied()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))?;
        let w: Vec<f64> = ll.iter().map(|v| (v - best).exp()).collect();
        let sw: f64 = w.iter().sum();
        let mean = w.iter().zip(&candidates).map(|(w, d)| w * d).sum::<f64>() / sw;
        let var = w
            .iter()
            .zip(&candidates)
            .map(|(w, d)| w * (d - mean).powi(2))
            .sum::<f64>()
            / sw;
        if var.sqrt() > (0.15 * l as f64).max(1.5) || k == 0 || k + 1 == ll.len() {
            return None;
        }
        let fine: Vec<f64> = (-12..=12)
            .map(|q| candidates[k] + q as f64 * 0.125)
            .filter(|d| d.abs() <= (l - 1) as f64)
            .collect();
        let fl: Vec<f64> = fine.iter().map(|&d| loglik(d)).collect();
        let top = fl.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let w: Vec<f64> = fl.iter().map(|v| (v - top).exp()).collect();
        let d0 = w.iter().zip(&fine).map(|(w, d)| w * d).sum::<f64>() / w.iter().sum::<f64>();
        Some(mixed_boundary(frame, position, normal, &pf, l, d0).unwrap_or(d0))
    }

    #[test]
    fn the_line_search_is_its_plainest_arithmetic() {
        // Edges at random angles, places and shading; lines of every
        // length the contour uses (long ones cross the image's border and
        // find nothing), from random points near the edge and far from
        // it, with slopes of 0.5 to 2 px; one thread's buffers shared by
        // them all, as in the tracker. The fast search keeps the same
        // arithmetic except the order of its sums (a product per
        // candidate, prefix sums, a tabulated step): equal to 1e-9 px.
        let mut rng = crate::rng::Rng::new(41);
        let (mut found, mut none) = (0, 0);
        for _ in 0..24 {
            let a = rng.uniform(0.0, std::f64::consts::TAU);
            let n = Vector2::new(a.cos(), a.sin());
            let p0 = Vector2::new(rng.uniform(28.0, 36.0), rng.uniform(28.0, 36.0));
            let (frame, coverage) = half_plane_shaded(n, p0, rng.uniform(0.0, 0.5), &mut rng);
            let mut colours = ColourModel::new(16);
            colours.learn(&frame, &coverage, (0, 0, 63, 63), 2, 1.0);
            for _ in 0..12 {
                let half = [5.0f32, 8.0, 10.0, 16.0, 32.0][rng.below(5) as usize];
                let slope = [0.5f32, 1.0, 2.0][rng.below(3) as usize];
                let off = rng.uniform(-12.0, 12.0);
                let turn = rng.uniform(-0.3, 0.3);
                let dir = Vector2::new(
                    n.x * turn.cos() - n.y * turn.sin(),
                    n.x * turn.sin() + n.y * turn.cos(),
                );
                let at = p0 - n * off;
                let fast = search_line(&frame, &colours, at, dir, half, slope);
                let plain = search_line_reference(&frame, &colours, at, dir, half, slope);
                match (fast, plain) {
                    (Some(f), Some(p)) => {
                        assert!(
                            (f - p).abs() < 1e-9,
                            "half {half}, slope {slope}: {f} vs {p}"
                        );
                        found += 1;
                    }
                    (None, None) => none += 1,
                    other => panic!("half {half}, slope {slope}, offset {off:.2}: {other:?}"),
                }
            }
        }
        assert!(found > 150 && none > 20, "found {found}, none {none}");
    }

    #[test]
    fn turn_of_is_the_direction_within_its_bound() {
        for (d, want) in [
            ((1.0, 0.0), 0.0),
            ((0.0, 1.0), 0.25),
            ((-1.0, 0.0), 0.5),
            ((0.0, -1.0), 0.75),
            ((1.0, 1.0), 0.125),
            ((-2.0, -2.0), 0.625),
            ((0.0, 0.0), 0.0),
            ((f64::NAN, 1.0), 0.0),
            ((f64::INFINITY, f64::NEG_INFINITY), 0.0),
        ] {
            assert!(
                (turn_of(Vector2::new(d.0, d.1)) - want).abs() < 1e-12,
                "{d:?}"
            );
        }
        let mut rng = crate::rng::Rng::new(3);
        let mut worst = 0.0f64;
        for _ in 0..100_000 {
            let d = Vector2::new(rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0));
            let t = turn_of(d);
            assert!((0.0..1.0).contains(&t), "{d:?}: {t}");
            let exact = (d.y.atan2(d.x) / std::f64::consts::TAU).rem_euclid(1.0);
            // The distance on the circle of turns.
            let e = (t - exact).abs();
            worst = worst.max(e.min(1.0 - e));
        }
        assert!(worst < 7e-4, "worst {worst} turns");
    }

    /// An object whose halves swap colours with the background behind
    /// them: yellow on the left against orange, orange on the right
    /// against yellow (a disc of radius 40 at (64.3, 63.7) in 128x128).
    fn swapped_halves(rng: &mut crate::rng::Rng) -> (image::RgbImage, Vec<bool>, Vector2<f64>) {
        let (w, h) = (128u32, 128u32);
        let c = Vector2::new(64.3, 63.7);
        let (yellow, orange) = ([220.0, 200.0, 40.0], [230.0, 120.0, 60.0]);
        let mut frame = image::RgbImage::new(w, h);
        let mut coverage = vec![false; (w * h) as usize];
        for (x, y, px) in frame.enumerate_pixels_mut() {
            let p = Vector2::new(x as f64, y as f64);
            let left = p.x < c.x;
            // The disc's share of the pixel, from 4x4 samples.
            let mut a = 0.0;
            for i in 0..4 {
                for j in 0..4 {
                    let q = p + Vector2::new((i as f64 - 1.5) / 4.0, (j as f64 - 1.5) / 4.0);
                    a += f64::from(u8::from((q - c).norm() < 40.0)) / 16.0;
                }
            }
            let (fg, bg) = if left {
                (yellow, orange)
            } else {
                (orange, yellow)
            };
            let mut v = [0u8; 3];
            for k in 0..3 {
                v[k] = (a * fg[k] + (1.0 - a) * bg[k] + 2.0 * rng.normal()).clamp(0.0, 255.0) as u8;
            }
            *px = image::Rgb(v);
            coverage[(y * w + x) as usize] = (p - c).norm() < 40.0;
        }
        (frame, coverage, c)
    }

    /// [`ColourModel::learn_around`] as first written: pixel by pixel,
    /// each count added to its bins in memory, [`turn_of`] per pixel.
    fn learn_around_reference(
        m: &mut ColourModel,
        frame: &image::RgbImage,
        coverage: &[bool],
        rect: (usize, usize, usize, usize),
        margin: usize,
        rate: f32,
        centre: Option<Vector2<f64>>,
    ) {
        let (w, h) = (frame.width() as usize, frame.height() as usize);
        let nbins = m.global.foreground.len();
        let ns = if centre.is_some() { m.sectors.len() } else { 0 };
        let (mut fg, mut bg) = (vec![0f32; nbins], vec![0f32; nbins]);
        let (mut sfg, mut sbg) = (vec![0f32; nbins * ns], vec![0f32; nbins * ns]);
        let (x0, y0) = (rect.0.min(w - 1), rect.1.min(h - 1));
        let (x1, y1) = (rect.2.min(w - 1).max(x0), rect.3.min(h - 1).max(y0));
        let centre = centre.unwrap_or_default();
        for y in y0..=y1 {
            for x in x0..=x1 {
                let covered = coverage[y * w + x];
                let (a, b) = (x.saturating_sub(margin), y.saturating_sub(margin));
                let (c, d) = ((x + margin).min(w - 1), (y + margin).min(h - 1));
                let mixed = (b..=d).any(|v| (a..=c).any(|u| coverage[v * w + u] != covered));
                if mixed {
                    continue;
                }
                let bin = m.bin(frame.get_pixel(x as u32, y as u32).0);
                let (side, sides) = if covered {
                    (&mut fg, &mut sfg)
                } else {
                    (&mut bg, &mut sbg)
                };
                side[bin] += 1.0;
                if ns > 0 {
                    let t = turn_of(Vector2::new(x as f64, y as f64) - centre) * ns as f64;
                    let k = (t as usize).min(ns - 1);
                    let f = (t - k as f64) as f32;
                    sides[k * nbins + bin] += 1.0 - f;
                    sides[(k + 1) % ns * nbins + bin] += f;
                }
            }
        }
        m.global.blend(&fg, &bg, 1.0, rate);
        for (k, hist) in m.sectors.iter_mut().enumerate().take(ns) {
            let r = k * nbins..(k + 1) * nbins;
            hist.blend(&sfg[r.clone()], &sbg[r], SECTOR_LEAST_PX, rate);
        }
    }

    #[test]
    fn learning_gives_the_pixel_by_pixel_sums_bit_for_bit() {
        // learn_around sums a run of pixels in the same bins in registers
        // and takes a row's directions at once (turns_of_row): the
        // histograms must be those of the plain loop exactly. Frames of
        // blocks of one colour (long runs) and of noise (short ones), blobs of
        // coverage, rectangles cut by the frame's edges, margins 0-3,
        // 0, 1, 2 and 8 sectors, centres inside and outside the frame
        // (and on a pixel: a zero direction), a second frame blended in.
        let mut rng = crate::rng::Rng::new(21);
        for case in 0..60 {
            let (w, h) = (8 + rng.below(90) as u32, 8 + rng.below(70) as u32);
            // Blocks of one colour (runs up to 12 pixels long), or noise.
            let blocks = case % 2 == 0;
            let frame = |rng: &mut crate::rng::Rng| {
                let palette: Vec<[u8; 3]> = (0..4)
                    .map(|_| [0; 3].map(|_| rng.below(256) as u8))
                    .collect();
                let mut f = image::RgbImage::new(w, h);
                for (x, y, px) in f.enumerate_pixels_mut() {
                    let v = if blocks {
                        palette[((x / 12 + y / 3) % 4) as usize]
                    } else {
                        [0; 3].map(|_| rng.below(256) as u8)
                    };
                    *px = image::Rgb(v);
                }
                f
            };
            let blobs: Vec<(f64, f64, f64)> = (0..3)
                .map(|_| {
                    let r = rng.uniform(2.0, 20.0);
                    (rng.uniform(0.0, w as f64), rng.uniform(0.0, h as f64), r)
                })
                .collect();
            let coverage: Vec<bool> = (0..(w * h) as usize)
                .map(|i| {
                    let (x, y) = ((i % w as usize) as f64, (i / w as usize) as f64);
                    blobs.iter().any(|(cx, cy, r)| (x - cx).hypot(y - cy) < *r)
                })
                .collect();
            let rect = (
                rng.below(w as u64 / 2) as usize,
                rng.below(h as u64 / 2) as usize,
                (w as u64 / 2 + rng.below(w as u64)) as usize,
                (h as u64 / 2 + rng.below(h as u64)) as usize,
            );
            let margin = rng.below(4) as usize;
            let sectors = [0, 1, 2, 8][case % 4];
            let centre = match case % 3 {
                0 => Some(Vector2::new(
                    rng.uniform(0.0, w as f64),
                    rng.uniform(0.0, h as f64),
                )),
                1 => Some(Vector2::new(
                    rng.below(w as u64) as f64,
                    rng.below(h as u64) as f64,
                )),
                _ => Some(Vector2::new(
                    rng.uniform(-200.0, 300.0),
                    rng.uniform(-200.0, 300.0),
                )),
            };
            let centre = if case % 5 == 4 { None } else { centre };
            let mut fast = ColourModel::with_sectors(4 + (case % 3) as u32 * 6, sectors);
            let mut plain = fast.clone();
            for rate in [1.0, 0.3] {
                let f = frame(&mut rng);
                fast.learn_around(&f, &coverage, rect, margin, rate, centre);
                learn_around_reference(&mut plain, &f, &coverage, rect, margin, rate, centre);
                assert!(
                    fast.global == plain.global && fast.sectors == plain.sectors,
                    "case {case}: {w}x{h}, rect {rect:?}, margin {margin}, {sectors} sectors, \
                     centre {centre:?}, rate {rate}"
                );
            }
        }
    }

    #[test]
    fn turns_of_a_row_are_turn_of_bit_for_bit() {
        let mut rng = crate::rng::Rng::new(22);
        let mut out = vec![0.0; 64];
        let rows = [0.0, -0.0, 3.0, -7.5, 1e-300, f64::NAN, f64::INFINITY];
        let randoms: Vec<f64> = (0..200).map(|_| rng.uniform(-300.0, 300.0)).collect();
        for (i, dy) in rows.into_iter().chain(randoms).enumerate() {
            let x0 = rng.below(400) as i32 - 200;
            let cx = match i % 4 {
                0 => rng.uniform(-300.0, 300.0),
                1 => (x0 + 10) as f64,
                2 => f64::NAN,
                _ => x0 as f64 + 0.5,
            };
            turns_of_row(x0, cx, dy, &mut out);
            for (k, t) in out.iter().enumerate() {
                let want = turn_of(Vector2::new((x0 + k as i32) as f64 - cx, dy));
                assert_eq!(
                    t.to_bits(),
                    want.to_bits(),
                    "x0 {x0}, cx {cx}, dy {dy}, k {k}"
                );
            }
        }
    }

    #[test]
    fn sectors_weigh_each_side_against_its_own_background() {
        let mut rng = crate::rng::Rng::new(12);
        let (frame, coverage, c) = swapped_halves(&mut rng);
        let rect = (0, 0, 127, 127);
        let mut global = ColourModel::new(16);
        global.learn(&frame, &coverage, rect, 2, 1.0);
        let mut sectors = ColourModel::with_sectors(16, 8);
        sectors.learn_around(&frame, &coverage, rect, 2, 1.0, Some(c));
        assert!((0..8).all(|k| sectors.sector_learned(k)));
        // Lines within 40 degrees of the horizontal, left and right, from
        // up to 3 px off the outline: with sectors every one finds it to
        // within its pixel; with one pair of histograms (both colours are
        // object and background alike) none does.
        let (mut found, mut global_found) = (0, 0);
        for i in 0..40 {
            let side = if i % 2 == 0 {
                0.0
            } else {
                std::f64::consts::PI
            };
            let a = side + rng.uniform(-0.7, 0.7);
            let n = Vector2::new(a.cos(), a.sin());
            let off = rng.uniform(-3.0, 3.0);
            let at = c + n * (40.0 - off);
            let d = search_line_toward(&frame, &sectors, n, at, n, 8.0, 1.0)
                .unwrap_or_else(|| panic!("angle {a:.2}: no boundary"));
            assert!(
                (d - off).abs() < 0.5,
                "angle {a:.2}: {d:.3} against {off:.3}"
            );
            found += 1;
            if let Some(d) = search_line(&frame, &global, at, n, 8.0, 1.0)
                && (d - off).abs() < 1.0
            {
                global_found += 1;
            }
        }
        assert_eq!(found, 40);
        assert!(
            global_found <= 4,
            "one pair of histograms found {global_found} of 40"
        );
        // Without sectors, or before a sector learns, a line uses the
        // whole object's histograms.
        assert!(std::ptr::eq(
            global.histograms_toward(Vector2::x()),
            global.global()
        ));
        let fresh = ColourModel::with_sectors(16, 8);
        assert!(std::ptr::eq(
            fresh.histograms_toward(Vector2::x()),
            fresh.global()
        ));
        // Each direction's nearest sector: 8 sectors centred every 45
        // degrees from +x towards +y.
        assert_eq!(sectors.sector_toward(Vector2::new(1.0, 0.3)), Some(0));
        assert_eq!(sectors.sector_toward(Vector2::new(0.1, 1.0)), Some(2));
        assert_eq!(sectors.sector_toward(Vector2::new(-1.0, -0.2)), Some(4));
        assert_eq!(sectors.sector_toward(Vector2::new(1.0, -0.3)), Some(0));
        assert_eq!(global.sector_toward(Vector2::x()), None);
    }

    #[test]
    fn a_sector_with_too_few_pixels_keeps_to_the_whole_objects_histograms() {
        // The object's centre far to the left of the window: every pixel
        // lies towards +x, so the sectors facing away see nothing.
        let mut rng = crate::rng::Rng::new(5);
        let (frame, coverage, _) = swapped_halves(&mut rng);
        let mut m = ColourModel::with_sectors(16, 8);
        m.learn_around(
            &frame,
            &coverage,
            (0, 0, 127, 127),
            2,
            1.0,
            Some(Vector2::new(-1e4, 63.7)),
        );
        assert!(m.is_learned());
        assert!(m.sector_learned(0));
        assert!(!m.sector_learned(4));
        assert!(std::ptr::eq(m.histograms_toward(-Vector2::x()), m.global()));
        // `learn` leaves the sectors alone.
        let mut g = ColourModel::with_sectors(16, 8);
        g.learn(&frame, &coverage, (0, 0, 127, 127), 2, 1.0);
        assert!(g.is_learned() && (0..8).all(|k| !g.sector_learned(k)));
    }

    #[test]
    fn the_boundary_is_found_within_its_pixel() {
        // Without the mixed colours (the posterior alone) the errors reach
        // a quarter of a pixel.
        let rms = edge_search_rms(5, 0.0, 0.1);
        assert!(rms < 0.05, "rms {rms:.3} px");
    }

    #[test]
    fn a_limb_darkening_towards_the_edge_does_not_pull_the_boundary_in() {
        // The object's side darkens towards its outline (half as bright at
        // the edge, as the synthetic `plain` object's limbs are under its
        // light): its shade is not a share of the background. Placed on
        // the segment between the two colours, as before, the darker
        // mixed samples read as background (the first of these edges was
        // found 0.30 px inside the true one).
        let rms = edge_search_rms(7, 0.5, 0.12);
        assert!(rms < 0.06, "rms {rms:.3} px");
    }

    #[test]
    fn lines_searched_on_several_cores_give_one_threads_rows_in_order() {
        let mut rng = crate::rng::Rng::new(9);
        let n = Vector2::new(0.6, 0.8);
        let (frame, coverage) = half_plane(n, Vector2::new(32.0, 32.0), &mut rng);
        let mut colours = ColourModel::new(16);
        colours.learn(&frame, &coverage, (0, 0, 63, 63), 2, 1.0);
        let cam = crate::geometry::Intrinsics::new(64, 64, 60.0, 60.0, 31.5, 31.5);
        // 150 lines across the edge, some off the image (no row).
        let found: Vec<Lifted> = (0..150)
            .map(|i| {
                let t = i as f64 * 0.6 - 45.0;
                let pos = Vector2::new(32.0, 32.0) + Vector2::new(-n.y, n.x) * t
                    - n * rng.uniform(-2.0, 2.0);
                let xc = cam.unproject(&pos, 1.0);
                Lifted {
                    point: ContourPoint {
                        pixel: [pos.x.max(0.0) as u32, pos.y.max(0.0) as u32],
                        position: pos,
                        normal: n,
                    },
                    xc,
                    row: contour_row(&cam.motion_predictors(&xc), &n, 0.0),
                }
            })
            .collect();
        let twist = Vector6::new(0.001, -0.002, 0.0, 0.0, 0.0, 0.01);
        let rows = search_lines(&frame, &colours, Vector2::zeros(), &found, &twist, 5.0, 1.0);
        let one: Vec<Observation> = found
            .iter()
            .filter_map(|l| {
                let moved = (l.row.predictors * twist)[0];
                let p = &l.point;
                search_line(
                    &frame,
                    &colours,
                    p.position + p.normal * moved,
                    p.normal,
                    5.0,
                    1.0,
                )
                .map(|d| Observation {
                    displacement: Vector2::new(moved + d, 0.0),
                    ..l.row
                })
            })
            .collect();
        assert!(
            one.len() > 64 && one.len() < found.len(),
            "{} rows",
            one.len()
        );
        assert_eq!(rows, one);
    }

    #[test]
    fn contour_row_is_the_normal_part_of_the_motion() {
        let l = Matrix2x6::from_fn(|r, c| (r * 6 + c) as f64 - 3.0);
        let n = Vector2::new(0.6, -0.8);
        let o = contour_row(&l, &n, 1.5);
        let a = nalgebra::Vector6::new(0.1, -0.2, 0.3, 0.01, 0.02, -0.03);
        let r = (o.predictors * a - o.displacement).norm();
        assert!((r - (n.dot(&(l * a)) - 1.5).abs()).abs() < 1e-12);
    }

    /// [`ModelNormals::normal_at`] as first written: every point of the
    /// 27 cells, read from the model's arrays.
    fn normal_at_reference(
        model: &crate::model::PointModel,
        grid: &ModelNormals,
        x: glam::Vec3,
        eye: glam::Vec3,
    ) -> Option<glam::Vec3> {
        let c = ((x - grid.lo) / grid.cell).floor();
        let (mut sum, mut wsum) = (glam::Vec3::ZERO, 0.0f32);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let q = c + glam::Vec3::new(dx as f32, dy as f32, dz as f32);
                    if q.min_element() < 0.0 {
                        continue;
                    }
                    let q = [q.x as usize, q.y as usize, q.z as usize];
                    if (0..3).any(|k| q[k] >= grid.dims[k]) {
                        continue;
                    }
                    let cell = [0, 1, 2].map(|k| q[k] as u32);
                    for (i, p) in model.positions.iter().enumerate() {
                        let at = ((*p - grid.lo) / grid.cell).as_uvec3();
                        let at = [0, 1, 2].map(|k| at[k].min(grid.dims[k] as u32 - 1));
                        if at != cell {
                            continue;
                        }
                        let (n, r) = (model.normals[i], model.radii[i]);
                        if n.dot(eye - *p) <= 0.0 || r.is_nan() || r <= 0.0 {
                            continue;
                        }
                        let d2 = (x - *p).length_squared() / (r * r);
                        if d2 > 4.0 {
                            continue;
                        }
                        let w = (-2.0 * d2).exp();
                        sum += n * w;
                        wsum += w;
                    }
                }
            }
        }
        (wsum > 0.0).then_some(sum)
    }

    #[test]
    fn model_normals_are_every_near_points_sum_bit_for_bit() {
        // normal_at reads its points packed in cell order and skips the
        // cells beyond their points' reach: the sums must be those over
        // every point of the 27 cells, in the model's order, exactly.
        // Radii from a tenth to four times the median (and some NaN, zero,
        // negative), queries on the surface, off it by up to a few radii
        // and across the grid's faces, eyes all round.
        let c = glam::Vec3::new(0.3, -0.1, 0.2);
        let mut model = crate::model::shapes::sphere(c, 0.5, 3_000, 1.2);
        let mut rng = crate::rng::Rng::new(23);
        for (i, r) in model.radii.iter_mut().enumerate() {
            *r = match i % 50 {
                0 => f32::NAN,
                1 => 0.0,
                2 => -0.01,
                _ => *r * rng.uniform(0.1, 4.0) as f32,
            };
        }
        let grid = ModelNormals::new(&model).unwrap();
        let median = 0.5 * grid.cell;
        let (mut some, mut none) = (0, 0);
        for _ in 0..600 {
            let u = rng.unit_vector();
            let u = glam::Vec3::new(u.x as f32, u.y as f32, u.z as f32);
            let off = rng.uniform(-4.0, 4.0) as f32 * median;
            let x = c + u * (0.5 + off);
            let e = rng.unit_vector();
            let eye = c + glam::Vec3::new(e.x as f32, e.y as f32, e.z as f32) * 3.0;
            let got = grid.normal_at(x, eye);
            let want = normal_at_reference(&model, &grid, x, eye);
            let bits = |v: Option<glam::Vec3>| v.map(|v| v.to_array().map(f32::to_bits));
            assert_eq!(bits(got), bits(want), "x {x}, eye {eye}");
            if got.is_some() {
                some += 1;
            } else {
                none += 1;
            }
        }
        assert!(some > 200 && none > 50, "{some} found, {none} not");
    }

    #[test]
    fn model_normals_are_the_sphere_radial_ones_and_only_facing_points_count() {
        let c = glam::Vec3::new(0.3, -0.1, 0.2);
        let model = crate::model::shapes::sphere(c, 0.5, 20_000, 1.2);
        let grid = ModelNormals::new(&model).unwrap();
        let mut rng = crate::rng::Rng::new(5);
        let mut worst = 0.0f32;
        for _ in 0..200 {
            let u = rng.unit_vector();
            let u = glam::Vec3::new(u.x as f32, u.y as f32, u.z as f32);
            // On the surface, or a radius's worth off it (a pushed-back
            // depth), seen from outside along any direction not behind it.
            let x = c + u * (0.5 + rng.uniform(-0.005, 0.005) as f32);
            let eye = c + u * 3.0;
            let n = grid.normal_at(x, eye).unwrap().normalize();
            worst = worst.max(n.angle_between(u));
            // Seen from the other side, every point near `x` faces away.
            assert!(grid.normal_at(x, c - u * 3.0).is_none());
        }
        assert!(worst < 0.02, "worst normal error {worst} rad");
        // Far from the model: nothing.
        assert!(
            grid.normal_at(c + glam::Vec3::X * 2.0, c + glam::Vec3::X * 3.0)
                .is_none()
        );
    }

    #[test]
    fn config_rules_name_their_field() {
        ContourConfig::default().validate().unwrap();
        let c = ContourConfig {
            search_px: vec![],
            ..Default::default()
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("contour.search_px")
        );
        for (c, field) in [
            (
                ContourConfig {
                    inset_px: f64::NAN,
                    ..Default::default()
                },
                "contour.inset_px",
            ),
            (
                ContourConfig {
                    fused_damping: -1.0,
                    ..Default::default()
                },
                "contour.fused_damping",
            ),
            (
                ContourConfig {
                    learn_margin_px: 100,
                    ..Default::default()
                },
                "contour.learn_margin_px",
            ),
            (
                ContourConfig {
                    reproject_px: f64::NAN,
                    ..Default::default()
                },
                "contour.reproject_px",
            ),
            (
                ContourConfig {
                    sectors: 65,
                    ..Default::default()
                },
                "contour.sectors",
            ),
        ] {
            assert!(c.validate().unwrap_err().to_string().contains(field));
        }
        let c = ContourConfig {
            bins: 1,
            ..Default::default()
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("contour.bins")
        );
    }
}
