//! Triangle meshes (OBJ, PLY with faces) and their sampling into point models.
//!
//! How sampling works: triangles are chosen by systematic sampling of the
//! cumulative area, i.e. the i-th of N samples falls at area `(i + u0) / N`
//! of the total for one random `u0`, so every triangle receives its expected
//! number of samples give or take one (stratified: no clumps, no empty
//! stretches). The position inside the triangle comes from the R2
//! low-discrepancy sequence (M. Roberts, "The unreasonable effectiveness of
//! quasirandom sequences", 2018), which the successive samples of one triangle
//! follow, mapped onto the triangle by E. Heitz's area-preserving low-distortion
//! square-to-triangle map ("A low-distortion map between triangle and square",
//! 2019). Measured on the cube's faces, that leaves the smallest gaps of the
//! variants tried: the `sqrt` warp of Osada et al. 2002 stretches the sequence
//! near a vertex (2.3 times the mean spacing needed to cover, against 2.0),
//! folding the square onto the triangle was worse still.
//!
//! Normals are the face normals by the winding (counter-clockwise seen from
//! outside, as OBJ files and scanners write them). Every sample gets the
//! radius `MESH_RADIUS_FACTOR * sqrt(A / (pi N))`: the radius of a disc of the
//! area per sample, enlarged so that neighbouring discs overlap and the
//! surface closes. Colours are interpolated from vertex colours.

use super::error::{ModelError, memory_path};
use super::ply::read_line_capped;
use super::schema;
use super::{AttributeSource, PointModel, Provenance};
use crate::rng::Rng;
use glam::{DVec3, Vec3};
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

/// Radius of a sampled disc relative to the radius of a disc of the area per
/// sample. With 2.0 no point inside a face of the cube of `tests/model_mesh.rs`
/// is left uncovered (over 1000 to 16000 samples per triangle pair); 1.5
/// leaves 0.1-2% of it uncovered. The same factor as
/// [`LoadOptions::radius_factor`](super::LoadOptions)'s default.
pub const MESH_RADIUS_FACTOR: f64 = 2.0;

/// The number of points [`PointModel::load_auto`] samples from an OBJ file
/// when the caller asks for 0.
pub const DEFAULT_MESH_POINTS: usize = 100_000;

const MAX_OBJ_LINE: u64 = 1 << 20;

/// A triangle mesh to sample points from.
#[derive(Debug, Clone, Default)]
pub struct TriangleMesh {
    pub vertices: Vec<Vec3>,
    /// Vertex indices, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex colours in 0..1, when every vertex has one.
    pub colors: Option<Vec<[f32; 3]>>,
    /// The file the mesh came from.
    pub path: Option<PathBuf>,
}

/// Reads a PLY mesh: its `vertex` element (x y z, optional red green blue)
/// and its `face` element (`vertex_indices` or `vertex_index` lists,
/// fan-triangulated).
pub fn load_mesh_ply(path: impl AsRef<Path>) -> Result<TriangleMesh, ModelError> {
    let path = path.as_ref();
    let c = schema::read(path, true, None)?;
    if c.degenerate_faces > 0 {
        log::warn!(
            "{}: skipped {} faces with fewer than 3 vertices",
            path.display(),
            c.degenerate_faces
        );
    }
    Ok(TriangleMesh {
        vertices: c.positions,
        triangles: c.triangles.unwrap_or_default(),
        colors: c.colors,
        path: Some(path.to_path_buf()),
    })
}

