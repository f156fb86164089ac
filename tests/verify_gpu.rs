//! The pose check's GPU scoring (`tracker::verify_gpu::GpuCheck`,
//! shaders/verify.wgsl) against its CPU reference (`tracker::verify::score`)
//! on random views and frames, on the edge test's synthetic scenes
//! (clutter, a faint outline), and on a scene with a known answer.

mod verify_common;

use splattrack::features::GreyImage;
use splattrack::gpu::shared_test_context;
use splattrack::rng::Rng;
use splattrack::tracker::verify::{VerifyConfig, VerifyScores, score};
use splattrack::tracker::verify_gpu::GpuCheck;
use verify_common::{At, Background, Fill};

/// A view covering a few random discs (weight > 0 there, NaN elsewhere)
/// with a random colour, and a frame of random grey levels that are the
/// view's grey plus noise inside and a random background outside.
fn random_case(rng: &mut Rng, w: usize, h: usize) -> (GreyImage, Vec<f32>, Vec<f32>) {
    let discs: Vec<(f32, f32, f32)> = (0..1 + rng.below(4) as usize)
        .map(|_| {
            (
                rng.uniform(0.0, w as f64) as f32,
                rng.uniform(0.0, h as f64) as f32,
                rng.uniform(4.0, w.min(h) as f64 / 2.0) as f32,
            )
        })
        .collect();
    let inside = |x: usize, y: usize| {
        discs
            .iter()
            .any(|(cx, cy, r)| (x as f32 - cx).powi(2) + (y as f32 - cy).powi(2) < r * r)
    };
    let mut weight = vec![f32::NAN; w * h];
    let mut colour = vec![f32::NAN; 3 * w * h];
    let mut frame = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if inside(x, y) {
                weight[i] = rng.uniform(0.1, 3.0) as f32;
                let c: Vec<f32> = (0..3).map(|_| rng.uniform(0.0, 1.0) as f32).collect();
                colour[3 * i..3 * i + 3].copy_from_slice(&c);
                let g = 0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2];
                frame[i] = 0.2 + 0.7 * g + rng.uniform(-0.1, 0.1) as f32;
            } else {
                frame[i] = rng.uniform(0.0, 1.0) as f32;
            }
        }
    }
    (GreyImage::new(w, h, frame).unwrap(), weight, colour)
}

fn cpu(
    frame: &GreyImage,
    weight: &[f32],
    colour: &[f32],
    step: usize,
    cfg: &VerifyConfig,
) -> VerifyScores {
    let covered: Vec<bool> = weight.iter().map(|v| *v > 0.0 && !v.is_nan()).collect();
    let view = GreyImage::from_rgb_f32(frame.width, frame.height, colour).unwrap();
    score(frame, &covered, Some(&view.data), 0.9, step, cfg)
}

#[test]
fn gpu_scores_are_the_cpu_reference_on_random_views() {
    // Covered pixels and contour counts exactly; the ZNCC within 1e-5 (f32
    // sums of mid-grey-centred values against f64 sums; measured 1e-7); the edge support
    // within 1% (an f32 gradient a rounding away from the threshold may
    // count differently; measured: identical on these cases).
    let mut check = GpuCheck::new(shared_test_context()).unwrap();
    let mut rng = Rng::new(13);
    for case in 0..24 {
        // Both kernels (a workgroup a row, the GPUs' default, and a
        // thread a row, the CPU adapters'), each on its own cases.
        check.set_tiled(case % 2 == 0);
        let (w, h) = (24 + rng.below(200) as usize, 16 + rng.below(150) as usize);
        let cfg = VerifyConfig {
            edge_search_px: rng.below(4) as usize,
            edge_gradient: rng.uniform(0.005, 0.1) as f32,
            edge_contrast: rng.uniform(0.0, 4.0) as f32,
            edge_band_px: rng.below(11) as usize,
            ..Default::default()
        };
        let (frame, weight, colour) = random_case(&mut rng, w, h);
        let step = 1 + (case / 2) % 6;
        let want = cpu(&frame, &weight, &colour, step, &cfg);
        let got = check
            .score_host(&frame, &weight, Some(&colour), 0.9, step, &cfg)
            .unwrap();
        eprintln!("case {case} ({w}x{h}): CPU {want:?}, GPU {got:?}");
        assert_eq!(got.covered_px, want.covered_px, "case {case}");
        assert_eq!(got.visible, 0.9);
        match (got.zncc, want.zncc) {
            (Some(a), Some(b)) => assert!((a - b).abs() < 1e-5, "case {case}: {a} vs {b}"),
            (a, b) => assert_eq!(a, b, "case {case}"),
        }
        match (got.edge_support, want.edge_support) {
            (Some(a), Some(b)) => assert!((a - b).abs() < 0.01, "case {case}: {a} vs {b}"),
            (a, b) => assert_eq!(a, b, "case {case}"),
        }
        // The view's texture within 1e-5 relative (f32 sums of squared
        // Laplacians of up to 4 grey levels; measured 2e-7).
        match (got.view_texture, want.view_texture) {
            (Some(a), Some(b)) => assert!((a - b).abs() < 1e-5 * b, "case {case}: {a} vs {b}"),
            (a, b) => assert_eq!(a, b, "case {case}"),
        }
        // Without a texture: no ZNCC, the same edges.
        let bare = check
            .score_host(&frame, &weight, None, 0.9, step, &cfg)
            .unwrap();
        assert_eq!((bare.zncc, bare.view_texture), (None, None));
        assert_eq!(bare.edge_support, got.edge_support);
    }
}

