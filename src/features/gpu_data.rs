//! Host twins of the structs in `shaders/harris_*.wgsl`, `shaders/ncc_*.wgsl`
//! and `shaders/pixel.wgsl` (`Pixel`), and the constants the shaders
//! share with the host. Each struct is declared with [`wgsl_struct!`](crate::wgsl_struct), and
//! the tests of [`crate::shaders`] compare it member by member with its
//! WGSL twin; each constant reaches WGSL through a shader's prelude, from
//! the tables here ([`PIXEL_CONSTANTS`], [`HARRIS_CONSTANTS`],
//! [`NCC_CONSTANTS`]), never by copy.

use crate::gpu::{GATHER_STRIDE, WORKGROUP_1D, WORKGROUP_2D};
use crate::shaders::{Constants, Part, WgslValue::F32, WgslValue::U32};
use crate::wgsl_struct;
use bytemuck::{Pod, Zeroable};

/// Number of Gaussian taps the Harris uniform holds (`HarrisParams.weights`):
/// derivative kernel (g and g', radius <= 7) then integration kernel
/// (radius <= 14): 2 x 15 + 29 = 59 <= 64.
pub const MAX_TAPS: usize = 64;
pub const MAX_DERIV_RADIUS: usize = 7;
pub const MAX_INTEGRATION_RADIUS: usize = 14;
/// Outputs one invocation of a Harris filter pass computes along the
/// filter's direction, from one window of `HARRIS_BLOCK + 2 r` pixels it
/// loads once: (8 + 2r) / 8 loads an output instead of 2r + 1. On lavapipe,
/// where every load of a storage buffer is a gather, this took the four
/// filter passes of a 640x480 image from 205 to 89 ms (each pass timed
/// alone) and a whole detection from 221 to 115 ms (docs/performance.md).
pub const HARRIS_BLOCK: u32 = 8;
/// The most rows (rd + ri) above and below a tile of the fused filter
/// pass (`maps_fused` in shaders/harris_maps.wgsl) reads: the default sigmas
/// (1.0, 1.5) need 3 + 5. Larger radii run the four passes.
pub const FUSED_HALO: u32 = 8;
/// Workgroup memory of the fused filter pass: six lines of
/// (`WORKGROUP_2D` + 2 [`FUSED_HALO`])^2 f32 and an atomic.
pub const FUSED_BYTES: u32 = 6 * (crate::gpu::WORKGROUP_2D + 2 * FUSED_HALO).pow(2) * 4 + 4;
/// The most candidates Harris selects among on the GPU
/// (`shaders/harris_select.wgsl`): its passes compare every
/// pair (at most 2^26 comparisons a pass). A detection with more (a
/// noisy image) reads its candidates back and selects on the host.
pub const SELECT_MAX: u32 = 8192;
/// [`SELECT_MAX`] on CPU adapters: there every comparison's loads are
/// gathers, and 4831 candidates took 0.4 s to select on lavapipe (a
/// 640x480 noise image), the host's selection a millisecond. The
/// tracker's few hundred candidates a window stay on the GPU.
pub const SELECT_MAX_CPU: u32 = 1024;
/// The earlier close corners the merge keeps per corner (more: it rescans
/// them).
pub const MERGE_LINKS: u32 = 8;
/// The merge's parallel rounds (`merge_round`), enough for chains of close
/// corners up to this long; the host finishes longer ones.
pub const MERGE_ROUNDS: usize = 3;

/// Pixel flags (`Pixel.flags`): the value is finite and usable...
pub const PIXEL_VALID: u32 = 1;
/// ...and a corner may be reported here (inside the mask).
pub const PIXEL_ALLOWED: u32 = 2;

/// Response of a pixel whose support leaves the image or touches an
/// invalid pixel.
pub const INVALID_RESPONSE: f32 = -3.0e38;

/// Score of a pair that cannot match (invalid window or out of the search
/// radius); below any NCC.
pub const NO_SCORE: f32 = -2.0;

/// `Best.index` when a row or column has no entry.
pub const NO_INDEX: u32 = u32::MAX;

wgsl_struct! {
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    pub struct Pixel {
        pub value: f32,
        pub flags: u32,
    }
}

/// ...or, for an invalid pixel, it is a pinhole: the odd empty pixel of a
/// splatted view, which Harris and NCC tolerate (see [`pinholes`]).
pub const PIXEL_HOLE: u32 = 4;

/// Valid 8-neighbours an invalid pixel needs to count as a pinhole: one or
/// two empty pixels inside a surface have 7 or 8; the empty pixels around
/// an object, along its outline, have at most 5 (3 along a straight edge),
/// and stay hard invalid, so that windows across the outline stay void as
/// before.
pub const PINHOLE_NEIGHBOURS: usize = 6;

