//! `splattrack.Camera`: pinhole intrinsics with OpenCV's distortion.

use numpy::PyArray2;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use splattrack::geometry::Intrinsics;
use std::path::PathBuf;

/// A calibrated camera: the image size, the focal lengths and principal
/// point in pixels (OpenCV's convention: pixel (0, 0)'s centre at 0), and
/// OpenCV's distortion (k1, k2, p1, p2, k3). Frames of a distorting camera
/// are undistorted before tracking.
#[pyclass(module = "splattrack", frozen)]
#[derive(Clone)]
pub struct Camera {
    pub cam: Intrinsics,
}

#[pymethods]
impl Camera {
    #[new]
    #[pyo3(signature = (fx, fy, cx, cy, width, height, distortion=None))]
    fn new(
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        width: u32,
        height: u32,
        distortion: Option<Vec<f64>>,
    ) -> PyResult<Self> {
        let mut cam = Intrinsics::new(width, height, fx, fy, cx, cy);
        if let Some(d) = distortion {
            if d.len() > 5 {
                return Err(PyValueError::new_err(format!(
                    "distortion has {} coefficients: expected at most 5 (k1, k2, p1, p2, k3)",
                    d.len()
                )));
            }
            cam.distortion[..d.len()].copy_from_slice(&d);
        }
        cam.validate()
            .map_err(|e| PyValueError::new_err(format!("impossible camera: {e}")))?;
        Ok(Self { cam })
    }

    /// Reads `camera.json` or an OpenCV calibration YAML.
    #[staticmethod]
    fn from_file(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let cam = py
            .detach(|| Intrinsics::load(&path))
            .map_err(crate::errors::input)?;
        Ok(Self { cam })
    }

    #[getter]
    fn fx(&self) -> f64 {
        self.cam.fx
    }
    #[getter]
    fn fy(&self) -> f64 {
        self.cam.fy
    }
    #[getter]
    fn cx(&self) -> f64 {
        self.cam.cx
    }
    #[getter]
    fn cy(&self) -> f64 {
        self.cam.cy
    }
    #[getter]
    fn width(&self) -> u32 {
        self.cam.width
    }
    #[getter]
    fn height(&self) -> u32 {
        self.cam.height
    }
    /// k1, k2, p1, p2, k3 (all 0 for an ideal pinhole).
    #[getter]
    fn distortion(&self) -> (f64, f64, f64, f64, f64) {
        let d = self.cam.distortion;
        (d[0], d[1], d[2], d[3], d[4])
    }

    /// The 3x3 intrinsic matrix K.
    fn matrix<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let k = self.cam.matrix();
        let rows: Vec<Vec<f64>> = (0..3)
            .map(|i| (0..3).map(|j| k[(i, j)]).collect())
            .collect();
        PyArray2::from_vec2(py, &rows).expect("3x3")
    }

    fn __repr__(&self) -> String {
        let c = &self.cam;
        format!(
            "Camera(fx={}, fy={}, cx={}, cy={}, width={}, height={}, distortion={:?})",
            c.fx, c.fy, c.cx, c.cy, c.width, c.height, c.distortion
        )
    }
}
