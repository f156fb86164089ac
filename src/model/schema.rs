//! The point-model schema of PLY files: which elements and properties make
//! a [`PointModel`] or a [`TriangleMesh`](super::TriangleMesh), read and
//! written through the codec in the `ply` module.
//!
//! Read: the `vertex` element's `x y z` (required), `nx ny nz` (or
//! `normal_x ...`), `red green blue` (or `diffuse_red ...`, `r g b`; uchar
//! and ushort scaled to 0..1, float as is) and `radius`; the `face`
//! element's `vertex_indices` (or `vertex_index`) list, fan-triangulated,
//! for meshes. Every other element and property is skipped. Written: float
//! `x y z nx ny nz`, uchar `red green blue` when the model has colours, and
//! float `radius`, binary little-endian.

use super::error::ModelError;
use super::ply::{self, BodyReader, Element, Header, Kind, Property, Scalar, Slot, Values};
use super::stage::Stage;
use super::types::{AttributeSource, PointModel};
use crate::progress::ProgressFn;
use glam::Vec3;
use std::path::Path;

const POS: usize = 0;
const NORMAL: usize = 3;
const COLOR: usize = 6;
const RADIUS: usize = 9;
/// Values per vertex row.
const VALUE_SLOTS: usize = 10;

/// What a PLY file held, before any filtering.
#[derive(Debug, Default)]
pub(crate) struct PlyContents {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub colors: Option<Vec<[f32; 3]>>,
    pub radii: Option<Vec<f32>>,
    /// Fan-triangulated faces, when asked for.
    pub triangles: Option<Vec<[u32; 3]>>,
    /// Faces with fewer than three vertices, skipped.
    pub degenerate_faces: usize,
    /// The file has a face element (whether or not it was read).
    pub has_faces: bool,
}

/// How the vertex element maps onto value slots, and how colours scale to 0..1.
struct VertexPlan {
    slots: Vec<Slot>,
    has_normals: bool,
    has_colors: bool,
    has_radius: bool,
    color_scale: [f64; 3],
}

fn vertex_plan(element: &Element, path: &Path) -> Result<VertexPlan, ModelError> {
    let named = |names: &[&str]| names.iter().find_map(|n| element.prop(n));
    let scalar_of = |p: &Property| -> Result<Scalar, ModelError> {
        match p.kind {
            Kind::Scalar(s) => Ok(s),
            Kind::List { .. } => Err(ModelError::MissingProperty {
                path: path.to_path_buf(),
                element: element.name.clone(),
                reason: format!("has property '{}' as a list, expected a number", p.name),
            }),
        }
    };
    let mut slots = vec![Slot::Skip; element.props.len()];
    let mut assign = |p: &Property, slot: usize| {
        if let Some(i) = element.props.iter().position(|q| q.name == p.name) {
            slots[i] = Slot::Value(slot);
        }
    };

    for (axis, name) in ["x", "y", "z"].iter().enumerate() {
        let Some(p) = element.prop(name) else {
            return Err(ModelError::MissingProperty {
                path: path.to_path_buf(),
                element: element.name.clone(),
                reason: format!("has no property '{name}'"),
            });
        };
        scalar_of(p)?;
        assign(p, POS + axis);
    }

    let normal_props = [
        named(&["nx", "normal_x"]),
        named(&["ny", "normal_y"]),
        named(&["nz", "normal_z"]),
    ];
    let normal_count = normal_props.iter().flatten().count();
    let has_normals = normal_count == 3;
    if has_normals {
        for (axis, p) in normal_props.iter().flatten().enumerate() {
            scalar_of(p)?;
            assign(p, NORMAL + axis);
        }
    } else if normal_count > 0 {
        log::warn!(
            "{}: only {normal_count} of the 3 normal components; normals ignored and estimated",
            path.display()
        );
    }

    let color_props = [
        named(&["red", "diffuse_red", "r"]),
        named(&["green", "diffuse_green", "g"]),
        named(&["blue", "diffuse_blue", "b"]),
    ];
    let color_count = color_props.iter().flatten().count();
    let has_colors = color_count == 3;
    let mut color_scale = [1.0; 3];
    if has_colors {
        for (c, p) in color_props.iter().flatten().enumerate() {
            color_scale[c] = match scalar_of(p)? {
                Scalar::U8 => 1.0 / 255.0,
                Scalar::U16 => 1.0 / 65535.0,
                Scalar::F32 | Scalar::F64 => 1.0,
                other => {
                    return Err(ModelError::Invalid {
                        path: path.to_path_buf(),
                        reason: format!(
                            "colour property '{}' has type {other:?}; expected uchar, ushort, float or double",
                            p.name
                        ),
                    });
                }
            };
            assign(p, COLOR + c);
        }
    } else if color_count > 0 {
        log::warn!(
            "{}: only {color_count} of the 3 colour components; colours ignored",
            path.display()
        );
    }

    let has_radius = match element.prop("radius") {
        Some(p) => {
            scalar_of(p)?;
            assign(p, RADIUS);
            true
        }
        None => false,
    };
    Ok(VertexPlan {
        slots,
        has_normals,
        has_colors,
        has_radius,
        color_scale,
    })
}

