//! # splattrack
//!
//! Tracks the 6-DoF pose of a rigid object through a monocular video, given a
//! point-based 3D model of the object (a PLY point cloud), after Dehais, Morin
//! & Charvillat, "From rendering to tracking point-based 3D models", Image and
//! Vision Computing 28 (2010).
//!
//! Modules, one concern each:
//! - [`model`]: point models from PLY (normals and radii estimated when absent),
//!   meshes sampled into points;
//! - [`geometry`]: intrinsics, poses (SE(3)), the projection, its Jacobian and
//!   the motion predictors: the host reference for every GPU kernel;
//! - [`gpu`]: the headless wgpu context, readback helpers, GPU timers;
//! - [`shaders`]: the WGSL sources, validated by naga;
//! - [`io`]: pose CSVs and raw `.npy` images;
//! - [`features`]: Harris corners and NCC matching (GPU, with CPU references).

pub mod features;
pub mod geometry;
pub mod gpu;
pub mod io;
pub mod model;
pub mod rng;
pub mod shaders;

pub use geometry::{Intrinsics, Pose};
pub use gpu::{AdapterChoice, GpuContext};
pub use model::PointModel;
