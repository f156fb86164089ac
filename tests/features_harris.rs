//! Harris corners: GPU against the CPU reference on random images, known
//! answers (rotated squares, a checkerboard), masks, invalid pixels and
//! degenerate inputs. Runs on lavapipe in CI.

use splattrack::features::patterns::{self, Square};
use splattrack::features::{
    Corner, FeatureError, GreyImage, Harris, HarrisConfig, REFINE_GROUP_RADIUS, SELECT_MAX,
    SELECT_MAX_CPU, harris_cpu, harris_host, harris_response_cpu, harris_response_host,
};
use splattrack::gpu::{self, GpuContext};

fn ctx() -> &'static GpuContext {
    gpu::shared_test_context()
}

fn random_images() -> Vec<(&'static str, GreyImage)> {
    vec![
        ("smooth noise 97x73", patterns::smooth_noise(97, 73, 1.5, 1)),
        (
            "smooth noise 160x120",
            patterns::smooth_noise(160, 120, 2.5, 2),
        ),
        ("polygons 131x89", patterns::polygons(131, 89, 12, 3)),
        ("polygons 64x64", patterns::polygons(64, 64, 6, 4)),
    ]
}

/// Tolerance on the response map: 1e-5 of the image's largest response
/// (f32 sums in the same order; the GPU may fuse multiply-adds).
#[test]
fn gpu_response_matches_cpu_on_random_images() {
    let cfg = HarrisConfig::default();
    let mut harris = Harris::new(ctx(), cfg.clone()).unwrap();
    for (name, img) in random_images() {
        let gpu = harris.response(&img).unwrap();
        let cpu = harris_response_cpu(&img, &cfg).unwrap();
        let max = cpu.iter().fold(0f32, |m, v| m.max(v.abs().min(1e30)));
        assert!(max > 0.0, "{name}: flat response");
        let mut worst = 0f32;
        for (i, (g, c)) in gpu.iter().zip(&cpu).enumerate() {
            let invalid = *c <= -1e38;
            assert_eq!(*g <= -1e38, invalid, "{name}: validity differs at {i}");
            if !invalid {
                worst = worst.max((g - c).abs() / max);
            }
        }
        assert!(
            worst <= 1e-5,
            "{name}: max |gpu - cpu| = {worst} of max response"
        );
    }
}

/// The filter passes compute HARRIS_BLOCK (8) pixels an invocation from
/// one window: sizes around and below a block and a workgroup, with the
/// default and the largest kernels (radii 7 and 14, windows wider than
/// some images), and NaN pixels (hard invalid and pinholes) near block
/// boundaries. Same tolerance as above.
#[test]
fn gpu_response_matches_cpu_across_block_boundaries() {
    let max_sigma = HarrisConfig::default().with_sigmas(7.0 / 3.0, 14.0 / 3.0);
    for cfg in [HarrisConfig::default(), max_sigma] {
        let mut harris = Harris::new(ctx(), cfg.clone()).unwrap();
        let reach = 3.0 * (cfg.sigma_d + cfg.sigma_i);
        for (i, (w, h)) in [
            (7, 5),
            (8, 8),
            (9, 23),
            (17, 8),
            (31, 33),
            (40, 129),
            (75, 61),
        ]
        .into_iter()
        .enumerate()
        {
            let mut img = patterns::smooth_noise(w, h, 1.0, 10 + i as u64);
            // A hole at a block's last pixel and a hard invalid pair.
            for (x, y) in [(7, 2), (w / 2, h / 2), (w / 2 + 1, h / 2)] {
                if x < w && y < h {
                    img.data[y * w + x] = f32::NAN;
                }
            }
            let name = format!("{w}x{h}, sigma_i {}", cfg.sigma_i);
            let gpu = harris.response(&img).unwrap();
            let cpu = harris_response_cpu(&img, &cfg).unwrap();
            let max = cpu.iter().fold(0f32, |m, v| m.max(v.abs().min(1e30)));
            let valid = cpu.iter().filter(|c| **c > -1e38).count();
            if (w.min(h) as f32) > 2.0 * reach + 4.0 {
                assert!(valid > 0, "{name}: no valid response to compare");
            }
            for (j, (g, c)) in gpu.iter().zip(&cpu).enumerate() {
                let invalid = *c <= -1e38;
                assert_eq!(*g <= -1e38, invalid, "{name}: validity differs at {j}");
                if !invalid {
                    assert!(
                        (g - c).abs() <= 1e-5 * max,
                        "{name}: {g} vs {c} at {j} (max {max})"
                    );
                }
            }
        }
    }
}