/// Reads the vertex element (and the faces when `want_faces`), skipping every
/// other element and ignoring unknown properties. Elements after the last one
/// needed are not read. Progress is reported as the stage "reading".
pub(crate) fn read(
    path: &Path,
    want_faces: bool,
    progress: Option<&ProgressFn>,
) -> Result<PlyContents, ModelError> {
    ply::read(
        path,
        PointSchema {
            path,
            want_faces,
            progress,
        },
    )
}

struct PointSchema<'a> {
    path: &'a Path,
    want_faces: bool,
    progress: Option<&'a ProgressFn>,
}

impl BodyReader for PointSchema<'_> {
    type Output = PlyContents;

    fn read<V: Values>(
        self,
        src: &mut V,
        header: &Header,
        body_len: u64,
    ) -> Result<PlyContents, ModelError> {
        read_body(
            src,
            header,
            body_len,
            self.want_faces,
            self.path,
            self.progress,
        )
    }
}

fn read_body<V: Values>(
    src: &mut V,
    header: &Header,
    body_len: u64,
    want_faces: bool,
    path: &Path,
    progress: Option<&ProgressFn>,
) -> Result<PlyContents, ModelError> {
    let find = |element: &'static str| {
        header
            .elements
            .iter()
            .position(|e| e.name == element)
            .ok_or_else(|| ModelError::MissingElement {
                path: path.to_path_buf(),
                element,
            })
    };
    let vertex_at = find("vertex")?;
    let face_at = if want_faces {
        let at = find("face")?;
        if header.elements[at].face_list().is_none() {
            return Err(ModelError::MissingProperty {
                path: path.to_path_buf(),
                element: "face".into(),
                reason: "has no 'vertex_indices' (or 'vertex_index') list".into(),
            });
        }
        Some(at)
    } else {
        None
    };
    let last = vertex_at.max(face_at.unwrap_or(0));
    let reserve = ply::check_counts(header, last + 1, body_len, path)?;

    let vertex = &header.elements[vertex_at];
    let plan = vertex_plan(vertex, path)?;
    // Bounded by the file size, whatever the header says.
    let n = reserve[vertex_at];
    let mut out = PlyContents {
        positions: Vec::with_capacity(n),
        normals: plan.has_normals.then(|| Vec::with_capacity(n)),
        colors: plan.has_colors.then(|| Vec::with_capacity(n)),
        radii: plan.has_radius.then(|| Vec::with_capacity(n)),
        triangles: None,
        degenerate_faces: 0,
        has_faces: header.has_faces(),
    };
    let rows: usize = header.elements[..=last].iter().map(|e| e.count).sum();
    let bar = &Stage::new(progress, "reading", rows);

    for (at, element) in header.elements.iter().enumerate().take(last + 1) {
        if at == vertex_at {
            let scale = plan.color_scale;
            ply::read_rows(
                src,
                element,
                &plan.slots,
                path,
                bar,
                |_, v: &[f64; VALUE_SLOTS], _| {
                    out.positions.push(Vec3::new(
                        v[POS] as f32,
                        v[POS + 1] as f32,
                        v[POS + 2] as f32,
                    ));
                    if let Some(normals) = out.normals.as_mut() {
                        normals.push(Vec3::new(
                            v[NORMAL] as f32,
                            v[NORMAL + 1] as f32,
                            v[NORMAL + 2] as f32,
                        ));
                    }
                    if let Some(colors) = out.colors.as_mut() {
                        colors.push([
                            (v[COLOR] * scale[0]) as f32,
                            (v[COLOR + 1] * scale[1]) as f32,
                            (v[COLOR + 2] * scale[2]) as f32,
                        ]);
                    }
                    if let Some(radii) = out.radii.as_mut() {
                        radii.push(v[RADIUS] as f32);
                    }
                    Ok(())
                },
            )?;
        } else if Some(at) == face_at {
            let slots: Vec<Slot> = element
                .props
                .iter()
                .map(|p| {
                    if element.face_list().is_some_and(|f| f.name == p.name) {
                        Slot::List
                    } else {
                        Slot::Skip
                    }
                })
                .collect();
            let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(reserve[at]);
            let mut degenerate = 0usize;
            ply::read_rows(src, element, &slots, path, bar, |i, _: &[f64; 0], list| {
                if list.len() < 3 {
                    degenerate += 1;
                    return Ok(());
                }
                let mut idx = [0u32; 3];
                let index = |k: usize| -> Result<u32, ModelError> {
                    let v = list[k];
                    if v >= 0.0 && v.fract() == 0.0 && v <= f64::from(u32::MAX) {
                        Ok(v as u32)
                    } else {
                        Err(ModelError::Invalid {
                            path: path.to_path_buf(),
                            reason: format!("face {i} has vertex index {v}"),
                        })
                    }
                };
                idx[0] = index(0)?;
                // Fan triangulation: polygons are assumed convex (and planar).
                for k in 1..list.len() - 1 {
                    idx[1] = index(k)?;
                    idx[2] = index(k + 1)?;
                    triangles.push(idx);
                }
                Ok(())
            })?;
            out.triangles = Some(triangles);
            out.degenerate_faces = degenerate;
        } else {
            let slots = vec![Slot::Skip; element.props.len()];
            ply::read_rows(src, element, &slots, path, bar, |_, _: &[f64; 0], _| Ok(()))?;
        }
    }
    if let Some(triangles) = &out.triangles {
        let nv = out.positions.len();
        if let Some((t, bad)) = index_out_of_range(triangles, nv) {
            return Err(ModelError::Invalid {
                path: path.to_path_buf(),
                reason: format!(
                    "triangle {t} references vertex {bad}, but there are only {nv} vertices"
                ),
            });
        }
    }
    bar.finish();
    Ok(out)
}

