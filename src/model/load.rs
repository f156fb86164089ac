//! Loading point models: from PLY (points, or a mesh's vertices), from
//! whatever file a path names, from a mesh or from bare points; the checks,
//! drops and estimates of the model docs.

use super::error::{ModelError, memory_path};
use super::estimate;
use super::mesh::{DEFAULT_MESH_POINTS, TriangleMesh, load_mesh_ply, load_obj};
use super::ply;
use super::schema;
use super::stage::Stage;
use super::stl::load_stl;
use super::types::{AttributeSource, LoadOptions, PointModel, Provenance};
use glam::Vec3;
use std::path::Path;

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

    /// Loads whatever `path` is: a `.obj` or `.stl` mesh is sampled with
    /// `mesh_points` points ([`DEFAULT_MESH_POINTS`] when 0); a PLY with
    /// faces is sampled when `mesh_points > 0` and loaded as its vertices
    /// otherwise; any other PLY is loaded as points. Sampling uses seed 0,
    /// so it is reproducible.
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
        if mesh_points == 0 && !is_ext(path, "obj") && !is_ext(path, "stl") {
            return Self::load_with(path, opts);
        }
        Self::load_any_with(path, mesh_points, opts)
    }

    /// Loads a model as the tracker takes it: any mesh (`.obj`, `.stl`, or
    /// a PLY with faces, whose vertices alone are not a surface) sampled
    /// with `mesh_points` points ([`DEFAULT_MESH_POINTS`] when 0, seed 0:
    /// reproducible), a PLY without faces as its points. A sampled mesh is
    /// logged (info) with its triangle and point counts; its points have
    /// [`AttributeSource::FromMesh`] normals.
    pub fn load_any_with(
        path: impl AsRef<Path>,
        mesh_points: usize,
        opts: &LoadOptions,
    ) -> Result<Self, ModelError> {
        let path = path.as_ref();
        let mesh = if is_ext(path, "obj") {
            load_obj(path)?
        } else if is_ext(path, "stl") {
            load_stl(path)?
        } else {
            let (header, _, _) = ply::open(path)?;
            if !header.has_faces() {
                return Self::load_with(path, opts);
            }
            load_mesh_ply(path)?
        };
        let n = if mesh_points == 0 {
            DEFAULT_MESH_POINTS
        } else {
            mesh_points
        };
        let model = mesh.sample(n, 0)?;
        log::info!(
            "{}: a mesh of {} triangles, sampled into {} points",
            path.display(),
            mesh.triangles.len(),
            model.len()
        );
        Ok(model)
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
}

fn is_ext(path: &Path, ext: &str) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case(ext))
}

fn retain<T: Copy>(v: &mut Vec<T>, keep: &[bool]) {
    let mut i = 0;
    v.retain(|_| {
        let k = keep[i];
        i += 1;
        k
    });
}
