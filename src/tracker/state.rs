//! The tracker's state ([`Tracker`]) and the frames it keeps, with the
//! accessors.

use super::config::TrackerConfig;
use super::contour::ContourState;
use super::features_on::{CornerDetector, Matcher};
pub(super) use super::frames::Frame;
use super::outline_gpu::GpuOutline;
use super::region::{Kept, Resident, ViewMade};
use super::result::{GpuMemoryUse, StageTimes};
use super::verify_gpu::GpuCheck;
use crate::device::Device;
use crate::geometry::{Intrinsics, Pose};
use crate::gpu::GpuContext;
use crate::keyframes::KeyframeStore;
use crate::model::PointModel;
use crate::pose::Anchor;
use crate::splat::{GpuModel, SplatTargets, Splatter, Window};
use nalgebra::Vector3;
use std::sync::Arc;

/// The tracker: create once per sequence, then call [`Tracker::track`] on
/// each frame in order. It runs on a [`Device`]: a GPU (it keeps its own
/// handle on the context, a cheap clone, so a program may keep both side
/// by side) or the CPU device, where it makes no GPU object.
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
/// let mut tracker = Tracker::builder(&ctx, model, seq.camera)
///     .keyframes(store)
///     .config(config)
///     .initial_pose(init)
///     .build()?;
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
    pub(super) cam: Intrinsics,
    pub(super) config: TrackerConfig,
    /// The model as splatted (its radii raised and grown); the caller's
    /// own, shared, where they needed no change.
    pub(super) model: Arc<PointModel>,
    pub(super) store: Option<Arc<KeyframeStore>>,
    pub(super) splatter: Splatter,
    /// The model uploaded, shared so that it can occlude another
    /// object's renders ([`crate::splat::Occluder`]).
    pub(super) geometry: Arc<GpuModel>,
    pub(super) textured: crate::keyframes::TexturedCache,
    /// The targets of the last render, the size of [`Tracker::window`].
    pub(super) targets: SplatTargets,
    /// The window of the last render (frame coordinates).
    pub(super) window: Window,
    /// Targets of other window sizes, for reuse.
    pub(super) spare: Vec<SplatTargets>,
    /// The check's render of the last reported pose, for the next IT step.
    pub(super) kept: Option<Kept>,
    /// The novel view the targets hold, while they hold it.
    pub(super) view_made: Option<ViewMade>,
    /// The model's bounding box grown by its largest splat (where renders
    /// can cover pixels).
    pub(super) box_lo: Vector3<f64>,
    pub(super) box_hi: Vector3<f64>,
    pub(super) harris: CornerDetector,
    pub(super) it_matcher: Matcher,
    pub(super) kf_matcher: Matcher,
    pub(super) recover_matcher: Matcher,
    pub(super) center: Vector3<f64>,
    pub(super) radius: f64,
    pub(super) pose: Pose,
    pub(super) prev: Option<Frame>,
    /// The bytes of the frame before `prev`, a buffer for the next one.
    pub(super) spare_frame: Option<image::RgbImage>,
    pub(super) lost_streak: usize,
    /// Recovering frames so far, which pick their KF step's start
    /// ([`Tracker::recovery_start`]).
    pub(super) recovery_turn: usize,
    /// A start's pose that passed only the usual check
    /// ([`Tracker::judge_start`]): the next recovering frame starts there.
    pub(super) recovery_next: Option<Pose>,
    /// The object was last lost hidden by another object (the recovery's
    /// turns of the last pose come first).
    pub(super) recovery_hidden: bool,
    /// The loss began on a frame after a tracked one (not at the first
    /// frame): during a short loss the last pose is each frame's first
    /// start ([`Tracker::recovery_first`]).
    pub(super) recovery_tracked: bool,
    /// The last tracked frames' edge support and shading, oldest first
    /// (cleared by a lost frame; [`super::steady`]).
    pub(super) steady: super::recent::History,
    /// The object's motion before a loss ([`super::drift::Drift`]).
    pub(super) drift: super::drift::Drift,
    /// KF+IT: consecutive frames tracked by IT alone.
    pub(super) it_only_streak: usize,
    /// No pose yet: each frame is searched (no initial pose given to [`Tracker::builder`]).
    pub(super) searching: bool,
    /// The last search's best candidate that failed the check (reported
    /// as refused when the search finds nothing).
    pub(super) search_refused: Option<super::result::Refused>,
    /// Whether the object's views show shading only (measured at the
    /// first search: `Tracker::shading_only`).
    pub(super) shading_only: Option<bool>,
    /// Whether the last search's answer was refined by the outline alone,
    /// on an object whose views show shading only.
    pub(super) found_by_outline: bool,
    /// Frames a start found by the outline alone must still track
    /// consistently before it is reported (0: none held).
    pub(super) confirm_left: usize,
    /// The pose reported while a start is held (the last good one).
    pub(super) confirm_report: Pose,
    /// The tracker's device (on a GPU, its own handle on the context: a
    /// cheap clone).
    pub(super) device: Device,
    /// The contour step's colours, coverage, normals and counts.
    pub(super) contour: ContourState,
    /// The inliers of this frame's last KF step (for the fused solve).
    pub(super) kf_anchors: Vec<Anchor>,
    /// The sub-stage times of the frame being tracked.
    pub(super) stages: StageTimes,
    /// Times the splat passes when on ([`super::Execution::gpu_timing`]).
    pub(super) gpu_timer: Option<crate::gpu::GpuTimer>,
    /// The frame's timed passes by label prefix, their timestamps still
    /// to come with the frame's readbacks (read at its end).
    pub(super) pending_gpu: Vec<(String, crate::gpu::Timings)>,
    /// The check's scoring on the GPU (`None` on the CPU device).
    pub(super) check: Option<GpuCheck>,
    /// The contour's outline found on the GPU (`None` on the CPU device).
    pub(super) outline: Option<GpuOutline>,
    /// The grey levels of the frame being tracked and of the previous one,
    /// on the GPU for NCC and the refinement ([`Resident`]).
    pub(super) resident: Resident,
    /// The search while lost, between frames, and its budget's times.
    pub(super) lost: super::lost::LostSearch,
    /// The search's detection by features, made at its first use.
    pub(super) detector: Option<super::detect::cache::Detector>,
    /// What the automatic choice of cues measured and chose, when it ran.
    pub(super) cue_choice: Option<super::config::CueChoice>,
    /// What other objects hide of this one in the frame being tracked
    /// (several objects, [`super::MultiTracker`]; `None`: nothing).
    pub(super) hidden: Option<super::occlusion::Hidden>,
}

