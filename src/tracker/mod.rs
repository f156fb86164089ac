//! The tracker (Dehais et al. 2010, sections 4 and 5): iterative
//! frame-to-frame tracking (IT), tracking against keyframe-textured novel
//! views (KF), and both in turn (KF+IT).
//!
//! How it works, per frame `t` (docs/how-it-works.md):
//! 1. Harris corners of the frame, inside the object's projected bounding
//!    circle (plus a margin) at the previous pose.
//! 2. IT: the motion predictors are splatted at the previous pose `E_{t-1}`;
//!    the previous frame's corners that land on the object (the splat covers
//!    them) are matched to the new corners by NCC (mutual best within a
//!    search radius); the predictors gathered at the old positions and the
//!    displacements give a robust update `a` (IRLS):
//!    `E_t' = exp(a^) E_{t-1}`.
//! 3. KF: the keyframe whose viewpoint is closest to `E_t'` textures the model;
//!    a novel view and its predictors are splatted at `E_t'` in one pass;
//!    corners of the novel view (never on its empty pixels) are matched to the
//!    frame's corners, and IRLS gives the correction: `E_t = exp(a'^) E_t'`.
//! 4. Each step is refined beyond the paper's single linear solve by a few
//!    Gauss-Newton iterations ([`crate::pose::Refiner`]): the matched points
//!    are lifted to 3-D with the splatted depth, re-projected at the updated
//!    pose, and the residuals solved again with the same robust loss
//!    (measured: it removes the first-order error of large motions).
//! 5. The KF result is used when enough inliers survive with a small
//!    residual, else the IT result (KF+IT keeps tracking frame to frame
//!    through a frame the keyframes cannot explain); when neither holds the
//!    frame is `lost`: the pose stays at the last good one, and the next
//!    frames try to recover against the keyframes with a wide search
//!    ([`decide`], a pure function with a typed [`LostReason`]).
//!
//! Files: `config.rs` (settings), `execution.rs` (the code paths),
//! `builder.rs` (making a tracker), `state.rs` (what it keeps),
//! `frame.rs` ([`Tracker::track`] running the steps in turn), `it.rs` and
//! `kf.rs` (the texture steps: each gathers correspondences on the GPU and
//! solves them), `contour/` (the contour step), `search.rs`,
//! `templates.rs`, `detect/` and `init.rs` (the search for the object),
//! `lost/` (that search in slices while the track is lost), `frames.rs`
//! (a frame as the steps see it), `check.rs` and `verify.rs` (the check of a
//! pose against the image), `decision.rs` (the rules), `result.rs` (what a
//! frame reports), `error.rs`, `region.rs` and `workspace.rs` (where the
//! steps work: the object's region of the image, its renders and reads),
//! `profile.rs` (GPU timing), `multi.rs` (several objects in one video).

#![warn(missing_docs)]

mod builder;
mod check;
mod config;
pub mod contour;
pub mod cues;
mod decision;
mod detect;
mod drift;
mod error;
mod execution;
mod features_on;
mod frame;
mod frames;
pub mod init;
mod it;
mod kf;
mod lost;
mod multi;
mod occlusion;
pub mod outline_gpu;
mod profile;
mod recent;
mod recovery;
mod region;
mod result;
mod search;
mod shading;
mod state;
mod steady;
mod templates;
pub mod verify;
pub mod verify_gpu;
mod workspace;

pub use builder::TrackerBuilder;
pub use config::{CueChoice, Modalities, Mode, TrackerConfig};
pub use contour::ContourConfig;
pub use decision::{Decision, Estimate, FrameSteps, Rules, StepOutcome, decide, verified};
pub use detect::DetectConfig;
pub use error::{CameraInvalid, ConfigError, TrackError};
pub use execution::Execution;
pub use init::InitConfig;
pub use multi::{MultiError, MultiTracker};
pub use result::{
    GpuMemoryUse, LostReason, NovelView, Refused, Source, Stage, StageTimes, StageWaits, Status,
    StepError, TrackResult,
};
pub use state::Tracker;
pub use verify::{Unverified, VerifyConfig, VerifyScores};
