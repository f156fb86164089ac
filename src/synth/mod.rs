//! Synthetic sequences with exact ground truth (docs/accuracy.md).
//!
//! How it works: a built-in procedural object ([`objects`]) is rendered as a
//! textured triangle mesh by an ordinary CPU rasteriser ([`raster`]), never by
//! the splatter under test, over a static background ([`Background`]: flat
//! shapes by default, or clutter with distractor objects in the object's own
//! colours), lit by a slowly moving light, with sensor noise, along a
//! trajectory ([`Trajectory`]). The point model is sampled from the mesh
//! surface, as a scanner would sample it, with the texture's colours.
//! Keyframes are rendered the same way from viewpoints spread over the
//! viewing sphere. [`framing`] measures and sets where the object sits in
//! the image (its size, how much of it is outside).
//!
//! [`MultiScene`] renders several objects that cross and hide each other,
//! all in one rasterisation with one depth test, with the visible fraction
//! of each from the rasteriser's object ids ([`multi`]).

#![warn(missing_docs)]

mod background;
mod error;
pub mod framing;
pub mod multi;
pub mod objects;
pub mod raster;
mod scene;
pub mod sequence;

pub use background::{Background, background};
pub use multi::{Layout, MultiConfig, MultiFrame, MultiObject, MultiScene};
pub use objects::{Light, SynthObject, Texture};
pub use scene::{
    SynthConfig, SynthFrame, SynthScene, Trajectory, base_pose, keyframe_images, keyframe_poses,
    render_frame, to_image, trajectory_pose,
};

#[cfg(test)]
mod multi_tests;
#[cfg(test)]
mod scene_tests;
