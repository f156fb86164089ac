//! Feature points: Harris corners and NCC matching with a mutual
//! cross-check, on the GPU (WGSL compute shaders) with CPU references.
//!
//! This is the low-level vision of Dehais, Morin & Charvillat (2010),
//! section 4.2: corners by the Harris criterion (Harris & Stephens, "A
//! combined corner and edge detector", Alvey Vision Conference 1988),
//! matched by normalised cross-correlation of 9x9 windows, best match per
//! row and per column of the score matrix, mutual best matches only.
//!
//! # How it works
//!
//! **Harris** ([`Harris`], GPU; [`harris_cpu`], its reference; both in [`harris`]):
//! 1. Gaussian-derivative gradients (`sigma_d`), as two separable passes.
//! 2. The structure tensor `[Ix², IxIy; IxIy, Iy²]` smoothed by a Gaussian
//!    (`sigma_i`), two more separable passes, then the response
//!    `det - k trace²`. Every pass also carries a validity flag: a pixel is
//!    valid only if its whole support (derivative plus integration radius)
//!    lies inside the image on valid (finite) pixels, so NaN pixels of a
//!    rendered novel view and the image border never produce corners.
//! 3. Non-maximum suppression (strict 3x3 maximum, ties broken by raster
//!    index) above `relative_threshold x max response` inside the optional
//!    mask; survivors are compacted with an atomic counter into a list.
//! 4. On the host (the list is small): the best `max_corners`, spread over
//!    the image by a grid: candidates are ranked inside their grid cell and
//!    taken rank by rank (all cells' best, then all cells' second best, ...;
//!    by score within a rank), so textured regions cannot starve the rest.
//! 5. Sub-pixel refinement on the GPU by gradient orthogonality (as OpenCV's
//!    `cornerSubPix`): the corner `q` is where `g(p) . (p - q) = 0` for the
//!    gradients `g(p)` of a window around it, solved in least squares,
//!    re-centred and iterated. Plain Harris maxima sit about one smoothing
//!    scale inside an L-corner and split around an X-junction; refinement
//!    moves them onto the true corner, and detections that converge to
//!    the same point (closer than `merge_radius`) are merged, keeping the
//!    strongest.
//!
//! **NCC** ([`NccMatcher`], GPU; [`ncc_match_cpu`], its reference):
//! 1. Each feature's `w x w` window is sampled bilinearly at its sub-pixel
//!    position and vectorised into one row of an `n x w²` buffer (the
//!    paper's layout), made zero-mean and unit-norm once. Windows that
//!    leave the image, touch an invalid pixel, or are flat get no match.
//! 2. All scores at once as the matrix product `A Bᵀ` (a tiled kernel),
//!    optionally only within a search radius.
//! 3. Best per row and per column (workgroup reductions); the host keeps
//!    pairs that are each other's best with a score above the threshold.
//!
//! Coordinates follow OpenCV: pixel (0, 0) is the centre of the top-left
//! pixel. Grey values are `f32` in 0..1 ([`GreyImage`]); NaN marks an
//! invalid (empty) pixel.

mod backend;
mod error;
pub(crate) mod gpu_data;
pub mod harris;
pub mod image;
pub mod ncc;
pub mod patterns;
pub mod refine;
pub mod resident;

pub use backend::FeatureBackend;
pub use error::FeatureError;
pub use gpu_data::{
    INVALID_RESPONSE, REFINE_GROUP_RADIUS, SELECT_MAX, SELECT_MAX_CPU, VECTORIZE_GROUP_WINDOW,
};
pub(crate) use harris::HostHarris;
pub use harris::{
    Corner, Detected, ExportPlace, Harris, HarrisConfig, HarrisGpuOptions, PendingCorners,
    harris_cpu, harris_host, harris_response_cpu, harris_response_host,
};
pub use image::GreyImage;
pub use ncc::{ExportFn, Match, NccConfig, NccMatcher, NccOptions, PendingMatches, ncc_match_cpu};
pub use refine::refine_match;
pub use resident::{FrameIntake, GpuGrey, Refinement, ResidentImage, ResidentMatch};
