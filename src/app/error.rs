//! Why a tracking run could not be set up or finished ([`AppError`]).

use crate::io::atomic::WriteError;
use crate::io::poses::PoseFileError;
use crate::io::sequence::SequenceError;
use crate::io::source::SourceError;
use crate::io::video::VideoError;
use crate::keyframes::KeyframeError;
use crate::model::ModelError;
use crate::splat::SplatError;
use crate::tracker::TrackError;
use crate::view::ViewError;
use std::path::PathBuf;

/// Why a tracking run could not be set up or finished (a lost frame is not
/// an error).
#[derive(Debug, thiserror::Error)]
pub enum AppError {
    /// The point model could not be loaded.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The sequence directory or one of its frames is unusable.
    #[error(transparent)]
    Sequence(#[from] SequenceError),
    /// A video or camera could not be read.
    #[error(transparent)]
    Video(#[from] VideoError),
    /// The camera file could not be read.
    #[error(transparent)]
    Camera(#[from] crate::io::camera::CameraError),
    /// A pose file could not be read or written.
    #[error(transparent)]
    Poses(#[from] PoseFileError),
    /// An output file (BOP results) could not be written.
    #[error(transparent)]
    Write(#[from] WriteError),
    /// A keyframe store could not be loaded or saved, or is for another model.
    #[error(transparent)]
    Keyframes(#[from] KeyframeError),
    /// The splatter could not be created.
    #[error(transparent)]
    Splat(#[from] SplatError),
    /// A keyframe path that is neither a store nor a keyframe directory.
    #[error("{0}: not a keyframe store file nor a directory with poses.csv")]
    NotKeyframes(PathBuf),
    /// Building a keyframe store from images failed.
    #[error("building keyframes from {path}: {source}")]
    BuildKeyframes {
        /// The keyframe directory.
        path: PathBuf,
        /// Why.
        #[source]
        source: KeyframeError,
    },
    /// A keyframe image could not be undistorted.
    #[error("{path}: cannot undistort: {reason}")]
    Undistort {
        /// The keyframe directory.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The tracker refused its inputs.
    #[error("starting the tracker on {sequence}: {source}")]
    Start {
        /// The sequence directory.
        sequence: PathBuf,
        /// Why.
        #[source]
        source: Box<TrackError>,
    },
    /// Tracking stopped at a frame (bad frame, GPU failure).
    #[error("{frame}: {source}")]
    Track {
        /// The frame's image file.
        frame: PathBuf,
        /// Why.
        #[source]
        source: Box<TrackError>,
    },
    /// An overlay picture could not be written.
    #[error("{path}: cannot write: {source}")]
    Overlay {
        /// The picture or its directory.
        path: PathBuf,
        /// Why.
        #[source]
        source: image::ImageError,
    },
    /// No frame to track (an empty range).
    #[error("no frames to track")]
    NoFrames,
    /// A run without a sequence was given no [`crate::io::source::FrameSource`].
    #[error("no frames to track: the inputs have no sequence and the run no frame source")]
    NoSource,
    /// The objects of a run of several cannot be tracked together (none,
    /// two of the same name, a name that cannot be a CSV field).
    #[error(transparent)]
    Objects(#[from] crate::tracker::MultiError),
    /// An output would overwrite one of the run's inputs.
    #[error(transparent)]
    Clobber(#[from] crate::io::guard::ClobberError),
    /// The live view failed.
    #[error(transparent)]
    View(#[from] ViewError),
}

impl From<SourceError> for AppError {
    fn from(e: SourceError) -> Self {
        match e {
            SourceError::Sequence(e) => AppError::Sequence(e),
            SourceError::Video(e) => AppError::Video(e),
        }
    }
}
