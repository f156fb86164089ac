//! Point-based models of rigid objects: positions, normals, splat radii and
//! optional colours, loaded from PLY (or sampled from a mesh).
//!
//! Everything the splatter needs per point lives here. Units are the model's
//! own (the PLY's; metres for most scanners).
//!
//! How loading works ([`PointModel::load_with`]):
//! 1. the PLY is read by the `ply` codec (ascii, binary little- or
//!    big-endian; counts checked against the file size before any
//!    allocation) through the point-model `schema` (which properties are
//!    positions, normals, colours, radii);
//! 2. points with a NaN or infinite coordinate are dropped (counted in
//!    [`Provenance::dropped_non_finite`], with a warning);
//! 3. loaded radii must be finite and > 0, or the file is refused; loaded
//!    normals are normalised, and zero-length or non-finite ones are
//!    re-estimated (with a warning, counted in
//!    [`Provenance::normals_reestimated`]) and oriented to agree with their
//!    loaded neighbours;
//! 4. missing normals and radii are estimated from the k nearest neighbours
//!    (PCA normals oriented after Hoppe et al. 1992, radii from the local
//!    spacing): the `estimate` submodule's docs give the method and the
//!    choice of the radius factor.
//!
//! A PLY with faces loads as its vertices under [`PointModel::load`]; to sample
//! the surface instead, use [`load_mesh_ply`] and [`TriangleMesh::sample`], or
//! [`PointModel::load_auto`] with a point count.

mod error;
mod estimate;
mod mesh;
mod ply;
mod schema;
pub mod shapes;

pub use error::ModelError;
pub use estimate::{GAP_MODEL_FRACTION, GAP_NEIGHBOURS, GapClosure};
pub use mesh::{DEFAULT_MESH_POINTS, MESH_RADIUS_FACTOR, TriangleMesh, load_mesh_ply, load_obj};

use crate::progress::{ProgressEvent, ProgressFn};
use error::memory_path;
use glam::{DVec3, Vec3};
use std::cell::Cell;
use std::path::{Path, PathBuf};

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
    pub positions: Vec<Vec3>,
    /// Unit outward normals, one per point.
    pub normals: Vec<Vec3>,
    /// Splat radii (model units), one per point, all > 0.
    pub radii: Vec<f32>,
    /// Linear RGB in 0..1, one per point, when the model has colours.
    pub colors: Option<Vec<[f32; 3]>>,
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

/// One stage of a job, reported to an optional [`ProgressFn`].
pub(crate) struct Stage<'a> {
    report: Option<&'a ProgressFn>,
    stage: &'static str,
    total: u64,
    done: Cell<u64>,
}

impl<'a> Stage<'a> {
    pub(crate) fn new(report: Option<&'a ProgressFn>, stage: &'static str, total: usize) -> Self {
        Self {
            report,
            stage,
            total: total as u64,
            done: Cell::new(0),
        }
    }

    /// A stage that reports nothing.
    pub(crate) fn silent() -> Self {
        Self::new(None, "", 0)
    }

    fn emit(&self) {
        if let Some(report) = self.report {
            report(ProgressEvent {
                stage: self.stage,
                done: self.done.get(),
                total: self.total,
            });
        }
    }

    /// `units` more are done.
    pub(crate) fn advance(&self, units: u64) {
        self.done.set(self.done.get() + units);
        self.emit();
    }

    /// The stage is complete.
    pub(crate) fn finish(&self) {
        self.done.set(self.total);
        self.emit();
    }
}

