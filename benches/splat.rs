//! Splatting time per render, both back ends (`render`: the render pass,
//! `compute`: the compute shader with atomics), colour only (novel views)
//! and colour + depth/normal + motion predictors (the tracker's render),
//! for sphere models of 10k and 100k points (and 1M with
//! `SPLATTRACK_BENCH_1M=1`) at 640x480 and 1280x720, on whichever adapter
//! is present (`SPLATTRACK_ADAPTER`). Wall time per render (submit +
//! wait) by criterion; GPU time per pass from timestamp queries (median of
//! 5), printed when the adapter has them.
//!
//! The host splatter (`splat_cpu`, no GPU needed, run first): the same
//! spheres on 1 and 2 threads (`cpu1`, `cpu2`), the sphere filling the
//! image, and the real cube (`SPLATTRACK_DATA`'s visp_rbt_cube at its
//! initial pose, in its window as the tracker renders it).
//!
//! `cargo bench --bench splat` (ids `splat/BACKEND/ATTRS/WxH/POINTS`,
//! `splat_cpu/cpuTHREADS/ATTRS/SCENE`; `cargo bench --bench splat --
//! splat_cpu` runs the host splatter alone; `cargo run --release --example
//! bench_report` tabulates the medians).

use criterion::{Criterion, criterion_group, criterion_main};
use glam::Vec3;
use nalgebra::Vector3;
use splattrack::geometry::{Intrinsics, Pose, look_at};
use splattrack::gpu::{GpuContext, GpuTimer};
use splattrack::model::PointModel;
use splattrack::model::shapes;
use splattrack::splat::cpu::{Accumulators, HostSplatter};
use splattrack::splat::{
    Attributes, Backend, GpuModel, ModelBounds, SplatParams, SplatTargets, Splatter, Window,
    pack_model,
};
use std::time::Duration;

/// Model sizes: 10k and 100k, plus 1M when `SPLATTRACK_BENCH_1M` is set
/// (about 1.5 s per render on lavapipe).
fn model_sizes() -> Vec<usize> {
    let mut n = vec![10_000, 100_000];
    if std::env::var("SPLATTRACK_BENCH_1M").is_ok_and(|v| v != "0") {
        n.push(1_000_000);
    }
    n
}

