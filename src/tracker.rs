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
//!    Gauss-Newton iterations: the matched points are lifted to 3-D with the
//!    splatted depth, re-projected at the updated pose, and the residuals
//!    solved again with the same robust loss (measured: it removes the
//!    first-order error of large motions).
//! 5. The KF result is used when enough inliers survive with a small
//!    residual, else the IT result (KF+IT keeps tracking frame to frame
//!    through a frame the keyframes cannot explain); when neither holds the
//!    frame is `lost`: the pose stays at the last good one, and the next
//!    frames try to recover against the keyframes with a wide search.

#![warn(missing_docs)]

use crate::features::{
    Corner, GreyImage, Harris, HarrisConfig, Match, NccConfig, NccMatcher, refine_match,
};
use crate::geometry::{Intrinsics, Pose};
use crate::gpu::GpuContext;
use crate::keyframes::KeyframeStore;
use crate::model::PointModel;
use crate::pose::{IrlsConfig, IrlsResult, Observation, SolveError, irls};
use crate::splat::{Attribute, Attributes, GatherMode, GpuModel, SplatTargets, Splatter};
use nalgebra::{Vector2, Vector3};
use std::time::{Duration, Instant};

/// Which of the paper's trackers runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// Frame to frame only: smooth, but drifts.
    It,
    /// Against keyframe-textured novel views only: no drift, but jitter.
    Kf,
    /// IT, then KF from the IT estimate (the paper's hybrid).
    #[default]
    KfIt,
}

impl Mode {
    /// The three modes, in the order the demo and the tables list them.
    pub const ALL: [Mode; 3] = [Mode::It, Mode::Kf, Mode::KfIt];

    /// The name used on the command line and in tables (`it`, `kf`,
    /// `kf+it`); [`str::parse`] accepts it back.
    pub fn name(&self) -> &'static str {
        match self {
            Mode::It => "it",
            Mode::Kf => "kf",
            Mode::KfIt => "kf+it",
        }
    }
}

impl std::str::FromStr for Mode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "it" => Ok(Mode::It),
            "kf" => Ok(Mode::Kf),
            "kf+it" | "kfit" | "it+kf" | "hybrid" => Ok(Mode::KfIt),
            _ => Err(format!("unknown mode {s:?} (use kf+it, it or kf)")),
        }
    }
}