impl PointModel {
    /// Loads a PLY point model with the default [`LoadOptions`].
    ///
    /// A PLY with faces loads as its vertices; see [`PointModel::load_auto`]
    /// to sample its surface instead.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ModelError> {
        Self::load_with(path, &LoadOptions::default())
    }

    /// Loads a PLY point model; see the module docs for what is checked,
    /// dropped and estimated.
    pub fn load_with(path: impl AsRef<Path>, opts: &LoadOptions) -> Result<Self, ModelError> {
        let path = path.as_ref();
        let contents = schema::read(path, false, opts.progress.as_ref())?;
        if contents.has_faces {
            log::info!(
                "{}: a mesh; its {} vertices are loaded as points (load_mesh_ply or load_auto sample its surface instead)",
                path.display(),
                contents.positions.len()
            );
        }
        Self::from_contents(contents, path, opts)
    }

    /// Loads whatever `path` is: a `.obj` mesh is sampled with `mesh_points`
    /// points ([`DEFAULT_MESH_POINTS`] when 0); a PLY with faces is sampled
    /// when `mesh_points > 0` and loaded as its vertices otherwise; any other
    /// PLY is loaded as points. Sampling uses seed 0, so it is reproducible.
    pub fn load_auto(path: impl AsRef<Path>, mesh_points: usize) -> Result<Self, ModelError> {
        Self::load_auto_with(path, mesh_points, &LoadOptions::default())
    }

    /// [`PointModel::load_auto`] with options for the point-cloud path.
    pub fn load_auto_with(
        path: impl AsRef<Path>,
        mesh_points: usize,
        opts: &LoadOptions,
    ) -> Result<Self, ModelError> {
        let path = path.as_ref();
        let is_obj = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
        if is_obj {
            let n = if mesh_points == 0 {
                DEFAULT_MESH_POINTS
            } else {
                mesh_points
            };
            return load_obj(path)?.sample(n, 0);
        }
        if mesh_points > 0 {
            let (header, _, _) = ply::open(path)?;
            if header.has_faces() {
                return load_mesh_ply(path)?.sample(mesh_points, 0);
            }
        }
        Self::load_with(path, opts)
    }

    /// Samples `n_points` points over a triangle mesh (counter-clockwise
    /// winding seen from outside); see [`TriangleMesh::sample`].
    pub fn from_mesh(
        vertices: &[Vec3],
        triangles: &[[u32; 3]],
        n_points: usize,
        seed: u64,
    ) -> Result<Self, ModelError> {
        TriangleMesh {
            vertices: vertices.iter().map(|v| v.as_dvec3()).collect(),
            triangles: triangles.to_vec(),
            ..Default::default()
        }
        .sample(n_points, seed)
    }

    /// Builds a model from bare points, estimating normals and radii. Points
    /// with non-finite coordinates are dropped, as when loading.
    pub fn from_points(
        positions: Vec<Vec3>,
        colors: Option<Vec<[f32; 3]>>,
        opts: &LoadOptions,
    ) -> Result<Self, ModelError> {
        if let Some(c) = &colors {
            if c.len() != positions.len() {
                return Err(ModelError::Invalid {
                    path: memory_path(),
                    reason: format!("{} colours for {} points", c.len(), positions.len()),
                });
            }
        }
        let contents = schema::PlyContents {
            positions,
            colors,
            ..Default::default()
        };
        let mut model = Self::from_contents(contents, &memory_path(), opts)?;
        model.provenance.path = None;
        Ok(model)
    }

    fn from_contents(
        mut c: schema::PlyContents,
        path: &Path,
        opts: &LoadOptions,
    ) -> Result<Self, ModelError> {
        let total = c.positions.len();
        if total == 0 {
            return Err(ModelError::Empty {
                path: path.to_path_buf(),
                reason: "the vertex element is empty".into(),
            });
        }

        // Drop points with non-finite coordinates; check what is kept.
        let keep: Vec<bool> = c.positions.iter().map(|p| p.is_finite()).collect();
        let dropped = keep.iter().filter(|&&k| !k).count();
        if dropped == total {
            return Err(ModelError::AllNonFinite {
                path: path.to_path_buf(),
                dropped,
            });
        }
        if let Some(radii) = &c.radii {
            if let Some((index, &value)) = radii
                .iter()
                .enumerate()
                .find(|&(i, &r)| keep[i] && !(r.is_finite() && r > 0.0))
            {
                return Err(ModelError::BadRadius {
                    path: path.to_path_buf(),
                    index,
                    value,
                });
            }
        }
        if let Some(colors) = &c.colors {
            if let Some(index) = colors
                .iter()
                .enumerate()
                .position(|(i, rgb)| keep[i] && !rgb.iter().all(|v| v.is_finite()))
            {
                return Err(ModelError::Invalid {
                    path: path.to_path_buf(),
                    reason: format!("point {index} has a NaN or infinite colour"),
                });
            }
        }
        if dropped > 0 {
            log::warn!(
                "{}: dropped {dropped} of {total} points with NaN or infinite coordinates",
                path.display()
            );
            retain(&mut c.positions, &keep);
            if let Some(v) = c.normals.as_mut() {
                retain(v, &keep);
            }
            if let Some(v) = c.colors.as_mut() {
                retain(v, &keep);
            }
            if let Some(v) = c.radii.as_mut() {
                retain(v, &keep);
            }
        }
        let n = c.positions.len();
        if let Some(colors) = c.colors.as_mut() {
            let clamped = colors
                .iter_mut()
                .flatten()
                .filter(|v| !(0.0..=1.0).contains(*v))
                .map(|v| *v = v.clamp(0.0, 1.0))
                .count();
            if clamped > 0 {
                log::warn!(
                    "{}: {clamped} colour values outside 0..1 were clamped",
                    path.display()
                );
            }
        }

        // Which normals to estimate: all (absent or asked), some (bad ones), none.
        let (mut normals, normals_source, estimate_mask, reestimated) = match c.normals.take() {
            Some(mut normals) if !opts.recompute_normals => {
                let mut bad = vec![false; n];
                for (nrm, b) in normals.iter_mut().zip(bad.iter_mut()) {
                    let len = nrm.length();
                    if len.is_finite() && len > 1e-6 {
                        *nrm /= len;
                    } else {
                        *b = true;
                    }
                }
                let count = bad.iter().filter(|&&b| b).count();
                if count == n {
                    log::warn!(
                        "{}: every normal is zero-length or not finite; estimating them all",
                        path.display()
                    );
                    (normals, AttributeSource::Estimated, Some(bad), 0)
                } else if count > 0 {
                    log::warn!(
                        "{}: {count} zero-length or non-finite normals; estimating those from their neighbours",
                        path.display()
                    );
                    (normals, AttributeSource::Loaded, Some(bad), count)
                } else {
                    (normals, AttributeSource::Loaded, None, 0)
                }
            }
            _ => (
                vec![Vec3::Z; n],
                AttributeSource::Estimated,
                Some(vec![true; n]),
                0,
            ),
        };
        let (mut radii, radii_source, estimate_radii) = match c.radii.take() {
            Some(r) if !opts.recompute_radii => (r, AttributeSource::Loaded, false),
            _ => (vec![0.0; n], AttributeSource::Estimated, true),
        };
        let task = estimate::Task {
            normals: estimate_mask.as_deref(),
            radii: estimate_radii,
            k: opts.k_neighbours,
            radius_factor: opts.radius_factor,
        };
        let bars = estimate::Bars {
            neighbours: Stage::new(opts.progress.as_ref(), "neighbours", n),
            orient: Stage::new(opts.progress.as_ref(), "orienting", n),
        };
        estimate::estimate(&c.positions, &mut normals, &mut radii, &task, path, &bars)?;

        let colors_source = if c.colors.is_some() {
            AttributeSource::Loaded
        } else {
            AttributeSource::Absent
        };
        let model = PointModel {
            positions: c.positions,
            normals,
            radii,
            colors: c.colors,
            provenance: Provenance {
                path: Some(path.to_path_buf()),
                normals: normals_source,
                radii: radii_source,
                colors: colors_source,
                dropped_non_finite: dropped,
                normals_reestimated: reestimated,
            },
        };
        model.validate().map_err(|e| match e {
            ModelError::Invalid { reason, .. } => ModelError::Invalid {
                path: path.to_path_buf(),
                reason,
            },
            other => other,
        })?;
        Ok(model)
    }

    /// Re-estimates every normal from the point neighbourhoods (PCA, oriented
    /// after Hoppe et al. 1992).
    pub fn estimate_normals(&mut self, opts: &LoadOptions) -> Result<(), ModelError> {
        let n = self.len();
        let mask = vec![true; n];
        let task = estimate::Task {
            normals: Some(&mask),
            radii: false,
            k: opts.k_neighbours,
            radius_factor: opts.radius_factor,
        };
        let bars = estimate::Bars {
            neighbours: Stage::new(opts.progress.as_ref(), "neighbours", n),
            orient: Stage::new(opts.progress.as_ref(), "orienting", n),
        };
        let path = self.provenance.path.clone().unwrap_or_else(memory_path);
        self.normals.resize(n, Vec3::Z);
        estimate::estimate(
            &self.positions,
            &mut self.normals,
            &mut [],
            &task,
            &path,
            &bars,
        )?;
        self.provenance.normals = AttributeSource::Estimated;
        self.provenance.normals_reestimated = 0;
        Ok(())
    }

    /// Re-estimates every radius from the local point spacing.
    pub fn estimate_radii(&mut self, opts: &LoadOptions) -> Result<(), ModelError> {
        let n = self.len();
        let task = estimate::Task {
            normals: None,
            radii: true,
            k: opts.k_neighbours,
            radius_factor: opts.radius_factor,
        };
        let bars = estimate::Bars {
            neighbours: Stage::new(opts.progress.as_ref(), "neighbours", n),
            orient: Stage::silent(),
        };
        let path = self.provenance.path.clone().unwrap_or_else(memory_path);
        self.radii.resize(n, 0.0);
        estimate::estimate(
            &self.positions,
            &mut [],
            &mut self.radii,
            &task,
            &path,
            &bars,
        )?;
        self.provenance.radii = AttributeSource::Estimated;
        Ok(())
    }

    /// Grows the radii that leave gaps between splats, and only those,
    /// never shrinking one: each point's radius becomes large enough to
    /// cover the farthest vertex of its Voronoi cell (in its tangent plane,
    /// among its [`GAP_NEIGHBOURS`] nearest neighbours) that no disc of the
    /// point or its neighbours covers. A model whose discs already cover its
    /// surface comes out unchanged. The method is in the `estimate` module.
    /// Models of fewer than 3 points are left as they are.
    pub fn close_gaps(&mut self) -> Result<GapClosure, ModelError> {
        let mut radii = std::mem::take(&mut self.radii);
        let closed = self.close_gaps_of(&mut radii);
        self.radii = radii;
        closed
    }

    /// [`PointModel::close_gaps`] applied to `radii` (one a point, in
    /// place of the model's own) instead of the model's radii, which stay
    /// as they are: for a model shared read-only.
    pub fn close_gaps_of(&self, radii: &mut [f32]) -> Result<GapClosure, ModelError> {
        let path = self.provenance.path.clone().unwrap_or_else(memory_path);
        if radii.len() != self.positions.len() {
            return Err(ModelError::Invalid {
                path,
                reason: format!("{} radii for {} points", radii.len(), self.positions.len()),
            });
        }
        estimate::close_gaps(
            &self.positions,
            &self.normals,
            radii,
            GAP_NEIGHBOURS,
            &path,
            &Stage::silent(),
        )
    }

    /// Writes the model as a binary little-endian PLY: float x y z nx ny nz,
    /// uchar red green blue when the model has colours, float radius. The file
    /// is written under a temporary name and renamed into place.
    pub fn save_ply(&self, path: impl AsRef<Path>) -> Result<(), ModelError> {
        let path = path.as_ref();
        self.validate().map_err(|e| match e {
            ModelError::Invalid { reason, .. } => ModelError::Invalid {
                path: path.to_path_buf(),
                reason: format!("refusing to save an invalid model: {reason}"),
            },
            other => other,
        })?;
        let source = |s: AttributeSource| match s {
            AttributeSource::Loaded => "loaded",
            AttributeSource::Estimated => "estimated",
            AttributeSource::FromMesh => "from a mesh",
            AttributeSource::Absent => "absent",
        };
        let mut comments = vec![format!(
            "splattrack point model: normals {}, radii {}",
            source(self.provenance.normals),
            source(self.provenance.radii)
        )];
        if let Some(p) = &self.provenance.path {
            comments.push(format!("source: {}", p.display()));
        }
        schema::write(
            path,
            &schema::WriteData {
                positions: &self.positions,
                normals: &self.normals,
                radii: &self.radii,
                colors: self.colors.as_deref(),
                comments: &comments,
            },
        )
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

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

fn retain<T: Copy>(v: &mut Vec<T>, keep: &[bool]) {
    let mut i = 0;
    v.retain(|_| {
        let k = keep[i];
        i += 1;
        k
    });
}
