//! Motion predictors and depth sampled at a few positions
//! ([`super::Splatter::gather`] and its CPU reference).

use nalgebra::Matrix2x6;

/// How [`super::Splatter::gather`] samples between pixel centres.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GatherMode {
    /// The pixel whose centre is nearest.
    Nearest,
    /// Bilinear interpolation of the normalised values when all four
    /// surrounding pixels are covered; else the nearest pixel.
    #[default]
    Bilinear,
}

/// Motion predictors and depth at one position, as [`super::Splatter::gather`]
/// returns them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GatherSample {
    /// du_tx, dv_tx, ..., du_rz, dv_rz (NaN when invalid).
    pub motion: [f32; 12],
    /// Camera-space z (NaN when invalid).
    pub depth: f32,
    /// False where no splat covers the position (or it is outside the image).
    pub valid: bool,
}

impl GatherSample {
    /// A sample from the 14 floats the GPU writes per position: 12 motion
    /// predictors, depth, then the validity flag (> 0.5: valid).
    pub fn from_floats(v: &[f32]) -> Self {
        Self {
            motion: std::array::from_fn(|k| v[k]),
            depth: v[12],
            valid: v[13] > 0.5,
        }
    }

    /// The predictors as the 2x6 matrix `L` of [`crate::geometry::Intrinsics::motion_predictors`].
    pub fn matrix(&self) -> Matrix2x6<f64> {
        Matrix2x6::from_fn(|r, c| self.motion[2 * c + r] as f64)
    }
}
