//! `splattrack.Tracker` and `splattrack.TrackResult`: the library's
//! tracker as the command line runs it (the mode chosen when none is
//! named, the cues chosen per object, keyframes from a folder or a store,
//! frames undistorted), one frame at a time from numpy arrays.

use crate::arrays::{fill_frame, pose_array, pose_from};
use crate::camera::Camera;
use crate::errors;
use crate::model::Model;
use crate::settings;
use numpy::{PyArray2, PyArray3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use splattrack::Device;
use splattrack::PointModel;
use splattrack::geometry::{Intrinsics, Pose, Undistorter};
use splattrack::keyframes::{KeyframeConfig, KeyframeStore};
use splattrack::splat::Splatter;
use splattrack::tracker::{self as lib, Mode, TrackerConfig};
use std::sync::Arc;

/// Tracks a rigid object through the frames of one camera.
#[pyclass(module = "splattrack")]
pub struct Tracker {
    ctx: Device,
    model: Arc<PointModel>,
    /// The camera as calibrated (with its distortion).
    camera: Intrinsics,
    undistorter: Option<Undistorter>,
    store: Option<Arc<KeyframeStore>>,
    config: TrackerConfig,
    /// The library's tracker, made by `start` (at its pose) or by the
    /// first `track` (searching for the object).
    inner: Option<lib::Tracker>,
    /// A tracker for `render` before any `start` or `track`.
    viewer: Option<lib::Tracker>,
}

#[pymethods]
impl Tracker {
    #[new]
    #[pyo3(signature = (model, camera, keyframes=None, *, mode=None, modalities="auto", device="auto", **kwargs))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments
    fn new(
        py: Python<'_>,
        model: PyRef<'_, Model>,
        camera: PyRef<'_, Camera>,
        keyframes: Option<&Bound<'_, PyAny>>,
        mode: Option<&str>,
        modalities: &str,
        device: &str,
        kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let settings::Settings { mut config, mode } = settings::parse(mode, modalities, kwargs)?;
        let ctx = crate::device_of(py, device)?;
        let model = model.model.clone();
        let camera = camera.cam;
        let store = match keyframes {
            None => None,
            Some(k) if k.is_none() => None,
            Some(k) => Some(Arc::new(load_keyframes(py, &ctx, &model, &camera, k)?)),
        };
        let textured = store.is_some() || model.colors.is_some();
        config.mode = splattrack::app::run_mode(mode, textured)
            .map_err(|m| errors::track(lib::TrackError::NeedsKeyframes(m.name())))?;
        let undistorter = camera.has_distortion().then(|| Undistorter::new(&camera));
        Ok(Self {
            ctx,
            model,
            camera,
            undistorter,
            store,
            config,
            inner: None,
            viewer: None,
        })
    }

    /// Starts (or restarts) the track at `pose`, the object-to-camera pose
    /// of the next frame (4x4, model units).
    fn start(&mut self, py: Python<'_>, pose: &Bound<'_, PyAny>) -> PyResult<()> {
        let pose = pose_from(pose, "pose")?;
        self.inner = None;
        self.inner = Some(self.build(py, Some(pose))?);
        Ok(())
    }

    /// Tracks the next frame: an HxWx3 `uint8` RGB array (or HxW grey) of
    /// the camera's size, as it comes from the camera (undistorted here
    /// when the camera has distortion).
    fn track(&mut self, py: Python<'_>, frame: &Bound<'_, PyAny>) -> PyResult<TrackResult> {
        if self.inner.is_none() {
            self.inner = Some(self.build(py, None)?);
        }
        let inner = self.inner.as_mut().expect("built above");
        // The one copy of the frame: into the tracker's own buffer, or
        // into the undistorter's source.
        let mut buf = match self.undistorter {
            None => inner.frame_buffer(),
            Some(_) => image::RgbImage::new(self.camera.width, self.camera.height),
        };
        fill_frame(frame, "frame", &mut buf)?;
        let und = self.undistorter.as_ref();
        let r = py
            .detach(|| {
                let img = crate::arrays::undistorted(und, buf)?;
                inner.track_owned(img)
            })
            .map_err(errors::track)?;
        Ok(TrackResult::of_tracker(&r, inner))
    }

    /// The novel view at `pose` (4x4): the model textured by the closest
    /// keyframe over the camera's undistorted image. Returns `(colour,
    /// depth, mask)`: HxWx3 `uint8` (0 where empty), HxW `float32` depth
    /// in model units (NaN where empty), HxW `bool` coverage.
    #[allow(clippy::type_complexity)]
    fn render<'py>(
        &mut self,
        py: Python<'py>,
        pose: &Bound<'py, PyAny>,
    ) -> PyResult<(
        Bound<'py, PyArray3<u8>>,
        Bound<'py, PyArray2<f32>>,
        Bound<'py, PyArray2<bool>>,
    )> {
        let pose = pose_from(pose, "pose")?;
        if self.inner.is_none() && self.viewer.is_none() {
            // Its own tracker (at this pose, frame to frame: nothing to
            // measure): the next `track` still searches or starts anew.
            let mut config = self.config.clone();
            config.mode = Mode::It;
            config.auto_modalities = false;
            self.viewer = Some(self.build_with(py, Some(pose), config)?);
        }
        let t = match (&mut self.inner, &mut self.viewer) {
            (Some(t), _) | (None, Some(t)) => t,
            (None, None) => unreachable!("made above"),
        };
        let v = py.detach(|| t.novel_view(&pose)).map_err(errors::track)?;
        let (w, h) = (v.width as usize, v.height as usize);
        let shape_err = |e: numpy::ndarray::ShapeError| PyValueError::new_err(e.to_string());
        let colour =
            numpy::ndarray::Array3::from_shape_vec((h, w, 3), v.color).map_err(shape_err)?;
        let depth = numpy::ndarray::Array2::from_shape_vec((h, w), v.depth).map_err(shape_err)?;
        let mask = numpy::ndarray::Array2::from_shape_vec((h, w), v.mask).map_err(shape_err)?;
        Ok((
            PyArray3::from_owned_array(py, colour),
            PyArray2::from_owned_array(py, depth),
            PyArray2::from_owned_array(py, mask),
        ))
    }

    /// The mode tracked: `kf+it`, `it` or `kf`.
    #[getter]
    fn mode(&self) -> &'static str {
        self.config.mode.name()
    }

    /// The cues tracked (`texture`, `contour` or `texture,contour`); with
    /// `modalities="auto"`, known once the tracker has started (`None`
    /// before).
    #[getter]
    fn modalities(&self) -> Option<String> {
        match (&self.inner, self.config.auto_modalities) {
            (Some(t), _) => Some(t.config().modalities.name().to_owned()),
            (None, false) => Some(self.config.modalities.name().to_owned()),
            (None, true) => None,
        }
    }

    /// The current pose (4x4), `None` before the track has started.
    #[getter]
    fn pose<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.inner
            .as_ref()
            .filter(|t| !t.searching())
            .map(|t| pose_array(py, &t.pose()))
    }

    /// The camera the tracker was made with.
    #[getter]
    fn camera(&self) -> Camera {
        Camera { cam: self.camera }
    }

    /// How many keyframes texture the novel views (0: none).
    #[getter]
    fn keyframes(&self) -> usize {
        self.store.as_ref().map_or(0, |s| s.keyframes.len())
    }

    fn __repr__(&self) -> String {
        format!(
            "Tracker(mode={}, modalities={}, keyframes={}, {})",
            self.config.mode.name(),
            self.modalities().unwrap_or_else(|| "auto".into()),
            self.keyframes(),
            if self.inner.is_some() {
                "started"
            } else {
                "not started"
            }
        )
    }
}

