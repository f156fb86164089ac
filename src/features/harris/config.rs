//! The Harris configuration, its corners and its kernel taps.

use crate::features::FeatureError;
use crate::features::gpu_data::{MAX_DERIV_RADIUS, MAX_INTEGRATION_RADIUS};

/// A corner: sub-pixel position (OpenCV convention: pixel (0, 0) is the
/// centre of the top-left pixel) and its Harris response.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corner {
    /// Column in pixels (0 at the centre of the left column).
    pub x: f32,
    /// Row in pixels (0 at the centre of the top row), downwards.
    pub y: f32,
    /// Harris response `det - k trace²` at the pixel where it was detected.
    pub score: f32,
}

/// Harris detector parameters. The defaults follow the paper where it says
/// something (about 900 corners, section 5.2) and common practice elsewhere.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HarrisConfig {
    /// Standard deviation of the Gaussian-derivative filter (pixels),
    /// at most 7/3. Default 1.
    pub sigma_d: f32,
    /// Standard deviation of the Gaussian smoothing the structure tensor
    /// (pixels), at most 14/3. Default 1.5.
    pub sigma_i: f32,
    /// `k` in `det - k trace²`. Default 0.04.
    pub k: f32,
    /// At most this many corners (the paper uses about 900). Default 900.
    pub max_corners: usize,
    /// Keep maxima whose response is at least this fraction of the image's
    /// largest response (inside the mask). Default 0.01.
    pub relative_threshold: f32,
    /// And at least this absolute response (grey values in 0..1), which only
    /// matters on nearly flat images. Default 1e-10.
    pub min_response: f32,
    /// Cell size (pixels) of the grid that spreads the selection; 0: plain
    /// best-N by response. Default 32.
    pub grid_cell: u32,
    /// Sub-pixel refinement by gradient orthogonality. Default on.
    pub refine: bool,
    /// Half-size of the refinement window (pixels). Default 4 (9x9).
    pub refine_radius: u32,
    /// Maximum refinement iterations. Default 10.
    pub refine_iterations: u32,
    /// Refined corners closer than this (pixels) are one corner. Default 1.5.
    pub merge_radius: f32,
    /// The structure tensor is the Gaussian-weighted mean of the valid
    /// gradients of its window (a gradient is valid when its derivative
    /// support holds no invalid pixel); a response needs at least this
    /// fraction of the window's weight valid, its own pixel valid, and its
    /// window inside the image. 1: any invalid gradient voids the response
    /// (up to weights below 1e-5). Default 0.8.
    #[serde(default = "default_min_valid_weight")]
    pub min_valid_weight: f32,
}

fn default_min_valid_weight() -> f32 {
    0.8
}

impl Default for HarrisConfig {
    fn default() -> Self {
        Self {
            sigma_d: 1.0,
            sigma_i: 1.5,
            k: 0.04,
            max_corners: 900,
            relative_threshold: 0.01,
            min_response: 1e-10,
            grid_cell: 32,
            refine: true,
            refine_radius: 4,
            refine_iterations: 10,
            merge_radius: 1.5,
            min_valid_weight: default_min_valid_weight(),
        }
    }
}

impl HarrisConfig {
    /// Sets [`max_corners`](Self::max_corners).
    pub fn with_max_corners(mut self, n: usize) -> Self {
        self.max_corners = n;
        self
    }
    /// Sets [`sigma_d`](Self::sigma_d) and [`sigma_i`](Self::sigma_i) (pixels).
    pub fn with_sigmas(mut self, sigma_d: f32, sigma_i: f32) -> Self {
        self.sigma_d = sigma_d;
        self.sigma_i = sigma_i;
        self
    }
    /// Sets [`k`](Self::k).
    pub fn with_k(mut self, k: f32) -> Self {
        self.k = k;
        self
    }
    /// Sets [`relative_threshold`](Self::relative_threshold).
    pub fn with_relative_threshold(mut self, t: f32) -> Self {
        self.relative_threshold = t;
        self
    }
    /// Sets [`grid_cell`](Self::grid_cell) (pixels; 0 disables the grid).
    pub fn with_grid_cell(mut self, cell: u32) -> Self {
        self.grid_cell = cell;
        self
    }
    /// Turns sub-pixel [`refine`](Self::refine)ment on or off.
    pub fn with_refine(mut self, on: bool) -> Self {
        self.refine = on;
        self
    }
}

/// Kernel radius for a Gaussian of standard deviation `sigma`: 3 sigma.
pub(crate) fn radius(sigma: f32) -> usize {
    ((3.0 * sigma).ceil() as usize).max(1)
}