impl Tracker {
    /// The model as the tracker splats it: the one it was given (the
    /// same `Arc`) where it needed no change, else a copy with its points
    /// merged to `detail_px` and its radii raised to
    /// `min_splat_radius_px` and grown to close gaps.
    pub fn model(&self) -> &Arc<PointModel> {
        &self.model
    }

    /// The model as uploaded to the tracker's device, to occlude the
    /// renders of another object's tracker on that device.
    pub(crate) fn gpu_model(&self) -> &Arc<GpuModel> {
        &self.geometry
    }

    /// What [`TrackerConfig::auto_modalities`] measured and chose when the
    /// tracker was built (`None` when the modalities were given).
    pub fn cue_choice(&self) -> Option<super::config::CueChoice> {
        self.cue_choice
    }

    /// Whether no pose has been found yet (no initial pose given to [`Tracker::builder`]).
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

    /// The device the tracker runs on.
    pub fn device(&self) -> &Device {
        &self.device
    }

    /// The GPU context the tracker runs on (`None` on the CPU device).
    pub fn context(&self) -> Option<&GpuContext> {
        self.device.gpu()
    }

    /// The GPU context, for the GPU's paths (never taken on the CPU
    /// device, where this is an error).
    pub(super) fn gpu_ctx(&self) -> Result<&GpuContext, crate::splat::SplatError> {
        self.device
            .gpu()
            .ok_or(crate::splat::SplatError::WrongDevice(
                "a GPU path on the CPU device",
            ))
    }

    /// The keyframe store in use: the one given to [`Tracker::builder`], or
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
    pub(super) fn roi(&self, pose: &Pose) -> Option<(usize, usize, usize, usize)> {
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
}

impl Tracker {
    /// The GPU memory of the splatting now ([`GpuMemoryUse`]).
    pub fn gpu_memory(&self) -> GpuMemoryUse {
        GpuMemoryUse {
            model: self.geometry.gpu_bytes(),
            keyframe_colors: self.textured.gpu_bytes(),
            targets: self.targets.gpu_bytes()
                + self.spare.iter().map(|t| t.gpu_bytes()).sum::<u64>()
                + self.kept.as_ref().map_or(0, |k| k.targets().gpu_bytes()),
        }
    }
}

#[cfg(test)]
mod tests {
    /// Embedders move trackers across threads and share them behind
    /// locks: the colour learner's queues must not take that away.
    #[test]
    fn the_tracker_stays_send_and_sync() {
        fn send_sync<T: Send + Sync>() {}
        send_sync::<super::Tracker>();
    }
}