/// Reads a Wavefront OBJ mesh: `v x y z [w]` (or `v x y z r g b`, vertex
/// colours in 0..1) and `f` lines in any of the forms `i`, `i/t`, `i//n`,
/// `i/t/n`, with negative (relative) indices; polygons are fan-triangulated.
/// Everything else (texture coordinates, normals, groups, materials) is
/// ignored.
pub fn load_obj(path: impl AsRef<Path>) -> Result<TriangleMesh, ModelError> {
    let path = path.as_ref();
    let file = File::open(path).map_err(|e| ModelError::Io {
        path: path.to_path_buf(),
        action: "open",
        source: e,
    })?;
    let mut reader = BufReader::with_capacity(1 << 16, file);
    let parse_err = |line: usize, reason: String| ModelError::Parse {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut vertices: Vec<Vec3> = Vec::new();
    let mut colors: Vec<[f32; 3]> = Vec::new();
    let mut all_colored = true;
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut face: Vec<u32> = Vec::new();
    let mut buf = Vec::new();
    let mut line_no = 0usize;
    loop {
        let n =
            read_line_capped(&mut reader, &mut buf, MAX_OBJ_LINE).map_err(|e| ModelError::Io {
                path: path.to_path_buf(),
                action: "read",
                source: e,
            })?;
        if n == 0 {
            break;
        }
        line_no += 1;
        if n as u64 == MAX_OBJ_LINE && !buf.ends_with(b"\n") {
            return Err(parse_err(line_no, "line too long".into()));
        }
        let text = String::from_utf8_lossy(&buf);
        let text = text.split('#').next().unwrap_or("");
        let mut tokens = text.split_ascii_whitespace();
        match tokens.next() {
            Some("v") => {
                let values: Vec<&str> = tokens.collect();
                let num = |s: &str| {
                    s.parse::<f32>().map_err(|_| {
                        let s: String = s.chars().take(32).collect();
                        parse_err(line_no, format!("'{s}' is not a number"))
                    })
                };
                if values.len() < 3 {
                    return Err(parse_err(line_no, "a vertex needs x y z".into()));
                }
                vertices.push(Vec3::new(num(values[0])?, num(values[1])?, num(values[2])?));
                if values.len() >= 6 {
                    colors.push([
                        num(values[3])?.clamp(0.0, 1.0),
                        num(values[4])?.clamp(0.0, 1.0),
                        num(values[5])?.clamp(0.0, 1.0),
                    ]);
                } else {
                    all_colored = false;
                }
            }
            Some("f") => {
                face.clear();
                for tok in tokens {
                    let first = tok.split('/').next().unwrap_or("");
                    let index: i64 = first.parse().map_err(|_| {
                        let s: String = tok.chars().take(32).collect();
                        parse_err(line_no, format!("bad face vertex '{s}'"))
                    })?;
                    // OBJ indices are 1-based; negative ones count back from
                    // the last vertex defined so far.
                    let resolved = match index {
                        i if i > 0 => i - 1,
                        i if i < 0 => vertices.len() as i64 + i,
                        _ => -1,
                    };
                    let resolved = u32::try_from(resolved).map_err(|_| {
                        parse_err(line_no, format!("face vertex index {index} is invalid"))
                    })?;
                    face.push(resolved);
                }
                if face.len() < 3 {
                    return Err(parse_err(
                        line_no,
                        format!("a face needs at least 3 vertices, found {}", face.len()),
                    ));
                }
                for k in 1..face.len() - 1 {
                    triangles.push([face[0], face[k], face[k + 1]]);
                }
            }
            _ => {}
        }
    }
    let nv = vertices.len();
    if let Some((t, v)) = triangles
        .iter()
        .enumerate()
        .find_map(|(t, tri)| tri.iter().find(|&&v| v as usize >= nv).map(|&v| (t, v)))
    {
        return Err(ModelError::Invalid {
            path: path.to_path_buf(),
            reason: format!(
                "triangle {t} references vertex {} but there are {nv} vertices",
                u64::from(v) + 1
            ),
        });
    }
    Ok(TriangleMesh {
        vertices,
        triangles,
        colors: (all_colored && nv > 0).then_some(colors),
        path: Some(path.to_path_buf()),
    })
}

impl TriangleMesh {
    /// Reads an OBJ mesh; see [`load_obj`].
    pub fn load_obj(path: impl AsRef<Path>) -> Result<Self, ModelError> {
        load_obj(path)
    }

    /// Reads a PLY mesh; see [`load_mesh_ply`].
    pub fn load_ply(path: impl AsRef<Path>) -> Result<Self, ModelError> {
        load_mesh_ply(path)
    }

    /// Total area of the triangles with finite vertices.
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .filter_map(|t| self.triangle(t))
            .map(|(a, b, c)| 0.5 * (b - a).cross(c - a).length())
            .sum()
    }

    fn triangle(&self, t: &[u32; 3]) -> Option<(DVec3, DVec3, DVec3)> {
        let v = |i: u32| {
            self.vertices
                .get(i as usize)
                .map(|p| p.as_dvec3())
                .filter(|p| p.is_finite())
        };
        Some((v(t[0])?, v(t[1])?, v(t[2])?))
    }

    /// Samples `n_points` points evenly over the surface (see the module
    /// docs); the same seed gives the same points.
    pub fn sample(&self, n_points: usize, seed: u64) -> Result<PointModel, ModelError> {
        let path = self.path.clone().unwrap_or_else(memory_path);
        let invalid = |reason: String| ModelError::Invalid {
            path: path.clone(),
            reason,
        };
        if n_points == 0 || n_points > u32::MAX as usize {
            return Err(invalid(format!(
                "asked for {n_points} sample points (1 to {} allowed)",
                u32::MAX
            )));
        }
        let nv = self.vertices.len();
        if let Some(colors) = &self.colors {
            if colors.len() != nv {
                return Err(invalid(format!(
                    "{} vertex colours for {nv} vertices",
                    colors.len()
                )));
            }
        }
        if let Some((t, v)) = self
            .triangles
            .iter()
            .enumerate()
            .find_map(|(t, tri)| tri.iter().find(|&&v| v as usize >= nv).map(|&v| (t, v)))
        {
            return Err(invalid(format!(
                "triangle {t} references vertex {v} but there are {nv} vertices"
            )));
        }
        let non_finite = self.vertices.iter().filter(|v| !v.is_finite()).count();
        if non_finite > 0 {
            log::warn!(
                "{}: {non_finite} vertices have NaN or infinite coordinates; their triangles are not sampled",
                path.display()
            );
        }

        // Degenerate triangles and those touching non-finite vertices get no
        // area, hence no samples.
        let mut areas = Vec::with_capacity(self.triangles.len());
        let mut normals = Vec::with_capacity(self.triangles.len());
        for t in &self.triangles {
            let (area, normal) = match self.triangle(t) {
                Some((a, b, c)) => {
                    let cross = (b - a).cross(c - a);
                    let len = cross.length();
                    if len > 0.0 && len.is_finite() {
                        (0.5 * len, cross / len)
                    } else {
                        (0.0, DVec3::Z)
                    }
                }
                None => (0.0, DVec3::Z),
            };
            areas.push(area);
            normals.push(normal.as_vec3());
        }
        let total: f64 = areas.iter().sum();
        let Some(last_positive) = areas.iter().rposition(|&a| a > 0.0) else {
            return Err(ModelError::Empty {
                path,
                reason: "the mesh has no triangle of positive area".into(),
            });
        };
        if !total.is_finite() {
            return Err(invalid("the mesh's area is not finite".into()));
        }

        let mut rng = Rng::new(seed);
        let u0 = rng.next_f64();
        let (s1, s2) = (rng.next_f64(), rng.next_f64());
        // R2 sequence: the generalised golden ratio in two dimensions.
        let g = 1.324_717_957_244_746_f64;
        let (a1, a2) = (1.0 / g, 1.0 / (g * g));

        let mut positions = Vec::with_capacity(n_points);
        let mut out_normals = Vec::with_capacity(n_points);
        let mut out_colors = self.colors.as_ref().map(|_| Vec::with_capacity(n_points));
        let mut t = 0usize;
        let mut end = areas[0];
        for i in 0..n_points {
            let target = (i as f64 + u0) / n_points as f64 * total;
            while t < last_positive && target >= end {
                t += 1;
                end += areas[t];
            }
            let fi = i as f64;
            let u = (s1 + fi * a1).fract();
            let v = (s2 + fi * a2).fract();
            // Heitz 2019: piecewise linear, continuous and area-preserving.
            let (t1, t2) = if v > u {
                (0.5 * u, v - 0.5 * u)
            } else {
                (u - 0.5 * v, 0.5 * v)
            };
            let w = [t1, t2, 1.0 - t1 - t2];
            let tri = self.triangles[t];
            let (a, b, c) = self.triangle(&tri).unwrap_or_default();
            positions.push((a * w[0] + b * w[1] + c * w[2]).as_vec3());
            out_normals.push(normals[t]);
            if let (Some(out), Some(colors)) = (out_colors.as_mut(), self.colors.as_ref()) {
                let mut rgb = [0.0f32; 3];
                for (k, &vi) in tri.iter().enumerate() {
                    for (ch, value) in rgb.iter_mut().enumerate() {
                        *value += w[k] as f32 * colors[vi as usize][ch];
                    }
                }
                out.push(rgb.map(|x| x.clamp(0.0, 1.0)));
            }
        }
        let radius =
            (MESH_RADIUS_FACTOR * (total / (std::f64::consts::PI * n_points as f64)).sqrt()) as f32;
        let has_colors = out_colors.is_some();
        let model = PointModel {
            positions,
            normals: out_normals,
            radii: vec![radius; n_points],
            colors: out_colors,
            provenance: Provenance {
                path: self.path.clone(),
                normals: AttributeSource::FromMesh,
                radii: AttributeSource::FromMesh,
                colors: if has_colors {
                    AttributeSource::FromMesh
                } else {
                    AttributeSource::Absent
                },
                dropped_non_finite: non_finite,
                normals_reestimated: 0,
            },
        };
        model.validate()?;
        Ok(model)
    }
}
