//! The tracker (Dehais et al. 2010, sections 4 and 5): iterative
//! frame-to-frame tracking (IT), tracking against keyframe-textured novel
//! views (KF), and both in turn (KF+IT).
//!
//! How it works, per frame `t` (DESIGN.md section 4):
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
//! Files: `config.rs` (settings), `it.rs` and `kf.rs` (the steps: each
//! gathers correspondences on the GPU and solves them), `decision.rs` (the
//! rules), this file (the state, and [`Tracker::track`] running the steps
//! in turn). A further source of residual rows (e.g. contours) is another
//! step file feeding the same [`crate::pose::Refiner`].

#![warn(missing_docs)]

mod config;
pub mod contour;
mod decision;
pub mod init;
mod it;
mod kf;
mod learner;
pub mod outline_gpu;
mod profile;
pub mod verify;
pub mod verify_gpu;
mod view;

pub use config::{ConfigError, Modalities, Mode, TrackerConfig};
pub use contour::ContourConfig;
pub use decision::{
    Decision, Estimate, FrameSteps, LostReason, Rules, Stage, Status, StepError, StepOutcome,
    decide, verified,
};
pub use init::InitConfig;
pub use verify::{Unverified, VerifyConfig, VerifyScores};

use crate::features::{Corner, GreyImage, Harris, NccMatcher};
use crate::geometry::{Intrinsics, Pose};
use crate::gpu::GpuContext;
use crate::keyframes::KeyframeStore;
use crate::model::PointModel;
use crate::pose::{Anchor, Correspondence, Observation, Refined, Refiner};
use crate::splat::{Attribute, Attributes, GatherSample, GpuModel, SplatTargets, Splatter, Window};
use nalgebra::{Matrix3, Vector2, Vector3};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Wall-clock time of each stage of one frame (GPU work included, since
/// every stage waits for its results).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StageTimes {
    /// Harris corners of the frame.
    pub features: Duration,
    /// The frame-to-frame step.
    pub it: Duration,
    /// The keyframe step(s).
    pub kf: Duration,
    /// The contour step (its iterations).
    #[serde(default)]
    pub contour: Duration,
    /// The check of the reported pose against the image.
    #[serde(default)]
    pub verify: Duration,
    /// The whole-frame search for the object (initialisation, re-detection).
    #[serde(default)]
    pub search: Duration,
    /// Within IT: the render at the previous pose and the gathers.
    #[serde(default)]
    pub it_render: Duration,
    /// Within IT: NCC matching.
    #[serde(default)]
    pub it_ncc: Duration,
    /// Within KF: the novel view's render and read-back.
    #[serde(default)]
    pub kf_render: Duration,
    /// Within KF: Harris corners of the novel view.
    #[serde(default)]
    pub kf_harris: Duration,
    /// Within KF: NCC matching, the gathers and the sub-pixel refinement.
    #[serde(default)]
    pub kf_ncc: Duration,
    /// GPU time of each pass, milliseconds, as "stage kernel pass" (from
    /// timestamp queries; empty unless [`Tracker::enable_gpu_timing`]).
    #[serde(default)]
    pub gpu: Vec<(String, f64)>,
    /// When the GPU worked during the frame, from the same timestamps:
    /// its passes' busy time and the gaps between them.
    #[serde(default)]
    pub gpu_timeline: crate::gpu::GpuTimeline,
    /// Bytes read back from the GPU during the call
    /// ([`GpuStats::bytes_read`](crate::gpu::GpuStats::bytes_read); a mean over frames is fractional).
    #[serde(default)]
    pub readback_bytes: f64,
    /// Readbacks (waits for the GPU) during the call
    /// ([`GpuStats::readbacks`](crate::gpu::GpuStats::readbacks)).
    #[serde(default)]
    pub readbacks: f64,
    /// The time the host spent blocked in those readbacks' waits
    /// ([`GpuStats::wait_time`](crate::gpu::GpuStats::wait_time)): the GPU's work queued before them and the
    /// round trip; the rest of `total` is the host's own work.
    #[serde(default)]
    pub gpu_wait: Duration,
    /// That time by stage.
    #[serde(default)]
    pub waits: StageWaits,
    /// The host's time finishing command encoders (wgpu's encoding and
    /// validation of the passes; [`GpuStats::finish_time`](crate::gpu::GpuStats::finish_time)): part of its
    /// own work.
    #[serde(default)]
    pub gpu_finish: Duration,
    /// The host's time in `Queue::submit` ([`GpuStats::submit_time`](crate::gpu::GpuStats::submit_time)).
    #[serde(default)]
    pub gpu_submit: Duration,
    /// Submissions of GPU work during the call
    /// ([`GpuStats::submissions`](crate::gpu::GpuStats::submissions)).
    #[serde(default)]
    pub submissions: f64,
    /// Command buffers in those submissions
    /// ([`GpuStats::command_buffers`](crate::gpu::GpuStats::command_buffers)).
    #[serde(default)]
    pub command_buffers: f64,
    /// Uploads during the call ([`GpuContext::write_buffer`]: each a
    /// staging buffer of wgpu's), and parameter uploads skipped as
    /// unchanged ([`crate::gpu::Uniform`]).
    #[serde(default)]
    pub uploads: f64,
    /// Parameter uploads skipped as unchanged during the call.
    #[serde(default)]
    pub uploads_skipped: f64,
    /// Passes recorded during the call ([`GpuStats::passes`](crate::gpu::GpuStats::passes)): one a
    /// stage where `--profile`'s timer times them.
    #[serde(default)]
    pub passes: f64,
    /// The passes an untimed call records (a chain of stages in one).
    #[serde(default)]
    pub passes_untimed: f64,
    /// Rounds (searches and solves) of the contour step during the call
    /// (a mean over frames is fractional).
    #[serde(default)]
    pub contour_rounds: f64,
    /// The renders of those rounds (a round after a small correction moves
    /// the last render's points instead).
    #[serde(default)]
    pub contour_renders: f64,
    /// The contour's colour learning from a tracked frame, wherever it ran:
    /// by default on a thread of its own, beside the next frame's texture
    /// steps (counted in the frame it finished in, and not in `total`
    /// then); see [`Tracker::set_background_learning`].
    #[serde(default)]
    pub colour_learning: Duration,
    /// Within the contour step: waiting for that thread to finish the
    /// previous frame's learning.
    #[serde(default)]
    pub colour_wait: Duration,
    /// The whole call to [`Tracker::track`].
    pub total: Duration,
}

