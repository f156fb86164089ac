//! STL meshes (the exchange format of CAD programs and 3-D printers), binary
//! and ASCII, read into a [`TriangleMesh`].
//!
//! - Binary: an 80-byte header, a little-endian u32 triangle count, then 50
//!   bytes a triangle (the facet normal, three vertices as f32 x y z, a
//!   2-byte attribute, all ignored but the vertices). The count is checked
//!   against the file's size before anything is allocated; a file shorter
//!   than the count says is refused as truncated, bytes beyond it are
//!   ignored with a warning.
//! - ASCII: `solid NAME`, then `facet normal nx ny nz`, `outer loop`,
//!   `vertex x y z` (three or more: polygons are fan-triangulated),
//!   `endloop`, `endfacet`, ..., `endsolid`; several solids may follow each
//!   other. A file that ends inside a solid is refused as truncated.
//!
//! Binary files may start with `solid` too (some exporters write it in the
//! header), so a file is binary when its size is exactly what its count
//! says, ASCII when it starts with `solid` otherwise, and binary else.
//!
//! Every triangle gets three vertices of its own (STL shares none); the
//! facet normals are ignored, the winding (counter-clockwise seen from
//! outside, as the format requires) gives the sides. Coordinates are the
//! file's units: CAD programs often write millimetres.

use super::error::ModelError;
use super::mesh::TriangleMesh;
use glam::Vec3;
use std::path::Path;

const HEADER: usize = 80;
const TRIANGLE_BYTES: usize = 50;
const MAX_LINE: usize = 1 << 20;

/// Reads an STL mesh, binary or ASCII (module docs).
pub fn load_stl(path: impl AsRef<Path>) -> Result<TriangleMesh, ModelError> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|e| ModelError::Io {
        path: path.to_path_buf(),
        action: "read",
        source: e,
    })?;
    parse_stl(&bytes, path)
}

impl TriangleMesh {
    /// Reads an STL mesh, binary or ASCII; see [`load_stl`].
    pub fn load_stl(path: impl AsRef<Path>) -> Result<Self, ModelError> {
        load_stl(path)
    }
}

/// Parses the bytes of an STL file; `path` names it in errors and in the
/// mesh.
pub fn parse_stl(bytes: &[u8], path: &Path) -> Result<TriangleMesh, ModelError> {
    let binary_count = (bytes.len() >= HEADER + 4).then(|| {
        let c = &bytes[HEADER..HEADER + 4];
        u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as usize
    });
    let exact = binary_count.is_some_and(|n| {
        n.checked_mul(TRIANGLE_BYTES)
            .and_then(|b| b.checked_add(HEADER + 4))
            == Some(bytes.len())
    });
    let starts_solid = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .is_some_and(|i| bytes[i..].starts_with(b"solid"));
    let (vertices, triangles) = if !exact && starts_solid {
        parse_ascii(bytes, path)?
    } else {
        parse_binary(bytes, binary_count, path)?
    };
    if triangles.is_empty() {
        return Err(ModelError::Empty {
            path: path.to_path_buf(),
            reason: "the STL file has no triangle".into(),
        });
    }
    Ok(TriangleMesh {
        vertices: vertices.iter().map(|v| v.as_dvec3()).collect(),
        triangles,
        normals: None,
        colors: None,
        path: Some(path.to_path_buf()),
    })
}

type Parsed = (Vec<Vec3>, Vec<[u32; 3]>);

fn parse_binary(bytes: &[u8], count: Option<usize>, path: &Path) -> Result<Parsed, ModelError> {
    let invalid = |reason: String| ModelError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    let Some(count) = count else {
        return Err(invalid(format!(
            "not an STL file: {} bytes, too short for a binary STL's header and count ({} bytes), and no 'solid' line",
            bytes.len(),
            HEADER + 4
        )));
    };
    let body = bytes.len() - HEADER - 4;
    let fits = body / TRIANGLE_BYTES;
    if count > fits {
        return Err(ModelError::Truncated {
            path: path.to_path_buf(),
            element: "triangle (binary STL)".into(),
            read: fits,
            count,
        });
    }
    if count * TRIANGLE_BYTES < body {
        log::warn!(
            "{}: {} bytes after the {count} triangles of the binary STL ignored",
            path.display(),
            body - count * TRIANGLE_BYTES
        );
    }
    // 3 * count vertices fit in u32 indices: count <= file size / 50.
    if count.saturating_mul(3) > u32::MAX as usize {
        return Err(invalid(format!("{count} triangles: too many")));
    }
    let mut vertices = Vec::with_capacity(3 * count);
    let mut triangles = Vec::with_capacity(count);
    let f = |b: &[u8], at: usize| f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
    for t in bytes[HEADER + 4..].chunks_exact(TRIANGLE_BYTES).take(count) {
        let first = vertices.len() as u32;
        for k in 0..3 {
            let at = 12 + 12 * k;
            vertices.push(Vec3::new(f(t, at), f(t, at + 4), f(t, at + 8)));
        }
        triangles.push([first, first + 1, first + 2]);
    }
    Ok((vertices, triangles))
}

