//! The exceptions: `splattrack.Error` and its subclasses for files, the
//! GPU and tracking, with the library's one-line messages (those the
//! command line prints); `ValueError` for arguments of the wrong shape,
//! type or range.

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use splattrack::app::AppError;
use splattrack::tracker::TrackError as LibTrackError;

create_exception!(
    splattrack,
    Error,
    PyException,
    "The base of splattrack's errors (files, the GPU, tracking)."
);
create_exception!(
    splattrack,
    ModelError,
    Error,
    "A model file that cannot be read or used."
);
create_exception!(
    splattrack,
    InputError,
    Error,
    "A camera, keyframe, pose, image or video file that cannot be read or used."
);
create_exception!(
    splattrack,
    GpuError,
    Error,
    "No usable GPU adapter, or the device failed."
);
create_exception!(
    splattrack,
    TrackError,
    Error,
    "The tracker cannot start or go on (a lost frame is not an error)."
);

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("Error", py.get_type::<Error>())?;
    m.add("ModelError", py.get_type::<ModelError>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("GpuError", py.get_type::<GpuError>())?;
    m.add("TrackError", py.get_type::<TrackError>())?;
    Ok(())
}

/// A GPU error.
pub fn gpu(e: impl std::fmt::Display) -> PyErr {
    GpuError::new_err(e.to_string())
}

/// A file that cannot be read or used.
pub fn input(e: impl std::fmt::Display) -> PyErr {
    InputError::new_err(e.to_string())
}

/// An error of the application layer (loading models, cameras, keyframes).
pub fn app(e: AppError) -> PyErr {
    let msg = e.to_string();
    match e {
        AppError::Model(_) => ModelError::new_err(msg),
        AppError::Splat(_) => GpuError::new_err(msg),
        AppError::Start { source, .. } => track(*source),
        AppError::Camera(_)
        | AppError::Sequence(_)
        | AppError::Video(_)
        | AppError::Poses(_)
        | AppError::Keyframes(_)
        | AppError::NotKeyframes(_)
        | AppError::BuildKeyframes { .. }
        | AppError::Undistort { .. } => InputError::new_err(msg),
        _ => Error::new_err(msg),
    }
}

/// An error of the tracker: arguments (a frame of the wrong size, settings
/// or a pose out of range) as `ValueError`, the GPU's as `GpuError`.
pub fn track(e: LibTrackError) -> PyErr {
    let msg = e.to_string();
    match e {
        LibTrackError::FrameSize { .. }
        | LibTrackError::Config(_)
        | LibTrackError::Camera(_)
        | LibTrackError::Pose(_)
        | LibTrackError::ObjectNotInView => PyValueError::new_err(msg),
        LibTrackError::Splat(_) | LibTrackError::Features(_) | LibTrackError::Search(_) => {
            GpuError::new_err(msg)
        }
        LibTrackError::Keyframes(_) => InputError::new_err(msg),
        _ => TrackError::new_err(msg),
    }
}
