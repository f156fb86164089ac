//! Built-in procedural objects: triangle meshes with procedural textures.
//!
//! Textures are functions of the *object-space* surface point (and normal),
//! so the mesh needs no UV mapping, the rasteriser can shade every sample
//! exactly, and a point model sampled from the same surface gets exactly the
//! colours the frames show (before lighting and noise). The geometry comes
//! from the crate's [`shapes`](crate::model::shapes).

use crate::model::TriangleMesh;
use glam::DVec3;
use nalgebra::Vector3;

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
    /// One plain colour (linear albedo): no texture at all, only shading.
    Plain([f32; 3]),
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
            Texture::Plain(c) => c,
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
    /// The geometry (object frame, metres, centred on the origin), with
    /// vertex normals.
    pub mesh: TriangleMesh,
    /// The surface colour.
    pub texture: Texture,
}

/// Names of the built-in objects, for the CLI.
pub const OBJECT_NAMES: [&str; 5] = ["blob", "box", "torus", "plain", "plainbox"];

impl SynthObject {
    /// One of [`OBJECT_NAMES`].
    pub fn by_name(name: &str) -> Option<Self> {
        match name {
            "blob" => Some(Self::blob()),
            "box" => Some(Self::printed_box()),
            "torus" => Some(Self::torus()),
            "plain" => Some(Self::plain()),
            "plainbox" => Some(Self::plain_box()),
            _ => None,
        }
    }

    /// A smooth organic shape (a lumpy sphere, ~0.2 m) with a strong
    /// cell texture.
    pub fn blob() -> Self {
        let r = |d: DVec3| {
            0.09 * (1.0
                + 0.12 * (3.0 * d.x + 0.4).sin() * (2.0 * d.y).cos()
                + 0.08 * (4.0 * d.z + 1.1).sin()
                + 0.05 * (5.0 * d.y + 2.0 * d.x).cos())
        };
        Self {
            name: "blob",
            description: "smooth organic shape with a strong texture",
            mesh: TriangleMesh::radial(r, 64, 128),
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
            mesh: TriangleMesh::cuboid(DVec3::new(0.06, 0.045, 0.03), 1),
            texture: Texture::Printed {
                seed: 11,
                shapes_per_face: 24,
            },
        }
    }

    /// An untextured, asymmetric object (~0.2 m): a lumpy, elongated body
    /// with two flat cuts (sharp edges where they meet the curved surface),
    /// in one plain yellow, like a 3-D print. Only its outline and shading
    /// show where it is.
    pub fn plain() -> Self {
        let cut = |d: DVec3, n: DVec3, h: f64| {
            let c = d.dot(n);
            if c > 1e-9 { h / c } else { f64::INFINITY }
        };
        let n1 = DVec3::new(0.8, 0.2, 0.55).normalize();
        let n2 = DVec3::new(-0.3, -0.9, -0.2).normalize();
        let r = move |d: DVec3| {
            let body = 0.07
                * (1.0 + 0.45 * d.x * d.x - 0.2 * d.z * d.z)
                * (1.0 + 0.08 * (3.0 * d.x + 0.4).sin() * (2.0 * d.y).cos());
            body.min(cut(d, n1, 0.055)).min(cut(d, n2, 0.05))
        };
        Self {
            name: "plain",
            description: "untextured: one plain colour, curved, with two flat cuts",
            mesh: TriangleMesh::radial(r, 96, 192),
            texture: Texture::Plain([0.85, 0.68, 0.12]),
        }
    }

    /// The 12 x 9 x 6 cm box of [`Self::printed_box`] in one plain blue.
    pub fn plain_box() -> Self {
        Self {
            name: "plainbox",
            description: "untextured box",
            mesh: TriangleMesh::cuboid(DVec3::new(0.06, 0.045, 0.03), 1),
            texture: Texture::Plain([0.2, 0.42, 0.75]),
        }
    }

    /// A torus (8 cm ring, 3 cm tube): it hides parts of itself.
    pub fn torus() -> Self {
        Self {
            name: "torus",
            description: "torus: self-occluding",
            mesh: TriangleMesh::torus(0.08, 0.03, 96, 32),
            texture: Texture::Cells {
                cell: 0.018,
                seed: 5,
            },
        }
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
            if name != "box" && name != "plainbox" {
                assert_eq!(open, 0, "{name}: {open} unmatched edges");
            }
            // Outward: the divergence theorem gives +volume for CCW-outside.
            let vol: f64 = m
                .triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| m.vertices[i as usize]);
                    a.dot(b.cross(c)) / 6.0
                })
                .sum();
            assert!(vol > 0.0, "{name}: volume {vol}");
            // Vertex normals agree with face winding.
            let normals = m.normals.as_ref().expect("vertex normals");
            for t in &m.triangles {
                let [a, b, c] = t.map(|i| m.vertices[i as usize]);
                let fnrm = (b - a).cross(c - a);
                if fnrm.length() > 1e-12 {
                    let vn = normals[t[0] as usize];
                    assert!(fnrm.dot(vn) > 0.0, "{name}: normal disagrees with winding");
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