/// Same corners, positions within 1e-3 px, scores within 1e-4 relative.
fn assert_same_corners(name: &str, gpu: &[Corner], cpu: &[Corner]) {
    assert_eq!(gpu.len(), cpu.len(), "{name}: corner counts differ");
    for c in cpu {
        let g = gpu
            .iter()
            .min_by(|a, b| {
                let da = (a.x - c.x).powi(2) + (a.y - c.y).powi(2);
                let db = (b.x - c.x).powi(2) + (b.y - c.y).powi(2);
                da.total_cmp(&db)
            })
            .unwrap();
        let d = ((g.x - c.x).powi(2) + (g.y - c.y).powi(2)).sqrt();
        assert!(d <= 1e-3, "{name}: cpu corner {c:?} vs gpu {g:?}: {d} px");
        assert!(
            (g.score - c.score).abs() <= 1e-4 * c.score.abs(),
            "{name}: scores {} vs {}",
            g.score,
            c.score
        );
    }
}

#[test]
fn gpu_corners_match_cpu_on_random_images() {
    let configs = [
        HarrisConfig::default(),
        HarrisConfig::default()
            .with_max_corners(25)
            .with_grid_cell(20),
        HarrisConfig::default().with_refine(false).with_k(0.06),
        HarrisConfig::default()
            .with_sigmas(1.4, 2.0)
            .with_grid_cell(0)
            .with_max_corners(40),
    ];
    for (ci, cfg) in configs.iter().enumerate() {
        let mut harris = Harris::new(ctx(), cfg.clone()).unwrap();
        for (name, img) in random_images() {
            let gpu = harris.detect(&img, None).unwrap();
            let cpu = harris_cpu(&img, cfg, None).unwrap();
            assert!(!cpu.is_empty(), "{name}: no corners");
            assert!(cpu.len() <= cfg.max_corners);
            assert_same_corners(&format!("config {ci}, {name}"), &gpu, &cpu);
        }
    }
}

#[test]
fn a_detection_selects_on_the_gpu_and_reads_its_corners_back_at_once() {
    // The corners are selected, refined and merged on the GPU and come
    // back with their count in one readback (one wait for the GPU),
    // refining or not, as many as recent detections kept and a quarter
    // more: a detection keeping more (the first of many after few)
    // reads the rest in a second. With more candidates than the GPU
    // selects among (SELECT_MAX, a large noisy image), the candidates
    // come back in a second readback, the host selects, and (refining) the
    // selected are refined after it (a third). The corners are the
    // reference's every time. Each wait shares its submission with the
    // passes before it (GpuContext::read_buffers_after): as many
    // submissions as waits. A context of its own, so that other tests'
    // readbacks are not counted.
    use splattrack::gpu::own_test_context;
    let c = own_test_context();
    let few = patterns::polygons(64, 64, 3, 5);
    let many = patterns::smooth_noise(320, 240, 1.2, 6);
    // Thousands of candidates after two detections of a few: each still
    // takes one thread of the selection (lavapipe ends an invocation's
    // loops after 65535 iterations in all; threads sized by the recent
    // counts and striding over the candidates kept one corner here).
    let busy = patterns::smooth_noise(640, 480, 1.5, 9);
    // 11.8k candidates at this threshold (more than SELECT_MAX).
    let noisy = patterns::smooth_noise(1024, 768, 0.8, 6);
    for (refine, over) in [(true, 3), (false, 2)] {
        let cfg = HarrisConfig::default().with_refine(refine);
        let mut harris = Harris::new(&c, cfg.clone()).unwrap();
        // The GPU selects among as many as it can on any adapter (on CPU
        // adapters by default only among SELECT_MAX_CPU).
        harris.set_options(splattrack::features::HarrisGpuOptions {
            select_limit: Some(SELECT_MAX as usize),
            ..harris.options()
        });
        let mut lax = Harris::new(&c, cfg.clone().with_relative_threshold(0.0)).unwrap();
        lax.set_options(splattrack::features::HarrisGpuOptions {
            select_limit: Some(SELECT_MAX as usize),
            ..lax.options()
        });
        let mut waits = Vec::new();
        for (name, img, strict) in [
            ("few", &few, true),
            ("many", &many, true),
            ("many again", &many, true),
            ("few", &few, true),
            ("few again", &few, true),
            ("busy", &busy, true),
            ("noisy", &noisy, false),
        ] {
            let (before, subs) = (c.stats().readbacks, c.stats().submissions);
            let (got, want) = if strict {
                let got = harris.detect(img, None).unwrap();
                (got, harris_cpu(img, &cfg, None).unwrap())
            } else {
                let got = lax.detect(img, None).unwrap();
                (got, harris_cpu(img, lax.config(), None).unwrap())
            };
            waits.push(c.stats().readbacks - before);
            assert_eq!(
                c.stats().submissions - subs,
                c.stats().readbacks - before,
                "refine {refine}, {name}: submissions"
            );
            assert!(!want.is_empty(), "{name}");
            assert_same_corners(&format!("refine {refine}, {name}"), &got, &want);
        }
        assert_eq!(waits, [1, 2, 1, 1, 1, 2, over], "refine {refine}");
        // On a CPU adapter a detector left at its default selects on the
        // GPU among at most SELECT_MAX_CPU candidates: the busy image's
        // are selected on the host (its candidates and then, refining,
        // their refinement read back), the corners the same.
        if c.is_cpu() {
            let mut default = Harris::new(&c, cfg.clone()).unwrap();
            default.detect(&few, None).unwrap();
            let before = c.stats().readbacks;
            let got = default.detect(&busy, None).unwrap();
            assert_eq!(c.stats().readbacks - before, over, "refine {refine}, busy");
            let want = harris_cpu(&busy, &cfg, None).unwrap();
            assert!(want.len() > SELECT_MAX_CPU as usize / 2);
            assert_same_corners(&format!("refine {refine}, busy, default"), &got, &want);
        }
    }
}

