//! The robust pose update (IRLS, `pose::irls`, on the host) for 100, 900
//! and 3000 matches with 20% outliers: the per-frame cost of the paper's
//! eq. 7 once the predictors are gathered. There is no GPU version (a 6x6
//! system per iteration; the matches' predictors are read back as 14 floats
//! each), so no GPU/CPU ratio.
//!
//! `cargo bench --bench pose` (ids `irls/MATCHES`).
//!
//! Also the contour's line search (`tracker::contour::search_line`, on
//! the host in every back end): 160 lines (a frame's contour points at a
//! 4 px spacing) across a disc's noisy outline, at the half-lengths the
//! contour step uses (ids `contour_lines/HALF`; one thread), and the
//! learning of its colour statistics from a 320 x 320 frame
//! (`contour_lines/learn_320x320_8_sectors`).
//!
//! And PnP (`pose::solve_pnp_ransac`): 50, 200 and 1000 correspondences of
//! a non-planar object at about 0.5 m with 0.5 px noise and half of them
//! outliers, RANSAC to 0.999 confidence then the refinement (ids
//! `pnp_ransac/N`); `pnp/8` is `solve_pnp` on 8 exact-ish points (the
//! `init` command's case).

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Vector2, Vector3, Vector6};
use splattrack::geometry::Intrinsics;
use splattrack::geometry::{Pose, rotation_exp};
use splattrack::pose::{
    IrlsConfig, Observation, PnpRansacOptions, irls, solve_pnp, solve_pnp_ransac,
};
use splattrack::rng::Rng;
use splattrack::tracker::contour::{ColourModel, search_line};
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

/// The disc of [`disc_lines`]: centre and radius, pixels.
const DISC: ([f64; 2], f64) = ([160.3, 159.7], 100.0);

/// A yellow disc ([`DISC`]) on a noisy two-tone background, with its
/// colours learnt, and its coverage.
fn disc_frame() -> (image::RgbImage, ColourModel, Vec<bool>) {
    let (w, h) = (320u32, 320u32);
    let mut rng = Rng::new(7);
    let (centre, r) = (Vector2::from(DISC.0), DISC.1);
    let mut frame = image::RgbImage::new(w, h);
    let mut coverage = vec![false; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let d = (Vector2::new(x as f64, y as f64) - centre).norm();
            // The pixel's share of the disc, across one pixel.
            let a = (r + 0.5 - d).clamp(0.0, 1.0);
            let bg = if (x / 16 + y / 16) % 2 == 0 {
                [60.0, 90.0, 140.0]
            } else {
                [120.0, 40.0, 60.0]
            };
            let fg = [220.0, 200.0, 40.0];
            let mut c = [0u8; 3];
            for k in 0..3 {
                let v = a * fg[k] + (1.0 - a) * bg[k] + rng.normal() * 6.0;
                c[k] = v.round().clamp(0.0, 255.0) as u8;
            }
            frame.put_pixel(x, y, image::Rgb(c));
            coverage[(y * w + x) as usize] = d <= r;
        }
    }
    let mut colours = ColourModel::new(16);
    colours.learn(
        &frame,
        &coverage,
        (0, 0, w as usize - 1, h as usize - 1),
        2,
        1.0,
    );
    (frame, colours, coverage)
}

/// 160 lines across [`DISC`]'s outline (start, outward normal), each
/// started off it by a fraction in [-0.4, 0.4] of `half`.
fn disc_lines(half: f32) -> Vec<(Vector2<f64>, Vector2<f64>)> {
    let mut rng = Rng::new(8);
    let (centre, r) = (Vector2::from(DISC.0), DISC.1);
    (0..160)
        .map(|i| {
            let t = i as f64 / 160.0 * std::f64::consts::TAU;
            let n = Vector2::new(t.cos(), t.sin());
            (centre + n * (r + rng.uniform(-0.4, 0.4) * half as f64), n)
        })
        .collect()
}

