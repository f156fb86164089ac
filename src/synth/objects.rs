//! Built-in procedural objects: triangle meshes with procedural textures.
//!
//! Textures are functions of the *object-space* surface point (and normal),
//! so the mesh needs no UV mapping, the rasteriser can shade every sample
//! exactly, and a point model sampled from the same surface gets exactly the
//! colours the frames show (before lighting and noise).

use nalgebra::Vector3;

/// An indexed triangle mesh with per-vertex normals (object frame, metres).
#[derive(Debug, Clone)]
pub struct TriMesh {
    /// Vertex positions.
    pub vertices: Vec<Vector3<f64>>,
    /// Unit normals, one per vertex (the smooth surface's).
    pub normals: Vec<Vector3<f64>>,
    /// Counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Bounding-box diagonal.
    pub fn diameter(&self) -> f64 {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for v in &self.vertices {
            lo = lo.inf(v);
            hi = hi.sup(v);
        }
        (hi - lo).norm()
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize]);
                (b - a).cross(&(c - a)).norm() * 0.5
            })
            .sum()
    }

    /// Wavefront OBJ text (positions, normals, faces).
    pub fn to_obj(&self) -> String {
        let mut s = String::from("# splattrack synthetic object\n");
        for v in &self.vertices {
            s.push_str(&format!("v {:.7} {:.7} {:.7}\n", v.x, v.y, v.z));
        }
        for n in &self.normals {
            s.push_str(&format!("vn {:.6} {:.6} {:.6}\n", n.x, n.y, n.z));
        }
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| i + 1);
            s.push_str(&format!("f {a}//{a} {b}//{b} {c}//{c}\n"));
        }
        s
    }
}

/// Surface colour as a function of the object-space point and normal.
#[derive(Debug, Clone)]
pub enum Texture {
    /// A 3-D grid of cells of random colour and brightness: every junction
    /// of cell boundaries on the surface is a corner.
    Cells {
        /// Cell size, metres.
        cell: f64,
        /// Seed of the cell colours.
        seed: u64,
    },
    /// "Printed" faces of a box: random rectangles and discs on white.
    Printed {
        /// Seed of the shapes.
        seed: u64,
        /// Shapes drawn per face.
        shapes_per_face: usize,
    },
}

fn hash(mut x: u64) -> u64 {
    x ^= x >> 33;
    x = x.wrapping_mul(0xff51_afd7_ed55_8ccd);
    x ^= x >> 33;
    x = x.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
    x ^ (x >> 33)
}

