//! The application layer: what `splattrack track`, `splattrack demo` and a
//! program embedding the crate share. Loading everything a tracking run
//! needs ([`TrackInputs`], and [`ObjectInputs`] for each object of a run
//! of several), the keyframe store from a file or from keyframe images
//! ([`load_keyframes`], [`load_or_build_keyframes`]), and the run over a
//! sequence, a video or a camera ([`TrackRun`], frames from any
//! [`crate::io::source::FrameSource`]): frames in order, undistorted, one
//! pose row per frame and object written as it is tracked (crash-safe),
//! optional overlays and BOP results, progress through a
//! [`crate::progress::ProgressFn`], a callback per frame and a
//! [`crate::view::FrameSink`] (the live view).

mod error;
mod inputs;
mod keyframes;
mod objects;
pub mod refused;
mod rows;
mod run;
mod stats;
mod tuning;

pub use error::AppError;
pub use inputs::{ObjectInputs, TrackInputs};
pub use keyframes::{KeyframeOrigin, build_keyframes, load_keyframes, load_or_build_keyframes};
pub use rows::{RESULT_COLUMNS, TIME_COLUMN, cues_name, result_row};
pub use run::{TRACKING_STAGE, TrackRun};
pub use stats::{FrameMs, ObjectStats, RunStats};
pub use tuning::{MAX_CORNERS, Tuning, TuningError, run_mode};
