//! Helpers shared by the `model_*` integration tests: a PLY writer that can
//! produce any encoding and property type (independent of the crate's own
//! writer) and temporary files.
#![allow(dead_code)]

use glam::Vec3;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A file under the temp dir with a unique name, removed on drop.
pub struct TempFile(pub PathBuf);

impl TempFile {
    pub fn new(tag: &str, ext: &str) -> Self {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let name = format!("splattrack-{}-{}-{n}.{ext}", std::process::id(), tag);
        Self(std::env::temp_dir().join(name))
    }

    pub fn with_bytes(tag: &str, ext: &str, bytes: &[u8]) -> Self {
        let f = Self::new(tag, ext);
        std::fs::write(&f.0, bytes).expect("write temp file");
        f
    }

    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// One value of a PLY row: a scalar or a list.
#[derive(Debug, Clone)]
pub enum Val {
    S(f64),
    L(Vec<f64>),
}

/// One element: `props` are `(type, name)` with type e.g. `"float"` or
/// `"list uchar int"`.
#[derive(Debug, Clone)]
pub struct El {
    pub name: String,
    pub props: Vec<(String, String)>,
    pub rows: Vec<Vec<Val>>,
}

impl El {
    pub fn new(name: &str, props: &[(&str, &str)]) -> Self {
        Self {
            name: name.into(),
            props: props
                .iter()
                .map(|(t, n)| (t.to_string(), n.to_string()))
                .collect(),
            rows: Vec::new(),
        }
    }

    pub fn row(mut self, values: Vec<Val>) -> Self {
        self.rows.push(values);
        self
    }
}

fn put(out: &mut Vec<u8>, ty: &str, v: f64, big: bool) {
    macro_rules! b {
        ($x:expr) => {{
            let x = $x;
            if big {
                out.extend_from_slice(&x.to_be_bytes())
            } else {
                out.extend_from_slice(&x.to_le_bytes())
            }
        }};
    }
    match ty {
        "char" | "int8" => b!(v as i8),
        "uchar" | "uint8" => b!(v as u8),
        "short" | "int16" => b!(v as i16),
        "ushort" | "uint16" => b!(v as u16),
        "int" | "int32" => b!(v as i32),
        "uint" | "uint32" => b!(v as u32),
        "float" | "float32" => b!(v as f32),
        "double" | "float64" => b!(v),
        other => panic!("bad type {other}"),
    }
}

/// A whole PLY file; `format` is `ascii`, `binary_little_endian` or
/// `binary_big_endian`.
pub fn ply_bytes(format: &str, elements: &[El]) -> Vec<u8> {
    let mut out = format!("ply\nformat {format} 1.0\ncomment test file\n").into_bytes();
    for e in elements {
        out.extend_from_slice(format!("element {} {}\n", e.name, e.rows.len()).as_bytes());
        for (t, n) in &e.props {
            out.extend_from_slice(format!("property {t} {n}\n").as_bytes());
        }
    }
    out.extend_from_slice(b"end_header\n");
    let big = format == "binary_big_endian";
    for e in elements {
        for row in &e.rows {
            assert_eq!(row.len(), e.props.len());
            if format == "ascii" {
                let mut words = Vec::new();
                for v in row {
                    match v {
                        Val::S(x) => words.push(format!("{x}")),
                        Val::L(xs) => {
                            words.push(xs.len().to_string());
                            words.extend(xs.iter().map(|x| format!("{x}")));
                        }
                    }
                }
                out.extend_from_slice(words.join(" ").as_bytes());
                out.push(b'\n');
            } else {
                for ((ty, _), v) in e.props.iter().zip(row) {
                    match v {
                        Val::S(x) => put(&mut out, ty, *x, big),
                        Val::L(xs) => {
                            let mut parts = ty.split_whitespace().skip(1);
                            let count_ty = parts.next().expect("list count type");
                            let item_ty = parts.next().expect("list item type");
                            put(&mut out, count_ty, xs.len() as f64, big);
                            for x in xs {
                                put(&mut out, item_ty, *x, big);
                            }
                        }
                    }
                }
            }
        }
    }
    out
}

/// Vertex rows `x y z` (float) plus optional `nx ny nz` and `radius`.
pub fn vertex_element(pos: &[Vec3], normals: Option<&[Vec3]>, radius: Option<f32>) -> El {
    let mut props = vec![("float", "x"), ("float", "y"), ("float", "z")];
    if normals.is_some() {
        props.extend([("float", "nx"), ("float", "ny"), ("float", "nz")]);
    }
    if radius.is_some() {
        props.push(("float", "radius"));
    }
    let mut el = El::new("vertex", &props);
    for (i, p) in pos.iter().enumerate() {
        let mut row: Vec<Val> = p.to_array().iter().map(|&v| Val::S(f64::from(v))).collect();
        if let Some(ns) = normals {
            row.extend(ns[i].to_array().iter().map(|&v| Val::S(f64::from(v))));
        }
        if let Some(r) = radius {
            row.push(Val::S(f64::from(r)));
        }
        el.rows.push(row);
    }
    el
}
