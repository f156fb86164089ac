//! The errors of feature detection and matching.

use crate::gpu::GpuError;

/// Errors of feature detection and matching.
#[derive(Debug, thiserror::Error)]
pub enum FeatureError {
    #[error("image data has {len} values for {width}x{height} pixels")]
    ImageSize {
        width: usize,
        height: usize,
        len: usize,
    },
    #[error("mask has {got} values for an image of {expected} pixels")]
    MaskSize { expected: usize, got: usize },
    #[error("image of {width}x{height} pixels is too large for the GPU ({reason})")]
    TooLarge {
        width: usize,
        height: usize,
        reason: String,
    },
    #[error("{n} features is more than the matcher supports ({max})")]
    TooManyFeatures { n: usize, max: usize },
    #[error("invalid configuration: {0}")]
    Config(String),
    #[error(transparent)]
    Gpu(#[from] GpuError),
}
