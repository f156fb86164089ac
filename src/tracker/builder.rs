//! Making a [`Tracker`].

use super::config::{Mode, TrackerConfig};
use super::contour::ContourState;
use super::error::{CameraInvalid, TrackError};
use super::execution::Execution;
use super::features_on::{CornerDetector, Matcher};
use super::outline_gpu::GpuOutline;
use super::region::Resident;
use super::result::StageTimes;
use super::state::Tracker;
use super::verify_gpu::GpuCheck;
use crate::device::Device;
use crate::geometry::{Intrinsics, Pose};
use crate::keyframes::KeyframeStore;
use crate::model::PointModel;
use crate::splat::{GpuModel, SplatTargets, Splatter, Window};
use nalgebra::{Matrix3, Vector3};
use std::sync::Arc;

/// Makes a [`Tracker`] ([`Tracker::builder`]): the device, the model and
/// the camera, then what the tracker needs beyond them.
///
/// - [`TrackerBuilder::keyframes`]: the keyframe store, moved in or
///   shared (`Arc`). None is needed in the IT mode, or when the model has
///   colours (they then serve as the single texture).
/// - [`TrackerBuilder::config`]: the settings (default:
///   [`TrackerConfig::default`]); they must pass
///   [`TrackerConfig::validate`].
/// - [`TrackerBuilder::initial_pose`]: the pose of the first frame given
///   to [`Tracker::track`]. Without one, each frame is searched for the
///   object ([`super::init`]) until it is found (until then the frames
///   are `lost`, reason `not found`), then tracked; the search needs a
///   texture (keyframes or model colours).
/// - [`TrackerBuilder::execution`]: the code paths ([`Execution`]).
pub struct TrackerBuilder<'a> {
    device: Device,
    /// Keeps the builder's lifetime parameter, for callers that name it.
    _borrow: std::marker::PhantomData<&'a ()>,
    model: Arc<PointModel>,
    cam: Intrinsics,
    keyframes: Option<Arc<KeyframeStore>>,
    config: TrackerConfig,
    initial: Option<Pose>,
    execution: Execution,
}

impl Tracker {
    /// A tracker for `model` seen by `cam` (undistorted frames), on
    /// `device`: a [`Device`], or a `&GpuContext` (the tracker keeps its
    /// own handle, a cheap clone), or `Device::Cpu` for the host's cores
    /// with no GPU driver (docs/guide.md says which is faster). The model
    /// may be shared (an `Arc<PointModel>`): the tracker copies it only
    /// where it merges its points or changes its radii (`detail_px`,
    /// `min_splat_radius_px`, `close_gaps`; [`Tracker::model`]).
    pub fn builder<'a>(
        device: impl Into<Device>,
        model: impl Into<Arc<PointModel>>,
        cam: Intrinsics,
    ) -> TrackerBuilder<'a> {
        TrackerBuilder {
            device: device.into(),
            _borrow: std::marker::PhantomData,
            model: model.into(),
            cam,
            keyframes: None,
            config: TrackerConfig::default(),
            initial: None,
            execution: Execution::default(),
        }
    }
}

