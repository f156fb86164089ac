//! # splattrack
//!
//! Tracks the 6-DoF pose of a rigid object through a monocular video, given a
//! point-based 3D model of the object (a PLY point cloud), after Dehais, Morin
//! & Charvillat, "From rendering to tracking point-based 3D models", Image and
//! Vision Computing 28 (2010).
//!
//! Modules, one concern each:
//! - [`model`]: point models from PLY (normals and radii estimated when absent),
//!   triangle meshes sampled into points, shapes with a known surface;
//! - [`geometry`]: intrinsics, poses (SE(3)), the projection, its Jacobian and
//!   the motion predictors: the host reference for every GPU kernel;
//! - [`device`]: where the frame loop runs: a GPU through wgpu, or the
//!   host's cores with no graphics driver ([`Device`]);
//! - [`gpu`]: the headless wgpu context, readback, bind-group and pipeline
//!   helpers, GPU timers;
//! - [`shaders`]: the WGSL sources, composed with a prelude generated from
//!   the Rust constants and validated by naga (with the Rust/WGSL struct
//!   layouts checked against each other);
//! - [`splat`]: GPU EWA surface splatting (novel views, depth, motion
//!   predictors) and its CPU reference;
//! - [`features`]: Harris corners and NCC matching (GPU, with CPU references);
//! - [`pose`]: the robust (IRLS) pose update from matches and its
//!   Gauss-Newton refinement;
//! - [`keyframes`]: the keyframe store (per-point colours from keyframes);
//! - [`tracker`]: the IT, KF and KF+IT trackers (settings, steps, and the
//!   tracking/lost decision);
//! - [`synth`]: synthetic sequences with exact ground truth (a CPU triangle
//!   rasteriser, also the splatter's independent reference in tests);
//! - [`eval`], [`plot`], [`draw`]: errors against ground truth and pictures;
//! - [`io`]: camera files, sequence directories (frames undistorted), pose
//!   CSVs and BOP results written crash-safely, raw `.npy` images;
//! - [`app`]: the application layer: a tracking run over a sequence with
//!   its keyframe store and outputs, as the command line does it;
//! - [`progress`]: progress of long jobs, for the caller to draw.
//!
//! # Example
//!
//! A short synthetic sequence with exact ground truth ([`synth`]), tracked
//! frame to frame from its first pose (any Vulkan adapter: a GPU, or Mesa's
//! software lavapipe):
//!
//! ```
//! use splattrack::io::{Sequence, read_poses};
//! use splattrack::synth::{SynthConfig, sequence::write_sequence};
//! use splattrack::tracker::{Mode, Status, Tracker, TrackerConfig};
//! use splattrack::{AdapterChoice, GpuContext, Intrinsics, PointModel};
//!
//! let dir = std::env::temp_dir().join("splattrack-crate-example");
//! let camera = Intrinsics::new(320, 240, 300.0, 300.0, 159.5, 119.5);
//! let synth = SynthConfig { frames: 4, camera, ..Default::default() };
//! write_sequence(&synth, &dir, 20_000, None)?; // frames, model.ply, init.csv, poses.csv
//!
//! let ctx = GpuContext::new(&AdapterChoice::from_env()?)?; // $SPLATTRACK_ADAPTER
//! let seq = Sequence::open(&dir)?;
//! let model = PointModel::load(dir.join("model.ply"))?;
//! let first = read_poses(&seq.init_path())?[0].pose;
//! let config = TrackerConfig { mode: Mode::It, ..Default::default() }; // no keyframes needed
//! let mut tracker = Tracker::builder(&ctx, model, seq.tracking_camera())
//!     .config(config)
//!     .initial_pose(first)
//!     .build()?;
//! for frame in seq.iter_frames() {
//!     let r = tracker.track(&frame?.image)?;
//!     assert_eq!(r.status, Status::Tracking, "{:?}", r.reason);
//! }
//! # std::fs::remove_dir_all(&dir)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Vocabulary: a *view* is a rendered image of the model (a splatting at a
//! pose); the *live view* ([`view`]) is the display that shows each
//! tracked frame as it is tracked, in an OS window (`view::DisplaySink`);
//! a *window* is the object's region of the image ([`splat::Window`]), the
//! part of a frame the tracker works in; a *patch* is the square of pixels
//! around a corner that NCC correlates ([`features::NccConfig::patch`]; the
//! paper's correlation window, `--ncc-window` on the command line).

#![warn(missing_docs)]

pub mod app;
pub mod device;
pub mod draw;
pub mod eval;
pub mod features;
pub mod geometry;
pub mod gpu;
pub mod io;
pub mod keyframes;
pub mod model;
pub mod par;
pub mod plot;
pub mod pose;
pub mod progress;
pub mod rng;
pub mod shaders;
pub mod splat;
pub mod synth;
pub mod tracker;
pub mod view;

pub use device::{Device, DeviceChoice};
pub use geometry::{Intrinsics, Pose};
pub use gpu::{AdapterChoice, GpuContext};
pub use model::PointModel;

/// The README's examples, compiled and run as doctests.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