impl Tracker {
    /// The camera as calibrated, with its distortion.
    pub(crate) fn calibrated(&self) -> &Intrinsics {
        &self.camera
    }

    pub(crate) fn build(&self, py: Python<'_>, pose: Option<Pose>) -> PyResult<lib::Tracker> {
        self.build_with(py, pose, self.config.clone())
    }

    fn build_with(
        &self,
        py: Python<'_>,
        pose: Option<Pose>,
        config: TrackerConfig,
    ) -> PyResult<lib::Tracker> {
        let (ctx, model, store) = (&self.ctx, self.model.clone(), self.store.clone());
        let cam = self.camera.undistorted();
        py.detach(|| {
            lib::Tracker::builder(ctx, model, cam)
                .maybe_keyframes(store)
                .config(config)
                .initial_pose(pose)
                .build()
        })
        .map_err(errors::track)
    }
}

/// The keyframes `k` names: a folder (images and `poses.csv`) or a store
/// file (`.stkf`), or a list of `(image, pose)` pairs.
fn load_keyframes(
    py: Python<'_>,
    ctx: &Device,
    model: &PointModel,
    camera: &Intrinsics,
    k: &Bound<'_, PyAny>,
) -> PyResult<KeyframeStore> {
    if k.is_instance_of::<PyString>() || k.hasattr("__fspath__")? {
        let path: std::path::PathBuf = k.extract()?;
        return py
            .detach(|| splattrack::app::load_keyframes(ctx, model, camera, &path))
            .map_err(errors::app);
    }
    let items: Vec<Bound<'_, PyAny>> = k.extract().map_err(|_| {
        PyValueError::new_err(
            "keyframes must be a folder, a .stkf store or a list of (image, pose) pairs",
        )
    })?;
    if items.is_empty() {
        return Err(PyValueError::new_err("keyframes: the list is empty"));
    }
    let und = camera.has_distortion().then(|| Undistorter::new(camera));
    let mut frames = Vec::with_capacity(items.len());
    for (i, item) in items.iter().enumerate() {
        let (img, pose): (Bound<'_, PyAny>, Bound<'_, PyAny>) = item.extract().map_err(|_| {
            PyValueError::new_err(format!("keyframes[{i}] must be an (image, pose) pair"))
        })?;
        let mut buf = image::RgbImage::new(camera.width, camera.height);
        fill_frame(&img, &format!("keyframes[{i}] image"), &mut buf)?;
        let buf = match &und {
            Some(u) => u.apply(&buf).map_err(PyValueError::new_err)?,
            None => buf,
        };
        let pose = pose_from(&pose, &format!("keyframes[{i}] pose"))?;
        frames.push((i.to_string(), buf, pose));
    }
    let cam = camera.undistorted();
    py.detach(|| {
        let splatter = Splatter::new(ctx).map_err(errors::gpu)?;
        KeyframeStore::build(
            ctx,
            &splatter,
            model,
            &cam,
            &frames,
            &KeyframeConfig::default(),
        )
        .map_err(errors::input)
    })
}

