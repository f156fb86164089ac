//! Holes in splatted views: pixels inside the object
//! that no splat covers. The object's extent comes from synth's CPU triangle
//! rasteriser of the mesh the points were sampled from (never from the
//! splatter under test): a pixel is *interior* when the mesh covers its whole
//! 5x5 neighbourhood, and an interior pixel with no splat weight is a hole.
//! Silhouettes must stay tight: the splat coverage against the mesh
//! coverage (IoU) may not drop when radii grow.
//!
//! - CI: a box whose points are sampled at random (Poisson, as scanners and
//!   photogrammetry give them, not the stratified sampling of
//!   `TriangleMesh::sample`) with radii of half the mean spacing leaves
//!   holes; after [`PointModel::close_gaps`] it has none, and its IoU is
//!   within 0.01 of the same points with generous radii. A stratified
//!   sampling with the default radii comes out unchanged.
//! - `#[ignore]`: the shared ViSP cube and dragon models at their
//!   ground-truth poses, radii as in the file, with the tracker's 1 px
//!   floor, and closed (`cargo test --release --test splat_holes --
//!   --ignored --nocapture`).

mod tracking_common;

use glam::DVec3;
use nalgebra::Vector3;
use splattrack::geometry::{Intrinsics, Pose, look_at};
use splattrack::gpu::{self, GpuContext};
use splattrack::model::{GAP_MODEL_FRACTION, PointModel, TriangleMesh};
use splattrack::splat::{Attribute, Attributes, GpuModel, SplatTargets, Splatter};
use splattrack::synth::raster;
use tracking_common::random_sample;

fn ctx() -> &'static GpuContext {
    gpu::shared_test_context()
}

#[derive(Debug, Clone, Copy)]
struct Holes {
    /// Interior pixels without splat weight.
    holes: usize,
    interior: usize,
    iou: f64,
}

fn holes(model: &PointModel, mesh: &TriangleMesh, cam: &Intrinsics, pose: &Pose) -> Holes {
    let splatter = Splatter::new(ctx()).unwrap();
    let gm = GpuModel::new(ctx(), model).unwrap();
    let mut targets = SplatTargets::new(ctx(), cam.width, cam.height);
    splatter
        .render(ctx(), &gm, cam, pose, Attributes::COLOR, &mut targets)
        .unwrap();
    let weight = splatter.read(ctx(), &targets, Attribute::Weight).unwrap();
    let mesh_depth = raster::depth(mesh, pose, cam);
    let (w, h) = (cam.width as i32, cam.height as i32);
    let covered = |x: i32, y: i32| !mesh_depth[(y * w + x) as usize].is_nan();
    let splat = |x: i32, y: i32| weight.pixel(x as u32, y as u32)[0] > 0.0;
    let (mut holes, mut interior, mut inter, mut union) = (0, 0, 0usize, 0usize);
    for y in 0..h {
        for x in 0..w {
            let (s, m) = (splat(x, y), covered(x, y));
            inter += (s && m) as usize;
            union += (s || m) as usize;
            if x < 2 || y < 2 || x + 2 >= w || y + 2 >= h {
                continue;
            }
            if (-2..=2).all(|j| (-2..=2).all(|i| covered(x + i, y + j))) {
                interior += 1;
                holes += !s as usize;
            }
        }
    }
    Holes {
        holes,
        interior,
        iou: inter as f64 / union.max(1) as f64,
    }
}

fn closed(model: &PointModel) -> PointModel {
    let mut m = model.clone();
    let c = m.close_gaps().unwrap();
    eprintln!(
        "close_gaps: {} of {} radii grown, mean {:.4} -> {:.4}",
        c.grown, c.points, c.mean_before, c.mean_after
    );
    m
}

#[test]
fn random_box_with_gapped_radii_renders_without_holes_once_closed() {
    let cam = Intrinsics::new(320, 240, 300.0, 300.0, 159.5, 119.5);
    let half = DVec3::new(0.5, 0.35, 0.25);
    let mesh = TriangleMesh::cuboid(half, 4);
    let n = 20_000;
    // Mean spacing sqrt(area / n): about 1.7 px at this distance.
    let spacing = (mesh.area() / n as f64).sqrt() as f32;
    let gapped = random_sample(&mesh, n, 0.5 * spacing, 5);
    let mut generous = gapped.clone();
    generous.radii.fill(1.5 * spacing);
    let fixed = closed(&gapped);
    for (k, a) in [0.4f64, 2.5, 4.6].into_iter().enumerate() {
        let eye = Vector3::new(a.cos(), a.sin(), 0.7).normalize() * 2.2;
        let pose = look_at(&eye, &Vector3::zeros(), &Vector3::new(0.0, 0.0, 1.0));
        let before = holes(&gapped, &mesh, &cam, &pose);
        let after = holes(&fixed, &mesh, &cam, &pose);
        let reference = holes(&generous, &mesh, &cam, &pose);
        eprintln!(
            "pose {k}: gapped {before:?}, closed {after:?}, radii 1.5x spacing {reference:?}"
        );
        assert!(after.interior > 10_000, "pose {k}: {after:?}");
        assert!(
            before.holes * 20 > before.interior,
            "pose {k}: the gapped model should leave holes: {before:?}"
        );
        // Measured: 5119 -> 5 holes at pose 0 (radii of 1.5 spacings
        // everywhere leave 17): the last few sit along the creases.
        assert!(after.holes * 1000 <= after.interior, "pose {k}: {after:?}");
        assert!(
            after.holes <= reference.holes,
            "pose {k}: {after:?} against {reference:?}"
        );
        assert!(
            after.iou >= reference.iou - 0.01,
            "pose {k}: silhouette {after:?} against {reference:?}"
        );
    }
}