impl TrackerBuilder<'_> {
    /// The keyframe store: moved in, or shared with the caller (an
    /// `Arc`): a store holds 12 bytes of colour per point and keyframe
    /// (144 MB for a 1M-point model and 12 keyframes), which a caller
    /// that keeps its own (an application tracking several runs from one
    /// set of inputs) need not copy.
    pub fn keyframes(mut self, store: impl Into<Arc<KeyframeStore>>) -> Self {
        self.keyframes = Some(store.into());
        self
    }

    /// [`TrackerBuilder::keyframes`] where `store` is `Some`; none where
    /// it is `None`.
    pub fn maybe_keyframes(mut self, store: Option<impl Into<Arc<KeyframeStore>>>) -> Self {
        self.keyframes = store.map(Into::into);
        self
    }

    /// The settings.
    pub fn config(mut self, config: TrackerConfig) -> Self {
        self.config = config;
        self
    }

    /// The pose of the first frame (`None`: search each frame for the
    /// object until it is found).
    pub fn initial_pose(mut self, pose: impl Into<Option<Pose>>) -> Self {
        self.initial = pose.into();
        self
    }

    /// The code paths ([`Execution`]; default: the adapter's).
    pub fn execution(mut self, execution: Execution) -> Self {
        self.execution = execution;
        self
    }

    /// The tracker. Fails on settings out of range, an impossible camera
    /// or initial pose, an initial pose that puts the object out of view,
    /// a mode or a search that needs a texture without one, or a GPU
    /// failure.
    pub fn build(self) -> Result<Tracker, TrackError> {
        let mut t = match self.initial {
            Some(initial) => Tracker::start(
                &self.device,
                self.model,
                self.cam,
                self.keyframes,
                self.config,
                initial,
            )?,
            None => Tracker::start_searching(
                &self.device,
                self.model,
                self.cam,
                self.keyframes,
                self.config,
            )?,
        };
        if t.config.auto_modalities {
            t.choose_modalities()?;
        }
        t.apply(&self.execution);
        // The detection's pipelines are made now: a lost frame that had
        // to make them would stall (a tenth of a second on lavapipe).
        if t.store.is_some() && t.config.init.detect.enabled {
            t.start_detector()?;
        }
        Ok(t)
    }
}