/// Both forms of the selection's O(n^2) passes (tiles of the items in
/// workgroup memory, the default on GPUs; one thread reading every item,
/// the default on CPU adapters) give the reference's corners bit for bit:
/// with and without the grid, with and without refinement, on images with
/// a few candidates (one partial tile) and thousands (many tiles, the last
/// partial).
#[test]
fn tiled_and_direct_selections_give_the_references_corners() {
    let few = patterns::polygons(64, 64, 3, 5);
    let busy = patterns::smooth_noise(640, 480, 1.5, 9);
    let odd = patterns::smooth_noise(203, 157, 1.1, 4);
    let configs = [
        HarrisConfig::default(),
        HarrisConfig::default()
            .with_grid_cell(0)
            .with_max_corners(300),
        HarrisConfig::default()
            .with_refine(false)
            .with_grid_cell(13)
            .with_max_corners(77),
        // More selected corners than a chunk of the split counts (the
        // merge's order over several chunks).
        HarrisConfig::default()
            .with_grid_cell(0)
            .with_max_corners(3000),
        // A refinement window wider than select_refine_group holds: a
        // thread a corner even where tiled.
        HarrisConfig {
            refine_radius: REFINE_GROUP_RADIUS + 2,
            ..HarrisConfig::default()
        },
    ];
    for (ci, cfg) in configs.iter().enumerate() {
        for tiled in [true, false] {
            let mut harris = Harris::new(ctx(), cfg.clone()).unwrap();
            harris.set_options(splattrack::features::HarrisGpuOptions {
                select_limit: Some(SELECT_MAX as usize),
                tiled_selection: Some(tiled),
                ..harris.options()
            });
            for (name, img) in [("few", &few), ("busy", &busy), ("odd", &odd)] {
                let got = harris.detect(img, None).unwrap();
                let want = harris_cpu(img, cfg, None).unwrap();
                assert!(!want.is_empty(), "{name}");
                assert_same_corners(&format!("config {ci}, tiled {tiled}, {name}"), &got, &want);
            }
        }
    }
}

/// Detections within `radius` of `p`.
fn near(corners: &[Corner], p: [f32; 2], radius: f32) -> Vec<Corner> {
    corners
        .iter()
        .filter(|c| (c.x - p[0]).hypot(c.y - p[1]) <= radius)
        .copied()
        .collect()
}

/// Every true corner: exactly one detection within 3 px, and it is within
/// 1 px of the truth. Returns the worst error.
fn assert_known_corners(name: &str, corners: &[Corner], truth: &[[f32; 2]]) -> f32 {
    let mut worst = 0f32;
    for t in truth {
        let close = near(corners, *t, 3.0);
        assert_eq!(close.len(), 1, "{name}: detections near {t:?}: {close:?}");
        let d = (close[0].x - t[0]).hypot(close[0].y - t[1]);
        assert!(
            d <= 1.0,
            "{name}: corner {t:?} found at {:?} ({d} px)",
            close[0]
        );
        worst = worst.max(d);
    }
    worst
}

#[test]
fn refined_corners_of_rotated_squares_are_within_one_pixel() {
    let sq = [
        Square {
            cx: 40.3,
            cy: 38.7,
            half: 16.0,
            angle: 0.0,
        },
        Square {
            cx: 112.6,
            cy: 41.2,
            half: 18.5,
            angle: 0.35,
        },
        Square {
            cx: 45.1,
            cy: 112.4,
            half: 20.0,
            angle: 0.785,
        },
        Square {
            cx: 118.8,
            cy: 116.9,
            half: 15.0,
            angle: -0.2,
        },
    ];
    let (img, truth) = patterns::squares(160, 160, &sq, 0.15, 0.85);
    let cfg = HarrisConfig::default();
    let mut harris = Harris::new(ctx(), cfg.clone()).unwrap();
    let gpu = harris.detect(&img, None).unwrap();
    let cpu = harris_cpu(&img, &cfg, None).unwrap();
    let worst_gpu = assert_known_corners("squares (gpu)", &gpu, &truth);
    let worst_cpu = assert_known_corners("squares (cpu)", &cpu, &truth);
    // Without refinement the maxima sit inside the corners: the test is
    // only meaningful if refinement is what brings them within 1 px.
    let plain = harris_cpu(&img, &cfg.clone().with_refine(false), None).unwrap();
    let plain_worst = truth
        .iter()
        .map(|t| {
            near(&plain, *t, 4.0)
                .iter()
                .map(|c| (c.x - t[0]).hypot(c.y - t[1]))
                .fold(f32::MAX, f32::min)
        })
        .fold(0f32, f32::max);
    eprintln!(
        "squares: worst error refined gpu {worst_gpu:.3} px, cpu {worst_cpu:.3} px; unrefined {plain_worst:.3} px"
    );
    // No detection away from the 16 true corners.
    for c in &gpu {
        assert!(
            truth.iter().any(|t| (c.x - t[0]).hypot(c.y - t[1]) <= 1.0),
            "spurious corner {c:?}"
        );
    }
}

