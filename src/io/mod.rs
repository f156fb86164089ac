//! Files on disk (FORMATS.md): pose CSVs, raw float images (.npy).

pub mod camera;
pub mod npy;
pub mod poses;
pub mod sequence;

pub use poses::{PoseRow, read_poses, write_poses};
pub use sequence::Sequence;
