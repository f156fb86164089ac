//! The contour's outline on the GPU (`tracker::outline_gpu::GpuOutline`,
//! shaders/outline.wgsl) against its CPU reference
//! (`tracker::contour::extract_contour`) on random depth windows: the same
//! points bit for bit, the depth at each, and the coverage.

use splattrack::gpu::shared_test_context;
use splattrack::rng::Rng;
use splattrack::tracker::contour::extract_contour;
use splattrack::tracker::outline_gpu::{GpuOutline, Outline};

/// A depth window: a few random ellipses and rectangles (some cut by the
/// window's edges, some thin, some with holes), random depths where
/// covered, and NaN or an infinity where not (all three are empty).
fn random_depth(rng: &mut Rng, w: usize, h: usize) -> Vec<f32> {
    let mut covered = vec![false; w * h];
    for _ in 0..1 + rng.below(5) {
        let (cx, cy) = (
            rng.uniform(-0.2, 1.2) * w as f64,
            rng.uniform(-0.2, 1.2) * h as f64,
        );
        let (rx, ry) = (
            rng.uniform(1.0, w as f64 / 2.0),
            rng.uniform(1.0, h as f64 / 2.0),
        );
        let (box_, set) = (rng.below(3) == 0, rng.below(4) != 0);
        let turn = rng.uniform(0.0, std::f64::consts::PI);
        let (c, s) = (turn.cos(), turn.sin());
        for y in 0..h {
            for x in 0..w {
                let (dx, dy) = (x as f64 - cx, y as f64 - cy);
                let (u, v) = ((c * dx + s * dy) / rx, (-s * dx + c * dy) / ry);
                let inside = if box_ {
                    u.abs() <= 1.0 && v.abs() <= 1.0
                } else {
                    u * u + v * v <= 1.0
                };
                if inside {
                    covered[y * w + x] = set;
                }
            }
        }
    }
    // Speckles: isolated pixels both ways.
    for _ in 0..rng.below(20) {
        let i = rng.below((w * h) as u64) as usize;
        covered[i] = !covered[i];
    }
    covered
        .iter()
        .map(|&c| {
            if c {
                rng.uniform(0.2, 5.0) as f32
            } else {
                [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][rng.below(3) as usize]
            }
        })
        .collect()
}

fn assert_reference(name: &str, got: &Outline, depth: &[f32], w: usize, h: usize, spacing: u32) {
    let mask: Vec<bool> = depth.iter().map(|v| v.is_finite()).collect();
    let want = extract_contour(&mask, w, h, spacing as usize);
    assert_eq!(got.points.len(), want.len(), "{name}: points");
    for (i, (a, b)) in got.points.iter().zip(&want).enumerate() {
        assert_eq!(a.pixel, b.pixel, "{name}: point {i}");
        for k in 0..2 {
            assert_eq!(
                a.position[k].to_bits(),
                b.position[k].to_bits(),
                "{name}: point {i}"
            );
            assert_eq!(
                a.normal[k].to_bits(),
                b.normal[k].to_bits(),
                "{name}: point {i}"
            );
        }
        let z = depth[b.pixel[1] as usize * w + b.pixel[0] as usize];
        assert_eq!(got.depths[i].to_bits(), z.to_bits(), "{name}: depth {i}");
    }
    assert_eq!(got.depths.len(), want.len(), "{name}: depths");
    assert_eq!(
        got.bits.len(),
        (w * h).div_ceil(32),
        "{name}: coverage words"
    );
    for y in 0..h {
        for x in 0..w {
            assert_eq!(
                got.covered(x as u32, y as u32),
                mask[y * w + x],
                "{name}: coverage at ({x}, {y})"
            );
        }
    }
}

#[test]
fn the_gpu_outline_is_the_references_bit_for_bit() {
    let ctx = shared_test_context();
    let mut outline = GpuOutline::new(ctx).expect("outline kernels");
    let mut rng = Rng::new(29);
    let mut found = 0;
    // Sizes that fill no workgroup or word exactly, spacings from 1 (a
    // point a pixel) to wider than some windows.
    for case in 0..24 {
        let (w, h) = (1 + rng.below(150) as usize, 1 + rng.below(120) as usize);
        let spacing = [1, 2, 3, 4, 7, 40][case % 6];
        let depth = random_depth(&mut rng, w, h);
        let got = outline
            .extract_host(&depth, w as u32, h as u32, spacing)
            .expect("extract");
        found += got.points.len();
        assert_reference(
            &format!("case {case}, {w}x{h}, spacing {spacing}"),
            &got,
            &depth,
            w,
            h,
            spacing,
        );
    }
    // Not an empty test: the cases hold many points.
    assert!(found > 500, "{found} points in all");
}

#[test]
fn more_points_than_the_last_outline_come_in_a_second_readback() {
    // The readback holds as many points as the last extraction found and a
    // quarter more: a large outline after a small one reads the rest
    // apart (counted), and the points are the reference's either way. A
    // context of its own, so that other tests' readbacks are not counted.
    use splattrack::gpu::own_test_context;
    let ctx = own_test_context();
    let mut outline = GpuOutline::new(&ctx).expect("outline kernels");
    let (w, h) = (200usize, 160usize);
    let disc = |r: f64| -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64 - 100.0, (i / w) as f64 - 80.0);
                if x * x + y * y <= r * r {
                    1.0 + (i % 7) as f32
                } else {
                    f32::NAN
                }
            })
            .collect()
    };
    let (small, large) = (disc(12.0), disc(70.0));
    let mut counts = Vec::new();
    for (name, depth) in [
        ("small", &small),
        ("large", &large),
        ("large again", &large),
        ("small", &small),
    ] {
        let before = ctx.stats().readbacks;
        let got = outline
            .extract_host(depth, w as u32, h as u32, 1)
            .expect("extract");
        assert_reference(name, &got, depth, w, h, 1);
        counts.push((got.points.len(), ctx.stats().readbacks - before));
    }
    // The large outline did not fit the small one's readback: two waits
    // for it after the small, one when it follows itself, one for the
    // small after it.
    let waits: Vec<u64> = counts.iter().map(|c| c.1).collect();
    assert_eq!(waits, [1, 2, 1, 1], "{counts:?}");
    assert!(counts[1].0 > counts[0].0 * 5 / 4 + 64, "{counts:?}");
}

#[test]
fn a_depth_of_the_wrong_size_is_refused() {
    let ctx = shared_test_context();
    let mut outline = GpuOutline::new(ctx).expect("outline kernels");
    let e = outline.extract_host(&[1.0; 10], 4, 4, 2).unwrap_err();
    assert!(e.to_string().contains("4x4"), "{e}");
    assert!(!outline.fits(0, 4));
}