fn parse_ascii(bytes: &[u8], path: &Path) -> Result<Parsed, ModelError> {
    let parse_err = |line: usize, reason: String| ModelError::Parse {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut vertices: Vec<Vec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut facet: Vec<Vec3> = Vec::new();
    // Where the open solid and facet began (1-based lines).
    let mut solid: Option<usize> = None;
    let mut in_facet: Option<usize> = None;
    let mut line_no = 0usize;
    for raw in bytes.split(|&b| b == b'\n') {
        line_no += 1;
        if raw.len() > MAX_LINE {
            return Err(parse_err(line_no, "line too long".into()));
        }
        let text = String::from_utf8_lossy(raw);
        let mut tokens = text.split_ascii_whitespace();
        let Some(keyword) = tokens.next() else {
            continue;
        };
        let word: String = keyword.chars().take(32).collect();
        match keyword {
            "solid" => {
                if solid.is_some() {
                    return Err(parse_err(
                        line_no,
                        "'solid' inside a solid (missing 'endsolid')".into(),
                    ));
                }
                solid = Some(line_no);
            }
            "endsolid" => {
                if in_facet.is_some() {
                    return Err(parse_err(line_no, "'endsolid' inside a facet".into()));
                }
                if solid.take().is_none() {
                    return Err(parse_err(line_no, "'endsolid' without 'solid'".into()));
                }
            }
            "facet" => {
                if solid.is_none() {
                    return Err(parse_err(line_no, "'facet' outside a solid".into()));
                }
                if in_facet.is_some() {
                    return Err(parse_err(
                        line_no,
                        "'facet' inside a facet (missing 'endfacet')".into(),
                    ));
                }
                in_facet = Some(line_no);
                facet.clear();
            }
            "vertex" => {
                if in_facet.is_none() {
                    return Err(parse_err(line_no, "'vertex' outside a facet".into()));
                }
                let mut xyz = [0.0f32; 3];
                for c in &mut xyz {
                    let tok = tokens
                        .next()
                        .ok_or_else(|| parse_err(line_no, "a vertex needs x y z".into()))?;
                    *c = tok.parse().map_err(|_| {
                        let s: String = tok.chars().take(32).collect();
                        parse_err(line_no, format!("'{s}' is not a number"))
                    })?;
                }
                facet.push(Vec3::from_array(xyz));
            }
            "endfacet" => {
                if in_facet.take().is_none() {
                    return Err(parse_err(line_no, "'endfacet' without 'facet'".into()));
                }
                if facet.len() < 3 {
                    return Err(parse_err(
                        line_no,
                        format!("a facet needs at least 3 vertices, found {}", facet.len()),
                    ));
                }
                let first = vertices.len();
                if (first + facet.len()) > u32::MAX as usize {
                    return Err(parse_err(line_no, "too many vertices".into()));
                }
                vertices.extend_from_slice(&facet);
                for k in 1..facet.len() - 1 {
                    triangles.push([first as u32, (first + k) as u32, (first + k + 1) as u32]);
                }
            }
            "outer" | "endloop" => {}
            _ => {
                return Err(parse_err(
                    line_no,
                    format!("unexpected '{word}' in an ASCII STL"),
                ));
            }
        }
    }
    if let Some(at) = in_facet {
        return Err(ModelError::Invalid {
            path: path.to_path_buf(),
            reason: format!("truncated ASCII STL: the file ends inside the facet of line {at}"),
        });
    }
    if let Some(at) = solid {
        return Err(ModelError::Invalid {
            path: path.to_path_buf(),
            reason: format!(
                "truncated ASCII STL: the file ends before the 'endsolid' of the solid of line {at}"
            ),
        });
    }
    Ok((vertices, triangles))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn binary(tris: &[[[f32; 3]; 3]], header: &[u8]) -> Vec<u8> {
        let mut b = vec![b' '; HEADER];
        b[..header.len()].copy_from_slice(header);
        b.extend_from_slice(&(tris.len() as u32).to_le_bytes());
        for t in tris {
            b.extend_from_slice(&[0u8; 12]);
            for v in t {
                for c in v {
                    b.extend_from_slice(&c.to_le_bytes());
                }
            }
            b.extend_from_slice(&[0, 0]);
        }
        b
    }

    fn ascii(tris: &[[[f32; 3]; 3]]) -> String {
        let mut s = String::from("solid test\n");
        for t in tris {
            s.push_str("  facet normal 0 0 1\n    outer loop\n");
            for v in t {
                s.push_str(&format!("      vertex {} {} {}\n", v[0], v[1], v[2]));
            }
            s.push_str("    endloop\n  endfacet\n");
        }
        s.push_str("endsolid test\n");
        s
    }

    /// A right triangle of legs 3 and 4 (area 6) and one of legs 1 and 2
    /// (area 1) in the plane x = 5.
    const TRIS: [[[f32; 3]; 3]; 2] = [
        [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 4.0, 0.0]],
        [[5.0, 0.0, 0.0], [5.0, 1.0, 0.0], [5.0, 0.0, 2.0]],
    ];

    fn p() -> &'static Path {
        Path::new("m.stl")
    }

    #[test]
    fn binary_and_ascii_give_the_triangles_and_their_areas() {
        // A header starting with "solid", as some exporters write it.
        for bytes in [
            binary(&TRIS, b"solid exported"),
            binary(&TRIS, b"binary"),
            ascii(&TRIS).into_bytes(),
        ] {
            let m = parse_stl(&bytes, p()).unwrap();
            assert_eq!(m.triangles.len(), 2);
            assert_eq!(m.vertices.len(), 6);
            assert!((m.area() - 7.0).abs() < 1e-9, "{}", m.area());
            assert_eq!(m.vertices[4], glam::DVec3::new(5.0, 1.0, 0.0));
        }
    }

    #[test]
    fn ascii_polygons_are_fanned_and_solids_may_follow_each_other() {
        let text = "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 2 0 0\n\
                    vertex 2 2 0\nvertex 0 2 0\nendloop\nendfacet\nendsolid a\n\
                    solid b\nendsolid b";
        let m = parse_stl(text.as_bytes(), p()).unwrap();
        assert_eq!(m.triangles.len(), 2);
        assert!((m.area() - 4.0).abs() < 1e-9);
    }

    #[test]
    fn truncated_and_garbage_files_are_refused_in_one_line() {
        let full = binary(&TRIS, b"bin");
        let cut = &full[..full.len() - 7];
        let e = parse_stl(cut, p()).unwrap_err().to_string();
        assert!(e.contains("truncated") && e.contains("1 of 2"), "{e}");

        let text = ascii(&TRIS);
        let cut = &text[..text.find("endloop").unwrap()];
        let e = parse_stl(cut.as_bytes(), p()).unwrap_err().to_string();
        assert!(e.contains("truncated") && e.contains("facet"), "{e}");
        let cut = &text[..text.rfind("endsolid").unwrap()];
        let e = parse_stl(cut.as_bytes(), p()).unwrap_err().to_string();
        assert!(e.contains("truncated") && e.contains("endsolid"), "{e}");

        // A count of 4 billion triangles in a small file: refused before
        // any allocation.
        let mut huge = binary(&TRIS, b"bin");
        huge[HEADER..HEADER + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = parse_stl(&huge, p()).unwrap_err().to_string();
        assert!(e.contains("truncated"), "{e}");

        for (bytes, want) in [
            (&b"hello"[..], "too short"),
            (b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 zero 0\n", "not a number"),
            (b"solid x\nbanana\nendsolid x\n", "unexpected 'banana'"),
            (b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nendloop\nendfacet\nendsolid\n", "at least 3"),
            (b"solid x\nendsolid x\n", "no triangle"),
            (&[0u8; 84][..], "no triangle"),
        ] {
            let e = parse_stl(bytes, p()).unwrap_err().to_string();
            assert!(e.contains(want), "{want}: {e}");
            assert!(e.starts_with("m.stl") && !e.contains('\n'), "{e}");
        }
    }

    #[test]
    fn mutated_files_are_read_or_refused_never_a_panic() {
        // A small stand-in for the fuzz target: bytes flipped, inserted,
        // cut and counts forged in binary and ASCII seeds.
        let seeds = [
            binary(&TRIS, b"bin"),
            binary(&TRIS, b"solid x"),
            ascii(&TRIS).into_bytes(),
        ];
        let mut rng = crate::rng::Rng::new(41);
        for case in 0..6000u64 {
            let mut b = seeds[(case % 3) as usize].clone();
            for _ in 0..=rng.below(4) {
                let at = rng.below(b.len() as u64) as usize;
                match rng.below(4) {
                    0 => b[at] ^= 1 << rng.below(8),
                    1 => b.truncate(at),
                    2 => {
                        let bytes = b"\n -.e9solidvertexfacet";
                        b.insert(at, bytes[rng.below(bytes.len() as u64) as usize]);
                    }
                    _ if b.len() >= HEADER + 4 => {
                        let n = rng.below(u64::from(u32::MAX)) as u32;
                        b[HEADER..HEADER + 4].copy_from_slice(&n.to_le_bytes());
                    }
                    _ => {}
                }
                if b.is_empty() {
                    break;
                }
            }
            match parse_stl(&b, p()) {
                Ok(m) => {
                    assert!(
                        m.triangles
                            .iter()
                            .flatten()
                            .all(|&i| (i as usize) < m.vertices.len())
                    );
                    let _ = m.sample(16, 0);
                }
                Err(e) => assert!(!e.to_string().contains('\n'), "{e}"),
            }
        }
    }

    #[test]
    fn trailing_bytes_after_the_binary_triangles_are_ignored() {
        let mut b = binary(&TRIS, b"bin");
        b.extend_from_slice(b"xyz");
        let m = parse_stl(&b, p()).unwrap();
        assert_eq!(m.triangles.len(), 2);
    }
}
