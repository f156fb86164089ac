//! The errors of feature detection and matching.

use crate::gpu::GpuError;

/// Errors of feature detection and matching.
#[derive(Debug, thiserror::Error)]
pub enum FeatureError {
    /// The pixel buffer's length does not match the image's width times height.
    #[error("image data has {len} values for {width}x{height} pixels")]
    ImageSize {
        /// Image width in pixels.
        width: usize,
        /// Image height in pixels.
        height: usize,
        /// Number of values in the buffer.
        len: usize,
    },
    /// A validity mask has a different number of flags than the image has pixels.
    #[error("mask has {got} values for an image of {expected} pixels")]
    MaskSize {
        /// Number of pixels in the image.
        expected: usize,
        /// Number of flags in the mask.
        got: usize,
    },
    /// An image exceeds the GPU's buffer or dispatch limits.
    #[error("image of {width}x{height} pixels is too large for the GPU ({reason})")]
    TooLarge {
        /// Width in pixels (for a pair of images, the wider one).
        width: usize,
        /// Height in pixels (for a pair of images, their summed heights).
        height: usize,
        /// Which limit was exceeded.
        reason: String,
    },
    /// The matcher was given more features than the GPU's limits allow.
    #[error("{n} features is more than the matcher supports ({max})")]
    TooManyFeatures {
        /// Number of features requested (the larger of the two sets).
        n: usize,
        /// The most the matcher supports on this device.
        max: usize,
    },
    /// A configuration parameter is out of range; the message names it.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// A GPU operation failed.
    #[error(transparent)]
    Gpu(#[from] GpuError),
}
