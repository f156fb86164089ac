//! `splattrack.MultiTracker`: several objects through the frames of one
//! camera, each with the model, keyframes and settings of a `Tracker`
//! made for it, tracked together by the library's `MultiTracker`.

use crate::arrays::{fill_frame, pose_array, pose_from};
use crate::errors;
use crate::tracker::{TrackResult, Tracker};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use splattrack::geometry::{Intrinsics, Pose, Undistorter};
use splattrack::tracker::{self as lib};

/// Several objects tracked through the same frames.
#[pyclass(module = "splattrack")]
pub struct MultiTracker {
    /// The objects, named, each with the tracker that describes it.
    objects: Vec<(String, Py<Tracker>)>,
    /// The camera as calibrated (the first object's; all the same).
    camera: Intrinsics,
    undistorter: Option<Undistorter>,
    /// The library's trackers, made by `start` or the first `track`.
    inner: Option<lib::MultiTracker>,
}

#[pymethods]
impl MultiTracker {
    #[new]
    fn new(py: Python<'_>, objects: &Bound<'_, PyAny>) -> PyResult<Self> {
        let pairs: Vec<(String, Py<Tracker>)> = match objects.cast::<PyDict>() {
            Ok(d) => d
                .iter()
                .map(|(k, v)| Ok((k.extract()?, v.extract()?)))
                .collect::<PyResult<_>>()?,
            Err(_) => objects.extract().map_err(|_| {
                PyValueError::new_err(
                    "objects must be a dict of name: Tracker, or a list of (name, Tracker) pairs",
                )
            })?,
        };
        let Some((_, first)) = pairs.first() else {
            return Err(PyValueError::new_err(lib::MultiError::Empty.to_string()));
        };
        let camera = *first.bind(py).borrow().calibrated();
        for (k, (name, t)) in pairs.iter().enumerate() {
            if pairs[..k].iter().any(|(n, _)| n == name) {
                let e = lib::MultiError::DuplicateName(name.clone());
                return Err(PyValueError::new_err(e.to_string()));
            }
            if *t.bind(py).borrow().calibrated() != camera {
                let e = lib::MultiError::OtherCamera(name.clone());
                return Err(PyValueError::new_err(e.to_string()));
            }
        }
        Ok(Self {
            objects: pairs,
            undistorter: camera.has_distortion().then(|| Undistorter::new(&camera)),
            camera,
            inner: None,
        })
    }

    /// Starts (or restarts) the track at the next frame's poses: a dict
    /// of name: pose (4x4); an object left out is searched for.
    fn start(&mut self, py: Python<'_>, poses: &Bound<'_, PyDict>) -> PyResult<()> {
        let mut given: Vec<Option<Pose>> = vec![None; self.objects.len()];
        for (k, v) in poses.iter() {
            let name: String = k.extract()?;
            let Some(i) = self.objects.iter().position(|(n, _)| *n == name) else {
                return Err(PyValueError::new_err(format!(
                    "start: no object named {name:?} (objects: {})",
                    self.names().join(", ")
                )));
            };
            given[i] = Some(pose_from(&v, &format!("poses[{name:?}]"))?);
        }
        self.inner = None;
        self.inner = Some(self.build(py, &given)?);
        Ok(())
    }

    /// Tracks the next frame (HxWx3 `uint8` RGB or HxW grey, the camera's
    /// size, undistorted here when the camera has distortion): a dict of
    /// name: TrackResult, in the objects' order.
    fn track<'py>(
        &mut self,
        py: Python<'py>,
        frame: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        if self.inner.is_none() {
            let none = vec![None; self.objects.len()];
            self.inner = Some(self.build(py, &none)?);
        }
        let mut buf = image::RgbImage::new(self.camera.width, self.camera.height);
        fill_frame(frame, "frame", &mut buf)?;
        let und = self.undistorter.as_ref();
        let multi = self.inner.as_mut().expect("built above");
        let results = py
            .detach(|| {
                let img = crate::arrays::undistorted(und, buf)?;
                multi.track(&img)
            })
            .map_err(errors::track)?;
        let out = PyDict::new(py);
        for (i, (r, (name, _))) in results.iter().zip(&self.objects).enumerate() {
            out.set_item(name, TrackResult::of_tracker(r, multi.tracker(i)))?;
        }
        Ok(out)
    }

    /// The objects' names, in their order.
    #[getter]
    fn names(&self) -> Vec<String> {
        self.objects.iter().map(|(n, _)| n.clone()).collect()
    }

    /// Each object's current pose (4x4), `None` before its track has
    /// started, by name.
    #[getter]
    fn poses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for (i, (name, _)) in self.objects.iter().enumerate() {
            let pose = self
                .inner
                .as_ref()
                .map(|m| m.tracker(i))
                .filter(|t| !t.searching())
                .map(|t| pose_array(py, &t.pose()));
            out.set_item(name, pose)?;
        }
        Ok(out)
    }

    fn __len__(&self) -> usize {
        self.objects.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "MultiTracker([{}], {})",
            self.names().join(", "),
            if self.inner.is_some() {
                "started"
            } else {
                "not started"
            }
        )
    }
}

impl MultiTracker {
    /// The library's trackers, each object's at its pose in `poses` (or
    /// searching).
    fn build(&self, py: Python<'_>, poses: &[Option<Pose>]) -> PyResult<lib::MultiTracker> {
        let mut named = Vec::with_capacity(self.objects.len());
        for ((name, t), pose) in self.objects.iter().zip(poses) {
            named.push((name.clone(), t.bind(py).borrow().build(py, *pose)?));
        }
        lib::MultiTracker::new(named).map_err(|e| PyValueError::new_err(e.to_string()))
    }
}
