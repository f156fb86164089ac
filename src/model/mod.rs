//! Point-based models of rigid objects: positions, normals, splat radii and
//! optional colours, loaded from PLY (or sampled from a mesh).
//!
//! Everything the splatter needs per point lives here. Units are the model's
//! own (the PLY's; metres for most scanners).

use glam::Vec3;
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
    pub path: Option<PathBuf>,
    pub normals: AttributeSource,
    pub radii: AttributeSource,
    pub colors: AttributeSource,
    /// Points dropped because a coordinate was NaN or infinite.
    pub dropped_non_finite: usize,
}

/// A point-sampled surface: one oriented disc (splat) per point.
#[derive(Debug, Clone)]
pub struct PointModel {
    pub positions: Vec<Vec3>,
    /// Unit outward normals, one per point.
    pub normals: Vec<Vec3>,
    /// Splat radii (model units), one per point, all > 0.
    pub radii: Vec<f32>,
    /// Linear RGB in 0..1, one per point, when the model has colours.
    pub colors: Option<Vec<[f32; 3]>>,
    pub provenance: Provenance,
}