fn bench(c: &mut Criterion) {
    let ctx = GpuContext::from_env().expect("a GPU adapter (lavapipe will do)");
    eprintln!("adapter: {}", ctx.describe());
    let pose = look_at(
        &Vector3::new(0.3, -0.4, -1.9),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let mut group = c.benchmark_group("splat");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(2));
    let sizes = model_sizes();
    let models: Vec<_> = sizes
        .iter()
        .map(|&n| (n, shapes::sphere(Vec3::ZERO, 0.5, n, 1.2)))
        .collect();
    for (w, h) in [(640u32, 480u32), (1280, 720)] {
        // The same field of view at both sizes.
        let f = 600.0 * w as f64 / 640.0;
        let cam = Intrinsics::new(w, h, f, f, (w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
        let mut targets = SplatTargets::new(&ctx, w, h);
        for backend in [Backend::RenderPass, Backend::Compute] {
            let params = SplatParams {
                backend,
                ..Default::default()
            };
            let splatter = Splatter::with_params(&ctx, params).unwrap();
            for (n, model) in &models {
                let gm = GpuModel::new(&ctx, model).unwrap();
                if backend == Backend::Compute {
                    // After a render, so the compute scratch is counted.
                    splatter
                        .render(&ctx, &gm, &cam, &pose, Attributes::ALL, &mut targets)
                        .unwrap();
                    let mb = |b: u64| b as f64 / (1u64 << 20) as f64;
                    eprintln!(
                        "gpu memory n={n} {w}x{h}: model {:.1} MB, one set of targets with the compute scratch {:.1} MB; median splat radius {:.2} px; auto renders with {}",
                        mb(gm.gpu_bytes()),
                        mb(targets.gpu_bytes()),
                        cam.fx * gm.bounds.median_splat_radius / pose.translation.norm(),
                        Splatter::new(&ctx).unwrap().backend_for(&gm, &cam, &pose)
                    );
                }
                for (name, attrs) in [
                    ("color", Attributes::COLOR),
                    ("predictors", Attributes::MOTION),
                    ("color+predictors", Attributes::ALL),
                ] {
                    let mut timer = GpuTimer::new(&ctx, 2);
                    if timer.enabled() {
                        let mut runs = Vec::new();
                        for _ in 0..5 {
                            splatter
                                .render_timed(
                                    &ctx,
                                    &gm,
                                    &cam,
                                    &pose,
                                    attrs,
                                    &mut targets,
                                    Some(&mut timer),
                                )
                                .unwrap();
                            let r = timer.read(&ctx).unwrap();
                            runs.push((
                                r.get("visibility").unwrap_or(f64::NAN),
                                r.get("attributes").unwrap_or(f64::NAN),
                            ));
                        }
                        runs.sort_by(|a, b| (a.0 + a.1).total_cmp(&(b.0 + b.1)));
                        let (v, a) = runs[2];
                        eprintln!(
                            "gpu timestamps {backend} {name} {w}x{h} n={n}: visibility {v:.3} ms, attributes {a:.3} ms (median of 5)"
                        );
                    }
                    group.bench_function(format!("{backend}/{name}/{w}x{h}/{n}"), |b| {
                        b.iter(|| {
                            splatter
                                .render(&ctx, &gm, &cam, &pose, attrs, &mut targets)
                                .unwrap();
                            ctx.wait().unwrap();
                        })
                    });
                }
            }
        }
    }
    group.finish();
}

/// The camera of the spheres: the same field of view at every size.
fn sphere_camera(w: u32, h: u32) -> Intrinsics {
    let f = 600.0 * w as f64 / 640.0;
    Intrinsics::new(w, h, f, f, (w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0)
}

/// The real cube at its initial pose, in the window the tracker renders
/// it into (its grown bounding box's projection, 16 px of margin), or
/// `None` without `SPLATTRACK_DATA`.
fn real_cube() -> Option<(PointModel, Intrinsics, Pose)> {
    let root = std::path::PathBuf::from(std::env::var_os("SPLATTRACK_DATA")?);
    let dir = root.join("visp_rbt_cube");
    let model = PointModel::load(dir.join("model.ply")).expect("the cube's model");
    let cam = Intrinsics::load(&dir.join("camera.json")).expect("the cube's camera");
    let pose = splattrack::io::read_poses(&dir.join("init.csv")).expect("init.csv")[0].pose;
    let pad = model.radii.iter().fold(0.0f64, |m, &r| m.max(r as f64));
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        -Vector3::repeat(f64::INFINITY),
    );
    for p in &model.positions {
        let p = Vector3::new(p.x as f64, p.y as f64, p.z as f64);
        (lo, hi) = (lo.inf(&p), hi.sup(&p));
    }
    let pad = Vector3::repeat(pad);
    let win = Window::of_box(&cam, &pose, &(lo - pad), &(hi + pad), 16.0, 8).expect("in view");
    eprintln!("real cube: window {}x{}", win.width, win.height);
    Some((model, win.camera(&cam), pose))
}

fn bench_cpu(c: &mut Criterion) {
    let mut group = c.benchmark_group("splat_cpu");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(2));
    let mut scenes: Vec<(String, PointModel, Intrinsics, Pose)> = Vec::new();
    if let Some((model, cam, pose)) = real_cube() {
        scenes.push(("cube-window".into(), model, cam, pose));
    }
    let far = look_at(
        &Vector3::new(0.3, -0.4, -1.9),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    // Near enough for the sphere to cover the whole 640x480 image.
    let near = look_at(
        &Vector3::new(0.0, 0.0, -0.75),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let sizes = model_sizes();
    for &n in &sizes {
        let model = shapes::sphere(Vec3::ZERO, 0.5, n, 1.2);
        for (w, h) in [(640u32, 480u32), (1280, 720)] {
            scenes.push((
                format!("{w}x{h}/{n}"),
                model.clone(),
                sphere_camera(w, h),
                far,
            ));
        }
        if n == 100_000 {
            scenes.push((
                format!("fill-640x480/{n}"),
                model,
                sphere_camera(640, 480),
                near,
            ));
        }
    }
    let params = SplatParams::default();
    for (name, model, cam, pose) in &scenes {
        let packed = pack_model(model, &params).unwrap();
        let uniform = ModelBounds::of(model).view(cam, pose, &params).unwrap();
        for threads in [1, 2] {
            let mut splatter = HostSplatter::with_threads(threads);
            let mut out = Accumulators::default();
            for (attrs_name, attrs) in [
                ("color", Attributes::COLOR),
                ("color+predictors", Attributes::MOTION),
            ] {
                group.bench_function(format!("cpu{threads}/{attrs_name}/{name}"), |b| {
                    b.iter(|| splatter.render(&packed, &uniform, attrs, &mut out))
                });
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench_cpu, bench);
criterion_main!(benches);
