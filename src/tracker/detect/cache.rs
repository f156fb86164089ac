//! What the detection by features ([`super`]) keeps between searches.

use super::config::DetectConfig;
use super::features::Descriptor;
use nalgebra::Vector3;

/// One keyframe's corners as model points, and their descriptors (one per
/// scale where the patch allows; `owners[i]` is the point described by
/// `descriptors[i]`, one point's adjacent).
#[derive(Debug, Clone, Default)]
pub(in crate::tracker) struct KeyframeFeatures {
    pub(in crate::tracker) points: Vec<Vector3<f64>>,
    /// Where each point's corner is in the keyframe's view, pixels.
    pub(in crate::tracker) pixels: Vec<[f32; 2]>,
    pub(in crate::tracker) descriptors: Vec<Descriptor>,
    pub(in crate::tracker) owners: Vec<usize>,
}

/// What the detection keeps between searches: its Harris (more corners
/// than the tracker's) and the keyframes' features.
pub(in crate::tracker) struct Detector {
    pub(in crate::tracker) harris: crate::tracker::features_on::CornerDetector,
    pub(in crate::tracker) keyframes: Vec<KeyframeFeatures>,
    /// Whether each keyframe's features have been made (the search while
    /// lost makes them a few at a time).
    pub(in crate::tracker) built: Vec<bool>,
    /// Searches in a row the features failed.
    pub(in crate::tracker) misses: usize,
}

impl Detector {
    /// The keyframes whose features are still to be made.
    pub(in crate::tracker) fn unbuilt(&self) -> impl Iterator<Item = usize> + '_ {
        self.built.iter().enumerate().filter(|b| !*b.1).map(|b| b.0)
    }

    /// Whether some keyframe has features enough to detect by.
    pub(in crate::tracker) fn textured(&self, cfg: &DetectConfig) -> bool {
        self.keyframes
            .iter()
            .any(|k| k.points.len() >= cfg.min_keyframe_features.max(1))
    }

    /// Whether the template search should follow the features' failure
    /// now ([`DetectConfig::templates_every`]).
    pub(in crate::tracker) fn templates_now(&self, cfg: &DetectConfig) -> bool {
        !self.textured(cfg)
            || (cfg.templates_every > 0
                && self.misses > 0
                && (self.misses - 1).is_multiple_of(cfg.templates_every))
    }
}
