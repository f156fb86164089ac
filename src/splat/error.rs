//! Errors of the splatter.

use super::Attribute;
use crate::gpu::GpuError;

/// Errors of the splatter.
#[derive(Debug, thiserror::Error)]
pub enum SplatError {
    /// A GPU operation failed.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// A model or targets made on one device were given to a splatter on
    /// the other (the CPU device's and a GPU's do not mix).
    #[error("{0} is on another device than the splatter (the CPU device and a GPU do not mix)")]
    WrongDevice(&'static str),
    /// The point model has no points.
    #[error("the point model is empty")]
    EmptyModel,
    /// A per-point array (normals, radii, colours) has a different length
    /// than the positions.
    #[error("the point model has {got} {what} for {expected} points")]
    Inconsistent {
        /// Which array.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The number of points.
        expected: usize,
    },
    /// A point has a non-finite position or normal, or a radius not > 0.
    #[error(
        "point {index} of the model has a non-finite position/normal or a radius that is not > 0"
    )]
    BadPoint {
        /// Index of the point in the model.
        index: usize,
    },
    /// The packed splats exceed the adapter's storage buffer limits.
    #[error(
        "the model has {points} points ({bytes} bytes), more than the adapter's storage binding limit of {limit} bytes"
    )]
    TooLarge {
        /// Number of points.
        points: usize,
        /// Size of the packed splats, in bytes.
        bytes: u64,
        /// The adapter's limit, in bytes.
        limit: u64,
    },
    /// The object's bounding sphere lies entirely behind the camera at the
    /// given pose.
    #[error("the object is entirely behind the camera (its bounding sphere ends at z = {far:.4})")]
    BehindCamera {
        /// Camera-frame depth of the sphere's far end (metres, not > 0).
        far: f64,
    },
    /// The camera intrinsics are invalid; the message says why.
    #[error("invalid camera: {0}")]
    Camera(String),
    /// The pose is not a finite rigid transform.
    #[error("invalid pose: {0}")]
    Pose(#[from] crate::geometry::PoseError),
    /// The render targets' size differs from the camera's image size.
    #[error("splat targets are {got_w}x{got_h} but the camera is {want_w}x{want_h}")]
    SizeMismatch {
        /// Targets' width in pixels.
        got_w: u32,
        /// Targets' height in pixels.
        got_h: u32,
        /// Camera's image width in pixels.
        want_w: u32,
        /// Camera's image height in pixels.
        want_h: u32,
    },
    /// An attribute was asked of targets it was not rendered into.
    #[error("{0:?} was not rendered into these targets (render with it first)")]
    NotRendered(Attribute),
    /// The adapter's limits do not allow a splatter, or a request cannot be
    /// served (an unknown splatter choice, an output buffer too small).
    #[error("the adapter cannot splat: {0}")]
    Unsupported(String),
}
