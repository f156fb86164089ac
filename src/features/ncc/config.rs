//! What a matching is: its configuration and its matches.

use crate::features::FeatureError;
use crate::features::gpu_data::NCC_TILE;

/// A mutual best match: feature `a` of the first image and feature `b` of
/// the second, with their NCC score in [-1, 1].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Match {
    /// Index of the feature in the first image's list.
    pub a: usize,
    /// Index of the feature in the second image's list.
    pub b: usize,
    /// NCC of the two windows, in [-1, 1].
    pub score: f32,
}

/// NCC matching parameters.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NccConfig {
    /// Side of the correlation patch in pixels, odd (the paper's 9x9
    /// window; `--ncc-window` on the command line).
    #[serde(rename = "window")]
    pub patch: u32,
    /// Keep mutual best matches scoring at least this. Default 0.8.
    pub min_score: f32,
    /// Only pairs at most this far apart (pixels) may match; `None`: all
    /// pairs (the paper's GPU version). Default `None`.
    pub search_radius: Option<f32>,
    /// Windows whose standard deviation (grey 0..1) is below this are flat
    /// and get no match. Default 0.005 (about 1.3 grey levels of 255).
    pub min_std: f32,
    /// A window may have invalid (NaN) pixels: it matches when at least
    /// this fraction of its samples are valid, the NCC of a pair then being
    /// taken over the samples valid in both windows (which must hold this
    /// fraction too). 1: any invalid pixel voids the window. Windows that
    /// leave the image get no match either way. Default 0.8.
    #[serde(default = "default_min_valid")]
    pub min_valid: f32,
}

fn default_min_valid() -> f32 {
    0.8
}

impl Default for NccConfig {
    fn default() -> Self {
        Self {
            patch: 9,
            min_score: 0.8,
            search_radius: None,
            min_std: 0.005,
            min_valid: default_min_valid(),
        }
    }
}

impl NccConfig {
    /// Sets [`patch`](Self::patch) (pixels, odd).
    pub fn with_patch(mut self, w: u32) -> Self {
        self.patch = w;
        self
    }
    /// Sets [`min_score`](Self::min_score).
    pub fn with_min_score(mut self, s: f32) -> Self {
        self.min_score = s;
        self
    }
    /// Sets [`search_radius`](Self::search_radius) (pixels; `None`: all pairs).
    pub fn with_search_radius(mut self, r: Option<f32>) -> Self {
        self.search_radius = r;
        self
    }

    /// Checks every parameter; the error names the first bad one.
    pub fn validate(&self) -> Result<(), FeatureError> {
        let bad = |m: String| Err(FeatureError::Config(m));
        if self.patch.is_multiple_of(2) || self.patch > 63 {
            return bad(format!("patch = {} is not odd and at most 63", self.patch));
        }
        if !(-1.0..=1.0).contains(&self.min_score) {
            return bad(format!("min_score = {} is not in [-1, 1]", self.min_score));
        }
        if let Some(r) = self.search_radius.filter(|r| !(*r >= 0.0 && r.is_finite())) {
            return bad(format!("search_radius = {r} is not a finite value >= 0"));
        }
        if !(self.min_std >= 0.0 && self.min_std.is_finite()) {
            return bad(format!("min_std = {} is not >= 0", self.min_std));
        }
        if !(self.min_valid > 0.0 && self.min_valid <= 1.0) {
            return bad(format!("min_valid = {} is not in (0, 1]", self.min_valid));
        }
        Ok(())
    }

    /// Descriptor row stride: w² padded with zeros to the score tile.
    pub(crate) fn stride(&self) -> u32 {
        (self.patch * self.patch).next_multiple_of(NCC_TILE)
    }
}
