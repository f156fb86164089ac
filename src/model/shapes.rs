//! Shapes with a known surface (sphere, box, torus, plane, star-shaped
//! blobs), as triangle meshes and as exact point samples, for tests,
//! benchmarks, demos and the synthetic objects.
//!
//! - Meshes ([`TriangleMesh::sphere`], [`TriangleMesh::radial`],
//!   [`TriangleMesh::cuboid`], [`TriangleMesh::torus`]) carry the smooth
//!   surface's unit normal at every vertex; they are what the synthetic
//!   sequences rasterise and what point models are sampled from.
//! - Point models ([`sphere`], [`plane`], [`cuboid`], [`random_cloud`]) put
//!   every point exactly on the parametric surface, with its exact normal,
//!   so tests can check rendered depth and predictors against the surface
//!   without any reference renderer.

use super::mesh::TriangleMesh;
use super::types::{AttributeSource, PointModel, Provenance};
use crate::rng::Rng;
use glam::{DVec3, Vec3};

impl TriangleMesh {
    /// A sphere of radius `radius` about the origin over a `nlat x nlon`
    /// latitude/longitude grid (see [`TriangleMesh::radial`]).
    pub fn sphere(radius: f64, nlat: usize, nlon: usize) -> Self {
        Self::radial(|_| radius, nlat, nlon)
    }

    /// A closed star-shaped surface `d -> r(d) d` (`d` a unit direction)
    /// over a latitude/longitude grid of `nlat` bands and `nlon` meridians,
    /// one vertex at each pole, with normals from the surface's own
    /// gradient (central differences).
    pub fn radial(r: impl Fn(DVec3) -> f64, nlat: usize, nlon: usize) -> Self {
        let dir = |th: f64, ph: f64| DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
        let point = |th: f64, ph: f64| {
            let d = dir(th, ph);
            d * r(d)
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
            let n = dth.cross(dph);
            let len = n.length();
            if len < 1e-14 { dir(th, ph) } else { n / len }
        };
        normals.push(DVec3::Z);
        for i in 1..nlat {
            let th = i as f64 / nlat as f64 * std::f64::consts::PI;
            for j in 0..nlon {
                let ph = j as f64 / nlon as f64 * std::f64::consts::TAU;
                normals.push(normal(th, ph));
            }
        }
        normals.push(DVec3::NEG_Z);
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
        Self::generated(vertices, normals, triangles)
    }

    /// An axis-aligned box of half extents `half` about the origin, each
    /// face split into `k x k` quads of four vertices each (flat normals).
    pub fn cuboid(half: DVec3, k: usize) -> Self {
        let mut vertices = Vec::new();
        let mut normals = Vec::new();
        let mut triangles = Vec::new();
        let at = |i: usize| -1.0 + 2.0 * i as f64 / k as f64;
        for axis in 0..3 {
            for sign in [-1.0, 1.0] {
                let mut n = DVec3::ZERO;
                n[axis] = sign;
                let mut u = DVec3::ZERO;
                u[(axis + 1) % 3] = 1.0;
                let v = n.cross(u);
                for i in 0..k {
                    for j in 0..k {
                        let base = vertices.len() as u32;
                        let (a0, a1, b0, b1) = (at(i), at(i + 1), at(j), at(j + 1));
                        for (a, b) in [(a0, b0), (a1, b0), (a1, b1), (a0, b1)] {
                            let p = n * half[axis]
                                + u * (a * half[(axis + 1) % 3])
                                + v * (b * half.dot(v.abs()));
                            vertices.push(p);
                            normals.push(n);
                        }
                        triangles.push([base, base + 1, base + 2]);
                        triangles.push([base, base + 2, base + 3]);
                    }
                }
            }
        }
        Self::generated(vertices, normals, triangles)
    }