/// Per pixel of `img`: invalid (NaN) and a pinhole (at least
/// [`PINHOLE_NEIGHBOURS`] of its 8 neighbours valid, not on the image
/// border).
pub fn pinholes(img: &crate::features::GreyImage) -> Vec<bool> {
    (0..img.data.len()).map(|i| is_pinhole(img, i)).collect()
}

/// Whether pixel `i` of `img` is a pinhole ([`pinholes`]).
fn is_pinhole(img: &crate::features::GreyImage, i: usize) -> bool {
    pinhole_at(img, i % img.width, i / img.width)
}

/// Whether pixel (x, y) of `img` is a pinhole ([`pinholes`]): it stops
/// at the first neighbour too many that is invalid (inside an empty
/// region, after three).
fn pinhole_at(img: &crate::features::GreyImage, x: usize, y: usize) -> bool {
    let (w, h) = (img.width, img.height);
    if img.data[y * w + x].is_finite() || x == 0 || y == 0 || x + 1 >= w || y + 1 >= h {
        return false;
    }
    let mut invalid = 0;
    for (dx, dy) in [
        (0, 0),
        (1, 0),
        (2, 0),
        (0, 1),
        (2, 1),
        (0, 2),
        (1, 2),
        (2, 2),
    ] {
        if !img.data[(y + dy - 1) * w + x + dx - 1].is_finite() {
            invalid += 1;
            if invalid > 8 - PINHOLE_NEIGHBOURS {
                return false;
            }
        }
    }
    true
}

/// The pixels of `img` as the kernels read them ([`Pixel::new`]), with
/// [`PIXEL_HOLE`] set on its pinholes; [`PIXEL_ALLOWED`] where `allow` and
/// `mask` (all pixels when `None`) say so.
pub fn pack_with_holes(
    img: &crate::features::GreyImage,
    mask: Option<&[bool]>,
    allow: bool,
) -> Vec<Pixel> {
    let mut out = Vec::new();
    pack_with_holes_into(img, mask, allow, &mut out);
    out
}

/// [`pack_with_holes`] into `out` (cleared first; its allocation reused,
/// so a per-frame caller allocates nothing once it has grown).
pub fn pack_with_holes_into(
    img: &crate::features::GreyImage,
    mask: Option<&[bool]>,
    allow: bool,
    out: &mut Vec<Pixel>,
) {
    out.clear();
    out.reserve(img.data.len());
    let w = img.width.max(1);
    for (y, row) in img.data.chunks(w).enumerate() {
        for (x, &v) in row.iter().enumerate() {
            let mut p = Pixel::new(v, allow && mask.is_none_or(|m| m[y * w + x]));
            if !v.is_finite() && pinhole_at(img, x, y) {
                p.flags |= PIXEL_HOLE;
            }
            out.push(p);
        }
    }
}

impl Pixel {
    /// A grey value as the kernels read it: a non-finite (invalid) value
    /// becomes 0 with [`PIXEL_VALID`] cleared; `allowed` sets
    /// [`PIXEL_ALLOWED`].
    pub fn new(value: f32, allowed: bool) -> Self {
        let valid = value.is_finite();
        Self {
            value: if valid { value } else { 0.0 },
            flags: if valid { PIXEL_VALID } else { 0 } | if allowed { PIXEL_ALLOWED } else { 0 },
        }
    }
}

wgsl_struct! {
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    pub struct HarrisParams {
        pub width: u32,
        pub height: u32,
        pub rd: u32,
        pub ri: u32,
        pub k: f32,
        pub rel_threshold: f32,
        pub min_response: f32,
        pub capacity: u32,
        pub refine_radius: u32,
        pub refine_iterations: u32,
        pub refine_inv_2s2: f32,
        pub n_corners: u32,
        pub max_shift: f32,
        /// Smallest valid fraction of the structure tensor's Gaussian
        /// weight ([`super::HarrisConfig::min_valid_weight`]).
        pub min_weight: f32,
        /// [`super::HarrisConfig::max_corners`] (the selection on the GPU).
        pub max_corners: u32,
        /// [`super::HarrisConfig::grid_cell`].
        pub grid_cell: u32,
        /// [`super::HarrisConfig::merge_radius`], squared.
        pub merge_r2: f32,
        /// 1: [`super::HarrisConfig::refine`].
        pub refine: u32,
        /// The most candidates the GPU selects among
        /// ([`super::HarrisGpuOptions::select_limit`]).
        pub select_limit: u32,
        pub _pad2: u32,
        /// g_d[0..2rd+1], g'_d[0..2rd+1], g_i[0..2ri+1], packed by fours.
        pub weights: [[f32; 4]; MAX_TAPS / 4],
    }
}