#[test]
fn refined_checkerboard_corners_are_within_one_pixel_once_each() {
    let (img, truth) = patterns::checkerboard(200, 170, [45.3, 20.6], 14.0, 0.3, 8, 7);
    let cfg = HarrisConfig::default();
    let mut harris = Harris::new(ctx(), cfg.clone()).unwrap();
    let gpu = harris.detect(&img, None).unwrap();
    let cpu = harris_cpu(&img, &cfg, None).unwrap();
    let worst_gpu = assert_known_corners("checkerboard (gpu)", &gpu, &truth);
    let worst_cpu = assert_known_corners("checkerboard (cpu)", &cpu, &truth);
    eprintln!(
        "checkerboard: {} X-junctions, worst error gpu {worst_gpu:.3} px, cpu {worst_cpu:.3} px",
        truth.len()
    );
}

#[test]
fn mask_and_invalid_pixels_keep_corners_out() {
    let img = patterns::polygons(120, 90, 14, 7);
    let cfg = HarrisConfig::default().with_refine(false);
    let mut harris = Harris::new(ctx(), cfg.clone()).unwrap();
    // Mask: left half only.
    let mask: Vec<bool> = (0..img.data.len()).map(|i| i % 120 < 60).collect();
    let gpu = harris.detect(&img, Some(&mask)).unwrap();
    let cpu = harris_cpu(&img, &cfg, Some(&mask)).unwrap();
    assert!(!gpu.is_empty());
    assert!(gpu.iter().all(|c| c.x < 60.0), "{gpu:?}");
    assert_same_corners("mask", &gpu, &cpu);

    // NaN disc (an empty region of a rendered view): with
    // min_valid_weight 1 no corner's support may touch it, so every corner
    // is farther than the support radius.
    let cfg = HarrisConfig {
        min_valid_weight: 1.0,
        ..cfg
    };
    let mut harris = Harris::new(ctx(), cfg.clone()).unwrap();
    let mut holed = img.clone();
    for y in 0..90 {
        for x in 0..120 {
            if (x as f32 - 60.0).hypot(y as f32 - 45.0) < 20.0 {
                holed.data[y * 120 + x] = f32::NAN;
            }
        }
    }
    let r = cfg.support_radius() as f32;
    let gpu = harris.detect(&holed, None).unwrap();
    let cpu = harris_cpu(&holed, &cfg, None).unwrap();
    assert!(!gpu.is_empty());
    for c in &gpu {
        // The nearest NaN pixel is at distance >= hypot - 20 (Chebyshev
        // support is larger than the Euclidean one, so be generous).
        assert!((c.x - 60.0).hypot(c.y - 45.0) >= 20.0 + r - 1.0, "{c:?}");
        assert!(
            c.x >= r && c.y >= r && c.x <= 119.0 - r && c.y <= 89.0 - r,
            "{c:?}"
        );
    }
    assert_same_corners("NaN hole", &gpu, &cpu);
}

#[test]
fn degenerate_images_give_no_corners_and_no_panic() {
    let cfg = HarrisConfig::default();
    let mut harris = Harris::new(ctx(), cfg.clone()).unwrap();
    let cases = [
        GreyImage::filled(0, 0, 0.0),
        GreyImage::filled(1, 1, 0.5),
        GreyImage::filled(5, 3, 0.5),
        GreyImage::filled(17, 17, 0.5),
        GreyImage::filled(40, 30, f32::NAN),
        GreyImage::filled(0, 7, 0.0),
        GreyImage::from_fn(12, 9, |x, y| ((x * 7 + y * 3) % 5) as f32),
    ];
    for img in &cases {
        let g = harris.detect(img, None).unwrap();
        let c = harris_cpu(img, &cfg, None).unwrap();
        assert_eq!(g.len(), c.len(), "{}x{}", img.width, img.height);
        if img.width <= 17 {
            // Support radius 8: a 17-pixel side has one interior pixel at
            // most, so no local maximum can be a corner.
            assert!(g.len() <= 1);
        }
    }
    // Constant images have no corners at all.
    assert!(harris.detect(&cases[3], None).unwrap().is_empty());
    // Growing then shrinking reuses buffers correctly.
    let big = patterns::polygons(150, 100, 10, 9);
    let small = patterns::polygons(50, 40, 4, 10);
    for img in [&big, &small, &big] {
        assert_same_corners(
            "resize",
            &harris.detect(img, None).unwrap(),
            &harris_cpu(img, &cfg, None).unwrap(),
        );
    }
}

