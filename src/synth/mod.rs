//! Synthetic sequences with exact ground truth (docs/accuracy.md).
//!
//! How it works: a built-in procedural object ([`objects`]) is rendered as a
//! textured triangle mesh by an ordinary CPU rasteriser ([`raster`]), never by
//! the splatter under test, over a cluttered background, lit by a slowly
//! moving light, with sensor noise, along a trajectory ([`Trajectory`]). The
//! point model is sampled from the mesh surface, as a scanner would sample
//! it, with the texture's colours. Keyframes are rendered the same way from
//! viewpoints spread over the viewing sphere.

#![warn(missing_docs)]

pub mod objects;
pub mod raster;
mod scene;
pub mod sequence;

pub use objects::{Light, SynthObject, Texture};
pub use scene::{
    SynthConfig, SynthFrame, Trajectory, background, base_pose, keyframe_images, keyframe_poses,
    render_frame, to_image, trajectory_pose,
};
