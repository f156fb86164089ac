//! The errors of writing and reading synthetic sequences.

use std::path::PathBuf;

/// Errors of writing a synthetic sequence and reading its files back.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// No built-in object has this name.
    #[error("unknown object {0:?} (built-in objects: {list})", list = super::objects::OBJECT_NAMES.join(", "))]
    UnknownObject(String),
    /// A directory or file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// An image could not be encoded or written.
    #[error("{path}: cannot write image: {source}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// Why.
        #[source]
        source: image::ImageError,
    },
    /// Sampling or saving the point model failed.
    #[error(transparent)]
    Model(#[from] crate::model::ModelError),
    /// Writing a pose file failed.
    #[error(transparent)]
    Poses(#[from] crate::io::poses::PoseFileError),
    /// A sequence needs at least two frames (the trajectory's start and end).
    #[error("a sequence needs at least 2 frames, got {0}")]
    TooFewFrames(usize),
    /// A visibility file is malformed.
    #[error("{path}, line {line}: {reason}")]
    Visibility {
        /// The file.
        path: PathBuf,
        /// The 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A scene of several objects was given the wrong number of them.
    #[error("scene {layout} takes {want} objects, got {got}")]
    ObjectCount {
        /// The scene's layout.
        layout: &'static str,
        /// How many it takes.
        want: usize,
        /// How many it was given.
        got: usize,
    },
}