/// What `Tracker.track` says about a frame.
#[pyclass(module = "splattrack", frozen)]
pub struct TrackResult {
    pose: [[f64; 4]; 4],
    /// `"tracking"` or `"lost"`.
    #[pyo3(get)]
    status: &'static str,
    /// `None`, or why the frame is lost, as the command line says it.
    #[pyo3(get)]
    reason: Option<String>,
    /// Inliers of the frame's last robust solve.
    #[pyo3(get)]
    inliers: usize,
    /// Their RMS residual, pixels (NaN without a solve).
    #[pyo3(get)]
    residual_px: f64,
    /// The tracker's time for the frame, milliseconds.
    #[pyo3(get)]
    time_ms: f64,
    /// The keyframe of the KF step, if any.
    #[pyo3(get)]
    keyframe: Option<usize>,
    /// The cues that held the pose, as the `cues` column writes them.
    #[pyo3(get)]
    cues: String,
}

impl TrackResult {
    /// `r`, a result of `tracker`: its pose NaN while the tracker has
    /// none yet (searching), as nothing good can be reported.
    pub(crate) fn of_tracker(r: &lib::TrackResult, tracker: &lib::Tracker) -> Self {
        let mut result = Self::of(r);
        if tracker.searching() {
            result.pose = [[f64::NAN; 4]; 4];
        }
        result
    }

    fn of(r: &lib::TrackResult) -> Self {
        let m = r.pose.to_matrix4();
        Self {
            pose: std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])),
            status: r.status.name(),
            reason: r.reason.as_ref().map(ToString::to_string),
            inliers: r.inliers,
            residual_px: r.residual_px,
            time_ms: r.times.total.as_secs_f64() * 1e3,
            keyframe: r.keyframe,
            cues: splattrack::app::cues_name(r.cues),
        }
    }
}

#[pymethods]
impl TrackResult {
    /// The object-to-camera pose (4x4 `float64`); the last good pose on a
    /// lost frame, NaN before the object was first found.
    #[getter]
    fn pose<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let rows: Vec<Vec<f64>> = self.pose.iter().map(|r| r.to_vec()).collect();
        PyArray2::from_vec2(py, &rows).expect("4x4")
    }

    fn __repr__(&self) -> String {
        let t = [self.pose[0][3], self.pose[1][3], self.pose[2][3]];
        match &self.reason {
            None => format!(
                "TrackResult({}, {} inliers, t={:?}, {:.1} ms)",
                self.status, self.inliers, t, self.time_ms
            ),
            Some(r) => format!("TrackResult({}: {r}, t={:?})", self.status, t),
        }
    }
}
