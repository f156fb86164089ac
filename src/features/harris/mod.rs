//! Harris corners (Harris & Stephens 1988; Dehais et al. 2010, section
//! 4.2): the configuration and the host steps that the GPU detector
//! ([`Harris`] in `gpu.rs`, `shaders/harris.wgsl`) and its CPU reference
//! ([`harris_cpu`] in `cpu.rs`) share (kernel taps, pixel packing, spread
//! selection, merging of refined duplicates). Both import from here and never from each other.
//! The host detector for CPU adapters ([`harris_host`] in `host.rs`, which
//! [`Harris`] runs in its host mode) is the reference's arithmetic in
//! faster loops: it shares the reference's NMS and refinement. See the
//! module docs of [`super`] for how it works.

mod cpu;
mod gpu;
mod host;

pub use cpu::{harris_cpu, harris_response_cpu};
pub(crate) use gpu::SHADER;
pub use gpu::{Detected, ExportPlace, Harris, PendingCorners};
pub use host::{harris_host, harris_response_host};

use super::FeatureError;
use super::gpu_data::{Candidate, MAX_DERIV_RADIUS, MAX_INTEGRATION_RADIUS, Pixel};
use super::image::GreyImage;

/// A corner: sub-pixel position (OpenCV convention: pixel (0, 0) is the
/// centre of the top-left pixel) and its Harris response.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corner {
    pub x: f32,
    pub y: f32,
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
    pub fn with_max_corners(mut self, n: usize) -> Self {
        self.max_corners = n;
        self
    }
    pub fn with_sigmas(mut self, sigma_d: f32, sigma_i: f32) -> Self {
        self.sigma_d = sigma_d;
        self.sigma_i = sigma_i;
        self
    }
    pub fn with_k(mut self, k: f32) -> Self {
        self.k = k;
        self
    }
    pub fn with_relative_threshold(mut self, t: f32) -> Self {
        self.relative_threshold = t;
        self
    }
    pub fn with_grid_cell(mut self, cell: u32) -> Self {
        self.grid_cell = cell;
        self
    }
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

/// The image and mask as the GPU sees them: NaN (invalid) pixels become 0
/// with the valid flag cleared.
pub(crate) fn pack_pixels(img: &GreyImage, mask: Option<&[bool]>) -> Vec<Pixel> {
    super::gpu_data::pack_with_holes(img, mask, true)
}

/// The best `max_corners` candidates, spread over the image: each is ranked
/// within its `grid_cell`-sized cell, and candidates are taken rank by rank
/// (ties by score, then position). Deterministic whatever the input order.
pub(crate) fn select_spread(cands: Vec<Candidate>, cfg: &HarrisConfig) -> Vec<Candidate> {
    select_spread_indices(&cands, cfg)
        .into_iter()
        .map(|i| cands[i])
        .collect()
}

/// [`select_spread`] as indices into `cands`, in the selection's order.
pub(crate) fn select_spread_indices(cands: &[Candidate], cfg: &HarrisConfig) -> Vec<usize> {
    let by_score = |a: &Candidate, b: &Candidate| {
        b.score
            .total_cmp(&a.score)
            .then(a.y.cmp(&b.y))
            .then(a.x.cmp(&b.x))
    };
    let mut order: Vec<usize> = (0..cands.len()).collect();
    order.sort_by(|&a, &b| by_score(&cands[a], &cands[b]));
    if cfg.grid_cell == 0 {
        order.truncate(cfg.max_corners);
        return order;
    }
    let cell = cfg.grid_cell;
    let mut rank_in_cell = std::collections::HashMap::new();
    let mut ranked: Vec<(u32, usize)> = order
        .into_iter()
        .map(|i| {
            let c = &cands[i];
            let r = rank_in_cell.entry((c.x / cell, c.y / cell)).or_insert(0u32);
            *r += 1;
            (*r, i)
        })
        .collect();
    ranked.sort_by(|&(ra, a), &(rb, b)| ra.cmp(&rb).then(by_score(&cands[a], &cands[b])));
    ranked.truncate(cfg.max_corners);
    ranked.into_iter().map(|(_, i)| i).collect()
}

/// The corners [`select_spread_indices`] selects among `cands`, at their
/// pixels (before any refinement), in the selection's order.
pub(crate) fn selected_starts(cands: &[Candidate], cfg: &HarrisConfig) -> Vec<Corner> {
    select_spread_indices(cands, cfg)
        .iter()
        .map(|&i| Corner {
            x: cands[i].x as f32,
            y: cands[i].y as f32,
            score: cands[i].score,
        })
        .collect()
}

/// Greedy merge of refined corners closer than `radius`, strongest first
/// (refinement pulls the split maxima of an X-junction onto one point).
/// The result is sorted by decreasing score.
pub(crate) fn merge(mut corners: Vec<Corner>, radius: f32) -> Vec<Corner> {
    corners.sort_by(|a, b| {
        b.score
            .total_cmp(&a.score)
            .then(a.y.total_cmp(&b.y))
            .then(a.x.total_cmp(&b.x))
    });
    if radius <= 0.0 {
        return corners;
    }
    let r2 = radius * radius;
    let mut kept: Vec<Corner> = Vec::with_capacity(corners.len());
    for c in corners {
        if kept
            .iter()
            .all(|k| (k.x - c.x).powi(2) + (k.y - c.y).powi(2) >= r2)
        {
            kept.push(c);
        }
    }
    kept
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

    #[test]
    fn spread_selection_takes_every_cell_first() {
        let cfg = HarrisConfig::default()
            .with_max_corners(3)
            .with_grid_cell(10);
        let c = |x, y, score| Candidate {
            x,
            y,
            score,
            _pad: 0,
        };
        // Three strong corners in one cell, one weak corner in another.
        let got = select_spread(
            vec![c(1, 1, 9.0), c(2, 5, 8.0), c(5, 2, 7.0), c(50, 50, 1.0)],
            &cfg,
        );
        let xs: Vec<u32> = got.iter().map(|c| c.x).collect();
        assert_eq!(xs, vec![1, 50, 2]);
    }

    #[test]
    fn merge_keeps_the_strongest_of_close_corners() {
        let c = |x, y, score| Corner { x, y, score };
        let got = merge(
            vec![c(10.0, 10.0, 1.0), c(10.5, 10.2, 2.0), c(20.0, 10.0, 0.5)],
            1.5,
        );
        assert_eq!(got, vec![c(10.5, 10.2, 2.0), c(20.0, 10.0, 0.5)]);
    }
}