/// Gaussian taps `g` (sum 1) and derivative taps `d` (`sum i d_i = 1`, so a
/// ramp of slope 1 has derivative exactly 1), index `i + r` for offset `i`.
pub(crate) fn gaussian_taps(sigma: f32) -> (Vec<f32>, Vec<f32>) {
    let r = radius(sigma) as i64;
    let s2 = 2.0 * (sigma as f64).powi(2);
    let g: Vec<f64> = (-r..=r).map(|i| (-(i * i) as f64 / s2).exp()).collect();
    let sum: f64 = g.iter().sum();
    let moment: f64 = (-r..=r).zip(&g).map(|(i, g)| (i * i) as f64 * g).sum();
    let taps = g.iter().map(|g| (g / sum) as f32).collect();
    let deriv = (-r..=r)
        .zip(&g)
        .map(|(i, g)| (i as f64 * g / moment) as f32)
        .collect();
    (taps, deriv)
}

impl HarrisConfig {
    /// Checks every parameter; the error names the first bad one.
    pub fn validate(&self) -> Result<(), FeatureError> {
        let bad = |m: String| Err(FeatureError::Config(m));
        let max_d = MAX_DERIV_RADIUS as f32 / 3.0;
        let max_i = MAX_INTEGRATION_RADIUS as f32 / 3.0;
        if !(self.sigma_d > 0.0 && self.sigma_d <= max_d) {
            return bad(format!(
                "sigma_d = {} is not in (0, {max_d:.3}]",
                self.sigma_d
            ));
        }
        if !(self.sigma_i > 0.0 && self.sigma_i <= max_i) {
            return bad(format!(
                "sigma_i = {} is not in (0, {max_i:.3}]",
                self.sigma_i
            ));
        }
        if !(self.k >= 0.0 && self.k < 0.25) {
            return bad(format!("k = {} is not in [0, 0.25)", self.k));
        }
        if !(0.0..=1.0).contains(&self.relative_threshold) {
            return bad(format!(
                "relative_threshold = {} is not in [0, 1]",
                self.relative_threshold
            ));
        }
        if !(self.min_response >= 0.0 && self.min_response.is_finite()) {
            return bad(format!("min_response = {} is not >= 0", self.min_response));
        }
        if self.max_corners == 0 {
            return bad("max_corners is 0".into());
        }
        if self.refine_radius == 0 || self.refine_radius > 15 {
            return bad(format!(
                "refine_radius = {} is not in 1..=15",
                self.refine_radius
            ));
        }
        if self.refine_iterations > 100 {
            return bad(format!(
                "refine_iterations = {} is more than 100",
                self.refine_iterations
            ));
        }
        if !(self.merge_radius >= 0.0 && self.merge_radius.is_finite()) {
            return bad(format!("merge_radius = {} is not >= 0", self.merge_radius));
        }
        if !(self.min_valid_weight > 0.0 && self.min_valid_weight <= 1.0) {
            return bad(format!(
                "min_valid_weight = {} is not in (0, 1]",
                self.min_valid_weight
            ));
        }
        Ok(())
    }

    /// The support radius (derivative + integration kernel radii, pixels)
    /// over which a corner's response depends on the image: corners lie at
    /// least this far from the border and from invalid pixels (Chebyshev
    /// distance, before refinement).
    pub fn support_radius(&self) -> usize {
        radius(self.sigma_d) + radius(self.sigma_i)
    }

    /// Gaussian window of the refinement, as `1 / (2 sigma_w^2)`.
    pub(crate) fn refine_inv_2s2(&self) -> f32 {
        let s = 0.75 * self.refine_radius as f32;
        1.0 / (2.0 * s * s)
    }

    pub(crate) fn max_shift(&self) -> f32 {
        self.refine_radius as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn taps_are_normalised() {
        for sigma in [0.7f32, 1.0, 1.5, 2.0] {
            let (g, d) = gaussian_taps(sigma);
            let r = radius(sigma) as i64;
            assert_eq!(g.len(), 2 * r as usize + 1);
            assert!((g.iter().sum::<f32>() - 1.0).abs() < 1e-6);
            let m: f32 = (-r..=r).zip(&d).map(|(i, d)| i as f32 * d).sum();
            assert!((m - 1.0).abs() < 1e-6, "derivative of a unit ramp: {m}");
            assert!(d.iter().sum::<f32>().abs() < 1e-6);
        }
    }
}
