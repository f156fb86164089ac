//! `splattrack.Model`: a point model, loaded or sampled from a mesh.

use numpy::PyArray2;
use pyo3::prelude::*;
use splattrack::PointModel;
use std::path::PathBuf;
use std::sync::Arc;

/// The object's point model (positions, normals, splat radii, colours
/// when the file has them), shared by the trackers made from it.
#[pyclass(module = "splattrack", frozen)]
pub struct Model {
    pub model: Arc<PointModel>,
}

#[pymethods]
impl Model {
    /// Loads a point PLY (normals and radii estimated when absent), or a
    /// mesh (OBJ, STL, PLY with faces) sampled into `points` points over
    /// its surface (0: 100,000), as `splattrack track --model` does.
    #[staticmethod]
    #[pyo3(signature = (path, points=0))]
    fn load(py: Python<'_>, path: PathBuf, points: usize) -> PyResult<Self> {
        let model = py
            .detach(|| PointModel::load_any_with(&path, points, &Default::default()))
            .map_err(|e| crate::errors::ModelError::new_err(e.to_string()))?;
        Ok(Self {
            model: Arc::new(model),
        })
    }

    fn __len__(&self) -> usize {
        self.model.len()
    }

    /// Whether the model has colours (a texture for the KF step without
    /// keyframes).
    #[getter]
    fn has_colors(&self) -> bool {
        self.model.colors.is_some()
    }

    /// The points' positions, an Nx3 `float32` array (model units).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        let rows: Vec<Vec<f32>> = self
            .model
            .positions
            .iter()
            .map(|p| vec![p.x, p.y, p.z])
            .collect();
        PyArray2::from_vec2(py, &rows).expect("Nx3")
    }

    fn __repr__(&self) -> String {
        format!(
            "Model({} points{})",
            self.model.len(),
            if self.has_colors() { ", colours" } else { "" }
        )
    }
}
