//! The host splatter's level of detail (`HostSplatter::set_thinning`:
//! every n-th splat, radii grown by sqrt(n)) against an independent
//! triangle rasterisation of the mesh the points were sampled from (synth's
//! CPU rasteriser, as in tests/splat_mesh.rs), at 640x480 with many splats
//! a pixel: a box of 1M points (about 25 splats a pixel) and a sphere of
//! 100k points filling the image (about 3 a pixel), thinned 1, 2, 4 and 8
//! times.
//!
//! Criteria, at every level (pixels "away from silhouettes": the mesh
//! covers the whole 5x5 neighbourhood and the splats the pixel itself):
//! silhouette IoU (splat coverage vs mesh coverage) >= 0.97; depth error
//! median <= 0.2% and 99th percentile <= 1.5% of the object's diameter.
//! Printed with `--nocapture`: the figures, the change of coverage against
//! the full model, and the render's time against the full model's (colour
//! and predictors, median of 3).

use glam::DVec3;
use nalgebra::Vector3;
use splattrack::geometry::{Intrinsics, Pose, look_at};
use splattrack::model::{AttributeSource, TriangleMesh};
use splattrack::splat::cpu::{Accumulators, HostSplatter};
use splattrack::splat::{Attribute, Attributes, ModelBounds, SplatParams, pack_model};
use splattrack::synth::raster;
use std::time::Instant;

fn percentile(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[((v.len() - 1) as f64 * p).round() as usize]
}

fn camera() -> Intrinsics {
    Intrinsics::new(640, 480, 600.0, 602.0, 318.7, 241.2)
}

fn median_ms(mut f: impl FnMut()) -> f64 {
    let mut ms: Vec<f64> = (0..3)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    percentile(&mut ms, 0.5)
}

fn compare(mesh: &TriangleMesh, n: usize, diameter: f64, pose: &Pose, label: &str) {
    // Splat radius 2 sqrt(area / n): about 2 closes the surface.
    let mut model = mesh.sample(n, 17).unwrap();
    let r = 2.0 * (mesh.area() / n as f64).sqrt();
    model.radii.fill(r as f32);
    model.provenance.radii = AttributeSource::Estimated;
    let cam = camera();
    let params = SplatParams::default();
    let packed = pack_model(&model, &params).unwrap();
    let uniform = ModelBounds::of(&model).view(&cam, pose, &params).unwrap();
    let mesh_depth = raster::depth(mesh, pose, &cam);
    let (w, h) = (cam.width, cam.height);
    let covered = |x: u32, y: u32| !mesh_depth[(y * w + x) as usize].is_nan();
    let mut host = HostSplatter::new();
    let mut out = Accumulators::default();
    let (mut full_cover, mut full_ms) = (0usize, 0.0);
    for step in [1, 2, 4, 8] {
        host.set_thinning(step);
        assert_eq!(host.thinning(), step);
        host.render(&packed, &uniform, Attributes::ALL, &mut out);
        let depth = out.resolve(Attribute::Depth);
        let (mut inter, mut union, mut cover) = (0usize, 0usize, 0usize);
        let mut dz = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let (s, mv) = (depth.is_valid(x, y), covered(x, y));
                inter += (s && mv) as usize;
                union += (s || mv) as usize;
                cover += s as usize;
                if !s || x < 2 || y < 2 || x + 2 >= w || y + 2 >= h {
                    continue;
                }
                let interior = (-2..=2i32).all(|j| {
                    (-2..=2i32).all(|i| covered((x as i32 + i) as u32, (y as i32 + j) as u32))
                });
                if interior {
                    let zm = mesh_depth[(y * w + x) as usize] as f64;
                    dz.push((depth.pixel(x, y)[0] as f64 - zm).abs() / diameter);
                }
            }
        }
        assert!(
            dz.len() > 1000,
            "{label}: only {} interior pixels",
            dz.len()
        );
        let ms = median_ms(|| host.render(&packed, &uniform, Attributes::MOTION, &mut out));
        if step == 1 {
            (full_cover, full_ms) = (cover, ms);
        }
        let iou = inter as f64 / union as f64;
        let (median, p99) = (percentile(&mut dz, 0.5), percentile(&mut dz, 0.99));
        eprintln!(
            "{label}, 1 splat in {step}: IoU {iou:.4}, depth/diameter median {:.3}% p99 {:.3}%, \
             coverage {:+.2}% of the full model's, colour+predictors {ms:.1} ms ({:.2}x faster)",
            100.0 * median,
            100.0 * p99,
            100.0 * (cover as f64 / full_cover as f64 - 1.0),
            full_ms / ms,
        );
        assert!(iou >= 0.97, "{label}, step {step}: IoU {iou}");
        assert!(median <= 0.002, "{label}, step {step}: median {median}");
        assert!(p99 <= 0.015, "{label}, step {step}: p99 {p99}");
    }
}

#[test]
fn thinned_box_of_1m_points_matches_its_mesh() {
    let half = DVec3::new(0.5, 0.35, 0.25);
    let mesh = TriangleMesh::cuboid(half, 8);
    let eye = Vector3::new(1.3, -1.1, 1.2);
    let pose = look_at(&eye, &Vector3::zeros(), &Vector3::new(0.0, 0.0, 1.0));
    let diameter = 2.0 * Vector3::new(half.x, half.y, half.z).norm();
    compare(&mesh, 1_000_000, diameter, &pose, "box 1M");
}

#[test]
fn thinned_sphere_filling_the_image_matches_its_mesh() {
    let mesh = TriangleMesh::sphere(0.5, 48, 96);
    let eye = Vector3::new(0.0, 0.0, -0.75);
    let pose = look_at(&eye, &Vector3::zeros(), &Vector3::new(0.0, -1.0, 0.0));
    compare(&mesh, 100_000, 1.0, &pose, "sphere 100k filling");
}