/// Tracker settings. Defaults follow the paper (900 corners, 9x9 NCC
/// windows) and were tuned on the synthetic sequences.
#[derive(Debug, Clone)]
pub struct TrackerConfig {
    /// Which tracker runs (default: KF+IT).
    pub mode: Mode,
    /// Harris corner detection on every frame and novel view.
    pub harris: HarrisConfig,
    /// NCC matching (window, minimum score); the search radius is set per
    /// step from the fields below.
    pub ncc: NccConfig,
    /// The robust solver of every pose update.
    pub irls: IrlsConfig,
    /// NCC search radius of frame-to-frame matching, pixels.
    pub it_search_px: f32,
    /// NCC search radius against the novel view, pixels.
    pub kf_search_px: f32,
    /// Search radius when recovering a lost track, pixels.
    pub recover_search_px: f32,
    /// Gauss-Newton refinements after each linear solve.
    pub refine_iterations: usize,
    /// KF steps per frame (each re-renders the novel view at the newest
    /// estimate).
    pub kf_iterations: usize,
    /// Margin around the object's projected bounding circle where corners
    /// are detected, pixels.
    pub roi_margin_px: f64,
    /// A step with fewer inliers than this is not trusted; when neither
    /// the KF nor the IT step of a frame is, the frame is `lost` (8: the box
    /// on the fast trajectory has frames with 8-11 good KF matches).
    pub min_inliers: usize,
    /// Inlier RMS residual above this: `lost`.
    pub max_residual_px: f64,
    /// In KF+IT, refine the KF correction jointly with the IT step's inlier
    /// matches (frame-to-frame constraints damp the KF jitter, the keyframe
    /// matches bound the drift) instead of the paper's plain sequence.
    pub fuse: bool,
    /// Weight of the IT matches relative to the KF matches when fusing.
    pub fuse_weight: f64,
    /// Refine each KF match to the sub-pixel NCC peak (window of this many
    /// pixels) rather than trusting the two detected corners; 0: off. The
    /// novel view is blurrier than the frame, which biases independently
    /// detected corners (see `features::refine`).
    pub refine_window: u32,
    /// Splat radii are raised to at least this many pixels (at the initial
    /// pose's distance). Models sampled at about one point per pixel leave
    /// scattered empty pixels in the splatted views, and each one voids every
    /// Harris corner and NCC window that touches it. 0: the radii as given.
    pub min_splat_radius_px: f32,
    /// KF+IT: consecutive frames whose KF step may fail while a sound IT
    /// estimate stands in for it (IT alone drifts); beyond that the frame
    /// is `lost`.
    pub max_it_only_frames: usize,
    /// IT uses only corners of the previous frame whose surroundings (8
    /// points at this distance, pixels; 4 = the NCC window's corners and
    /// edge midpoints) are on the object too. 0 (default): every corner on
    /// the object, outline included. Outline corners mix the background's
    /// motion in: with 4, IT's mean rotation error on the real ViSP cube
    /// drops from 2.7 to 0.75 degrees, but on the synthetic box (fast
    /// trajectory) it rises from 1.0 to 2.9 degrees (half the matches gone),
    /// so it is off by default.
    pub it_interior_px: f32,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self {
            mode: Mode::KfIt,
            // 0.003 rather than the detector's 0.01: the threshold is
            // relative to the strongest corner in the region of interest,
            // often in the background on real frames (on the ViSP cube the
            // object kept too few corners at 0.01).
            harris: HarrisConfig::default().with_relative_threshold(0.003),
            ncc: NccConfig::default(),
            irls: IrlsConfig::default(),
            it_search_px: 40.0,
            kf_search_px: 24.0,
            recover_search_px: 80.0,
            refine_iterations: 2,
            kf_iterations: 1,
            roi_margin_px: 24.0,
            min_inliers: 8,
            max_residual_px: 3.0,
            fuse: false,
            fuse_weight: 0.5,
            refine_window: 15,
            min_splat_radius_px: 1.0,
            max_it_only_frames: 5,
            it_interior_px: 0.0,
        }
    }
}

/// Whether the track holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// The frame's pose passed the inlier and residual checks.
    Tracking,
    /// It did not: the reported pose is the last good one.
    Lost,
}

impl Status {
    /// `tracking` or `lost`, as in the tracker output's `status` column.
    pub fn name(&self) -> &'static str {
        match self {
            Status::Tracking => "tracking",
            Status::Lost => "lost",
        }
    }
}

/// Wall-clock time of each stage of one frame (GPU work included, since
/// every stage waits for its results).
#[derive(Debug, Clone, Default)]
pub struct StageTimes {
    /// Harris corners of the frame.
    pub features: Duration,
    /// The frame-to-frame step.
    pub it: Duration,
    /// The keyframe step(s).
    pub kf: Duration,
    /// The whole call to [`Tracker::track`].
    pub total: Duration,
}

/// What [`Tracker::track`] says about a frame.
#[derive(Debug, Clone)]
pub struct TrackResult {
    /// The object-to-camera pose of the frame; on a lost frame, the last
    /// good pose (a pose that failed is never reported).
    pub pose: Pose,
    /// Inliers of the last robust solve of this frame.
    pub inliers: usize,
    /// Their RMS reprojection residual, pixels.
    pub residual_px: f64,
    /// Whether the track holds at this frame.
    pub status: Status,
    /// Why the frame is lost (when it is).
    pub reason: Option<String>,
    /// The keyframe used by the KF step, if any.
    pub keyframe: Option<usize>,
    /// Where the time went.
    pub times: StageTimes,
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
}

/// An impossible camera.
#[derive(Debug, thiserror::Error)]
#[error("impossible camera: {0}")]
pub struct CameraInvalid(pub String);

/// How far the KF step searches for matches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Search {
    /// From an IT estimate: the object is nearly where predicted.
    Refine,
    /// From the previous pose: as far as the object moves between frames.
    Motion,
    /// After a loss.
    Recover,
}

struct PrevFrame {
    grey: GreyImage,
    corners: Vec<Corner>,
}

/// The outcome of one robust step.
struct Step {
    pose: Pose,
    solve: IrlsResult,
    /// The step's inlier correspondences: object-frame point, position in
    /// the live frame.
    anchors: Vec<(Vector3<f64>, Vector2<f64>)>,
}