impl Tracker {
    /// The tracker starting at `initial`.
    fn start(
        device: &Device,
        mut model: Arc<PointModel>,
        cam: Intrinsics,
        keyframes: Option<Arc<KeyframeStore>>,
        config: TrackerConfig,
        initial: Pose,
    ) -> Result<Self, TrackError> {
        config.validate()?;
        cam.validate().map_err(CameraInvalid)?;
        initial.validate()?;
        // The bounding sphere: box centre, farthest point.
        let crate::splat::ModelBounds { center, radius, .. } =
            crate::splat::ModelBounds::of(&model);
        let z0 = initial.transform_point(&center).z;
        // The detail the camera resolves at that distance (the cell is
        // the size of `detail_px` pixels there).
        let cell = (config.detail_px as f64 * z0 / cam.fx.max(cam.fy)) as f32;
        let mut keyframes = keyframes;
        if cell > 0.0 && cell.is_finite() {
            let (merged, group) = model.merged(cell);
            // A store for another model is left to fail as it would have.
            let store = match &keyframes {
                Some(k) => k.merged(&merged, &group).map(|s| Some(Arc::new(s))),
                None => Some(None),
            };
            if let (true, Some(store)) = (merged.len() < model.len(), store) {
                log::debug!(
                    "model points merged to {} px at {z0:.3}: {} of {}",
                    config.detail_px,
                    merged.len(),
                    model.len()
                );
                model = Arc::new(merged);
                keyframes = store;
            }
        }
        let store =
            keyframes.or_else(|| KeyframeStore::from_model_colors(&model, &initial).map(Arc::new));
        if store.is_none() && config.mode != Mode::It {
            return Err(TrackError::NeedsKeyframes(config.mode.name()));
        }
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
        let splatter = Splatter::with_params(
            device,
            crate::splat::SplatParams {
                backend: config.splatter,
                ..Default::default()
            },
        )?;
        let geometry = Arc::new(GpuModel::new(device, &model)?);
        let targets = SplatTargets::new(device, cam.width, cam.height).motion_depth();
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
        let on_host = config.feature_backend.host_on_device(device);
        let harris = CornerDetector::new(device, config.harris.clone(), on_host)?;
        let matcher = |r: f32| {
            Matcher::new(
                device,
                config.ncc.clone().with_search_radius(Some(r)),
                on_host,
            )
        };
        let n_kf = store.as_ref().map_or(0, |s| s.keyframes.len());
        let model_len = model.len();
        let config_colours = (config.contour.bins, config.contour.sectors);
        // Resident images and the GPU's check and outline: on GPUs; the
        // host's paths measured faster on CPU adapters, and are the CPU
        // device's only ones.
        let resident = device
            .gpu()
            .is_some_and(|ctx| config.resident.unwrap_or(!ctx.is_cpu()));
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
            view_made: None,
            box_lo,
            box_hi,
            harris,
            center,
            radius,
            pose: initial,
            prev: None,
            spare_frame: None,
            lost_streak: 0,
            recovery_turn: 0,
            recovery_next: None,
            recovery_hidden: false,
            recovery_tracked: false,
            steady: Default::default(),
            drift: Default::default(),
            it_only_streak: 0,
            searching: false,
            search_refused: None,
            shading_only: None,
            found_by_outline: false,
            confirm_left: 0,
            confirm_report: initial,
            device: device.clone(),
            contour: ContourState::new(config_colours.0, config_colours.1),
            kf_anchors: Vec::new(),
            stages: StageTimes::default(),
            gpu_timer: None,
            pending_gpu: Vec::new(),
            check: device
                .gpu()
                .map(GpuCheck::new)
                .transpose()
                .map_err(crate::splat::SplatError::from)?,
            outline: device
                .gpu()
                .map(GpuOutline::new)
                .transpose()
                .map_err(crate::splat::SplatError::from)?,
            resident: Resident::new(resident),
            lost: Default::default(),
            detector: None,
            cue_choice: None,
            hidden: None,
        };
        if let Some(c) = tracker.check.as_mut() {
            c.set_resident(resident);
        }
        if let Some(o) = tracker.outline.as_mut() {
            o.set_resident(resident);
        }
        if tracker.roi(&initial).is_none() {
            return Err(TrackError::ObjectNotInView);
        }
        Ok(tracker)
    }

    /// The tracker without an initial pose: searching each frame.
    fn start_searching(
        device: &Device,
        model: Arc<PointModel>,
        cam: Intrinsics,
        keyframes: Option<Arc<KeyframeStore>>,
        config: TrackerConfig,
    ) -> Result<Self, TrackError> {
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
        let mut t = Self::start(device, model, cam, keyframes, config, initial)?;
        if t.store.is_none() {
            return Err(TrackError::NeedsKeyframes("search (no initial pose)"));
        }
        t.searching = true;
        // The keyframes' features now, so the first search is a search.
        if t.config.init.detect.enabled {
            t.ensure_detector()?;
        }
        Ok(t)
    }

    /// Takes the code paths of `e` (after the constructor's own choices;
    /// each where it is not the default).
    fn apply(&mut self, e: &Execution) {
        if let Some(gpu) = e.gpu_kernels {
            self.set_gpu_kernels(gpu);
        }
        if let Some(tiled) = e.harris_tiled_selection {
            self.harris.set_tiled_selection(tiled);
        }
        if let Some(small) = e.harris_small_selection {
            self.harris.set_small_selection(Some(small));
        }
        if let Some(n) = e.harris_select_limit {
            self.harris.set_select_limit(n);
        }
        // The CPU device has no resident images, GPU check or outline.
        if let Some(on) = e.resident_matching.filter(|_| !self.device.is_cpu()) {
            self.set_resident_matching(on);
        }
        self.resident.chain_kf = e.chained_kf;
        self.resident.chain_it = e.chained_it;
        if let (Some(on), Some(c)) = (e.resident_check, self.check.as_mut()) {
            c.set_resident(on);
        }
        if let (Some(on), Some(o)) = (e.resident_outline, self.outline.as_mut()) {
            o.set_resident(on);
        }
        self.contour.colours.set_background(e.background_learning);
        if e.gpu_timing && !self.device.is_cpu() {
            self.enable_gpu_timing();
        }
    }
}
