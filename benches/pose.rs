//! The robust pose update (IRLS, `pose::irls`, on the host) for 100, 900
//! and 3000 matches with 20% outliers: the per-frame cost of the paper's
//! eq. 7 once the predictors are gathered. There is no GPU version (a 6x6
//! system per iteration; the matches' predictors are read back as 14 floats
//! each), so no GPU/CPU ratio.
//!
//! `cargo bench --bench pose` (ids `irls/MATCHES`).

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Vector2, Vector3, Vector6};
use splattrack::geometry::Intrinsics;
use splattrack::pose::{IrlsConfig, Observation, irls};
use splattrack::rng::Rng;
use std::hint::black_box;
use std::time::Duration;

/// Matches on a surface at about 0.5 m in front of a 640x480 camera, moved
/// by a small twist, with 0.3 px noise and 20% gross outliers.
fn observations(n: usize, seed: u64) -> Vec<Observation> {
    let cam = Intrinsics::new(640, 480, 600.0, 600.0, 319.5, 239.5);
    let twist = Vector6::new(0.002, -0.001, 0.004, 0.01, -0.008, 0.005);
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|i| {
            let x = Vector3::new(
                rng.uniform(-0.1, 0.1),
                rng.uniform(-0.08, 0.08),
                rng.uniform(0.45, 0.55),
            );
            let l = cam.motion_predictors(&x);
            let mut d = l * twist + Vector2::new(rng.normal() * 0.3, rng.normal() * 0.3);
            if i % 5 == 0 {
                d += Vector2::new(rng.uniform(-30.0, 30.0), rng.uniform(-30.0, 30.0));
            }
            Observation {
                predictors: l,
                displacement: d,
            }
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("irls");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    let cfg = IrlsConfig::default();
    for n in [100usize, 900, 3000] {
        let obs = observations(n, n as u64);
        assert!(
            irls(&obs, &cfg).is_ok(),
            "the benchmark's problem must solve"
        );
        group.bench_function(format!("{n}"), |b| {
            b.iter(|| black_box(irls(black_box(&obs), &cfg).unwrap()))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