#[test]
fn bad_inputs_are_typed_errors() {
    let img = GreyImage::filled(10, 10, 0.5);
    let mut harris = Harris::new(ctx(), HarrisConfig::default()).unwrap();
    assert!(matches!(
        harris.detect(&img, Some(&[true; 3])),
        Err(FeatureError::MaskSize { .. })
    ));
    let broken = GreyImage {
        width: 10,
        height: 10,
        data: vec![0.0; 7],
    };
    assert!(matches!(
        harris.detect(&broken, None),
        Err(FeatureError::ImageSize { .. })
    ));
    for cfg in [
        HarrisConfig::default().with_max_corners(0),
        HarrisConfig::default().with_sigmas(0.0, 1.5),
        HarrisConfig::default().with_sigmas(1.0, 50.0),
        HarrisConfig::default().with_k(f32::NAN),
        HarrisConfig::default().with_relative_threshold(2.0),
    ] {
        assert!(matches!(
            Harris::new(ctx(), cfg.clone()),
            Err(FeatureError::Config(_))
        ));
        assert!(matches!(
            harris_cpu(&img, &cfg, None),
            Err(FeatureError::Config(_))
        ));
    }
}

#[test]
fn selection_is_spread_over_the_image() {
    // Strong texture on the left, weak on the right: a plain best-N takes
    // everything from the left, the grid keeps the right alive.
    let strong = patterns::smooth_noise(200, 100, 1.5, 11);
    let img = GreyImage::from_fn(200, 100, |x, y| {
        let v = strong.get(x, y);
        if x < 100 { v } else { 0.5 + 0.5 * (v - 0.5) }
    });
    let n = 60;
    let spread = harris_cpu(&img, &HarrisConfig::default().with_max_corners(n), None).unwrap();
    let plain = harris_cpu(
        &img,
        &HarrisConfig::default()
            .with_max_corners(n)
            .with_grid_cell(0),
        None,
    )
    .unwrap();
    let right = |cs: &[Corner]| cs.iter().filter(|c| c.x >= 100.0).count();
    assert!(
        right(&spread) >= n / 4,
        "grid: {} of {n} on the right",
        right(&spread)
    );
    assert!(right(&plain) < right(&spread));
}

#[test]
fn pass_timings_are_reported_when_enabled() {
    let img = patterns::polygons(64, 48, 5, 12);
    let mut harris = Harris::new(ctx(), HarrisConfig::default()).unwrap();
    harris.set_options(splattrack::features::HarrisGpuOptions {
        timing: true,
        ..harris.options()
    });
    for _ in 0..3 {
        // Repeated calls (and response maps) must not fill the timer up.
        harris.response(&img).unwrap();
        let corners = harris.detect(&img, None).unwrap();
        let t = harris.last_timings();
        if ctx().has_timestamps() {
            let labels: Vec<&str> = t.passes.iter().map(|(l, _)| l.as_str()).collect();
            // GPUs run the filter passes as one (`Harris::set_fused_maps`).
            let maps: &[&str] = if ctx().is_cpu() {
                &["deriv_h", "deriv_v", "integrate_h", "integrate_v", "nms"]
            } else {
                &["maps", "nms"]
            };
            assert!(labels.starts_with(maps), "{labels:?}");
            assert_eq!(labels.contains(&"refine"), !corners.is_empty());
            assert!(t.passes.iter().all(|(_, ms)| ms.is_finite() && *ms >= 0.0));
        } else {
            assert!(t.passes.is_empty());
        }
    }
}

#[test]
fn gpu_grey_conversion_of_rgb_frames_matches_cpu() {
    // Each channel an independent random polygon picture.
    let (w, h) = (120, 90);
    let ch: Vec<GreyImage> = (0..3)
        .map(|s| patterns::polygons(w, h, 10, 80 + s))
        .collect();
    let rgb = image::RgbImage::from_fn(w as u32, h as u32, |x, y| {
        image::Rgb(std::array::from_fn(|c| {
            (ch[c].get(x as usize, y as usize) * 255.0).round() as u8
        }))
    });
    let grey = GreyImage::from_rgb8(&rgb);
    let mask: Vec<bool> = (0..w * h).map(|i| (i / w) < 60).collect();
    let cfg = HarrisConfig::default();
    let mut harris = Harris::new(ctx(), cfg.clone()).unwrap();
    for m in [None, Some(&mask[..])] {
        let gpu = harris.detect_rgb8(&rgb, m).unwrap();
        let cpu = harris_cpu(&grey, &cfg, m).unwrap();
        assert!(!cpu.is_empty());
        assert_same_corners("rgb8", &gpu, &cpu);
        if m.is_some() {
            assert!(
                gpu.iter()
                    .all(|c| c.y < 60.0 + 0.5 + cfg.refine_radius as f32)
            );
        }
    }
    assert!(matches!(
        harris.detect_rgb8(&rgb, Some(&mask[..10])),
        Err(FeatureError::MaskSize { .. })
    ));
    assert!(
        harris
            .detect_rgb8(&image::RgbImage::new(0, 0), None)
            .unwrap()
            .is_empty()
    );
}

