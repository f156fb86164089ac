//! numpy arrays in and out: frames (HxWx3 or HxW `uint8`, copied once into
//! the tracker's own buffer), poses (4x4 `float64`), images read from
//! files. Wrong shapes and dtypes are `ValueError`s that say what was
//! expected.

use numpy::ndarray::{ArrayView2, ArrayView3};
use numpy::prelude::*;
use numpy::{PyArray2, PyArray3, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArray};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use splattrack::geometry::Pose;

/// The frame `obj` (`what` names it in errors) copied into `buf` (the
/// camera's size): HxWx3 `uint8` RGB, or HxW `uint8` grey (each level
/// copied into the three channels).
pub fn fill_frame(obj: &Bound<'_, PyAny>, what: &str, buf: &mut image::RgbImage) -> PyResult<()> {
    let (w, h) = (buf.width() as usize, buf.height() as usize);
    let arr = uint8_array(obj, what)?;
    let shape = arr.shape().to_vec();
    let size_error = || {
        PyValueError::new_err(format!(
            "{what} is {}, the camera is {w}x{h}: expected an array of shape ({h}, {w}, 3) or ({h}, {w})",
            shape_text(&shape),
        ))
    };
    match shape.as_slice() {
        [hh, ww, 3] if (*hh, *ww) == (h, w) => {
            let a: PyReadonlyArray3<'_, u8> = arr.cast::<PyArray3<u8>>()?.readonly();
            match a.as_slice() {
                Ok(s) => buf.copy_from_slice(s),
                Err(_) => copy_strided3(a.as_array(), buf),
            }
        }
        [hh, ww] if (*hh, *ww) == (h, w) => {
            let a: PyReadonlyArray2<'_, u8> = arr.cast::<PyArray2<u8>>()?.readonly();
            copy_grey(a.as_array(), buf);
        }
        [_, _, c] if *c != 3 => {
            return Err(PyValueError::new_err(format!(
                "{what} has {c} channels: expected RGB (H, W, 3) or grey (H, W)"
            )));
        }
        [_, _, 3] | [_, _] => return Err(size_error()),
        _ => {
            return Err(PyValueError::new_err(format!(
                "{what} has shape {}: expected (H, W, 3) RGB or (H, W) grey",
                shape_text(&shape)
            )));
        }
    }
    Ok(())
}

fn copy_strided3(a: ArrayView3<'_, u8>, buf: &mut image::RgbImage) {
    for (dst, src) in buf.iter_mut().zip(a.iter()) {
        *dst = *src;
    }
}

fn copy_grey(a: ArrayView2<'_, u8>, buf: &mut image::RgbImage) {
    for (px, v) in buf.pixels_mut().zip(a.iter()) {
        px.0 = [*v; 3];
    }
}

/// `obj` as a numpy array of `uint8` (`ValueError` otherwise).
fn uint8_array<'py>(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<Bound<'py, PyUntypedArray>> {
    let arr = obj.cast::<PyUntypedArray>().map_err(|_| {
        PyValueError::new_err(format!(
            "{what} must be a numpy array, not {}",
            type_name(obj)
        ))
    })?;
    let dtype = arr.dtype();
    if !dtype.is_equiv_to(&numpy::dtype::<u8>(obj.py())) {
        return Err(PyValueError::new_err(format!(
            "{what} has dtype {}: expected uint8",
            dtype
        )));
    }
    Ok(arr.clone())
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

fn shape_text(shape: &[usize]) -> String {
    let parts: Vec<String> = shape.iter().map(ToString::to_string).collect();
    match parts.len() {
        1 => format!("({},)", parts[0]),
        _ => format!("({})", parts.join(", ")),
    }
}

/// A pose from a 4x4 array-like (object-to-camera, model units): its
/// rotation re-orthonormalised to full precision, as the library does on
/// reading a pose file, so that a pose read from `init.csv` in Python
/// gives the command line's.
pub fn pose_from(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Pose> {
    let m: Vec<Vec<f64>> = obj.extract().map_err(|_| {
        PyValueError::new_err(format!(
            "{what} must be a 4x4 array of numbers (object-to-camera), not {}",
            type_name(obj)
        ))
    })?;
    if m.len() != 4 || m.iter().any(|r| r.len() != 4) {
        let rows = m.len();
        let cols = m.first().map_or(0, Vec::len);
        return Err(PyValueError::new_err(format!(
            "{what} is {rows}x{cols}: expected a 4x4 matrix (object-to-camera)"
        )));
    }
    if !m.iter().flatten().all(|v| v.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{what} has a NaN or infinite entry"
        )));
    }
    let last = &m[3];
    if last[0] != 0.0 || last[1] != 0.0 || last[2] != 0.0 || (last[3] - 1.0).abs() > 1e-9 {
        return Err(PyValueError::new_err(format!(
            "{what}: the last row must be 0 0 0 1 (a rigid transform)"
        )));
    }
    let r = nalgebra::Matrix3::from_fn(|i, j| m[i][j]);
    let t = nalgebra::Vector3::new(m[0][3], m[1][3], m[2][3]);
    let pose = Pose::new(r, t).map_err(|e| PyValueError::new_err(format!("{what}: {e}")))?;
    Ok(pose.orthonormalized())
}

/// A pose as a 4x4 `float64` array.
pub fn pose_array<'py>(py: Python<'py>, pose: &Pose) -> Bound<'py, PyArray2<f64>> {
    let m = pose.to_matrix4();
    let rows: Vec<Vec<f64>> = (0..4)
        .map(|i| (0..4).map(|j| m[(i, j)]).collect())
        .collect();
    PyArray2::from_vec2(py, &rows).expect("4x4")
}

/// An image file (PNG, JPEG) as an HxWx3 `uint8` RGB array.
#[pyfunction]
pub fn read_image<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let img = py
        .detach(|| image::open(&path).map(|i| i.to_rgb8()))
        .map_err(|e| crate::errors::input(format!("{}: {e}", path.display())))?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let a = numpy::ndarray::Array3::from_shape_vec((h, w, 3), img.into_raw())
        .map_err(|e| PyTypeError::new_err(e.to_string()))?;
    Ok(PyArray3::from_owned_array(py, a))
}

/// The image files of a folder (PNG, JPEG), in the order the command line
/// reads a sequence's frames (natural order of their names: `2.png`
/// before `10.png`).
#[pyfunction]
pub fn list_images(dir: std::path::PathBuf) -> PyResult<Vec<std::path::PathBuf>> {
    splattrack::io::sequence::list_images(&dir).map_err(crate::errors::input)
}

/// The frame `buf` undistorted by `und` (as it is without one): the image
/// the tracker takes.
pub fn undistorted(
    und: Option<&splattrack::geometry::Undistorter>,
    buf: image::RgbImage,
) -> Result<image::RgbImage, splattrack::tracker::TrackError> {
    match und {
        Some(u) => u.apply(&buf).map_err(|reason| {
            splattrack::tracker::TrackError::Camera(splattrack::tracker::CameraInvalid(format!(
                "cannot undistort: {reason}"
            )))
        }),
        None => Ok(buf),
    }
}
