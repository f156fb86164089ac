//! Robust pose updates from feature matches: iteratively reweighted least
//! squares (IRLS) on the motion-predictor model (Dehais et al. 2010, eqs. 6-7;
//! docs/how-it-works.md).
//!
//! How it works: match `i` moved from `m_{t-1}^i` to `m_t^i`; the motion
//! predictors `L^i` (2x6) sampled at `m_{t-1}^i` say that a small twist `a`
//! moves it by `L^i a`. IRLS minimises `sum_i rho(|L^i a - d^i|)` with
//! `d^i = m_t^i - m_{t-1}^i` by solving the weighted 6x6 normal equations
//! `(L^T W L) a = L^T W d` repeatedly, re-weighting each match by its
//! residual. The scale comes from the median absolute residual (MAD). A few
//! Huber iterations (convex, so they cannot lock onto outliers) come first,
//! then Tukey's biweight (redescending: gross outliers get exactly zero
//! weight). Before every solve the system is checked: a normal matrix that
//! is rank-deficient or badly conditioned (after scaling its rows and columns
//! to unit diagonal, so that model units and radians compare) is refused with
//! the reason, never inverted into a garbage update.
//!
//! Beyond the paper's single linear solve, [`Refiner`] re-projects the
//! matched points, lifted to 3-D with the splatted depth, at the updated
//! pose and solves again with the same robust loss (Gauss-Newton).

#![warn(missing_docs)]

mod irls;
mod p3p;
mod pnp;
mod refine;

pub use irls::{IrlsConfig, IrlsResult, Loss, Observation, SolveError, irls, irls_grouped};
pub use pnp::{
    PnpError, PnpRansacOptions, PnpSolution, reprojection_errors, solve_pnp, solve_pnp_ransac,
};
pub use refine::{Anchor, Correspondence, Refined, Refiner};