wgsl_struct! {
    /// A local maximum of the response, as the NMS kernel writes it.
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    pub struct Candidate {
        pub x: u32,
        pub y: u32,
        pub score: f32,
        pub _pad: u32,
    }
}

wgsl_struct! {
    /// Corner counters: the response maximum (f32 bits, positive responses
    /// only, so integer order is float order), the candidate count, the
    /// corners the selection on the GPU kept and those its merge left
    /// undecided.
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    pub struct Counters {
        pub max_bits: u32,
        pub count: u32,
        pub selected: u32,
        pub undecided: u32,
    }
}

wgsl_struct! {
    /// A corner being refined: position, score, status (1 = refined, 0 = kept
    /// at its start because the refinement was ill-posed or ran away).
    #[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
    pub struct RefineCorner {
        pub x: f32,
        pub y: f32,
        pub score: f32,
        pub status: f32,
    }
}

wgsl_struct! {
    /// Where [`crate::features::Harris::export_corners`] puts a
    /// detection's corners ([`crate::features::ExportPlace`]): moved by
    /// the origin, kept where inside the clip rectangle (`clip` 1), less
    /// the first row of NCC's band in y, from slot `first` of NCC's
    /// positions on; `n` slots written.
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    pub struct ExportParams {
        pub origin_x: f32,
        pub origin_y: f32,
        pub band_y0: f32,
        pub n: u32,
        pub first: u32,
        pub clip: u32,
        pub _pad0: u32,
        pub _pad1: u32,
        pub clip_x0: f32,
        pub clip_y0: f32,
        pub clip_x1: f32,
        pub clip_y1: f32,
    }
}

wgsl_struct! {
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    pub struct NccParams {
        pub na: u32,
        pub nb: u32,
        /// Row stride of the descriptor buffer: w² rounded up to the tile size.
        pub stride: u32,
        pub window: u32,
        pub wa: u32,
        pub ha: u32,
        pub wb: u32,
        pub hb: u32,
        /// Pixel offset of image B in the pixel buffer (= wa * ha).
        pub offset_b: u32,
        /// Squared search radius in pixels; negative: no limit.
        pub radius2: f32,
        pub min_std: f32,
        /// Smallest fraction of a window's samples that must be valid
        /// ([`super::NccConfig::min_valid`]).
        pub min_valid: f32,
        /// Mutual bests below this are no match (`mutual_refine`).
        pub min_score: f32,
        /// 1: `mutual_refine` refines B's point (features::refine_match).
        pub refine_on: u32,
        /// Half the side of the refinement's windows.
        pub refine_half: u32,
        /// The refinement's integer search, pixels.
        pub max_shift: u32,
        /// The refinement's least peak score.
        pub refine_min: f32,
        /// Where B's pixel (0, 0) lies in A's pixels (an integer shift),
        /// for the search radius.
        pub shift_bx: f32,
        pub shift_by: f32,
        /// 1: B's features are in their own order (no spatial order uploaded).
        pub b_in_order: u32,
    }
}

wgsl_struct! {
    /// A feature of A's mutual match as `mutual_refine` writes it: `b`
    /// ([`NO_INDEX`]: none), the NCC score, B's point (refined when
    /// `refined` is 1, with its peak score).
    #[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
    pub struct MatchOut {
        pub b: u32,
        pub score: f32,
        pub x: f32,
        pub y: f32,
        pub peak: f32,
        pub refined: u32,
    }
}

/// The largest Harris refinement radius `select_refine_group` (a
/// workgroup a corner) holds a window's terms of in workgroup memory; with
/// a larger one the corners are refined a thread each (`select_refine`).
pub const REFINE_GROUP_RADIUS: u32 = 10;

/// The largest refinement window (odd, in pixels a side) whose samples
/// `mutual_refine` holds in workgroup memory; wider ones run
/// `mutual_refine_wide`, which samples the images for every score.
pub const REFINE_LOCAL_WINDOW: u32 = 21;

/// The largest NCC window (pixels a side) whose samples `vectorize_group`
/// (a workgroup a window) holds in workgroup memory; wider ones run
/// `vectorize`, a thread a window.
pub const VECTORIZE_GROUP_WINDOW: u32 = 31;

/// Tile edge (and workgroup size) of the score kernels; descriptor rows are
/// padded with zeros to a multiple of it.
pub const NCC_TILE: u32 = 16;

wgsl_struct! {
    /// Best entry of a score row or column.
    #[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
    pub struct Best {
        pub index: u32,
        pub score: f32,
    }
}

/// The grey pixel of the feature kernels (`Pixel` and its flag tests),
/// composed first into each of them; its constants: [`PIXEL_CONSTANTS`].
pub(crate) const PIXEL_WGSL: Part = crate::wgsl_file!("pixel.wgsl");