fn bench_lines(c: &mut Criterion) {
    let mut group = c.benchmark_group("contour_lines");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    let (frame, colours, coverage) = disc_frame();
    // Learning a frame's colours, the whole object's and 8 sectors', over
    // the whole 320 x 320 frame (the contour step learns over its window
    // after every tracked frame).
    let mut sectors = ColourModel::with_sectors(16, 8);
    let rect = (
        0,
        0,
        frame.width() as usize - 1,
        frame.height() as usize - 1,
    );
    let centre = Some(Vector2::from(DISC.0));
    sectors.learn_around(&frame, &coverage, rect, 2, 1.0, centre);
    assert!((0..8).all(|k| sectors.sector_learned(k)));
    group.bench_function("learn_320x320_8_sectors", |b| {
        b.iter(|| sectors.learn_around(&frame, &coverage, rect, 2, 0.1, centre))
    });
    for half in [32.0f32, 16.0, 5.0] {
        let lines = disc_lines(half);
        let found = lines
            .iter()
            .filter(|(p, n)| search_line(&frame, &colours, *p, *n, half, 1.0).is_some())
            .count();
        assert!(
            found > 150,
            "the benchmark's lines must find the outline ({found})"
        );
        group.bench_function(format!("{half}"), |b| {
            b.iter(|| {
                lines
                    .iter()
                    .filter_map(|(p, n)| search_line(&frame, &colours, *p, *n, half, 1.0))
                    .sum::<f64>()
            })
        });
    }
    group.finish();
}

/// `n` model points in a 0.2 m cube, their pixels at a fixed pose with
/// 0.5 px noise, every other one replaced by a random pixel.
fn pnp_problem(n: usize, outliers: bool) -> (Vec<Vector3<f64>>, Vec<Vector2<f64>>, Intrinsics) {
    let cam = Intrinsics::new(640, 480, 600.0, 600.0, 319.5, 239.5);
    let pose = Pose {
        rotation: rotation_exp(&Vector3::new(0.4, -0.3, 0.2)),
        translation: Vector3::new(0.01, -0.02, 0.5),
    };
    let mut rng = Rng::new(n as u64);
    let mut pts = Vec::new();
    let mut pix = Vec::new();
    for i in 0..n {
        let p = Vector3::new(
            rng.uniform(-0.1, 0.1),
            rng.uniform(-0.1, 0.1),
            rng.uniform(-0.1, 0.1),
        );
        let q = cam.project(&pose.transform_point(&p)).unwrap()
            + Vector2::new(rng.normal(), rng.normal()) * 0.5;
        let q = if outliers && i % 2 == 0 {
            Vector2::new(rng.uniform(0.0, 640.0), rng.uniform(0.0, 480.0))
        } else {
            q
        };
        pts.push(p);
        pix.push(q);
    }
    (pts, pix, cam)
}

fn bench_pnp(c: &mut Criterion) {
    let mut group = c.benchmark_group("pnp_ransac");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(2));
    let opts = PnpRansacOptions::default();
    for n in [50usize, 200, 1000] {
        let (pts, pix, cam) = pnp_problem(n, true);
        let s = solve_pnp_ransac(&pts, &pix, &cam, &opts).expect("the problem must solve");
        assert!(s.inliers.len() >= n / 2 - 2, "{}", s.inliers.len());
        group.bench_function(format!("{n}"), |b| {
            b.iter(|| black_box(solve_pnp_ransac(black_box(&pts), &pix, &cam, &opts).unwrap()))
        });
    }
    group.finish();
    let mut group = c.benchmark_group("pnp");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    let (pts, pix, cam) = pnp_problem(8, false);
    group.bench_function("8", |b| {
        b.iter(|| black_box(solve_pnp(black_box(&pts), &pix, &cam).unwrap()))
    });
    group.finish();
}

criterion_group!(benches, bench, bench_lines, bench_pnp);
criterion_main!(benches);