/// What `write` stores per point.
pub(crate) struct WriteData<'a> {
    pub positions: &'a [Vec3],
    pub normals: &'a [Vec3],
    pub radii: &'a [f32],
    pub colors: Option<&'a [[f32; 3]]>,
    pub comments: &'a [String],
}

/// Writes a point model (see the module docs for the properties).
pub(crate) fn write(path: &Path, data: &WriteData) -> Result<(), ModelError> {
    let mut props = vec![
        ("float", "x"),
        ("float", "y"),
        ("float", "z"),
        ("float", "nx"),
        ("float", "ny"),
        ("float", "nz"),
    ];
    if data.colors.is_some() {
        props.extend([("uchar", "red"), ("uchar", "green"), ("uchar", "blue")]);
    }
    props.push(("float", "radius"));
    ply::write(
        path,
        data.comments,
        "vertex",
        data.positions.len(),
        &props,
        |i, rec| {
            for v in [data.positions[i], data.normals[i]] {
                for c in v.to_array() {
                    rec.extend_from_slice(&c.to_le_bytes());
                }
            }
            if let Some(colors) = data.colors {
                for c in colors[i] {
                    rec.push((c.clamp(0.0, 1.0) * 255.0).round() as u8);
                }
            }
            rec.extend_from_slice(&data.radii[i].to_le_bytes());
        },
    )
}

/// The first triangle with a vertex index of `nv` or more, and that index.
pub(crate) fn index_out_of_range(triangles: &[[u32; 3]], nv: usize) -> Option<(usize, u32)> {
    triangles
        .iter()
        .enumerate()
        .find_map(|(t, tri)| tri.iter().find(|&&v| v as usize >= nv).map(|&v| (t, v)))
}

impl PointModel {
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
        write(
            path,
            &WriteData {
                positions: &self.positions,
                normals: &self.normals,
                radii: &self.radii,
                colors: self.colors.as_deref(),
                comments: &comments,
            },
        )
    }
}
