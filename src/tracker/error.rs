//! Errors: settings out of range ([`ConfigError`]), and what stops
//! tracking ([`TrackError`]).

use crate::features::FeatureError;

/// A tracker setting out of its range.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The field (named as in [`super::TrackerConfig`], e.g. `it_search_px` or
    /// `harris.relative_threshold`) breaks its rule.
    #[error("{field} = {value}: must be {rule}")]
    OutOfRange {
        /// The field's path in [`super::TrackerConfig`].
        field: &'static str,
        /// Its value, as its type prints it.
        value: String,
        /// What it must be, e.g. `>= 0`.
        rule: &'static str,
    },
    /// The Harris or NCC settings are impossible.
    #[error(transparent)]
    Features(#[from] FeatureError),
}

/// Errors that stop tracking (bad input, GPU failure), as opposed to a
/// frame that is merely lost.
#[derive(Debug, thiserror::Error)]
pub enum TrackError {
    /// [`super::Tracker::track`] got a frame whose size is not the camera's.
    #[error("frame is {got_w}x{got_h}, the camera is {want_w}x{want_h}")]
    FrameSize {
        /// The frame's width, pixels.
        got_w: u32,
        /// The frame's height, pixels.
        got_h: u32,
        /// The camera's width, pixels.
        want_w: u32,
        /// The camera's height, pixels.
        want_h: u32,
    },
    /// The KF and KF+IT modes (named) need a texture for the novel views:
    /// a keyframe store, or colours in the model.
    #[error("{}", needs_keyframes(.0))]
    NeedsKeyframes(&'static str),
    /// The initial pose puts the object behind the camera or wholly
    /// outside the image.
    #[error("the initial pose puts the object behind the camera or outside the image")]
    ObjectNotInView,
    /// The settings are out of range.
    #[error("tracker settings: {0}")]
    Config(#[from] ConfigError),
    /// The camera's intrinsics are impossible.
    #[error(transparent)]
    Camera(#[from] CameraInvalid),
    /// The splatter failed (GPU error, unusable model).
    #[error(transparent)]
    Splat(#[from] crate::splat::SplatError),
    /// Feature detection or matching failed on the GPU.
    #[error(transparent)]
    Features(#[from] crate::features::FeatureError),
    /// The initial pose is not a rigid transform.
    #[error(transparent)]
    Pose(#[from] crate::geometry::PoseError),
    /// The keyframe store is unusable.
    #[error(transparent)]
    Keyframes(#[from] crate::keyframes::KeyframeError),
    /// The GPU failed during the search for the object.
    #[error("searching for the object: {0}")]
    Search(String),
}

/// A device error outside the splatter and the features (the pose
/// check's scores): reported as the splatter's, as before.
impl From<crate::gpu::GpuError> for TrackError {
    fn from(e: crate::gpu::GpuError) -> Self {
        TrackError::Splat(crate::splat::SplatError::from(e))
    }
}

/// The text of [`TrackError::NeedsKeyframes`]: a KF mode is pointed to
/// the IT mode, which needs no texture.
fn needs_keyframes(what: &str) -> String {
    match what {
        "kf" | "kf+it" => format!(
            "mode {what} needs keyframes or a model with colours (mode it tracks frame to frame without them)"
        ),
        _ => format!("{what} needs keyframes or a model with colours"),
    }
}

/// An impossible camera.
#[derive(Debug, thiserror::Error)]
#[error("impossible camera: {0}")]
pub struct CameraInvalid(pub String);
