//! Making a [`Tracker`].

use super::config::{Mode, TrackerConfig};
use super::contour::ContourState;
use super::error::{CameraInvalid, TrackError};
use super::outline_gpu::GpuOutline;
use super::region::Resident;
use super::result::StageTimes;
use super::state::Tracker;
use super::verify_gpu::GpuCheck;
use crate::features::{Harris, NccMatcher};
use crate::geometry::{Intrinsics, Pose};
use crate::gpu::GpuContext;
use crate::keyframes::KeyframeStore;
use crate::model::PointModel;
use crate::splat::{GpuModel, SplatTargets, Splatter, Window};
use nalgebra::{Matrix3, Vector3};
use std::sync::Arc;

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
            contour: ContourState::new(config_colours.0, config_colours.1),
            kf_anchors: Vec::new(),
            stages: StageTimes::default(),
            gpu_timer: None,
            pending_gpu: Vec::new(),
            check: GpuCheck::new(ctx).map_err(crate::splat::SplatError::from)?,
            outline: GpuOutline::new(ctx).map_err(crate::splat::SplatError::from)?,
            resident: Resident::new(resident),
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
}