#[test]
fn gpu_grey_and_packing_of_a_resolved_view_match_cpu() {
    // A splatted view's colour as the splatter resolves it (3 floats a
    // pixel, NaN where empty): an object (a disc) with a few pinholes, on
    // an empty background. Converted and packed on the GPU
    // (Harris::detect_resolved), it gives the grey levels of
    // GreyImage::from_rgb_f32 (within 1e-6: the GPU may fuse
    // multiply-adds) and the corners of the CPU reference on them, with
    // and without the tolerance of pinholes.
    let (w, h) = (131, 97);
    let ch: Vec<GreyImage> = (0..3)
        .map(|s| patterns::polygons(w, h, 12, 90 + s))
        .collect();
    // Isolated pinholes (8 valid neighbours), a run of three (its middle
    // has 6, PINHOLE_NEIGHBOURS: still a pinhole) and a 2x2 block (5 each:
    // hard invalid).
    let pinholes = [
        (60, 40),
        (70, 55),
        (45, 50),
        (80, 35),
        (50, 62),
        (51, 62),
        (52, 62),
        (75, 44),
        (76, 44),
        (75, 45),
        (76, 45),
    ];
    let empty = |x: usize, y: usize| {
        let (dx, dy) = (x as f32 - 65.0, y as f32 - 48.0);
        dx * dx + dy * dy > 44.0 * 44.0 || pinholes.contains(&(x, y))
    };
    let colour: Vec<f32> = (0..w * h)
        .flat_map(|i| {
            let (x, y) = (i % w, i / w);
            let e = empty(x, y);
            [0, 1, 2].map(|c| if e { f32::NAN } else { ch[c].get(x, y) })
        })
        .collect();
    let want = GreyImage::from_rgb_f32(w, h, &colour).unwrap();
    for cfg in [
        HarrisConfig::default(),
        HarrisConfig {
            min_valid_weight: 1.0,
            ..HarrisConfig::default()
        },
    ] {
        let mut harris = Harris::new(ctx(), cfg.clone()).unwrap();
        let target = harris.colour_target(w, h).unwrap();
        ctx()
            .queue
            .write_buffer(&target, 0, bytemuck::cast_slice(&colour));
        let (corners, grey) = harris.detect_resolved(w, h).unwrap();
        assert_eq!((grey.width, grey.height), (w, h));
        for (i, (g, c)) in grey.data.iter().zip(&want.data).enumerate() {
            assert_eq!(g.is_nan(), c.is_nan(), "pixel {i}");
            assert!(c.is_nan() || (g - c).abs() <= 1e-6, "pixel {i}: {g} vs {c}");
        }
        let cpu = harris_cpu(&want, &cfg, None).unwrap();
        assert!(cpu.len() > 10, "{} corners", cpu.len());
        assert_same_corners(
            &format!("resolved view, min_valid_weight {}", cfg.min_valid_weight),
            &corners,
            &cpu,
        );
    }
}

/// Images for the host detector: the random ones, sizes below and around
/// the kernels (narrower than a window, one pixel), and NaN pixels (hard
/// invalid regions and pinholes) near the borders and inside.
fn host_images() -> Vec<(String, GreyImage)> {
    let mut out: Vec<(String, GreyImage)> = random_images()
        .into_iter()
        .map(|(n, i)| (n.to_string(), i))
        .collect();
    for (w, h) in [
        (1, 1),
        (3, 5),
        (7, 5),
        (9, 31),
        (23, 17),
        (37, 40),
        (64, 3),
        (200, 150),
    ] {
        out.push((
            format!("polygons {w}x{h}"),
            patterns::polygons(w, h, 6, (w * h) as u64),
        ));
    }
    let mut holed = patterns::polygons(150, 110, 14, 77);
    for (i, v) in holed.data.iter_mut().enumerate() {
        let (x, y) = ((i % 150) as f32, (i / 150) as f32);
        // A hard invalid disc, a band at the left border, and pinholes.
        if (x - 90.0).hypot(y - 60.0) < 15.0 || x < 2.0 || (i % 997 == 0) {
            *v = f32::NAN;
        }
    }
    out.push(("polygons 150x110 with NaN".into(), holed));
    out
}

