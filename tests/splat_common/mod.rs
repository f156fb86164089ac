//! Helpers shared by the `splat_*` integration tests: the shared lavapipe
//! context, a splatter on a given back end, and random views of a target.
#![allow(dead_code)]

use nalgebra::Vector3;
use splattrack::geometry::{Intrinsics, Pose, look_at};
use splattrack::gpu::{self, GpuContext};
use splattrack::rng::Rng;
use splattrack::splat::{Attribute, Backend, SplatImage, SplatParams, Splatter};

pub fn ctx() -> &'static GpuContext {
    gpu::shared_test_context()
}

/// A splatter on `backend` (checked to be the one it runs).
pub fn splatter(backend: Backend) -> Splatter {
    let s = Splatter::with_params(
        ctx(),
        SplatParams {
            backend,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(s.backend(), backend);
    s
}

/// A random camera (80-199 x 60-159 pixels, focal 0.8-1.6 widths, a
/// principal point within 8 px of the centre) looking at `target` from
/// `dist` away in a random direction, with a random up vector.
pub fn random_view(rng: &mut Rng, target: Vector3<f64>, dist: f64) -> (Intrinsics, Pose) {
    let w = 80 + rng.below(120) as u32;
    let h = 60 + rng.below(100) as u32;
    let f = rng.uniform(0.8, 1.6) * w as f64;
    let cam = Intrinsics::new(
        w,
        h,
        f,
        f * rng.uniform(0.9, 1.1),
        w as f64 / 2.0 + rng.uniform(-8.0, 8.0),
        h as f64 / 2.0 + rng.uniform(-8.0, 8.0),
    );
    let eye = target + rng.unit_vector() * dist;
    let pose = look_at(&eye, &target, &rng.unit_vector());
    (cam, pose)
}

/// How many values of two images differ bit for bit (NaN equal to NaN).
pub fn differing(a: &splattrack::splat::SplatImage, b: &splattrack::splat::SplatImage) -> usize {
    a.data
        .iter()
        .zip(&b.data)
        .filter(|(p, q)| p.to_bits() != q.to_bits() && !(p.is_nan() && q.is_nan()))
        .count()
}

/// Covered pixels of two renders' images (the order of the `READ` lists
/// of `splat_compute.rs` and `splat_occluders.rs`: colour, depth, normal,
/// motion, weight), and those whose coverage or values disagree: colour
/// and normal within 1e-4, depth within 1e-5 relative, the predictors
/// within 1e-4 of their largest, the weight within 1e-4 relative.
pub fn disagreement(a: &[SplatImage], b: &[SplatImage]) -> (usize, usize) {
    let (w, h) = (a[0].width, a[0].height);
    let (mut covered, mut bad) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let (va, vb) = (a[1].is_valid(x, y), b[1].is_valid(x, y));
            covered += (va || vb) as usize;
            if va != vb {
                bad += 1;
                continue;
            }
            if !va {
                continue;
            }
            let maxdiff = |k: usize| {
                a[k].pixel(x, y)
                    .iter()
                    .zip(b[k].pixel(x, y))
                    .map(|(p, q)| (p - q).abs())
                    .fold(0.0f32, f32::max)
            };
            let z = b[1].pixel(x, y)[0];
            let scale = b[3]
                .pixel(x, y)
                .iter()
                .map(|v| v.abs())
                .fold(1e-6, f32::max);
            let ok = maxdiff(0) <= 1e-4
                && maxdiff(1) <= 1e-5 * z
                && maxdiff(2) <= 1e-4
                && maxdiff(3) <= 1e-4 * scale
                && maxdiff(4) <= 1e-4 * b[4].pixel(x, y)[0].max(1.0);
            bad += !ok as usize;
        }
    }
    (covered, bad)
}

/// The images [`disagreement`] compares, in its order.
pub const READ: [Attribute; 5] = [
    Attribute::Color,
    Attribute::Depth,
    Attribute::Normal,
    Attribute::Motion,
    Attribute::Weight,
];
