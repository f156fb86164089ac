//! The point model and what describes it: [`PointModel`], where its
//! attributes came from ([`Provenance`]), the options of loading and
//! estimation ([`LoadOptions`]), and the invariants every consumer relies
//! on ([`PointModel::validate`]).

use super::error::{ModelError, memory_path};
use crate::progress::ProgressFn;
use glam::{DVec3, Vec3};
use std::path::PathBuf;

/// Where an attribute of a [`PointModel`] came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AttributeSource {
    /// Read from the file.
    Loaded,
    /// Estimated from the points' neighbourhoods.
    Estimated,
    /// Taken from the faces of a mesh the points were sampled from.
    FromMesh,
    /// Absent (colours only).
    Absent,
}

/// How a model was obtained: what was read, what was estimated, what was dropped.
#[derive(Debug, Clone)]
pub struct Provenance {
    /// The file the model (or the mesh it was sampled from) was read from;
    /// `None` for a model built in memory.
    pub path: Option<PathBuf>,
    /// Where the normals came from.
    pub normals: AttributeSource,
    /// Where the radii came from.
    pub radii: AttributeSource,
    /// Where the colours came from (`Absent` when the model has none).
    pub colors: AttributeSource,
    /// Points dropped because a coordinate was NaN or infinite (for sampled
    /// meshes: vertices with such coordinates, whose triangles were skipped).
    pub dropped_non_finite: usize,
    /// Loaded normals that were zero-length or not finite, and were estimated
    /// instead (only when `normals` is `Loaded`).
    pub normals_reestimated: usize,
}

/// A point-sampled surface: one oriented disc (splat) per point.
#[derive(Debug, Clone)]
pub struct PointModel {
    /// Point positions (splat centres) in model coordinates (the file's units).
    pub positions: Vec<Vec3>,
    /// Unit outward normals, one per point.
    pub normals: Vec<Vec3>,
    /// Splat radii (model units), one per point, all > 0.
    pub radii: Vec<f32>,
    /// Linear RGB in 0..1, one per point, when the model has colours.
    pub colors: Option<Vec<[f32; 3]>>,
    /// Where the attributes came from, and what was dropped on loading.
    pub provenance: Provenance,
}

/// Options for loading and estimation.
#[derive(Clone)]
pub struct LoadOptions {
    /// Receives the progress of reading ("reading", rows of the file),
    /// finding neighbours ("neighbours", points) and orienting normals
    /// ("orienting", points), in steps of 16384 and once more at the end
    /// of each stage. Small clouds load in a blink: a caller drawing bars
    /// may skip those of under 200,000 units. Default: None.
    pub progress: Option<ProgressFn>,
    /// Neighbours used for normals and radii. Default: 16.
    pub k_neighbours: usize,
    /// Estimated radius = `radius_factor * d_k / sqrt(k)`, `d_k` the distance
    /// to the k-th neighbour: `radius_factor` times the radius of a disc of the
    /// local area per point. Default: 2.0 (see the `estimate` module docs).
    pub radius_factor: f32,
    /// Estimate normals even when the file has them. Default: false.
    pub recompute_normals: bool,
    /// Estimate radii even when the file has them. Default: false.
    pub recompute_radii: bool,
}

impl std::fmt::Debug for LoadOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoadOptions")
            .field("progress", &self.progress.as_ref().map(|_| "callback"))
            .field("k_neighbours", &self.k_neighbours)
            .field("radius_factor", &self.radius_factor)
            .field("recompute_normals", &self.recompute_normals)
            .field("recompute_radii", &self.recompute_radii)
            .finish()
    }
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            progress: None,
            k_neighbours: 16,
            radius_factor: 2.0,
            recompute_normals: false,
            recompute_radii: false,
        }
    }
}

impl PointModel {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when the model has no points.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Axis-aligned bounding box `(min, max)` of the positions;
    /// `(Vec3::ZERO, Vec3::ZERO)` for an empty model.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        if self.positions.is_empty() {
            return (Vec3::ZERO, Vec3::ZERO);
        }
        self.positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(*p), hi.max(*p))
            })
    }

    /// Mean of the positions (accumulated in f64); zero for an empty model.
    pub fn centroid(&self) -> Vec3 {
        if self.positions.is_empty() {
            return Vec3::ZERO;
        }
        let sum = self
            .positions
            .iter()
            .fold(DVec3::ZERO, |acc, p| acc + p.as_dvec3());
        (sum / self.positions.len() as f64).as_vec3()
    }

    /// The model's size: the length of its bounding-box diagonal (an upper
    /// bound on the bounding-sphere diameter, at most sqrt(3) times it).
    pub fn diameter(&self) -> f32 {
        let (lo, hi) = self.bounds();
        (hi - lo).length()
    }

    /// Checks the invariants every consumer relies on: one normal, radius (and
    /// colour) per point, finite positions, unit normals (within 1e-3), finite
    /// radii > 0, finite colours in 0..1.
    pub fn validate(&self) -> Result<(), ModelError> {
        let path = self.provenance.path.clone().unwrap_or_else(memory_path);
        let invalid = |reason: String| {
            Err(ModelError::Invalid {
                path: path.clone(),
                reason,
            })
        };
        let n = self.positions.len();
        if self.normals.len() != n || self.radii.len() != n {
            return invalid(format!(
                "{n} positions but {} normals and {} radii",
                self.normals.len(),
                self.radii.len()
            ));
        }
        if let Some(c) = &self.colors {
            if c.len() != n {
                return invalid(format!("{n} positions but {} colours", c.len()));
            }
            if let Some(i) = c
                .iter()
                .position(|rgb| !rgb.iter().all(|v| (0.0..=1.0).contains(v)))
            {
                return invalid(format!("point {i} has colour {:?} outside 0..1", c[i]));
            }
        }
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return invalid(format!("point {i} has a non-finite position"));
        }
        if let Some(i) = self.normals.iter().position(|v| {
            let error = (v.length() - 1.0).abs();
            error.is_nan() || error > 1e-3
        }) {
            return invalid(format!(
                "point {i} has normal {:?}, not unit length",
                self.normals[i]
            ));
        }
        if let Some(i) = self.radii.iter().position(|&r| !(r.is_finite() && r > 0.0)) {
            return invalid(format!("point {i} has radius {}", self.radii[i]));
        }
        Ok(())
    }
}