#[test]
fn stratified_samplings_with_default_radii_come_out_nearly_unchanged() {
    // TriangleMesh::sample (R2 sequence, radii of MESH_RADIUS_FACTOR), as
    // the synthetic objects of tests/synth_accuracy.rs and the demo are
    // sampled (60k points for the blob there, 100k by default).
    use splattrack::synth::{SynthObject, sequence::sample_model};
    for (name, n) in [
        ("blob", 60_000),
        ("box", 60_000),
        ("torus", 60_000),
        ("plain", 60_000),
    ] {
        let object = SynthObject::by_name(name).unwrap();
        let mut m = sample_model(&object, n, 1).unwrap();
        let c = m.close_gaps().unwrap();
        eprintln!(
            "{name}: {} of {} grown, mean radius {:+.3}%",
            c.grown,
            c.points,
            100.0 * (c.mean_after / c.mean_before - 1.0)
        );
        // Measured: 3% (blob) to 6% (box, along its creases) of the radii
        // grow, the mean radius by 0.2% to 0.6%: below the tracker's gate,
        // so it keeps these radii.
        assert!(
            (c.grown as f64) < GAP_MODEL_FRACTION * c.points as f64
                && c.mean_after <= 1.01 * c.mean_before,
            "{name}: {c:?}"
        );
    }
}

/// The shared real models at their ground-truth poses (frames 0, 43, 98).
#[test]
#[ignore = "reads the real data (SPLATTRACK_DATA); prints the figures of the docs"]
fn shared_models_at_ground_truth() {
    let Some(root) = tracking_common::data_common::real_data("") else {
        return;
    };
    for name in ["visp_rbt_cube", "visp_rbt_dragon"] {
        let dir = root.join(name);
        let cam = Intrinsics::load(&dir.join("camera.json")).unwrap();
        let model = PointModel::load(dir.join("model.ply")).unwrap();
        let mesh = TriangleMesh::load_obj(dir.join("mesh.obj")).unwrap();
        let poses = splattrack::io::read_poses(&dir.join("poses.csv")).unwrap();
        // The tracker's 1 px floor at the object's distance in frame 0,
        // then close_gaps, as Tracker::new does.
        let z0 = poses[0].pose.transform_point(&Vector3::zeros()).z;
        let mut floored = model.clone();
        let floor = (z0 / cam.fx.max(cam.fy)) as f32;
        floored.radii.iter_mut().for_each(|r| *r = r.max(floor));
        let t = std::time::Instant::now();
        let fixed = closed(&floored);
        eprintln!("{name}: close_gaps took {:.2} s", t.elapsed().as_secs_f64());
        let alone = closed(&model);
        let mean = |m: &PointModel| m.radii.iter().map(|&r| r as f64).sum::<f64>() / m.len() as f64;
        eprintln!(
            "{name}: mean radius {:.4} mm in the file, {:.4} closed; {:.4} with the floor, {:.4} floor + closed",
            1e3 * mean(&model),
            1e3 * mean(&alone),
            1e3 * mean(&floored),
            1e3 * mean(&fixed),
        );
        for frame in [0usize, 43, 98] {
            let pose = poses[frame].pose;
            let a = holes(&model, &mesh, &cam, &pose);
            let b = holes(&alone, &mesh, &cam, &pose);
            let c = holes(&floored, &mesh, &cam, &pose);
            let d = holes(&fixed, &mesh, &cam, &pose);
            eprintln!(
                "{name} frame {frame} ({} interior px): file radii {} holes (IoU {:.4}); closed {} ({:.4}); \
                 1 px floor {} ({:.4}); floor + closed {} ({:.4})",
                a.interior, a.holes, a.iou, b.holes, b.iou, c.holes, c.iou, d.holes, d.iou
            );
        }
    }
}