/// The host's time blocked waiting for the GPU within each stage of
/// [`StageTimes`] ([`GpuStats::wait_time`](crate::gpu::GpuStats::wait_time)): what the stage's time is not
/// the host's own work.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StageWaits {
    /// In [`StageTimes::features`].
    pub features: Duration,
    /// In [`StageTimes::it`].
    pub it: Duration,
    /// In [`StageTimes::kf`].
    pub kf: Duration,
    /// In [`StageTimes::contour`].
    pub contour: Duration,
    /// In [`StageTimes::verify`].
    pub verify: Duration,
    /// In [`StageTimes::search`].
    pub search: Duration,
}

impl StageTimes {
    /// Adds `other`'s times multiplied by `k` (for means over frames).
    pub fn add_scaled(&mut self, other: &StageTimes, k: f64) {
        let pairs = [
            (&mut self.features, other.features),
            (&mut self.it, other.it),
            (&mut self.kf, other.kf),
            (&mut self.contour, other.contour),
            (&mut self.verify, other.verify),
            (&mut self.search, other.search),
            (&mut self.it_render, other.it_render),
            (&mut self.it_ncc, other.it_ncc),
            (&mut self.kf_render, other.kf_render),
            (&mut self.kf_harris, other.kf_harris),
            (&mut self.kf_ncc, other.kf_ncc),
            (&mut self.colour_learning, other.colour_learning),
            (&mut self.colour_wait, other.colour_wait),
            (&mut self.gpu_wait, other.gpu_wait),
            (&mut self.gpu_finish, other.gpu_finish),
            (&mut self.gpu_submit, other.gpu_submit),
            (&mut self.waits.features, other.waits.features),
            (&mut self.waits.it, other.waits.it),
            (&mut self.waits.kf, other.waits.kf),
            (&mut self.waits.contour, other.waits.contour),
            (&mut self.waits.verify, other.waits.verify),
            (&mut self.waits.search, other.waits.search),
            (&mut self.total, other.total),
        ];
        for (acc, d) in pairs {
            *acc += d.mul_f64(k);
        }
        self.readback_bytes += other.readback_bytes * k;
        self.readbacks += other.readbacks * k;
        self.submissions += other.submissions * k;
        self.uploads += other.uploads * k;
        self.uploads_skipped += other.uploads_skipped * k;
        self.passes += other.passes * k;
        self.passes_untimed += other.passes_untimed * k;
        self.command_buffers += other.command_buffers * k;
        self.contour_rounds += other.contour_rounds * k;
        self.contour_renders += other.contour_renders * k;
        for (label, ms) in &other.gpu {
            profile::add(&mut self.gpu, label, ms * k);
        }
        self.gpu_timeline.add_scaled(&other.gpu_timeline, k);
    }
}

/// What [`Tracker::track`] says about a frame. Serialised field by field
/// (a NaN residual as `null`).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct TrackResult {
    /// The object-to-camera pose of the frame; on a lost frame, the last
    /// good pose (a pose that failed is never reported).
    pub pose: Pose,
    /// Inliers of the last robust solve of this frame.
    pub inliers: usize,
    /// Their RMS reprojection residual, pixels (NaN on a lost frame
    /// without any solve).
    #[serde(with = "nan_as_null")]
    pub residual_px: f64,
    /// Whether the track holds at this frame.
    pub status: Status,
    /// Why the frame is lost (when it is); its `Display` is the text.
    pub reason: Option<LostReason>,
    /// The keyframe used by the KF step, if any.
    pub keyframe: Option<usize>,
    /// Where the time went.
    pub times: StageTimes,
    /// What the check of the pose against the image measured (`None`
    /// when it did not run: verification off, or no pose to check).
    #[serde(default)]
    pub verify: Option<VerifyScores>,
    /// Whether the texture steps were trusted but their pose failed the
    /// check on its appearance, so that the contour alone gave this
    /// frame's pose (checked by its edges): the texture matched something
    /// the keyframes do not show, such as an untextured object's shading.
    #[serde(default)]
    pub texture_set_aside: bool,
}

/// serde of an `f64` that may be NaN, which JSON cannot write: NaN as
/// `null`, and back.
mod nan_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_nan() {
            s.serialize_none()
        } else {
            s.serialize_some(v)
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }
}

