//! The contour modality (beyond the paper; docs/contour.md): the object's silhouette, splatted at the predicted pose, is
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
//!
//! Files: `config.rs` (settings), `outline.rs` (the silhouette's points),
//! `colour.rs`, `histograms.rs` and `sectors.rs` (the colour statistics),
//! `learner.rs` (their learning off the tracking thread), `line.rs` (the
//! search along each normal), `rows.rs` (the residual rows), `normals.rs`
//! (the model's normals for depth-only renders), `state.rs` (what the
//! tracker keeps between frames) and `step.rs` (the step itself).

mod colour;
mod config;
mod histograms;
pub(crate) mod learner;
mod line;
mod normals;
mod outline;
mod rows;
mod sectors;
mod state;
mod step;
#[cfg(test)]
mod tests;

pub use colour::ColourModel;
pub use config::ContourConfig;
pub use histograms::Histograms;
pub use line::{search_line, search_line_toward};
pub use normals::{ModelNormals, crease_radii};
pub(crate) use outline::contour_point;
pub use outline::{
    ContourPoint, OUTLINE_MAX_MISMATCH, OUTLINE_MIN_GRADIENT, OUTLINE_WINDOW, crease_inset,
    extract_contour, inset, inset_each, insets, limb_normals, limb_normals_with, straight_edge,
    straight_edges,
};
pub use rows::{contour_predictors, contour_row};
pub use sectors::{SECTOR_LEAST_PX, turn_of};
pub(crate) use state::ContourState;