/// The tracker: create once per sequence, then call [`Tracker::track`] on
/// each frame in order.
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
///     println!("{} {:?} {} inliers", r.status.name(), r.pose.translation, r.inliers);
///     if r.status == Status::Lost {
///         // r.pose is the last good pose; later frames try to recover.
///     }
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Tracker<'a> {
    ctx: &'a GpuContext,
    cam: Intrinsics,
    config: TrackerConfig,
    model: PointModel,
    store: Option<KeyframeStore>,
    splatter: Splatter,
    geometry: GpuModel,
    textured: Vec<Option<GpuModel>>,
    targets: SplatTargets,
    harris: Harris<'a>,
    it_matcher: NccMatcher<'a>,
    kf_matcher: NccMatcher<'a>,
    recover_matcher: NccMatcher<'a>,
    center: Vector3<f64>,
    radius: f64,
    pose: Pose,
    prev: Option<PrevFrame>,
    lost_streak: usize,
    /// KF+IT: consecutive frames tracked by IT alone.
    it_only_streak: usize,
}

impl<'a> Tracker<'a> {
    /// A tracker for `model` seen by `cam` (undistorted frames), starting at
    /// `initial` (the pose of the first frame given to [`Tracker::track`]).
    /// `keyframes` may be `None` for the IT mode, or when the model has
    /// colours (they then serve as the single texture).
    pub fn new(
        ctx: &'a GpuContext,
        model: PointModel,
        cam: Intrinsics,
        keyframes: Option<KeyframeStore>,
        config: TrackerConfig,
        initial: Pose,
    ) -> Result<Self, TrackError> {
        cam.validate().map_err(CameraInvalid)?;
        initial.validate()?;
        let store = keyframes.or_else(|| KeyframeStore::from_model_colors(&model, &initial));
        if store.is_none() && config.mode != Mode::It {
            return Err(TrackError::NeedsKeyframes(config.mode.name()));
        }
        let mut model = model;
        // The bounding sphere: box centre, farthest point.
        let crate::splat::ModelBounds { center, radius, .. } =
            crate::splat::ModelBounds::of(&model);
        let z0 = initial.transform_point(&center).z;
        let floor = (config.min_splat_radius_px as f64 * z0 / cam.fx.max(cam.fy)) as f32;
        if floor > 0.0 && floor.is_finite() {
            model.radii.iter_mut().for_each(|r| *r = r.max(floor));
        }
        let splatter = Splatter::new(ctx)?;
        let geometry = GpuModel::new(ctx, &model)?;
        let targets = SplatTargets::new(ctx, cam.width, cam.height);
        let harris = Harris::new(ctx, config.harris.clone())?;
        let matcher = |r: f32| NccMatcher::new(ctx, config.ncc.clone().with_search_radius(Some(r)));
        let n_kf = store.as_ref().map_or(0, |s| s.keyframes.len());
        let tracker = Self {
            ctx,
            it_matcher: matcher(config.it_search_px)?,
            kf_matcher: matcher(config.kf_search_px)?,
            recover_matcher: matcher(config.recover_search_px)?,
            cam,
            config,
            model,
            store,
            splatter,
            geometry,
            textured: (0..n_kf).map(|_| None).collect(),
            targets,
            harris,
            center,
            radius,
            pose: initial,
            prev: None,
            lost_streak: 0,
            it_only_streak: 0,
        };
        if tracker.roi(&initial).is_none() {
            return Err(TrackError::ObjectNotInView);
        }
        Ok(tracker)
    }

