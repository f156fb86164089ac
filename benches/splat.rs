//! Splatting throughput at 640x480: colour only (novel views) and colour +
//! depth/normal + motion predictors (the tracker's pass), for sphere models
//! of 10k, 100k and 1M points on whichever adapter is present
//! (`SPLATTRACK_ADAPTER`), plus the CPU reference at 10k for the CPU/GPU
//! ratio. Wall time per render (submit + wait) by criterion; GPU time per
//! pass from timestamp queries, printed as medians of 5 renders.
//!
//! `cargo bench --bench splat`

use criterion::{Criterion, criterion_group, criterion_main};
use glam::Vec3;
use nalgebra::Vector3;
use splattrack::geometry::{Intrinsics, look_at};
use splattrack::gpu::{GpuContext, GpuTimer};
use splattrack::model::shapes;
use splattrack::splat::{Attributes, GpuModel, SplatParams, SplatTargets, Splatter, cpu};
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let ctx = GpuContext::from_env().expect("a GPU adapter (lavapipe will do)");
    eprintln!("adapter: {}", ctx.describe());
    let cam = Intrinsics::new(640, 480, 600.0, 600.0, 319.5, 239.5);
    let pose = look_at(
        &Vector3::new(0.3, -0.4, -1.9),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let splatter = Splatter::new(&ctx).unwrap();
    let mut targets = SplatTargets::new(&ctx, cam.width, cam.height);
    let mut group = c.benchmark_group("splat_640x480");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for n in [10_000usize, 100_000, 1_000_000] {
        let model = shapes::sphere(Vec3::ZERO, 0.5, n, 1.2);
        let gm = GpuModel::new(&ctx, &model).unwrap();
        for (name, attrs) in [
            ("color", Attributes::COLOR),
            ("color+predictors", Attributes::ALL),
        ] {
            let mut timer = GpuTimer::new(&ctx, 2);
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
                "gpu timestamps {name} n={n}: visibility {v:.2} ms, attributes {a:.2} ms (median of 5)"
            );
            group.bench_function(format!("{name}/{n}"), |b| {
                b.iter(|| {
                    splatter
                        .render(&ctx, &gm, &cam, &pose, attrs, &mut targets)
                        .unwrap();
                    ctx.wait().unwrap();
                })
            });
        }
    }
    let model = shapes::sphere(Vec3::ZERO, 0.5, 10_000, 1.2);
    group.bench_function("cpu_reference/10000", |b| {
        b.iter(|| cpu::splat(&model, &cam, &pose, &SplatParams::default()).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
