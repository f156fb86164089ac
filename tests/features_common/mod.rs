//! Helpers shared by the `features_*` integration tests: the shared
//! lavapipe context and random feature points.
#![allow(dead_code)]

use splattrack::features::Corner;
use splattrack::gpu::{self, GpuContext};
use splattrack::rng::Rng;

pub fn ctx() -> &'static GpuContext {
    gpu::shared_test_context()
}

/// `n` points uniformly over a `w x h` image and 3 px beyond its borders
/// (so that some windows leave it), score 1.
pub fn random_points(rng: &mut Rng, n: usize, w: usize, h: usize) -> Vec<Corner> {
    (0..n)
        .map(|_| Corner {
            x: rng.uniform(-3.0, w as f64 + 3.0) as f32,
            y: rng.uniform(-3.0, h as f64 + 3.0) as f32,
            score: 1.0,
        })
        .collect()
}