fn hash3(i: i64, j: i64, k: i64, seed: u64) -> u64 {
    hash(
        (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ hash((j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F) ^ hash((k as u64) ^ seed)),
    )
}

fn unit(h: u64, k: u32) -> f32 {
    ((hash(h.wrapping_add(k as u64)) >> 40) as f32) / (1u64 << 24) as f32
}

/// A saturated colour of brightness `l` (0..1), hue from `h`.
fn colour(h: u64, l: f32) -> [f32; 3] {
    let hue = unit(h, 1) * 6.0;
    let sat = 0.5 + 0.5 * unit(h, 2);
    let f = hue.fract();
    let (r, g, b) = match hue as u32 {
        0 => (1.0, f, 0.0),
        1 => (1.0 - f, 1.0, 0.0),
        2 => (0.0, 1.0, f),
        3 => (0.0, 1.0 - f, 1.0),
        4 => (f, 0.0, 1.0),
        _ => (1.0, 0.0, 1.0 - f),
    };
    let mix = |c: f32| (1.0 - sat + sat * c) * l;
    [mix(r), mix(g), mix(b)]
}

impl Texture {
    /// Linear albedo in 0..1.
    pub fn albedo(&self, p: &Vector3<f64>, n: &Vector3<f64>) -> [f32; 3] {
        match *self {
            Texture::Cells { cell, seed } => {
                let q = p / cell;
                let h = hash3(
                    q.x.floor() as i64,
                    q.y.floor() as i64,
                    q.z.floor() as i64,
                    seed,
                );
                // Brightness alternates strongly so corners survive greying.
                let l = 0.15 + 0.8 * unit(h, 0);
                colour(h, l)
            }
            Texture::Printed {
                seed,
                shapes_per_face,
            } => {
                // Face coordinates: the two axes orthogonal to the dominant
                // normal direction.
                let a = n.iamax();
                let face = (a as u64) * 2 + u64::from(n[a] > 0.0);
                let (u, v) = match a {
                    0 => (p.y, p.z),
                    1 => (p.x, p.z),
                    _ => (p.x, p.y),
                };
                let mut c = [0.92f32, 0.9, 0.85];
                for s in 0..shapes_per_face as u64 {
                    let h = hash(seed ^ (face << 32) ^ s.wrapping_mul(0x1234_5677));
                    let cu = (unit(h, 3) as f64 - 0.5) * 0.12;
                    let cv = (unit(h, 4) as f64 - 0.5) * 0.12;
                    let size = 0.006 + 0.018 * unit(h, 5) as f64;
                    let inside = if unit(h, 6) < 0.55 {
                        (u - cu).abs() < size && (v - cv).abs() < size * (0.5 + unit(h, 7) as f64)
                    } else {
                        (u - cu).powi(2) + (v - cv).powi(2) < size * size
                    };
                    if inside {
                        c = colour(h, 0.1 + 0.6 * unit(h, 8));
                    }
                }
                c
            }
        }
    }
}

/// A directional light in the camera frame plus ambient light.
#[derive(Debug, Clone, Copy)]
pub struct Light {
    /// Unit vector from the surface towards the light, camera frame.
    pub direction: Vector3<f64>,
    /// Ambient intensity (0..1).
    pub ambient: f64,
    /// Diffuse (Lambertian) intensity at normal incidence.
    pub diffuse: f64,
}

impl Light {
    /// A light above-left of the camera, turned by `phase` radians about the
    /// optical axis (sequences move it slowly).
    pub fn moving(phase: f64) -> Self {
        let d = Vector3::new(-0.4 * phase.cos(), -0.6 - 0.2 * phase.sin(), -1.0).normalize();
        Self {
            direction: d,
            ambient: 0.45,
            diffuse: 0.6,
        }
    }

    /// The intensity on a surface of camera-frame unit normal `n_cam`:
    /// ambient plus Lambertian diffuse (the albedo multiplies it).
    pub fn shade(&self, n_cam: &Vector3<f64>) -> f64 {
        self.ambient + self.diffuse * n_cam.dot(&self.direction).max(0.0)
    }
}

/// A built-in object: mesh, texture, name.
#[derive(Debug, Clone)]
pub struct SynthObject {
    /// One of [`OBJECT_NAMES`].
    pub name: &'static str,
    /// A line for help texts.
    pub description: &'static str,
    /// The geometry (object frame, metres, centred on the origin).
    pub mesh: TriMesh,
    /// The surface colour.
    pub texture: Texture,
}

/// Names of the built-in objects, for the CLI.
pub const OBJECT_NAMES: [&str; 3] = ["blob", "box", "torus"];

impl SynthObject {
    /// One of [`OBJECT_NAMES`].
    pub fn by_name(name: &str) -> Option<Self> {
        match name {
            "blob" => Some(Self::blob()),
            "box" => Some(Self::printed_box()),
            "torus" => Some(Self::torus()),
            _ => None,
        }
    }

    /// A smooth organic shape (a lumpy sphere, ~0.2 m) with a strong
    /// cell texture.
    pub fn blob() -> Self {
        let r = |d: &Vector3<f64>| {
            0.09 * (1.0
                + 0.12 * (3.0 * d.x + 0.4).sin() * (2.0 * d.y).cos()
                + 0.08 * (4.0 * d.z + 1.1).sin()
                + 0.05 * (5.0 * d.y + 2.0 * d.x).cos())
        };
        Self {
            name: "blob",
            description: "smooth organic shape with a strong texture",
            mesh: radial_mesh(r, 64, 128),
            texture: Texture::Cells {
                cell: 0.022,
                seed: 7,
            },
        }
    }

    /// A 12 x 9 x 6 cm box with printed faces.
    pub fn printed_box() -> Self {
        Self {
            name: "box",
            description: "box with printed faces",
            mesh: box_mesh(Vector3::new(0.06, 0.045, 0.03)),
            texture: Texture::Printed {
                seed: 11,
                shapes_per_face: 24,
            },
        }
    }

    /// A torus (8 cm ring, 3 cm tube): it hides parts of itself.
    pub fn torus() -> Self {
        let (rr, r) = (0.08, 0.03);
        let (nu, nv) = (96usize, 32usize);
        let mut vertices = Vec::new();
        let mut normals = Vec::new();
        for i in 0..nu {
            let u = i as f64 / nu as f64 * std::f64::consts::TAU;
            for j in 0..nv {
                let v = j as f64 / nv as f64 * std::f64::consts::TAU;
                let n = Vector3::new(v.cos() * u.cos(), v.cos() * u.sin(), v.sin());
                let c = Vector3::new(rr * u.cos(), rr * u.sin(), 0.0);
                vertices.push(c + n * r);
                normals.push(n);
            }
        }
        let mut triangles = Vec::new();
        for i in 0..nu {
            for j in 0..nv {
                let a = (i * nv + j) as u32;
                let b = (((i + 1) % nu) * nv + j) as u32;
                let c = (((i + 1) % nu) * nv + (j + 1) % nv) as u32;
                let d = (i * nv + (j + 1) % nv) as u32;
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            }
        }
        Self {
            name: "torus",
            description: "torus: self-occluding",
            mesh: TriMesh {
                vertices,
                normals,
                triangles,
            },
            texture: Texture::Cells {
                cell: 0.018,
                seed: 5,
            },
        }
    }
}

/// A closed star-shaped surface `d -> r(d) d` over a latitude/longitude grid,
/// with normals from the surface's own gradient (finite differences).
fn radial_mesh(r: impl Fn(&Vector3<f64>) -> f64, nlat: usize, nlon: usize) -> TriMesh {
    let dir = |th: f64, ph: f64| Vector3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
    let point = |th: f64, ph: f64| {
        let d = dir(th, ph);
        d * r(&d)
    };
    let mut vertices = vec![point(0.0, 0.0)];
    let mut normals = Vec::new();
    for i in 1..nlat {
        let th = i as f64 / nlat as f64 * std::f64::consts::PI;
        for j in 0..nlon {
            let ph = j as f64 / nlon as f64 * std::f64::consts::TAU;
            vertices.push(point(th, ph));
        }
    }
    vertices.push(point(std::f64::consts::PI, 0.0));
    // Normals: cross product of the surface's partial derivatives.
    let h = 1e-5;
    let normal = |th: f64, ph: f64| {
        let dth = point(th + h, ph) - point(th - h, ph);
        let dph = point(th, ph + h) - point(th, ph - h);
        let n = dth.cross(&dph);
        if n.norm() < 1e-14 {
            dir(th, ph)
        } else {
            n.normalize()
        }
    };
    normals.push(Vector3::new(0.0, 0.0, 1.0));
    for i in 1..nlat {
        let th = i as f64 / nlat as f64 * std::f64::consts::PI;
        for j in 0..nlon {
            let ph = j as f64 / nlon as f64 * std::f64::consts::TAU;
            normals.push(normal(th, ph));
        }
    }
    normals.push(Vector3::new(0.0, 0.0, -1.0));
    let south = (vertices.len() - 1) as u32;
    let ring = |i: usize, j: usize| (1 + (i - 1) * nlon + j % nlon) as u32;
    let mut triangles = Vec::new();
    for j in 0..nlon {
        triangles.push([0, ring(1, j), ring(1, j + 1)]);
        triangles.push([south, ring(nlat - 1, j + 1), ring(nlat - 1, j)]);
    }
    for i in 1..nlat - 1 {
        for j in 0..nlon {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i + 1, j),
                ring(i + 1, j + 1),
                ring(i, j + 1),
            );
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    TriMesh {
        vertices,
        normals,
        triangles,
    }
}

/// An axis-aligned box with half extents `h`, 4 vertices per face (flat
/// normals), CCW from outside.
fn box_mesh(h: Vector3<f64>) -> TriMesh {
    let mut vertices = Vec::new();
    let mut normals = Vec::new();
    let mut triangles = Vec::new();
    for axis in 0..3 {
        for sign in [-1.0, 1.0] {
            let n = Vector3::ith(axis, sign);
            let u = Vector3::ith((axis + 1) % 3, 1.0);
            let v = n.cross(&u);
            let base = vertices.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let p = n * h[axis] + u * (a * h[(axis + 1) % 3]) + v * (b * h.dot(&v.abs()));
                vertices.push(p);
                normals.push(n);
            }
            triangles.push([base, base + 1, base + 2]);
            triangles.push([base, base + 2, base + 3]);
        }
    }
    TriMesh {
        vertices,
        normals,
        triangles,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meshes_are_closed_and_outward() {
        for name in OBJECT_NAMES {
            let o = SynthObject::by_name(name).unwrap();
            let m = &o.mesh;
            // Closed and consistently oriented: every directed edge has its
            // reverse exactly once.
            let mut edges = std::collections::HashMap::new();
            for t in &m.triangles {
                for k in 0..3 {
                    *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
                }
            }
            let open = edges
                .keys()
                .filter(|(a, b)| edges.get(&(*b, *a)) != Some(&1))
                .count();
            // The box has duplicated corner vertices (flat normals), so its
            // faces do not share indices: check its orientation only.
            if name != "box" {
                assert_eq!(open, 0, "{name}: {open} unmatched edges");
            }
            // Outward: the divergence theorem gives +volume for CCW-outside.
            let vol: f64 = m
                .triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| m.vertices[i as usize]);
                    a.dot(&b.cross(&c)) / 6.0
                })
                .sum();
            assert!(vol > 0.0, "{name}: volume {vol}");
            // Vertex normals agree with face winding.
            for t in &m.triangles {
                let [a, b, c] = t.map(|i| m.vertices[i as usize]);
                let fnrm = (b - a).cross(&(c - a));
                if fnrm.norm() > 1e-12 {
                    let vn = m.normals[t[0] as usize];
                    assert!(fnrm.dot(&vn) > 0.0, "{name}: normal disagrees with winding");
                }
            }
        }
    }

    #[test]
    fn box_has_the_stated_size() {
        let b = SynthObject::printed_box();
        let d = b.mesh.diameter();
        assert!((d - (0.12f64.powi(2) + 0.09f64.powi(2) + 0.06f64.powi(2)).sqrt()).abs() < 1e-12);
        assert!((b.mesh.area() - 2.0 * (0.12 * 0.09 + 0.12 * 0.06 + 0.09 * 0.06)).abs() < 1e-12);
    }
}
