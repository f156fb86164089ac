//! Splatted point models against an independent triangle rasterisation of
//! the mesh they were sampled from: area-weighted
//! samples of a sphere, a box and a torus (self-occluding), several poses
//! each, against the z-buffer of synth's CPU rasteriser (the one that
//! renders the synthetic sequences' ground truth, at exact OpenCV pixel
//! centres).
//!
//! Criteria (pixels "away from silhouettes": the mesh covers the whole 5x5
//! neighbourhood and the splats the pixel itself):
//! - silhouette IoU (splat coverage vs mesh coverage) >= 0.97;
//! - depth error: median <= 0.2% and 99th percentile <= 1.5% of the
//!   object's diameter;
//! - motion predictors vs the host's `motion_predictors` at the mesh depth
//!   unprojected (relative Frobenius error of the 2x6 matrix): median <= 1%,
//!   95th percentile <= 5%.

use glam::DVec3;
use nalgebra::{Vector2, Vector3};
use splattrack::geometry::{Intrinsics, Pose, look_at};
use splattrack::gpu::{self, GpuContext};
use splattrack::model::{AttributeSource, TriangleMesh};
use splattrack::splat::{Attribute, Attributes, GpuModel, SplatTargets, Splatter};
use splattrack::synth::raster;

fn ctx() -> &'static GpuContext {
    gpu::shared_test_context()
}

fn percentile(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[((v.len() - 1) as f64 * p).round() as usize]
}

struct Figures {
    iou: f64,
    depth_median: f64,
    depth_p99: f64,
    motion_median: f64,
    motion_p95: f64,
}

fn compare(
    mesh: &TriangleMesh,
    n: usize,
    diameter: f64,
    cam: &Intrinsics,
    poses: &[Pose],
    label: &str,
) {
    // Splat radius 2 sqrt(area / n): about 2 closes the surface.
    let mut model = mesh.sample(n, 17).unwrap();
    let r = 2.0 * (mesh.area() / n as f64).sqrt();
    model.radii.fill(r as f32);
    model.provenance.radii = AttributeSource::Estimated;
    let splatter = Splatter::new(ctx()).unwrap();
    let gm = GpuModel::new(ctx(), &model).unwrap();
    let mut targets = SplatTargets::new(ctx(), cam.width, cam.height);
    for (k, pose) in poses.iter().enumerate() {
        splatter
            .render(ctx(), &gm, cam, pose, Attributes::ALL, &mut targets)
            .unwrap();
        let depth = splatter.read(ctx(), &targets, Attribute::Depth).unwrap();
        let motion = splatter.read(ctx(), &targets, Attribute::Motion).unwrap();
        let mesh_depth = raster::depth(mesh, pose, cam);
        let (w, h) = (cam.width, cam.height);
        let covered = |x: u32, y: u32| !mesh_depth[(y * w + x) as usize].is_nan();
        let (mut inter, mut union) = (0usize, 0usize);
        let mut dz = Vec::new();
        let mut dl = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let (s, mv) = (depth.is_valid(x, y), covered(x, y));
                inter += (s && mv) as usize;
                union += (s || mv) as usize;
                if !s || x < 2 || y < 2 || x + 2 >= w || y + 2 >= h {
                    continue;
                }
                let interior = (-2..=2i32).all(|j| {
                    (-2..=2i32).all(|i| covered((x as i32 + i) as u32, (y as i32 + j) as u32))
                });
                if !interior {
                    continue;
                }
                let zm = mesh_depth[(y * w + x) as usize] as f64;
                dz.push((depth.pixel(x, y)[0] as f64 - zm).abs() / diameter);
                let xc = cam.unproject(&Vector2::new(x as f64, y as f64), zm);
                let l = cam.motion_predictors(&xc);
                let mp = motion.pixel(x, y);
                let err: f64 = (0..6)
                    .flat_map(|j| (0..2).map(move |r| (j, r)))
                    .map(|(j, r)| (mp[2 * j + r] as f64 - l[(r, j)]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                dl.push(err / l.norm());
            }
        }
        assert!(
            dz.len() > 1000,
            "{label} pose {k}: only {} interior pixels",
            dz.len()
        );
        let f = Figures {
            iou: inter as f64 / union as f64,
            depth_median: percentile(&mut dz, 0.5),
            depth_p99: percentile(&mut dz, 0.99),
            motion_median: percentile(&mut dl, 0.5),
            motion_p95: percentile(&mut dl, 0.95),
        };
        eprintln!(
            "{label} pose {k}: IoU {:.4}, depth/diameter median {:.3}% p99 {:.3}%, predictors median {:.3}% p95 {:.3}% ({} px)",
            f.iou,
            100.0 * f.depth_median,
            100.0 * f.depth_p99,
            100.0 * f.motion_median,
            100.0 * f.motion_p95,
            dz.len()
        );
        assert!(f.iou >= 0.97, "{label} pose {k}: IoU {}", f.iou);
        assert!(f.depth_median <= 0.002, "{label} pose {k}");
        assert!(f.depth_p99 <= 0.015, "{label} pose {k}");
        assert!(f.motion_median <= 0.01, "{label} pose {k}");
        assert!(f.motion_p95 <= 0.05, "{label} pose {k}");
    }
}

fn camera() -> Intrinsics {
    Intrinsics::new(640, 480, 600.0, 602.0, 318.7, 241.2)
}

fn poses(target: Vector3<f64>, dist: f64, count: usize) -> Vec<Pose> {
    (0..count)
        .map(|i| {
            let a = 2.1 * i as f64 + 0.4;
            let eye =
                target + Vector3::new(a.cos(), a.sin(), 0.6 - 0.5 * i as f64).normalize() * dist;
            look_at(&eye, &target, &Vector3::new(0.0, 0.0, 1.0))
        })
        .collect()
}

#[test]
fn splatted_sphere_matches_its_mesh() {
    let mesh = TriangleMesh::sphere(0.5, 48, 96);
    compare(
        &mesh,
        150_000,
        1.0,
        &camera(),
        &poses(Vector3::zeros(), 2.0, 3),
        "sphere",
    );
}

#[test]
fn splatted_box_matches_its_mesh() {
    let mesh = TriangleMesh::cuboid(DVec3::new(0.5, 0.35, 0.25), 8);
    let diameter = 2.0 * Vector3::new(0.5, 0.35, 0.25).norm();
    compare(
        &mesh,
        300_000,
        diameter,
        &camera(),
        &poses(Vector3::zeros(), 2.2, 3),
        "box",
    );
}

#[test]
fn splatted_torus_matches_its_mesh() {
    let mesh = TriangleMesh::torus(0.45, 0.18, 96, 48);
    compare(
        &mesh,
        200_000,
        2.0 * 0.63,
        &camera(),
        &poses(Vector3::zeros(), 2.2, 3),
        "torus",
    );
}