    /// The current pose estimate.
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// The settings the tracker runs with.
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// The keyframe store in use: the one given to [`Tracker::new`], or
    /// the single texture made from the model's colours, or none (IT mode).
    pub fn keyframes(&self) -> Option<&KeyframeStore> {
        self.store.as_ref()
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

    fn roi_mask(&self, pose: &Pose) -> Vec<bool> {
        let (w, h) = (self.cam.width as usize, self.cam.height as usize);
        let mut mask = vec![false; w * h];
        if let Some((x0, y0, x1, y1)) = self.roi(pose) {
            for y in y0..=y1 {
                mask[y * w + x0..=y * w + x1].fill(true);
            }
        }
        mask
    }

    /// Tracks one frame (RGB, undistorted, the camera's size).
    pub fn track(&mut self, frame: &image::RgbImage) -> Result<TrackResult, TrackError> {
        if frame.width() != self.cam.width || frame.height() != self.cam.height {
            return Err(TrackError::FrameSize {
                got_w: frame.width(),
                got_h: frame.height(),
                want_w: self.cam.width,
                want_h: self.cam.height,
            });
        }
        let t0 = Instant::now();
        let mut times = StageTimes::default();
        let grey = GreyImage::from_rgb8(frame);
        let start_pose = self.pose;
        let mask = self.roi_mask(&start_pose);
        let corners = self.harris.detect(&grey, Some(&mask))?;
        times.features = t0.elapsed();

        let recovering = self.lost_streak > 0;
        let (min_inliers, max_residual) = (self.config.min_inliers, self.config.max_residual_px);
        let good = move |s: &IrlsResult| {
            s.inlier_count >= min_inliers && s.residual_rms_px <= max_residual
        };
        let mut it_anchors = Vec::new();
        let mut it_result: Option<(Pose, IrlsResult)> = None;
        let mut it_error: Option<String> = None;
        let had_prev = self.prev.is_some();

        // IT: needs a previous frame; skipped while recovering.
        let t_it = Instant::now();
        if matches!(self.config.mode, Mode::It | Mode::KfIt) && !recovering {
            if let Some(prev) = self.prev.take() {
                match self.it_step(&prev, &grey, &corners, &start_pose) {
                    Ok(step) => {
                        if self.config.fuse {
                            it_anchors = step.anchors;
                        }
                        it_result = Some((step.pose, step.solve));
                    }
                    Err(e) => it_error = Some(format!("IT: {e}")),
                }
            }
        }
        times.it = t_it.elapsed();

        let t_kf = Instant::now();
        let mut kf_result: Option<(Pose, IrlsResult)> = None;
        let mut kf_error: Option<String> = None;
        let mut keyframe = None;
        let use_kf = matches!(self.config.mode, Mode::Kf | Mode::KfIt)
            || (recovering && self.store.is_some());
        if use_kf && self.store.is_some() {
            // Start from a sound IT estimate when there is one; without it
            // the first KF step must search as far as frame-to-frame
            // matching does, and after a loss farther.
            let it_ok = it_result.as_ref().filter(|(_, s)| good(s));
            let (mut pose, first) = match (recovering, it_ok) {
                (true, _) => (start_pose, Search::Recover),
                (false, Some((p, _))) => (*p, Search::Refine),
                (false, None) => (start_pose, Search::Motion),
            };
            for it in 0..self.config.kf_iterations.max(1) {
                let search = if it == 0 { first } else { Search::Refine };
                match self.kf_step(&grey, &corners, &pose, search, &it_anchors) {
                    Ok((step, k)) => {
                        pose = step.pose;
                        kf_result = Some((step.pose, step.solve));
                        keyframe = Some(k);
                    }
                    Err(e) => {
                        kf_error = Some(format!("KF: {e}"));
                        break;
                    }
                }
            }
        }
        times.kf = t_kf.elapsed();

        // The KF result when it is sound; else the IT result (KF+IT keeps
        // tracking frame to frame through a frame the keyframes cannot
        // explain); else the frame is lost.
        let describe = |s: &IrlsResult| {
            format!(
                "{} inliers, residual {:.2} px (need >= {} and <= {:.1} px)",
                s.inlier_count,
                s.residual_rms_px,
                self.config.min_inliers,
                self.config.max_residual_px
            )
        };
        let mut reason = None;
        let it_may_stand =
            self.config.mode != Mode::KfIt || self.it_only_streak < self.config.max_it_only_frames;
        let chosen = match (&kf_result, &it_result) {
            (Some((p, s)), _) if good(s) => {
                self.it_only_streak = 0;
                Some((*p, s.clone()))
            }
            (_, Some((p, s))) if good(s) && it_may_stand => {
                if self.config.mode == Mode::KfIt {
                    self.it_only_streak += 1;
                }
                let why = kf_error.clone().or_else(|| {
                    kf_result
                        .as_ref()
                        .map(|(_, s)| format!("KF: {}", describe(s)))
                });
                if let Some(why) = why {
                    log::debug!("KF step not used ({why}); keeping the IT estimate");
                }
                Some((*p, s.clone()))
            }
            _ => {
                reason = kf_error
                    .clone()
                    .or_else(|| {
                        kf_result
                            .as_ref()
                            .map(|(_, s)| format!("KF: {}", describe(s)))
                    })
                    .or_else(|| it_error.clone())
                    .or_else(|| {
                        it_result
                            .as_ref()
                            .map(|(_, s)| format!("IT: {}", describe(s)))
                    });
                if !it_may_stand && it_result.as_ref().is_some_and(|(_, s)| good(s)) {
                    reason = Some(format!(
                        "{}; IT alone has stood in for {} frames and drifts",
                        reason.unwrap_or_default(),
                        self.config.max_it_only_frames
                    ));
                }
                self.it_only_streak = 0;
                None
            }
        };
        // The first frame of a sequence has nothing to track against in IT
        // mode: it is the initial pose, by definition tracking.
        let first_it_frame = matches!(self.config.mode, Mode::It | Mode::KfIt)
            && it_result.is_none()
            && it_error.is_none()
            && !had_prev
            && !recovering;
        let last = kf_result.as_ref().or(it_result.as_ref()).map(|(_, s)| s);
        let (status, pose, inliers, residual) = match (&chosen, last) {
            (Some((p, s)), _) => (Status::Tracking, *p, s.inlier_count, s.residual_rms_px),
            (None, _) if first_it_frame => (Status::Tracking, start_pose, 0, 0.0),
            (None, Some(s)) => (Status::Lost, start_pose, s.inlier_count, s.residual_rms_px),
            (None, None) => (Status::Lost, start_pose, 0, f64::NAN),
        };
        if status == Status::Lost && reason.is_none() {
            reason = Some("nothing to track against".into());
        }
        if status == Status::Tracking {
            self.pose = pose;
            self.lost_streak = 0;
        } else {
            // Keep the last good pose: never report a pose that failed.
            self.lost_streak += 1;
        }
        self.prev = Some(PrevFrame { grey, corners });
        times.total = t0.elapsed();
        Ok(TrackResult {
            pose: self.pose,
            inliers,
            residual_px: residual,
            status,
            reason: if status == Status::Lost { reason } else { None },
            keyframe,
            times,
        })
    }

    /// Frame-to-frame step from the previous frame's corners.
    fn it_step(
        &mut self,
        prev: &PrevFrame,
        grey: &GreyImage,
        corners: &[Corner],
        pose: &Pose,
    ) -> Result<Step, String> {
        self.splatter
            .render(
                self.ctx,
                &self.geometry,
                &self.cam,
                pose,
                Attributes::ALL,
                &mut self.targets,
            )
            .map_err(|e| e.to_string())?;
        let pts: Vec<[f32; 2]> = prev.corners.iter().map(|c| [c.x, c.y]).collect();
        let samples = self
            .splatter
            .gather(self.ctx, &self.targets, &pts, GatherMode::Bilinear)
            .map_err(|e| e.to_string())?;
        // Only corners on the object take part; with `it_interior_px`, only
        // those whose surroundings are on the object too (see the field).
        let mut on_object: Vec<usize> = (0..samples.len()).filter(|&i| samples[i].valid).collect();
        let r = self.config.it_interior_px;
        if r > 0.0 && !on_object.is_empty() {
            const RING: [(f32, f32); 8] = [
                (-1.0, -1.0),
                (0.0, -1.0),
                (1.0, -1.0),
                (-1.0, 0.0),
                (1.0, 0.0),
                (-1.0, 1.0),
                (0.0, 1.0),
                (1.0, 1.0),
            ];
            let probes: Vec<[f32; 2]> = on_object
                .iter()
                .flat_map(|&i| {
                    let c = prev.corners[i];
                    RING.iter()
                        .map(move |(dx, dy)| [c.x + dx * r, c.y + dy * r])
                })
                .collect();
            let ring = self
                .splatter
                .gather(self.ctx, &self.targets, &probes, GatherMode::Bilinear)
                .map_err(|e| e.to_string())?;
            on_object = on_object
                .iter()
                .zip(ring.chunks(RING.len()))
                .filter(|(_, ring)| ring.iter().all(|s| s.valid))
                .map(|(&i, _)| i)
                .collect();
        }
        let src: Vec<Corner> = on_object.iter().map(|&i| prev.corners[i]).collect();
        let matches = self
            .it_matcher
            .match_features(&prev.grey, &src, grey, corners)
            .map_err(|e| e.to_string())?;
        let obs: Vec<(Observation, Vector3<f64>, Vector2<f64>)> = matches
            .iter()
            .map(|m| {
                let s = &samples[on_object[m.a]];
                let a = &src[m.a];
                let from = Vector2::new(a.x as f64, a.y as f64);
                // Frame-to-frame, both images are equally sharp: the
                // detected corners are unbiased against each other.
                let b = &corners[m.b];
                let to = Vector2::new(b.x as f64, b.y as f64);
                (
                    Observation {
                        predictors: s.matrix(),
                        displacement: to - from,
                    },
                    self.lift(&from, s.depth as f64, pose),
                    to,
                )
            })
            .collect();
        self.solve_and_refine(&obs, pose, &[])
    }

    /// One step against the novel view of the closest keyframe.
    fn kf_step(
        &mut self,
        grey: &GreyImage,
        corners: &[Corner],
        pose: &Pose,
        search: Search,
        anchors: &[(Vector3<f64>, Vector2<f64>)],
    ) -> Result<(Step, usize), String> {
        let store = self.store.as_ref().ok_or("no keyframes")?;
        let k = store.closest(pose);
        if self.textured[k].is_none() {
            let m = store.textured(&self.model, k);
            self.textured[k] = Some(GpuModel::new(self.ctx, &m).map_err(|e| e.to_string())?);
        }
        let gm = self.textured[k].as_ref().ok_or("keyframe model missing")?;
        self.splatter
            .render(
                self.ctx,
                gm,
                &self.cam,
                pose,
                Attributes::ALL,
                &mut self.targets,
            )
            .map_err(|e| e.to_string())?;
        let colour = self
            .splatter
            .read(self.ctx, &self.targets, Attribute::Color)
            .map_err(|e| e.to_string())?;
        let view =
            GreyImage::from_rgb_f32(colour.width as usize, colour.height as usize, &colour.data)
                .map_err(|e| e.to_string())?;
        let view_corners = self.harris.detect(&view, None).map_err(|e| e.to_string())?;
        let matcher = match search {
            Search::Recover => &mut self.recover_matcher,
            Search::Motion => &mut self.it_matcher,
            Search::Refine => &mut self.kf_matcher,
        };
        let matches = matcher
            .match_features(&view, &view_corners, grey, corners)
            .map_err(|e| e.to_string())?;
        let pts: Vec<[f32; 2]> = matches
            .iter()
            .map(|m| [view_corners[m.a].x, view_corners[m.a].y])
            .collect();
        let samples = self
            .splatter
            .gather(self.ctx, &self.targets, &pts, GatherMode::Bilinear)
            .map_err(|e| e.to_string())?;
        let obs: Vec<(Observation, Vector3<f64>, Vector2<f64>)> = matches
            .iter()
            .zip(&samples)
            .filter(|(_, s)| s.valid)
            .filter_map(|(m, s): (&Match, _)| {
                let a = &view_corners[m.a];
                let from = Vector2::new(a.x as f64, a.y as f64);
                let to = self.match_target(&view, a, grey, &corners[m.b])?;
                Some((
                    Observation {
                        predictors: s.matrix(),
                        displacement: to - from,
                    },
                    self.lift(&from, s.depth as f64, pose),
                    to,
                ))
            })
            .collect();
        self.solve_and_refine(&obs, pose, anchors).map(|s| (s, k))
    }

    /// Where the corner `a` of image `src` lies in the live frame: the
    /// matched corner `b`, moved to the NCC peak when refinement is on;
    /// `None` drops a match whose refinement fails.
    fn match_target(
        &self,
        src: &GreyImage,
        a: &Corner,
        live: &GreyImage,
        b: &Corner,
    ) -> Option<Vector2<f64>> {
        if self.config.refine_window == 0 {
            return Some(Vector2::new(b.x as f64, b.y as f64));
        }
        let (p, _) = refine_match(
            src,
            [a.x, a.y],
            live,
            [b.x, b.y],
            self.config.refine_window,
            2,
            self.config.ncc.min_score * 0.8,
        )?;
        Some(Vector2::new(p[0] as f64, p[1] as f64))
    }

    /// The object-frame point seen at pixel `uv` with camera depth `z` at
    /// `pose`.
    fn lift(&self, uv: &Vector2<f64>, z: f64, pose: &Pose) -> Vector3<f64> {
        pose.inverse().transform_point(&self.cam.unproject(uv, z))
    }

    /// The paper's linear solve, then Gauss-Newton refinements that
    /// re-project the lifted points at the updated pose. `extra` are
    /// correspondences from another step (the IT inliers, when fusing) that
    /// join the refinement with the same robust loss.
    fn solve_and_refine(
        &self,
        obs: &[(Observation, Vector3<f64>, Vector2<f64>)],
        pose: &Pose,
        extra: &[(Vector3<f64>, Vector2<f64>)],
    ) -> Result<Step, String> {
        let linear: Vec<Observation> = obs.iter().map(|o| o.0).collect();
        let first = irls(&linear, &self.config.irls).map_err(|e: SolveError| e.to_string())?;
        let mut current = pose.apply_twist(&first.twist);
        let mut solve = first;
        let own: Vec<(Vector3<f64>, Vector2<f64>)> = obs.iter().map(|o| (o.1, o.2)).collect();
        let mut points: Vec<(Vector3<f64>, Vector2<f64>)> = own.clone();
        points.extend_from_slice(extra);
        // Borrowed matches count with `fuse_weight`: scaling a row of the
        // linearised system by sqrt(w) weights its squared residual by w.
        let row_scale = |i: usize| {
            if i < own.len() {
                1.0
            } else {
                self.config.fuse_weight.sqrt()
            }
        };
        // Which of `points` the last refinement kept, in its order.
        let mut last_kept: Option<Vec<usize>> = None;
        for _ in 0..self
            .config
            .refine_iterations
            .max(usize::from(!extra.is_empty()))
        {
            let (refined, kept): (Vec<Observation>, Vec<usize>) = points
                .iter()
                .enumerate()
                .filter_map(|(i, (x, to))| {
                    let xc = current.transform_point(x);
                    let uv = self.cam.project(&xc)?;
                    let k = row_scale(i);
                    Some((
                        Observation {
                            predictors: self.cam.motion_predictors(&xc) * k,
                            displacement: (to - uv) * k,
                        },
                        i,
                    ))
                })
                .unzip();
            match irls(&refined, &self.config.irls) {
                Ok(s) => {
                    current = current.apply_twist(&s.twist);
                    let small = s.twist.norm() < 1e-9;
                    // Report this step's own matches, not the borrowed ones.
                    let own_inliers = kept
                        .iter()
                        .zip(&s.inliers)
                        .filter(|(i, inl)| **i < own.len() && **inl)
                        .count();
                    solve = IrlsResult {
                        inlier_count: own_inliers,
                        ..s
                    };
                    last_kept = Some(kept);
                    if small {
                        break;
                    }
                }
                Err(_) => break,
            }
        }
        let mut inliers = vec![false; points.len()];
        match &last_kept {
            Some(kept) => {
                for (&i, &inl) in kept.iter().zip(&solve.inliers) {
                    inliers[i] = inl;
                }
            }
            // The linear solve's inliers are over `obs`, i.e. `own`.
            None => inliers[..solve.inliers.len()].copy_from_slice(&solve.inliers),
        }
        let anchors = own
            .iter()
            .zip(&inliers)
            .filter(|(_, i)| **i)
            .map(|(a, _)| *a)
            .collect();
        Ok(Step {
            pose: current.orthonormalized(),
            solve,
            anchors,
        })
    }

    /// Renders the model at `pose` and returns its coverage mask (for
    /// overlays): one flag per pixel.
    pub fn silhouette(&mut self, pose: &Pose) -> Result<Vec<bool>, TrackError> {
        self.splatter.render(
            self.ctx,
            &self.geometry,
            &self.cam,
            pose,
            Attributes::COLOR,
            &mut self.targets,
        )?;
        let w = self
            .splatter
            .read(self.ctx, &self.targets, Attribute::Weight)?;
        Ok(w.data.iter().map(|v| *v > 0.0 && !v.is_nan()).collect())
    }
}