/// The host detector ([`harris_host`]) is the CPU reference's arithmetic
/// in other loops: its responses and corners equal the reference's bit for
/// bit, on every image and setting (kernels up to the largest, pinhole
/// tolerance off, no refinement, a mask).
#[test]
fn host_detector_is_the_reference_bit_for_bit() {
    let configs = [
        HarrisConfig::default(),
        HarrisConfig::default().with_sigmas(7.0 / 3.0, 14.0 / 3.0),
        HarrisConfig {
            min_valid_weight: 1.0,
            ..HarrisConfig::default().with_refine(false)
        },
        HarrisConfig::default()
            .with_sigmas(1.4, 2.0)
            .with_grid_cell(0)
            .with_max_corners(40),
    ];
    let mut compared = 0;
    for (ci, cfg) in configs.iter().enumerate() {
        for (name, img) in host_images() {
            let (hr, cr) = (
                harris_response_host(&img, cfg).unwrap(),
                harris_response_cpu(&img, cfg).unwrap(),
            );
            assert_eq!(hr.len(), cr.len());
            for (i, (a, b)) in hr.iter().zip(&cr).enumerate() {
                assert_eq!(a.to_bits(), b.to_bits(), "config {ci}, {name}: pixel {i}");
            }
            let mask: Vec<bool> = (0..img.data.len())
                .map(|i| (i % img.width) * 3 < img.width * 2)
                .collect();
            for m in [None, Some(&mask[..])] {
                let host = harris_host(&img, cfg, m).unwrap();
                let cpu = harris_cpu(&img, cfg, m).unwrap();
                assert_eq!(host, cpu, "config {ci}, {name}, mask {}", m.is_some());
                compared += cpu.len();
            }
        }
    }
    assert!(compared > 1000, "only {compared} corners compared");
}

/// [`Harris`] in host mode (what the tracker runs on CPU adapters): every
/// way in gives the reference's corners (frames in grey or RGB with a mask,
/// a splatted view resolved on the GPU, with its grey levels and, resident,
/// its pixels packed on the GPU as NCC reads them).
#[test]
fn harris_in_host_mode_gives_the_references_corners() {
    let cfg = HarrisConfig::default();
    let mut harris = Harris::new(ctx(), cfg.clone()).unwrap();
    harris.set_options(splattrack::features::HarrisGpuOptions {
        host: true,
        ..harris.options()
    });
    assert!(harris.host());
    let img = patterns::polygons(160, 120, 14, 21);
    let mask: Vec<bool> = (0..img.data.len()).map(|i| i % 160 >= 30).collect();
    assert_eq!(
        harris.detect(&img, Some(&mask)).unwrap(),
        harris_cpu(&img, &cfg, Some(&mask)).unwrap()
    );
    let rgb = image::RgbImage::from_fn(160, 120, |x, y| {
        let v = (img.get(x as usize, y as usize) * 255.0).round() as u8;
        image::Rgb([v, v.wrapping_mul(3), 255 - v])
    });
    let grey = GreyImage::from_rgb8(&rgb);
    assert_eq!(
        harris.detect_rgb8(&rgb, Some(&mask)).unwrap(),
        harris_cpu(&grey, &cfg, Some(&mask)).unwrap()
    );
    // A view with an empty outside and pinholes, as the splatter resolves it.
    let (w, h) = (131, 97);
    let ch: Vec<GreyImage> = (0..3)
        .map(|s| patterns::polygons(w, h, 12, 90 + s))
        .collect();
    let colour: Vec<f32> = (0..w * h)
        .flat_map(|i| {
            let (x, y) = (i % w, i / w);
            let (dx, dy) = (x as f32 - 65.0, y as f32 - 48.0);
            let pinhole = [(60, 40), (70, 55), (45, 50), (80, 35)].contains(&(x, y));
            let empty = dx * dx + dy * dy > 44.0 * 44.0 || pinhole;
            [0, 1, 2].map(|c| if empty { f32::NAN } else { ch[c].get(x, y) })
        })
        .collect();
    let want = GreyImage::from_rgb_f32(w, h, &colour).unwrap();
    let cpu = harris_cpu(&want, &cfg, None).unwrap();
    assert!(cpu.len() > 10, "{} corners", cpu.len());
    let target = harris.colour_target(w, h).unwrap();
    ctx()
        .queue
        .write_buffer(&target, 0, bytemuck::cast_slice(&colour));
    let (corners, grey) = harris.detect_resolved(w, h).unwrap();
    assert_eq!(corners, cpu);
    assert_eq!(grey.data.len(), want.data.len());
    assert!(
        grey.data
            .iter()
            .zip(&want.data)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    );
    let target = harris.colour_target(w, h).unwrap();
    ctx()
        .queue
        .write_buffer(&target, 0, bytemuck::cast_slice(&colour));
    assert_eq!(harris.detect_resolved_resident(w, h).unwrap(), cpu);
    let view = harris.resident_view(w, h).unwrap();
    let packed: Vec<[u32; 2]> = ctx().read_buffer(view.pixels, w * h).unwrap();
    let mut gpu_harris = Harris::new(ctx(), cfg.clone()).unwrap();
    let target = gpu_harris.colour_target(w, h).unwrap();
    ctx()
        .queue
        .write_buffer(&target, 0, bytemuck::cast_slice(&colour));
    gpu_harris.detect_resolved_resident(w, h).unwrap();
    let shader: Vec<[u32; 2]> = ctx()
        .read_buffer(gpu_harris.resident_view(w, h).unwrap().pixels, w * h)
        .unwrap();
    // The detector keeps its images between calls: larger and smaller
    // images after these still give the reference's corners.
    for (w, h, seed) in [(200, 150, 5), (64, 48, 6), (160, 120, 21)] {
        let img = patterns::polygons(w, h, 10, seed);
        assert_eq!(
            harris.detect(&img, None).unwrap(),
            harris_cpu(&img, &cfg, None).unwrap(),
            "{w}x{h}"
        );
    }
    // The packing the shaders leave (grey levels within their fused
    // multiply-adds, the same flags).
    for (i, (a, b)) in packed.iter().zip(&shader).enumerate() {
        assert_eq!(a[1], b[1], "pixel {i}: flags");
        let (a, b) = (f32::from_bits(a[0]), f32::from_bits(b[0]));
        assert!((a - b).abs() <= 1e-6, "pixel {i}: {a} vs {b}");
    }
}

