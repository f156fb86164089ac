//! `PointModel::close_gaps`: radii grow only where
//! the discs leave gaps, by what the gap needs. Known answers on grids
//! (the covering radius of a square grid of spacing s is s / sqrt 2) and a
//! brute-force coverage count on random samplings, independent of the
//! Voronoi construction under test.

mod tracking_common;

use glam::{DVec3, Vec3};
use splattrack::model::{PointModel, TriangleMesh, shapes};
use tracking_common::random_sample;

/// Fraction of probe points of the square `[-half, half]^2` of the plane
/// z = 0 that no disc covers (points within `margin` of the square's edge
/// are skipped).
fn uncovered(model: &PointModel, half: f32, margin: f32) -> f64 {
    let probes = 300;
    let (mut out, mut total) = (0usize, 0usize);
    // A coarse bucket grid so that each probe looks at nearby discs only.
    let rmax = model.radii.iter().fold(0f32, |m, &r| m.max(r));
    let cell = rmax.max(1e-6);
    let cells = ((2.0 * half / cell).ceil() as usize + 3).min(4096);
    let key = |x: f32| (((x + half) / cell).floor() as i64 + 1).clamp(0, cells as i64 - 1) as usize;
    let mut buckets = vec![Vec::new(); cells * cells];
    for (i, p) in model.positions.iter().enumerate() {
        buckets[key(p.y) * cells + key(p.x)].push(i);
    }
    for a in 0..probes {
        for b in 0..probes {
            let x = -half + margin + (2.0 * (half - margin)) * (a as f32 + 0.5) / probes as f32;
            let y = -half + margin + (2.0 * (half - margin)) * (b as f32 + 0.5) / probes as f32;
            total += 1;
            let (kx, ky) = (key(x), key(y));
            let mut hit = false;
            'search: for cy in ky.saturating_sub(1)..=(ky + 1).min(cells - 1) {
                for cx in kx.saturating_sub(1)..=(kx + 1).min(cells - 1) {
                    for &i in &buckets[cy * cells + cx] {
                        let p = model.positions[i];
                        let r = model.radii[i];
                        if (p.x - x).powi(2) + (p.y - y).powi(2) <= r * r {
                            hit = true;
                            break 'search;
                        }
                    }
                }
            }
            out += !hit as usize;
        }
    }
    out as f64 / total as f64
}

#[test]
fn a_square_grid_grows_to_its_covering_radius_and_no_further() {
    let (half, k) = (1.0f32, 24);
    let step = 2.0 * half / k as f32;
    let mut thin = shapes::plane(Vec3::ZERO, Vec3::Z, half, k, 0.3);
    let c = thin.close_gaps().unwrap();
    assert_eq!(c.grown, k * k, "{c:?}");
    let want = step / 2f32.sqrt();
    for (i, &r) in thin.radii.iter().enumerate() {
        assert!(
            (r - want).abs() <= 1e-4 * want,
            "point {i}: {r} against {want}"
        );
    }
    // Discs of the covering radius, or larger, already cover: unchanged.
    for factor in [0.75f32, 1.0, 2.0] {
        let mut covered = shapes::plane(Vec3::ZERO, Vec3::Z, half, k, factor);
        let before = covered.radii.clone();
        let c = covered.close_gaps().unwrap();
        assert_eq!(c.grown, 0, "factor {factor}: {c:?}");
        assert_eq!(covered.radii, before);
    }
}

#[test]
fn random_samplings_grow_only_around_their_gaps_and_end_covered() {
    let half = 1.0f64;
    let mesh = TriangleMesh::cuboid(DVec3::new(half, half, 0.01), 2);
    // Only the top face (z = +0.01) is probed; the sampler spreads points
    // over the whole box, so count the area.
    let n = 40_000;
    let spacing = (mesh.area() / n as f64).sqrt() as f32;
    for (factor, seed) in [(0.5f32, 1u64), (1.0, 2), (1.5, 3)] {
        let mut model = random_sample(&mesh, n, factor * spacing, seed);
        // Keep the top face's points, flattened onto z = 0.
        let keep: Vec<usize> = (0..model.len())
            .filter(|&i| model.normals[i].z > 0.5)
            .collect();
        model.positions = keep
            .iter()
            .map(|&i| model.positions[i] * Vec3::new(1.0, 1.0, 0.0))
            .collect();
        model.normals = vec![Vec3::Z; keep.len()];
        model.radii = vec![factor * spacing; keep.len()];
        let margin = 3.0 * spacing;
        let before = uncovered(&model, half as f32, margin);
        let c = model.close_gaps().unwrap();
        let after = uncovered(&model, half as f32, margin);
        eprintln!(
            "radii {factor} x spacing: {:.3}% uncovered -> {:.4}%, {} of {} grown, mean radius {:.3} -> {:.3} spacings",
            100.0 * before,
            100.0 * after,
            c.grown,
            c.points,
            c.mean_before / spacing as f64,
            c.mean_after / spacing as f64
        );
        assert!(
            before > 0.001,
            "factor {factor}: no gap to close ({before})"
        );
        assert_eq!(after, 0.0, "factor {factor}: {:.4}% left", 100.0 * after);
        assert!(c.grown < c.points, "{c:?}");
        // Only what the gaps need: far less than a uniform growth to the
        // largest grown radius.
        let rmax = model.radii.iter().fold(0f32, |m, &r| m.max(r)) as f64;
        assert!(c.mean_after < 0.8 * rmax, "{c:?}, largest {rmax}");
    }
}

#[test]
fn tiny_and_degenerate_models_are_left_as_they_are() {
    let mut two = shapes::plane(Vec3::ZERO, Vec3::Z, 1.0, 2, 0.1);
    two.positions.truncate(2);
    two.normals.truncate(2);
    two.radii.truncate(2);
    let before = two.radii.clone();
    assert_eq!(two.close_gaps().unwrap().grown, 0);
    assert_eq!(two.radii, before);
    // All points at one position: no neighbour at a positive distance.
    let mut same = shapes::plane(Vec3::ZERO, Vec3::Z, 1.0, 4, 0.1);
    same.positions.fill(Vec3::new(0.5, 0.5, 0.5));
    let before = same.radii.clone();
    assert_eq!(same.close_gaps().unwrap().grown, 0);
    assert_eq!(same.radii, before);
}
