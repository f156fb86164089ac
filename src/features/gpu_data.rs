//! Host twins of the structs in `shaders/harris.wgsl` and `shaders/ncc.wgsl`.
//! Keep every field order in sync with the WGSL: a mismatch is silent on
//! the GPU, so each struct's size is asserted here.

use bytemuck::{Pod, Zeroable};

/// Number of Gaussian taps the Harris uniform holds (`HarrisParams.weights`):
/// derivative kernel (g and g', radius <= 7) then integration kernel
/// (radius <= 14): 2 x 15 + 29 = 59 <= 64.
pub const MAX_TAPS: usize = 64;
pub const MAX_DERIV_RADIUS: usize = 7;
pub const MAX_INTEGRATION_RADIUS: usize = 14;

/// Pixel flags (`Pixel.flags`): the value is finite and usable...
pub const PIXEL_VALID: u32 = 1;
/// ...and a corner may be reported here (inside the mask).
pub const PIXEL_ALLOWED: u32 = 2;

/// Response of a pixel whose support leaves the image or touches an
/// invalid pixel. Same constant as `INVALID` in harris.wgsl.
pub const INVALID_RESPONSE: f32 = -3.0e38;

/// Score of a pair that cannot match (invalid window or out of the search
/// radius). Same constant as `NO_SCORE` in ncc.wgsl; below any NCC.
pub const NO_SCORE: f32 = -2.0;

/// `Best.index` when a row or column has no entry.
pub const NO_INDEX: u32 = u32::MAX;

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Pixel {
    // Keep in sync with `Pixel` in shaders/harris.wgsl and shaders/ncc.wgsl.
    pub value: f32,
    pub flags: u32,
}
const _: () = assert!(std::mem::size_of::<Pixel>() == 8);

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct HarrisParams {
    // Keep this field order in sync with `Params` in shaders/harris.wgsl.
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
    pub _pad: [u32; 3],
    /// g_d[0..2rd+1], g'_d[0..2rd+1], g_i[0..2ri+1], packed by fours.
    pub weights: [[f32; 4]; MAX_TAPS / 4],
}
const _: () = assert!(std::mem::size_of::<HarrisParams>() == 64 + 4 * MAX_TAPS);

/// A local maximum of the response, as the NMS kernel writes it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Candidate {
    // Keep in sync with `Candidate` in shaders/harris.wgsl.
    pub x: u32,
    pub y: u32,
    pub score: f32,
    pub _pad: u32,
}
const _: () = assert!(std::mem::size_of::<Candidate>() == 16);

/// Corner counters: the response maximum (f32 bits, positive responses
/// only, so integer order is float order) and the candidate count.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Counters {
    // Keep in sync with `Counters` in shaders/harris.wgsl.
    pub max_bits: u32,
    pub count: u32,
    pub _pad: [u32; 2],
}
const _: () = assert!(std::mem::size_of::<Counters>() == 16);

/// A corner being refined: position, score, status (1 = refined, 0 = kept
/// at its start because the refinement was ill-posed or ran away).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct RefineCorner {
    // Keep in sync with `vec4<f32>` corners in shaders/harris.wgsl.
    pub x: f32,
    pub y: f32,
    pub score: f32,
    pub status: f32,
}
const _: () = assert!(std::mem::size_of::<RefineCorner>() == 16);

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct NccParams {
    // Keep this field order in sync with `Params` in shaders/ncc.wgsl.
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
    pub _pad: u32,
}
const _: () = assert!(std::mem::size_of::<NccParams>() == 48);

/// Tile edge of the score kernel (`TILE` in ncc.wgsl); descriptor rows are
/// padded with zeros to a multiple of it.
pub const NCC_TILE: u32 = 16;

/// Best entry of a score row or column.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct Best {
    // Keep in sync with `Best` in shaders/ncc.wgsl.
    pub index: u32,
    pub score: f32,
}
const _: () = assert!(std::mem::size_of::<Best>() == 8);