/// The pixel flags (shaders/pixel.wgsl and the kernels that read pixels).
pub(crate) const PIXEL_CONSTANTS: Constants = &[
    ("PIXEL_VALID", U32(PIXEL_VALID)),
    ("PIXEL_ALLOWED", U32(PIXEL_ALLOWED)),
    ("PIXEL_HOLE", U32(PIXEL_HOLE)),
];

/// The constants of the Harris shader (shaders/harris_*.wgsl).
pub(crate) const HARRIS_CONSTANTS: Constants = &[
    ("WORKGROUP_1D", U32(WORKGROUP_1D)),
    ("WORKGROUP_2D", U32(WORKGROUP_2D)),
    ("PINHOLE_NEIGHBOURS", U32(PINHOLE_NEIGHBOURS as u32)),
    ("INVALID_RESPONSE", F32(INVALID_RESPONSE)),
    ("MAX_TAPS", U32(MAX_TAPS as u32)),
    ("MAX_DERIV_RADIUS", U32(MAX_DERIV_RADIUS as u32)),
    ("MAX_INTEGRATION_RADIUS", U32(MAX_INTEGRATION_RADIUS as u32)),
    ("HARRIS_BLOCK", U32(HARRIS_BLOCK)),
    ("FUSED_HALO", U32(FUSED_HALO)),
    ("SELECT_MAX", U32(SELECT_MAX)),
    ("MERGE_LINKS", U32(MERGE_LINKS)),
    ("REFINE_GROUP_RADIUS", U32(REFINE_GROUP_RADIUS)),
];

/// The constants of the NCC shader (shaders/ncc_*.wgsl).
pub(crate) const NCC_CONSTANTS: Constants = &[
    ("WORKGROUP_1D", U32(WORKGROUP_1D)),
    ("NO_SCORE", F32(NO_SCORE)),
    ("NO_INDEX", U32(NO_INDEX)),
    ("NCC_TILE", U32(NCC_TILE)),
    ("REFINE_LOCAL_WINDOW", U32(REFINE_LOCAL_WINDOW)),
    ("VECTORIZE_GROUP_WINDOW", U32(VECTORIZE_GROUP_WINDOW)),
    ("GATHER_STRIDE", U32(GATHER_STRIDE as u32)),
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::GreyImage;

    #[test]
    fn packing_is_its_plainest_definition() {
        // Per pixel: Pixel::new of its value and mask, the hole flag where
        // it is invalid, off the border and at least PINHOLE_NEIGHBOURS of
        // its 8 neighbours are valid; on images from nearly all valid to
        // nearly all invalid, with and without a mask.
        let mut rng = crate::rng::Rng::new(9);
        let mut holes = 0;
        for (k, (w, h)) in [(1, 1), (2, 3), (5, 4), (37, 23), (64, 48)]
            .into_iter()
            .enumerate()
        {
            for density in [0.02, 0.2, 0.5, 0.9] {
                let img = GreyImage::from_fn(w, h, |_, _| {
                    if rng.uniform(0.0, 1.0) < density {
                        f32::NAN
                    } else {
                        rng.uniform(0.0, 1.0) as f32
                    }
                });
                let mask: Vec<bool> = (0..w * h).map(|_| rng.uniform(0.0, 1.0) < 0.7).collect();
                let valid = |x: usize, y: usize| img.data[y * w + x].is_finite();
                for (m, allow) in [
                    (None, true),
                    (Some(&mask[..]), true),
                    (Some(&mask[..]), false),
                ] {
                    let got = pack_with_holes(&img, m, allow);
                    assert_eq!(got.len(), w * h);
                    for (i, p) in got.iter().enumerate() {
                        let (x, y) = (i % w, i / w);
                        let mut want = Pixel::new(img.data[i], allow && m.is_none_or(|m| m[i]));
                        let inner = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
                        if !valid(x, y) && inner {
                            let n = (0..9)
                                .filter(|&j| j != 4 && valid(x + j % 3 - 1, y + j / 3 - 1))
                                .count();
                            if n >= PINHOLE_NEIGHBOURS {
                                want.flags |= PIXEL_HOLE;
                                holes += 1;
                            }
                        }
                        assert_eq!(
                            (p.value.to_bits(), p.flags),
                            (want.value.to_bits(), want.flags),
                            "image {k}, density {density}, pixel ({x}, {y})"
                        );
                    }
                    let pin = pinholes(&img);
                    assert!(
                        got.iter()
                            .zip(&pin)
                            .all(|(p, &h)| (p.flags & PIXEL_HOLE != 0) == h)
                    );
                }
            }
        }
        assert!(holes > 50, "{holes} holes");
    }
}
