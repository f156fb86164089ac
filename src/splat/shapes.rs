//! Point models of analytic surfaces (plane, sphere, box) and random splat
//! clouds, for tests, benchmarks and demos. The exact surface is known, so
//! tests can check rendered depth and predictors against it without any
//! reference renderer.

use crate::model::{AttributeSource, PointModel, Provenance};
use crate::rng::Rng;
use glam::Vec3;

fn provenance() -> Provenance {
    Provenance {
        path: None,
        normals: AttributeSource::FromMesh,
        radii: AttributeSource::FromMesh,
        colors: AttributeSource::FromMesh,
        dropped_non_finite: 0,
        normals_reestimated: 0,
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
    PointModel {
        positions,
        normals,
        radii,
        colors: Some(colors),
        provenance: provenance(),
    }
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
    PointModel {
        positions,
        normals,
        radii,
        colors: Some(colors),
        provenance: provenance(),
    }
}
