//! Errors of the splatter.

use super::Attribute;
use crate::gpu::GpuError;

/// Errors of the splatter.
#[derive(Debug, thiserror::Error)]
pub enum SplatError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error("the point model is empty")]
    EmptyModel,
    #[error("the point model has {got} {what} for {expected} points")]
    Inconsistent {
        what: &'static str,
        got: usize,
        expected: usize,
    },
    #[error(
        "point {index} of the model has a non-finite position/normal or a radius that is not > 0"
    )]
    BadPoint { index: usize },
    #[error(
        "the model has {points} points ({bytes} bytes), more than the adapter's storage binding limit of {limit} bytes"
    )]
    TooLarge {
        points: usize,
        bytes: u64,
        limit: u64,
    },
    #[error("the object is entirely behind the camera (its bounding sphere ends at z = {far:.4})")]
    BehindCamera { far: f64 },
    #[error("invalid camera: {0}")]
    Camera(String),
    #[error("invalid pose: {0}")]
    Pose(#[from] crate::geometry::PoseError),
    #[error("splat targets are {got_w}x{got_h} but the camera is {want_w}x{want_h}")]
    SizeMismatch {
        got_w: u32,
        got_h: u32,
        want_w: u32,
        want_h: u32,
    },
    #[error("{0:?} was not rendered into these targets (render with it first)")]
    NotRendered(Attribute),
    #[error("the adapter cannot splat: {0}")]
    Unsupported(String),
}