    /// A torus about the z axis (ring radius `big`, tube radius `small`)
    /// over `nu` steps around the ring and `nv` around the tube.
    pub fn torus(big: f64, small: f64, nu: usize, nv: usize) -> Self {
        let mut vertices = Vec::new();
        let mut normals = Vec::new();
        for i in 0..nu {
            let u = i as f64 / nu as f64 * std::f64::consts::TAU;
            for j in 0..nv {
                let v = j as f64 / nv as f64 * std::f64::consts::TAU;
                let n = DVec3::new(v.cos() * u.cos(), v.cos() * u.sin(), v.sin());
                let c = DVec3::new(big * u.cos(), big * u.sin(), 0.0);
                vertices.push(c + n * small);
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
        Self::generated(vertices, normals, triangles)
    }

    fn generated(vertices: Vec<DVec3>, normals: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Self {
        Self {
            vertices,
            triangles,
            normals: Some(normals),
            colors: None,
            path: None,
        }
    }
}

/// Points exactly on a shape, with its exact normals: attributes as good
/// as a mesh's.
fn exact(
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    radii: Vec<f32>,
    colors: Vec<[f32; 3]>,
) -> PointModel {
    PointModel {
        positions,
        normals,
        radii,
        colors: Some(colors),
        provenance: Provenance {
            path: None,
            normals: AttributeSource::FromMesh,
            radii: AttributeSource::FromMesh,
            colors: AttributeSource::FromMesh,
            dropped_non_finite: 0,
            normals_reestimated: 0,
        },
    }
}

/// A smooth colour field over space (period ~ `scale`), so that renders
/// have texture without a texture.
pub fn color_field(p: Vec3, scale: f32) -> [f32; 3] {
    let q = p * (std::f32::consts::TAU / scale);
    [
        0.5 + 0.4 * (q.x + 0.3 * q.y).sin(),
        0.5 + 0.4 * (q.y - 0.5 * q.z).sin(),
        0.5 + 0.4 * (q.z + 0.7 * q.x).cos(),
    ]
}

fn model(positions: Vec<Vec3>, normals: Vec<Vec3>, radius: f32, color_scale: f32) -> PointModel {
    let colors = positions
        .iter()
        .map(|&p| color_field(p, color_scale))
        .collect();
    let radii = vec![radius; positions.len()];
    exact(positions, normals, radii, colors)
}

/// `n` points on a sphere (a Fibonacci lattice: nearly uniform), outward
/// normals, splat radius `radius_factor` times the mean spacing
/// `sqrt(area / n)` (1.0 leaves no holes: the lattice's covering radius is
/// about 0.62 spacings).
pub fn sphere(center: Vec3, radius: f32, n: usize, radius_factor: f32) -> PointModel {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut positions = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    for i in 0..n {
        let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
        let rr = (1.0 - z * z).max(0.0).sqrt();
        let phi = golden * i as f64;
        let nrm = Vec3::new((rr * phi.cos()) as f32, (rr * phi.sin()) as f32, z as f32);
        normals.push(nrm);
        positions.push(center + nrm * radius);
    }
    let spacing = (4.0 * std::f32::consts::PI * radius * radius / n as f32).sqrt();
    model(positions, normals, radius_factor * spacing, 2.0 * radius)
}

/// A square patch of a plane through `center` with unit normal `normal`,
/// side `2 half`, sampled on a `k x k` grid; splat radius `radius_factor`
/// grid spacings (0.71 is the grid's covering radius).
pub fn plane(center: Vec3, normal: Vec3, half: f32, k: usize, radius_factor: f32) -> PointModel {
    let normal = normal.normalize();
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    let step = 2.0 * half / k as f32;
    let mut positions = Vec::with_capacity(k * k);
    for i in 0..k {
        for j in 0..k {
            let a = -half + (i as f32 + 0.5) * step;
            let b = -half + (j as f32 + 0.5) * step;
            positions.push(center + u * a + v * b);
        }
    }
    let normals = vec![normal; positions.len()];
    model(positions, normals, radius_factor * step, half)
}

/// An axis-aligned box of half extents `half` around `center`, every face
/// sampled on a grid of spacing about `step` (cell centres, so no point
/// lies on an edge); splat radius `radius_factor * step`.
pub fn cuboid(center: Vec3, half: Vec3, step: f32, radius_factor: f32) -> PointModel {
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for axis in 0..3 {
        let (ua, va) = ((axis + 1) % 3, (axis + 2) % 3);
        let (hu, hv) = (half[ua], half[va]);
        let (nu, nv) = (
            ((2.0 * hu / step).round() as usize).max(1),
            ((2.0 * hv / step).round() as usize).max(1),
        );
        for sign in [-1.0f32, 1.0] {
            let mut n = Vec3::ZERO;
            n[axis] = sign;
            for i in 0..nu {
                for j in 0..nv {
                    let mut p = Vec3::ZERO;
                    p[axis] = sign * half[axis];
                    p[ua] = -hu + (i as f32 + 0.5) * 2.0 * hu / nu as f32;
                    p[va] = -hv + (j as f32 + 0.5) * 2.0 * hv / nv as f32;
                    positions.push(center + p);
                    normals.push(n);
                }
            }
        }
    }
    model(positions, normals, radius_factor * step, half.max_element())
}

/// `n` splats with random centres in a ball of radius `extent` around
/// `center`, random normals, radii in `[r_min, r_max]` and random colours:
/// inputs for GPU-vs-CPU comparisons that no structured surface would give.
pub fn random_cloud(
    rng: &mut Rng,
    center: Vec3,
    extent: f32,
    n: usize,
    r_min: f32,
    r_max: f32,
) -> PointModel {
    let mut positions = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    let mut radii = Vec::with_capacity(n);
    let mut colors = Vec::with_capacity(n);
    for _ in 0..n {
        let dir = rng.unit_vector();
        let r = extent as f64 * rng.next_f64().cbrt();
        positions.push(center + Vec3::new(dir.x as f32, dir.y as f32, dir.z as f32) * r as f32);
        let nv = rng.unit_vector();
        normals.push(Vec3::new(nv.x as f32, nv.y as f32, nv.z as f32));
        radii.push(rng.uniform(r_min as f64, r_max as f64) as f32);
        colors.push([
            rng.next_f64() as f32,
            rng.next_f64() as f32,
            rng.next_f64() as f32,
        ]);
    }
    exact(positions, normals, radii, colors)
}

/// `n` points uniformly random over a torus about the z axis (ring radius
/// `big`, tube radius `small`) and their outward normals: a cloud with no
/// structure for normal and radius estimation to lean on.
pub fn random_torus(n: usize, big: f32, small: f32, seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut rng = Rng::new(seed);
    let mut pos = Vec::with_capacity(n);
    let mut nrm = Vec::with_capacity(n);
    while pos.len() < n {
        let u = std::f32::consts::TAU * rng.next_f64() as f32;
        let v = std::f32::consts::TAU * rng.next_f64() as f32;
        // Rejection sampling for uniform area density.
        if rng.next_f64() as f32 > (big + small * v.cos()) / (big + small) {
            continue;
        }
        let d = Vec3::new(v.cos() * u.cos(), v.cos() * u.sin(), v.sin());
        let centre = Vec3::new(big * u.cos(), big * u.sin(), 0.0);
        pos.push(centre + small * d);
        nrm.push(d);
    }
    (pos, nrm)
}

/// `n` points on a sphere (centre `c`, radius `r`): a Fibonacci lattice
/// jittered with `seed`, even but not regular, and their outward normals.
pub fn jittered_sphere(n: usize, c: Vec3, r: f32, seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut rng = Rng::new(seed);
    let mut pos = Vec::with_capacity(n);
    let mut nrm = Vec::with_capacity(n);
    for i in 0..n {
        // Fibonacci lattice plus a small jitter: even but not regular.
        let z = 1.0 - 2.0 * (i as f64 + 0.2 + 0.6 * rng.next_f64()) / n as f64;
        let phi = i as f64 * 2.399_963_229_728_653 + 0.3 * rng.next_f64();
        let s = (1.0 - z * z).max(0.0).sqrt();
        let d = Vec3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, z as f32);
        pos.push(c + r * d);
        nrm.push(d);
    }
    (pos, nrm)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meshes_have_the_shapes_area_and_outward_normals() {
        let pi = std::f64::consts::PI;
        let (a, b, c) = (0.5, 0.35, 0.25);
        for (name, mesh, area, tol) in [
            ("sphere", TriangleMesh::sphere(0.5, 48, 96), pi, 0.01),
            (
                "box",
                TriangleMesh::cuboid(DVec3::new(a, b, c), 8),
                8.0 * (a * b + a * c + b * c),
                1e-12,
            ),
            (
                "torus",
                TriangleMesh::torus(0.45, 0.18, 96, 48),
                4.0 * pi * pi * 0.45 * 0.18,
                0.01,
            ),
        ] {
            let err = (mesh.area() - area).abs() / area;
            assert!(err < tol, "{name}: area {} vs {area}", mesh.area());
            let normals = mesh.normals.as_ref().unwrap();
            assert_eq!(normals.len(), mesh.vertices.len());
            for t in &mesh.triangles {
                let [p, q, r] = t.map(|i| mesh.vertices[i as usize]);
                let face = (q - p).cross(r - p);
                for &i in t {
                    let n = normals[i as usize];
                    assert!((n.length() - 1.0).abs() < 1e-9, "{name}");
                    assert!(face.dot(n) > 0.0, "{name}: triangle {t:?} winds inward");
                }
            }
        }
    }
}