#[test]
fn a_textured_square_at_its_place_scores_one() {
    // Known answer: the view is the frame's texture under a gain and an
    // offset (ZNCC exactly 1) and every contour pixel lies on the frame's
    // step edge (support 1); shifted by 8 px both fall.
    let (w, h) = (64, 48);
    let tex = |x: usize, y: usize| 0.6 + 0.2 * (((x * 7 + y * 3) % 5) as f32 / 4.0);
    let inside =
        |x: usize, y: usize, off: usize| (16 + off..40 + off).contains(&x) && (12..36).contains(&y);
    let frame = GreyImage::from_fn(w, h, |x, y| if inside(x, y, 0) { tex(x, y) } else { 0.2 });
    let cfg = VerifyConfig::default();
    let mut check = GpuCheck::new(shared_test_context()).unwrap();
    for dx in [0, 8] {
        let weight: Vec<f32> = (0..w * h)
            .map(|i| if inside(i % w, i / w, dx) { 1.0 } else { 0.0 })
            .collect();
        let colour: Vec<f32> = (0..w * h)
            .flat_map(|i| {
                let (x, y) = (i % w, i / w);
                let g = if inside(x, y, dx) {
                    tex(x - dx, y) * 0.5 + 0.1
                } else {
                    f32::NAN
                };
                [g, g, g]
            })
            .collect();
        let s = check
            .score_host(&frame, &weight, Some(&colour), 1.0, 4, &cfg)
            .unwrap();
        assert_eq!(s.covered_px, 24 * 24);
        if dx == 0 {
            assert!((s.zncc.unwrap() - 1.0).abs() < 1e-5, "{s:?}");
            assert_eq!(s.edge_support, Some(1.0), "{s:?}");
        } else {
            assert!(s.zncc.unwrap() < cfg.min_zncc, "{s:?}");
            assert!(s.edge_support.unwrap() < cfg.strong_edge_support, "{s:?}");
            assert_eq!(
                s.edge_support,
                cpu(&frame, &weight, &colour, 4, &cfg).edge_support
            );
        }
    }
}

#[test]
fn the_views_texture_is_zero_on_a_ramp_and_known_on_a_square_wave() {
    // Known answers (as `verify`'s unit test): a linear ramp has no
    // Laplacian; a square wave of amplitude a and period twice the step
    // along x has 4 a at every pixel far enough inside.
    let (w, h) = (40, 30);
    let frame = GreyImage::from_fn(w, h, |x, y| 0.3 + 0.01 * ((x * y) % 7) as f32);
    let weight: Vec<f32> = (0..w * h)
        .map(|i| {
            let inside = (1..w - 1).contains(&(i % w)) && (1..h - 1).contains(&(i / w));
            if inside { 1.0 } else { f32::NAN }
        })
        .collect();
    let grey = |g: &dyn Fn(usize, usize) -> f32| -> Vec<f32> {
        (0..w * h).flat_map(|i| [g(i % w, i / w); 3]).collect()
    };
    let ramp = grey(&|x, y| 0.2 + 0.01 * x as f32 + 0.005 * y as f32);
    let a = 0.05f32;
    let d = 3;
    let wave = grey(&|x, _| if x % (2 * d) < d { 0.5 + a } else { 0.5 - a });
    let cfg = VerifyConfig::default();
    let mut check = GpuCheck::new(shared_test_context()).unwrap();
    let t = check
        .score_host(&frame, &weight, Some(&ramp), 1.0, d, &cfg)
        .unwrap()
        .view_texture
        .unwrap();
    assert!(t < 1e-5, "ramp: {t}");
    let t = check
        .score_host(&frame, &weight, Some(&wave), 1.0, d, &cfg)
        .unwrap()
        .view_texture
        .unwrap();
    assert!((t - 4.0 * a as f64).abs() < 1e-5, "square wave: {t}");
}

#[test]
fn gpu_edge_support_is_the_cpu_references_in_clutter_and_on_faint_outlines() {
    // The edge test's scenes (tests/verify_edges.rs) at the right pose
    // and wrong ones: the same supported contour pixels but for an f32
    // gradient a rounding away from a threshold (within 1%, as above;
    // measured: identical).
    let (w, h) = (240, 180);
    let at = At::new(115.0, 90.0, 10.0);
    let cfg = VerifyConfig::default();
    let mut check = GpuCheck::new(shared_test_context()).unwrap();
    let scenes = [
        (Background::Clutter, Fill::Textured),
        (Background::Clutter, Fill::Plain(0.8)),
        (
            Background::Plain {
                grey: 0.5,
                noise: 0.01,
            },
            Fill::Plain(0.53),
        ),
    ];
    for (k, (bg, fill)) in scenes.into_iter().enumerate() {
        let frame = verify_common::frame(w, h, bg, &[(at, fill)], 7 + k as u64);
        for pose in [at, at.turned(30.0), at.shifted(6.0), at.shifted(80.0)] {
            let (covered, grey) = verify_common::view(w, h, pose);
            let weight: Vec<f32> = covered
                .iter()
                .map(|c| if *c { 1.0 } else { f32::NAN })
                .collect();
            let colour: Vec<f32> = grey.iter().flat_map(|g| [*g; 3]).collect();
            let want = score(&frame, &covered, Some(&grey), 1.0, 2, &cfg);
            let got = check
                .score_host(&frame, &weight, Some(&colour), 1.0, 2, &cfg)
                .unwrap();
            eprintln!("scene {k} {pose:?}: CPU {want:?}, GPU {got:?}");
            let (a, b) = (got.edge_support.unwrap(), want.edge_support.unwrap());
            assert!((a - b).abs() < 0.01, "scene {k} {pose:?}: {a} vs {b}");
        }
    }
}