/// The four filter passes as one dispatch of tiles (`maps_fused`: their
/// lines in workgroup memory, GPUs' default) against the four passes:
/// the same responses bit for bit and the same corners (their
/// refinements read the gradients the fused pass writes), on sizes below,
/// at and across the 16-pixel tiles, with holes, hard invalid pixels and
/// a mask; radii too wide for the tile's halo run the four passes
/// whatever is asked.
#[test]
fn fused_filter_passes_give_the_four_passes_responses_and_corners() {
    let wide = HarrisConfig::default().with_sigmas(1.0, 2.0);
    let mut checked = 0;
    for (ci, cfg) in [HarrisConfig::default(), wide].into_iter().enumerate() {
        let mut four = Harris::new(ctx(), cfg.clone()).unwrap();
        four.set_options(splattrack::features::HarrisGpuOptions {
            fused_maps: Some(false),
            ..four.options()
        });
        let mut one = Harris::new(ctx(), cfg.clone()).unwrap();
        one.set_options(splattrack::features::HarrisGpuOptions {
            fused_maps: Some(true),
            timing: true,
            ..one.options()
        });
        for (i, (w, h)) in [(7, 5), (16, 16), (17, 8), (31, 33), (75, 61), (203, 157)]
            .into_iter()
            .enumerate()
        {
            let mut img = if i % 2 == 0 {
                patterns::smooth_noise(w, h, 1.2, 40 + i as u64)
            } else {
                patterns::polygons(w, h, 8, 40 + i as u64)
            };
            // A hole and a hard invalid pair, near tile borders.
            for (x, y) in [(15, 2), (w / 2, h / 2), (w / 2 + 1, h / 2), (16, 16)] {
                if x < w && y < h {
                    img.data[y * w + x] = f32::NAN;
                }
            }
            let name = format!("config {ci}, {w}x{h}");
            let a = four.response(&img).unwrap();
            let b = one.response(&img).unwrap();
            let passes: Vec<String> = one
                .last_timings()
                .passes
                .iter()
                .map(|(l, _)| l.clone())
                .collect();
            if ctx().has_timestamps() {
                assert_eq!(
                    passes.contains(&"maps".to_string()),
                    ci == 0,
                    "{name}: {passes:?}"
                );
            }
            let differ = a
                .iter()
                .zip(&b)
                .filter(|(p, q)| p.to_bits() != q.to_bits())
                .count();
            assert_eq!(differ, 0, "{name}: {differ} responses differ");
            // And the CPU reference's, to the tolerance of the tests above.
            let cpu = harris_response_cpu(&img, &cfg).unwrap();
            let max = cpu.iter().fold(0f32, |m, v| m.max(v.abs().min(1e30)));
            for (j, (g, c)) in b.iter().zip(&cpu).enumerate() {
                let invalid = *c <= -1e38;
                assert_eq!(*g <= -1e38, invalid, "{name}: validity differs at {j}");
                assert!(
                    invalid || (g - c).abs() <= 1e-5 * max,
                    "{name}: {g} vs the CPU's {c} at {j}"
                );
            }
            let mask: Vec<bool> = (0..w * h).map(|k| (k % w) * 3 < w * 2).collect();
            for m in [None, Some(mask.as_slice())] {
                let want = four.detect(&img, m).unwrap();
                assert_eq!(
                    one.detect(&img, m).unwrap(),
                    want,
                    "{name}, mask {}",
                    m.is_some()
                );
                checked += want.len();
            }
        }
    }
    assert!(checked > 200, "{checked} corners compared");
}
