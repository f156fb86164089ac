//! Files on disk (docs/formats.md): sequence directories, pose CSVs, BOP
//! results, raw float images (.npy), all written crash-safely
//! ([`atomic`]); frames from a sequence, a video file or a camera
//! ([`source`], [`video`], [`live`]).

pub mod atomic;
pub mod bop;
pub mod camera;
pub mod correspondences;
pub mod ffmpeg;
#[doc(hidden)]
pub mod fuzz_entry;
pub mod guard;
pub mod live;
pub mod npy;
pub mod poses;
pub mod sequence;
pub mod source;
// The real data for the readers' unit tests, as the integration tests find it.
#[cfg(test)]
#[path = "../../tests/data_common/mod.rs"]
mod testing;
pub mod video;

pub use atomic::{PartialFile, WriteError, write_atomic};
pub use bop::BopWriter;
pub use poses::{PoseRow, PoseWriter, read_poses, write_poses};
pub use sequence::{Frame, Sequence};
pub use source::{FrameSource, SourceError, Start};