/// Errors that stop tracking (bad input, GPU failure), as opposed to a
/// frame that is merely lost.
#[derive(Debug, thiserror::Error)]
pub enum TrackError {
    /// [`Tracker::track`] got a frame whose size is not the camera's.
    #[error("frame is {got_w}x{got_h}, the camera is {want_w}x{want_h}")]
    FrameSize {
        /// The frame's width, pixels.
        got_w: u32,
        /// The frame's height, pixels.
        got_h: u32,
        /// The camera's width, pixels.
        want_w: u32,
        /// The camera's height, pixels.
        want_h: u32,
    },
    /// The KF and KF+IT modes (named) need a texture for the novel views:
    /// a keyframe store, or colours in the model.
    #[error("mode {0} needs keyframes or a model with colours")]
    NeedsKeyframes(&'static str),
    /// The initial pose puts the object behind the camera or wholly
    /// outside the image.
    #[error("the initial pose puts the object behind the camera or outside the image")]
    ObjectNotInView,
    /// The settings are out of range.
    #[error("tracker settings: {0}")]
    Config(#[from] ConfigError),
    /// The camera's intrinsics are impossible.
    #[error(transparent)]
    Camera(#[from] CameraInvalid),
    /// The splatter failed (GPU error, unusable model).
    #[error(transparent)]
    Splat(#[from] crate::splat::SplatError),
    /// Feature detection or matching failed on the GPU.
    #[error(transparent)]
    Features(#[from] crate::features::FeatureError),
    /// The initial pose is not a rigid transform.
    #[error(transparent)]
    Pose(#[from] crate::geometry::PoseError),
    /// The keyframe store is unusable.
    #[error(transparent)]
    Keyframes(#[from] crate::keyframes::KeyframeError),
    /// The GPU failed during the search for the object.
    #[error("searching for the object: {0}")]
    Search(String),
}

/// A device error outside the splatter and the features (the pose
/// check's scores): reported as the splatter's, as before.
impl From<crate::gpu::GpuError> for TrackError {
    fn from(e: crate::gpu::GpuError) -> Self {
        TrackError::Splat(crate::splat::SplatError::from(e))
    }
}

/// An impossible camera.
#[derive(Debug, thiserror::Error)]
#[error("impossible camera: {0}")]
pub struct CameraInvalid(pub String);

/// A frame as the steps see it (the one being tracked, and the previous
/// one for IT): its bytes, kept (the next frame's frozen check compares
/// them), its corners, and its grey levels, made from the bytes when a
/// host path first asks for them ([`Frame::grey`]). The resident loop
/// never does: the GPU makes its own grey image from the uploaded bytes
/// ([`crate::features::resident::FrameIntake`]).
struct Frame {
    rgb: image::RgbImage,
    grey: std::sync::OnceLock<GreyImage>,
    corners: Vec<Corner>,
}

impl Frame {
    /// Frame `rgb`, its corners to come.
    fn new(rgb: image::RgbImage) -> Self {
        Self {
            rgb,
            grey: std::sync::OnceLock::new(),
            corners: Vec::new(),
        }
    }

    /// The frame's grey levels ([`GreyImage::from_rgb8`]), made at the
    /// first call.
    fn grey(&self) -> &GreyImage {
        self.grey.get_or_init(|| GreyImage::from_rgb8(&self.rgb))
    }

    /// The whole frame as a window.
    fn whole(&self) -> crate::splat::Window {
        crate::splat::Window {
            x0: 0,
            y0: 0,
            width: self.rgb.width(),
            height: self.rgb.height(),
        }
    }
}

/// The tracker: create once per sequence, then call [`Tracker::track`] on
/// each frame in order. It keeps its own handle on the GPU context (a
/// cheap clone), so a program may keep both side by side.
///
/// ```no_run
/// use splattrack::gpu::{AdapterChoice, GpuContext};
/// use splattrack::io::{Sequence, read_poses};
/// use splattrack::keyframes::KeyframeStore;
/// use splattrack::tracker::{Mode, Status, Tracker, TrackerConfig};
/// use splattrack::PointModel;
/// use std::path::Path;
///
/// let ctx = GpuContext::new(&AdapterChoice::from_env()?)?;
/// let model = PointModel::load("object.ply")?;
/// let seq = Sequence::open(Path::new("sequence"))?; // camera.json, frames/, init.csv
/// let init = read_poses(&seq.init_path())?[0].pose;
/// // A store built once by `splattrack keyframes` (or KeyframeStore::build).
/// let store = KeyframeStore::load(Path::new("object.stkf"))?;
/// store.check_model(&model, Path::new("object.stkf"))?;
/// let config = TrackerConfig { mode: Mode::KfIt, ..Default::default() };
/// let mut tracker = Tracker::new(&ctx, model, seq.camera, Some(store), config, init)?;
/// for path in &seq.frames {
///     let frame = image::open(path)?.to_rgb8(); // undistorted, the camera's size
///     let r = tracker.track(&frame)?;
///     println!("{} {:?} {} inliers", r.status, r.pose.translation, r.inliers);
///     if let Some(reason) = &r.reason {
///         // Lost: r.pose is the last good pose; later frames try to recover.
///         println!("lost: {reason}");
///     }
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Tracker {
    cam: Intrinsics,
    config: TrackerConfig,
    /// The model as splatted (its radii raised and grown); the caller's
    /// own, shared, where they needed no change.
    model: Arc<PointModel>,
    store: Option<Arc<KeyframeStore>>,
    splatter: Splatter,
    geometry: GpuModel,
    textured: crate::keyframes::TexturedCache,
    /// The targets of the last render, the size of [`Tracker::window`].
    targets: SplatTargets,
    /// The window of the last render (frame coordinates).
    window: Window,
    /// Targets of other window sizes, for reuse.
    spare: Vec<SplatTargets>,
    /// The check's render of the last reported pose, for the next IT step.
    kept: Option<view::Kept>,
    /// The model's bounding box grown by its largest splat (where renders
    /// can cover pixels).
    box_lo: Vector3<f64>,
    box_hi: Vector3<f64>,
    harris: Harris,
    it_matcher: NccMatcher,
    kf_matcher: NccMatcher,
    recover_matcher: NccMatcher,
    center: Vector3<f64>,
    radius: f64,
    pose: Pose,
    prev: Option<Frame>,
    /// The bytes of the frame before `prev`, a buffer for the next one.
    spare_frame: Option<image::RgbImage>,
    lost_streak: usize,
    /// KF+IT: consecutive frames tracked by IT alone.
    it_only_streak: usize,
    /// No pose yet: each frame is searched ([`Tracker::new_searching`]).
    searching: bool,
    /// The tracker's own handle on the device (a cheap clone).
    ctx: GpuContext,
    /// Contour: the object's and the background's colours, learnt online.
    colours: learner::Colours,
    /// Contour: the coverage of its last render, to learn the colours from
    /// (the frame's size; a buffer kept between frames).
    contour_mask: Vec<bool>,
    /// Contour: whether `contour_mask` is this frame's (a render of this
    /// frame's contour step; cleared when the frame starts and once learnt).
    contour_mask_fresh: bool,
    /// Contour: the model's normals for limbs of depth-only renders
    /// (made on first use).
    model_normals: Option<contour::ModelNormals>,
    /// Contour: the rounds of the frame being tracked.
    contour_rounds: usize,
    /// Contour: the renders of the frame being tracked.
    contour_renders: usize,
    /// The inliers of this frame's last KF step (for the fused solve).
    kf_anchors: Vec<Anchor>,
    /// The sub-stage times of the frame being tracked.
    stages: StageTimes,
    /// Times the splat passes when on ([`Tracker::enable_gpu_timing`]).
    gpu_timer: Option<crate::gpu::GpuTimer>,
    /// The frame's timed passes by label prefix, their timestamps still
    /// to come with the frame's readbacks (read at its end).
    pending_gpu: Vec<(String, crate::gpu::Timings)>,
    /// The check's scoring on the GPU.
    check: verify_gpu::GpuCheck,
    /// The contour's outline found on the GPU.
    outline: outline_gpu::GpuOutline,
    /// The grey levels of the frame being tracked and of the previous one,
    /// on the GPU for NCC and the refinement ([`view::Resident`]).
    resident: view::Resident,
}

impl Tracker {
    /// A tracker for `model` seen by `cam` (undistorted frames), starting at
    /// `initial` (the pose of the first frame given to [`Tracker::track`]).
    /// `keyframes` may be `None` for the IT mode, or when the model has
    /// colours (they then serve as the single texture). `config` must pass
    /// [`TrackerConfig::validate`].
    pub fn new(
        ctx: &GpuContext,
        model: impl Into<Arc<PointModel>>,
        cam: Intrinsics,
        keyframes: Option<KeyframeStore>,
        config: TrackerConfig,
        initial: Pose,
    ) -> Result<Self, TrackError> {
        Self::new_shared(ctx, model, cam, keyframes.map(Arc::new), config, initial)
    }

    /// [`Tracker::new`] with a keyframe store shared with the caller
    /// instead of moved in: a store holds 12 bytes of colour per point and
    /// keyframe (144 MB for a 1M-point model and 12 keyframes), which a
    /// caller that keeps its own (an application tracking several runs
    /// from one set of inputs) need not copy. The model may be shared
    /// likewise (an `Arc<PointModel>`): the tracker copies it only where
    /// it changes its radii (`min_splat_radius_px`, `close_gaps`;
    /// [`Tracker::model`]).
    pub fn new_shared(
        ctx: &GpuContext,
        model: impl Into<Arc<PointModel>>,
        cam: Intrinsics,
        keyframes: Option<Arc<KeyframeStore>>,
        config: TrackerConfig,
        initial: Pose,
    ) -> Result<Self, TrackError> {
        config.validate()?;
        cam.validate().map_err(CameraInvalid)?;
        initial.validate()?;
        let mut model: Arc<PointModel> = model.into();
        let store =
            keyframes.or_else(|| KeyframeStore::from_model_colors(&model, &initial).map(Arc::new));
        if store.is_none() && config.mode != Mode::It {
            return Err(TrackError::NeedsKeyframes(config.mode.name()));
        }
        // The bounding sphere: box centre, farthest point.
        let crate::splat::ModelBounds { center, radius, .. } =
            crate::splat::ModelBounds::of(&model);
        let z0 = initial.transform_point(&center).z;
        let floor = (config.min_splat_radius_px as f64 * z0 / cam.fx.max(cam.fy)) as f32;
        // The radii splatted: the model's, raised to the floor and grown
        // where they leave gaps. Only where they change is the model
        // copied (`Arc::make_mut`); else the caller's is shared as it is
        // (40 bytes a point: 40 MB at 1M points).
        let mut radii: Option<Vec<f32>> = None;
        if floor > 0.0 && floor.is_finite() && model.radii.iter().any(|&r| r.max(floor) != r) {
            radii = Some(model.radii.iter().map(|&r| r.max(floor)).collect());
        }
        if config.close_gaps {
            // A failure (points that all coincide) keeps the radii as they
            // were before.
            let mut grown = radii.clone().unwrap_or_else(|| model.radii.clone());
            match model.close_gaps_of(&mut grown) {
                Ok(c) if c.grown as f64 >= crate::model::GAP_MODEL_FRACTION * c.points as f64 => {
                    log::debug!(
                        "{} of {} splat radii grown to close gaps",
                        c.grown,
                        c.points
                    );
                    radii = Some(grown);
                }
                Ok(c) => {
                    log::debug!(
                        "splat radii kept: only {} of {} leave a gap (pinholes at most)",
                        c.grown,
                        c.points
                    );
                }
                Err(e) => {
                    log::warn!("splat radii kept as given: {e}");
                }
            }
        }
        if let Some(r) = radii {
            Arc::make_mut(&mut model).radii = r;
        }
        let gpu = ctx;
        let splatter = Splatter::with_params(
            gpu,
            crate::splat::SplatParams {
                backend: config.splatter,
                ..Default::default()
            },
        )?;
        let geometry = GpuModel::new(gpu, &model)?;
        let targets = SplatTargets::new(gpu, cam.width, cam.height);
        let (box_lo, box_hi) = {
            let pad = Vector3::repeat(model.radii.iter().fold(0.0f64, |m, &r| m.max(r as f64)));
            let (lo, hi) = model.positions.iter().fold(
                (
                    Vector3::repeat(f64::INFINITY),
                    Vector3::repeat(f64::NEG_INFINITY),
                ),
                |(lo, hi), p| {
                    let p = Vector3::new(p.x as f64, p.y as f64, p.z as f64);
                    (lo.inf(&p), hi.sup(&p))
                },
            );
            (lo - pad, hi + pad)
        };
        let on_host = config.feature_backend.host_on(gpu);
        let mut harris = Harris::new(gpu, config.harris.clone())?;
        harris.set_host(on_host);
        let matcher = |r: f32| {
            let mut m = NccMatcher::new(gpu, config.ncc.clone().with_search_radius(Some(r)))?;
            m.set_host(on_host);
            Ok::<_, crate::features::FeatureError>(m)
        };
        let n_kf = store.as_ref().map_or(0, |s| s.keyframes.len());
        let model_len = model.len();
        let config_colours = (config.contour.bins, config.contour.sectors);
        let resident = config.resident.unwrap_or(!ctx.is_cpu());
        let mut tracker = Self {
            it_matcher: matcher(config.it_search_px)?,
            kf_matcher: matcher(config.kf_search_px)?,
            recover_matcher: matcher(config.recover_search_px)?,
            cam,
            config,
            model,
            store,
            splatter,
            geometry,
            textured: crate::keyframes::TexturedCache::new(
                n_kf,
                model_len,
                crate::keyframes::DEFAULT_TEXTURED_BUDGET,
            ),
            targets,
            window: Window::full(&cam),
            spare: Vec::new(),
            kept: None,
            box_lo,
            box_hi,
            harris,
            center,
            radius,
            pose: initial,
            prev: None,
            spare_frame: None,
            lost_streak: 0,
            it_only_streak: 0,
            searching: false,
            ctx: ctx.clone(),
            colours: learner::Colours::new(config_colours.0, config_colours.1),
            contour_mask: Vec::new(),
            contour_mask_fresh: false,
            model_normals: None,
            contour_rounds: 0,
            contour_renders: 0,
            kf_anchors: Vec::new(),
            stages: StageTimes::default(),
            gpu_timer: None,
            pending_gpu: Vec::new(),
            check: verify_gpu::GpuCheck::new(ctx).map_err(crate::splat::SplatError::from)?,
            outline: outline_gpu::GpuOutline::new(ctx).map_err(crate::splat::SplatError::from)?,
            resident: view::Resident::new(resident),
        };
        tracker.check.set_resident(resident);
        tracker.outline.set_resident(resident);
        if tracker.roi(&initial).is_none() {
            return Err(TrackError::ObjectNotInView);
        }
        Ok(tracker)
    }

    /// A tracker without an initial pose: each frame is searched for the
    /// object ([`init`]) until it is found (until then the frames are
    /// `lost`, reason `not found`), then tracked. Needs a texture
    /// (keyframes or model colours) for the search.
    pub fn new_searching(
        ctx: &GpuContext,
        model: impl Into<Arc<PointModel>>,
        cam: Intrinsics,
        keyframes: Option<KeyframeStore>,
        config: TrackerConfig,
    ) -> Result<Self, TrackError> {
        Self::new_searching_shared(ctx, model, cam, keyframes.map(Arc::new), config)
    }

    /// [`Tracker::new_searching`] with a shared keyframe store (see
    /// [`Tracker::new_shared`]).
    pub fn new_searching_shared(
        ctx: &GpuContext,
        model: impl Into<Arc<PointModel>>,
        cam: Intrinsics,
        keyframes: Option<Arc<KeyframeStore>>,
        config: TrackerConfig,
    ) -> Result<Self, TrackError> {
        let model: Arc<PointModel> = model.into();
        // A placeholder pose: the object's centre on the axis, a third of
        // the image across; the store's own viewpoint when there is one.
        let bounds = crate::splat::ModelBounds::of(&model);
        let placeholder = |r: Matrix3<f64>| {
            let d =
                cam.fx.min(cam.fy) * 2.0 * bounds.radius / (cam.width.min(cam.height) as f64 / 3.0);
            let d = d.max(bounds.radius * 1.5);
            Pose::new(r, Vector3::new(0.0, 0.0, d) - r * bounds.center)
        };
        let initial = match keyframes.as_ref().and_then(|s| s.keyframes.first()) {
            Some(k) => placeholder(k.pose.rotation)?,
            None => placeholder(Matrix3::identity())?,
        };
        let mut t = Self::new_shared(ctx, model, cam, keyframes, config, initial)?;
        if t.store.is_none() {
            return Err(TrackError::NeedsKeyframes("search (no initial pose)"));
        }
        t.searching = true;
        Ok(t)
    }

    /// The model as the tracker splats it: the one it was given (the
    /// same `Arc`) where its radii needed no change, else a copy with the
    /// radii raised to `min_splat_radius_px` and grown to close gaps.
    pub fn model(&self) -> &Arc<PointModel> {
        &self.model
    }

    /// Whether no pose has been found yet ([`Tracker::new_searching`]).
    pub fn searching(&self) -> bool {
        self.searching
    }

    /// The current pose estimate.
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// The settings the tracker runs with.
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// The GPU context the tracker runs on.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// The keyframe store in use: the one given to [`Tracker::new`], or
    /// the single texture made from the model's colours, or none (IT mode).
    pub fn keyframes(&self) -> Option<&KeyframeStore> {
        self.store.as_deref()
    }

    /// The radius, pixels, of the object's bounding sphere seen at `pose`
    /// (at its centre's depth; not positive behind the camera).
    pub(super) fn radius_px(&self, pose: &Pose) -> f64 {
        let c = pose.transform_point(&self.center);
        self.cam.fx.max(self.cam.fy) * self.radius / c.z
    }

    /// The object's projected bounding circle plus the margin, as a pixel
    /// rectangle (x0, y0, x1, y1) clipped to the image; `None` when the
    /// object is behind the camera or wholly outside the image.
    fn roi(&self, pose: &Pose) -> Option<(usize, usize, usize, usize)> {
        let c = pose.transform_point(&self.center);
        if c.z <= self.radius * 0.1 {
            return None;
        }
        let uv = self.cam.project(&c)?;
        let r = self.cam.fx.max(self.cam.fy) * self.radius / (c.z - self.radius).max(c.z * 0.1)
            + self.config.roi_margin_px;
        let (w, h) = (self.cam.width as f64, self.cam.height as f64);
        let x0 = (uv.x - r).floor().max(0.0);
        let y0 = (uv.y - r).floor().max(0.0);
        let x1 = (uv.x + r).ceil().min(w - 1.0);
        let y1 = (uv.y + r).ceil().min(h - 1.0);
        (x0 <= x1 && y0 <= y1).then_some((x0 as usize, y0 as usize, x1 as usize, y1 as usize))
    }

    /// Tracks one frame (RGB, undistorted, the camera's size): Harris
    /// corners, the IT step, the KF step(s), then [`decide`].
    pub fn track(&mut self, frame: &image::RgbImage) -> Result<TrackResult, TrackError> {
        let rgb = frame;
        if frame.width() != self.cam.width || frame.height() != self.cam.height {
            return Err(TrackError::FrameSize {
                got_w: frame.width(),
                got_h: frame.height(),
                want_w: self.cam.width,
                want_h: self.cam.height,
            });
        }
        let t0 = Instant::now();
        let read0 = self.ctx.stats();
        self.resident.begin();
        self.pending_gpu.clear();
        self.contour_rounds = 0;
        self.contour_renders = 0;
        self.contour_mask_fresh = false;
        let mut times = StageTimes::default();
        self.stages = StageTimes::default();
        // No pose yet, or lost for a while: search the whole frame.
        let every = self.config.init.redetect_after_lost;
        if self.searching
            || (every > 0 && self.lost_streak >= every && self.lost_streak.is_multiple_of(every))
        {
            let found = self.find(frame)?;
            times.search = t0.elapsed();
            times.waits.search = self.ctx.stats().wait_time.saturating_sub(read0.wait_time);
            // The search's KF-like steps are its own time ("search"), not
            // the KF stage's parts, which would otherwise exceed it (the
            // passes' GPU times stay, under their own labels).
            let s = &mut self.stages;
            for part in [
                &mut s.it_render,
                &mut s.it_ncc,
                &mut s.kf_render,
                &mut s.kf_harris,
                &mut s.kf_ncc,
            ] {
                *part = Duration::ZERO;
            }
            match found {
                Some(p) => {
                    log::info!("object found by search");
                    self.pose = p;
                    self.searching = false;
                    self.lost_streak = 0;
                    self.it_only_streak = 0;
                    self.prev = None;
                }
                None if self.searching => {
                    times.total = t0.elapsed();
                    return Ok(TrackResult {
                        pose: self.pose,
                        inliers: 0,
                        residual_px: f64::NAN,
                        status: Status::Lost,
                        reason: Some(LostReason::NotFound),
                        keyframe: None,
                        times,
                        verify: None,
                        texture_set_aside: false,
                    });
                }
                None => {}
            }
        }
        let t_features = Instant::now();
        let w_features = self.ctx.stats().wait_time;
        // The frame kept for the next one, in the buffer of the frame
        // before the last where it fits.
        let kept = match self.spare_frame.take() {
            Some(mut b) if b.dimensions() == rgb.dimensions() => {
                b.copy_from_slice(rgb);
                b
            }
            _ => rgb.clone(),
        };
        let mut frame = Frame::new(kept);
        let frozen = self
            .prev
            .as_ref()
            .is_some_and(|p| p.rgb.as_raw() == rgb.as_raw());
        let start_pose = self.pose;
        let texture = self.config.modalities.texture;
        let recovering = self.lost_streak > 0;
        // The frame's intake and its window's packing go to the GPU with
        // Harris's first readback (their parameters have buffers of their
        // own), and so do IT's render and gather, which do not need the
        // frame: that readback brings the gather's samples too.
        let intake = self.ctx.batch();
        let t_early = Instant::now();
        let it_early = if texture {
            self.it_gather_early(&start_pose, recovering)
        } else {
            None
        };
        let it_early_time = t_early.elapsed();
        if texture {
            self.resident.upload(&self.ctx, rgb)?;
        }
        // With IT's matching chained behind the frame's Harris where it
        // can be (one wait for both).
        let it_early = if texture {
            let (corners, early) = self.frame_corners_chained(&frame, &start_pose, it_early)?;
            frame.corners = corners;
            early
        } else {
            None
        };
        drop(intake);
        // IT's early render and gather count as IT's.
        times.features = t_features.elapsed().saturating_sub(it_early_time);
        times.waits.features = self.ctx.stats().wait_time.saturating_sub(w_features);

        let rules = Rules::of(&self.config);
        let first_frame = self.prev.is_none() && !recovering;
        let t_it = Instant::now();
        let w_it = self.ctx.stats().wait_time;
        let (it, it_anchors) = if texture {
            self.it_stage(&frame, &start_pose, recovering, it_early)
        } else {
            (StepOutcome::default(), Vec::new())
        };
        times.it = t_it.elapsed() + it_early_time;
        times.waits.it = self.ctx.stats().wait_time.saturating_sub(w_it);
        let t_kf = Instant::now();
        let w_kf = self.ctx.stats().wait_time;
        let it_trusted = it.estimate.filter(|e| rules.trusted(e)).map(|e| e.pose);
        self.kf_anchors.clear();
        let (kf, keyframe) = if texture {
            let fused: &[Anchor] = if self.config.fuse { &it_anchors } else { &[] };
            self.kf_stage(&frame, &start_pose, recovering, it_trusted, fused)
        } else {
            (StepOutcome::default(), None)
        };
        times.kf = t_kf.elapsed();
        times.waits.kf = self.ctx.stats().wait_time.saturating_sub(w_kf);
        let t_contour = Instant::now();
        let w_contour = self.ctx.stats().wait_time;
        let contour = if self.config.modalities.contour {
            // From the best texture estimate, fused with its inliers; else
            // from the previous pose with longer lines.
            let kf_trusted = kf.estimate.filter(|e| rules.trusted(e)).map(|e| e.pose);
            let anchors = std::mem::take(&mut self.kf_anchors);
            match (kf_trusted, it_trusted) {
                // A trusted KF step: the outline only refines it where
                // configured ([`ContourConfig::refine_texture`]).
                (Some(_), _) if !self.config.contour.refine_texture => StepOutcome::default(),
                (Some(p), _) => self.contour_stage(rgb, &p, false, &anchors),
                // IT's matches are not fused: they carry its drift (on the
                // real dragon they pulled the fused pose 20 degrees off).
                (None, Some(p)) => self.contour_stage(rgb, &p, false, &[]),
                (None, None) => self.contour_stage(rgb, &start_pose, true, &[]),
            }
        } else {
            StepOutcome::default()
        };
        times.contour = t_contour.elapsed();
        times.waits.contour = self.ctx.stats().wait_time.saturating_sub(w_contour);

        let texture_held = kf.estimate.is_some_and(|e| rules.trusted(&e))
            || it.estimate.is_some_and(|e| rules.trusted(&e));
        let d = decide(
            &rules,
            &FrameSteps {
                it,
                kf,
                contour,
                first_frame,
                it_only_streak: self.it_only_streak,
            },
        );
        // Every pose reported `tracking` is checked against the image.
        let mut scores = None;
        let mut texture_set_aside = false;
        let t_verify = Instant::now();
        let w_verify = self.ctx.stats().wait_time;
        let mut d = d;
        if d.status == Status::Tracking && self.config.verify.enabled {
            let check = if frozen {
                Err(Unverified::FrozenFrame)
            } else {
                let s = self.verify_scores(&frame, &d.pose.unwrap_or(start_pose))?;
                scores = Some(s);
                log::debug!("verify: {s:?}");
                // Without a trusted texture step the object shows no
                // texture to correlate (an untextured object's shading):
                // the contour's edges decide.
                if self.config.modalities.contour && !texture_held {
                    verify::judge_with_contour(&s, &self.config.verify)
                } else {
                    verify::judge(&s, &self.config.verify)
                }
            };
            // A trusted texture step whose pose does not look like the
            // frame matched something the keyframes do not show (on an
            // untextured object, the shading of a moving light): set the
            // texture aside and let the contour alone solve from that
            // pose, checked as when no texture step is trusted.
            let aside = match &check {
                Err(Unverified::Appearance { .. })
                    if self.config.modalities.contour && texture_held =>
                {
                    self.contour_alone(&rules, &frame, rgb, &d, first_frame)?
                }
                _ => None,
            };
            match aside {
                Some((alone, s)) => {
                    scores = Some(s);
                    texture_set_aside = true;
                    d = alone;
                }
                None => d = verified(d, check),
            }
        }
        times.verify = t_verify.elapsed();
        times.waits.verify = self.ctx.stats().wait_time.saturating_sub(w_verify);
        if let Some(why) = &d.kf_passed_over {
            log::debug!("KF step not used ({why}); keeping the IT estimate");
        }
        self.it_only_streak = d.it_only_streak;
        if d.status == Status::Tracking {
            self.pose = d.pose.unwrap_or(start_pose);
            self.lost_streak = 0;
            if self.config.modalities.contour {
                let pose = self.pose;
                self.learn_colours(rgb, &pose);
            }
        } else {
            // Keep the last good pose: never report a pose that failed.
            self.lost_streak += 1;
        }
        if let Some(old) = self.prev.replace(frame) {
            self.spare_frame = Some(old.rgb);
        }
        self.resident.done();
        self.collect_gpu_times();
        let sub = std::mem::take(&mut self.stages);
        times.it_render = sub.it_render;
        times.it_ncc = sub.it_ncc;
        times.kf_render = sub.kf_render;
        times.kf_harris = sub.kf_harris;
        times.kf_ncc = sub.kf_ncc;
        times.gpu = sub.gpu;
        times.gpu_timeline = sub.gpu_timeline;
        let done = self.ctx.stats().since(&read0);
        times.readback_bytes = done.bytes_read as f64;
        times.readbacks = done.readbacks as f64;
        times.submissions = done.submissions as f64;
        times.command_buffers = done.command_buffers as f64;
        times.uploads = done.uploads as f64;
        times.uploads_skipped = done.uploads_skipped as f64;
        times.passes = done.passes as f64;
        times.passes_untimed = done.passes_untimed as f64;
        times.gpu_wait = done.wait_time;
        times.gpu_finish = done.finish_time;
        times.gpu_submit = done.submit_time;
        times.contour_rounds = self.contour_rounds as f64;
        times.contour_renders = self.contour_renders as f64;
        (times.colour_learning, times.colour_wait) = self.colours.take_times();
        times.total = t0.elapsed();
        Ok(TrackResult {
            pose: self.pose,
            inliers: d.inliers,
            residual_px: d.residual_px,
            status: d.status,
            reason: d.reason,
            keyframe,
            times,
            verify: scores,
            texture_set_aside,
        })
    }

    /// The contour alone from the pose of decision `d` (whose texture
    /// steps were trusted but whose check failed on appearance), decided
    /// as if no texture step had run and checked by the contour's edges
    /// ([`verify::judge_with_contour`]): the decision and its scores when
    /// that pose passes, `None` when it does not (the frame stays lost).
    fn contour_alone(
        &mut self,
        rules: &Rules,
        frame: &Frame,
        rgb: &image::RgbImage,
        d: &Decision,
        first_frame: bool,
    ) -> Result<Option<(Decision, VerifyScores)>, TrackError> {
        let Some(from) = d.pose else {
            return Ok(None);
        };
        let contour = self.contour_stage(rgb, &from, false, &[]);
        let alone = decide(
            rules,
            &FrameSteps {
                it: StepOutcome::default(),
                kf: StepOutcome::default(),
                contour,
                first_frame,
                it_only_streak: 0,
            },
        );
        let Some(pose) = alone.pose.filter(|_| alone.status == Status::Tracking) else {
            return Ok(None);
        };
        let s = self.verify_scores(frame, &pose)?;
        log::debug!("verify (contour alone): {s:?}");
        match verify::judge_with_contour(&s, &self.config.verify) {
            Ok(()) => {
                log::debug!(
                    "texture set aside (its pose did not look like the frame); the contour alone: {:.2} deg from it",
                    pose.rotation_error_deg(&from)
                );
                Ok(Some((alone, s)))
            }
            Err(why) => {
                log::debug!("the contour alone does not pass either: {why}");
                Ok(None)
            }
        }
    }

    /// The model's coverage mask at `pose` (for overlays and the live
    /// view): one flag per pixel of the frame. Only the window the model
    /// can cover at `pose` is splatted and read back (the whole frame with
    /// windows off), the rest is uncovered; at the pose the last frame's
    /// check rendered (a tracked frame's), that render's coverage is read
    /// instead of splatting again.
    pub fn silhouette(&mut self, pose: &Pose) -> Result<Vec<bool>, TrackError> {
        let (weight, window) = match self.kept_at(pose) {
            Some((targets, window)) => (
                self.splatter.read(&self.ctx, targets, Attribute::Weight)?,
                window,
            ),
            None => {
                let window = self.view_window(pose);
                let cam = self.use_window(window);
                self.splatter.render(
                    &self.ctx,
                    &self.geometry,
                    &cam,
                    pose,
                    Attributes::COLOR,
                    &mut self.targets,
                )?;
                let weight = self
                    .splatter
                    .read(&self.ctx, &self.targets, Attribute::Weight)?;
                (weight, window)
            }
        };
        let (fw, fh) = (self.cam.width as usize, self.cam.height as usize);
        let (x0, y0, ww) = (
            window.x0 as usize,
            window.y0 as usize,
            window.width as usize,
        );
        let mut mask = vec![false; fw * fh];
        for (y, row) in weight.data.chunks(ww.max(1)).enumerate() {
            let at = (y0 + y) * fw + x0;
            for (m, v) in mask[at..at + row.len()].iter_mut().zip(row) {
                *m = *v > 0.0 && !v.is_nan();
            }
        }
        Ok(mask)
    }
}

/// What the steps share: the view of the model at a pose, turning a match
/// into a correspondence, and the robust solve.
impl Tracker {
    /// Splats `attrs` of the model at `pose` into window `w` of the image
    /// (the tracker's targets for that size), textured by the keyframe
    /// closest to `pose` (its index is returned), or untextured when there
    /// is no keyframe store (`None`); its GPU passes are timed under
    /// `stage`.
    fn render_view_in(
        &mut self,
        pose: &Pose,
        attrs: Attributes,
        w: Window,
        stage: &str,
    ) -> Result<Option<usize>, crate::splat::SplatError> {
        let cam = self.use_window(w);
        let k = self.store.as_ref().map(|s| s.closest(pose));
        let texture = k.map_or(profile::Texture::None, profile::Texture::Keyframe);
        self.splat(texture, &cam, pose, attrs, stage)?;
        Ok(k)
    }

    /// The match of pixel `from` of the view splatted at `pose` (`s`: its
    /// predictors and depth there) with `to` in the live frame: its row of
    /// the linear solve, and the object point seen at `from` (lifted with
    /// the splatted depth) for the refinement.
    fn correspondence(
        &self,
        s: &GatherSample,
        from: Vector2<f64>,
        to: Vector2<f64>,
        pose: &Pose,
    ) -> Correspondence {
        Correspondence {
            observation: Observation {
                predictors: s.matrix(),
                displacement: to - from,
            },
            anchor: Anchor {
                point: pose
                    .inverse()
                    .transform_point(&self.cam.unproject(&from, s.depth as f64)),
                target: to,
            },
        }
    }

    /// The linear solve of `obs` from `pose`, then the Gauss-Newton
    /// refinements, with `extra` anchors from another step.
    fn refine(
        &self,
        obs: &[Correspondence],
        pose: &Pose,
        extra: &[Anchor],
    ) -> Result<Refined, StepError> {
        let refiner = Refiner {
            cam: &self.cam,
            irls: &self.config.irls,
            iterations: self.config.refine_iterations,
            extra_weight: self.config.fuse_weight,
        };
        Ok(refiner.solve(obs, pose, extra)?)
    }
}

/// A step's estimate from its refined solve.
fn estimate(r: &Refined) -> Estimate {
    Estimate {
        pose: r.pose,
        inliers: r.solve.inlier_count,
        residual_px: r.solve.residual_rms_px,
        scale_px: r.solve.scale_px,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn track_result_serde_roundtrip() {
        let r = TrackResult {
            pose: Pose::new(
                crate::geometry::rotation_exp(&Vector3::new(0.1, -0.2, 0.3)),
                Vector3::new(0.01, 0.02, 0.6),
            )
            .unwrap(),
            inliers: 0,
            residual_px: f64::NAN,
            status: Status::Lost,
            reason: Some(LostReason::NothingToTrackAgainst),
            keyframe: Some(3),
            times: StageTimes {
                features: Duration::from_micros(1500),
                total: Duration::from_millis(20),
                ..Default::default()
            },
            verify: None,
            texture_set_aside: true,
        };
        let json = serde_json::to_string(&r).unwrap();
        assert!(json.contains(r#""residual_px":null"#), "{json}");
        let back: TrackResult = serde_json::from_str(&json).unwrap();
        assert!(back.residual_px.is_nan());
        // serde_json reads floats to within an ulp.
        assert!((back.pose.to_matrix4() - r.pose.to_matrix4()).amax() < 1e-15);
        assert_eq!((back.inliers, back.keyframe), (r.inliers, r.keyframe));
        assert!(back.texture_set_aside);
        assert_eq!(
            (back.status, back.reason, back.times),
            (r.status, r.reason, r.times)
        );
    }
}

/// GPU memory the splatting of a [`Tracker`] holds (bytes), from the sizes
/// of the buffers and textures it created ([`GpuModel::gpu_bytes`],
/// [`SplatTargets::gpu_bytes`], `TexturedCache::gpu_bytes`). Not counted:
/// the Harris and NCC buffers (grow-only, sized by the frame and the
/// features), pipelines, and the driver's own allocations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GpuMemory {
    /// The model's geometry and colours.
    pub model: u64,
    /// The keyframe colours resident in the textured cache.
    pub keyframe_colors: u64,
    /// Every set of render targets (the current one, the spare ones, the
    /// kept render), with the compute splatter's scratch.
    pub targets: u64,
}

impl GpuMemory {
    /// All of it.
    pub fn total(&self) -> u64 {
        self.model + self.keyframe_colors + self.targets
    }
}

impl Tracker {
    /// The GPU memory of the splatting now ([`GpuMemory`]).
    pub fn gpu_memory(&self) -> GpuMemory {
        GpuMemory {
            model: self.geometry.gpu_bytes(),
            keyframe_colors: self.textured.gpu_bytes(),
            targets: self.targets.gpu_bytes()
                + self.spare.iter().map(|t| t.gpu_bytes()).sum::<u64>()
                + self.kept.as_ref().map_or(0, |k| k.targets().gpu_bytes()),
        }
    }
}
