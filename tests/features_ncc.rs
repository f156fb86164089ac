//! NCC matching: GPU against the CPU reference on random images and
//! features, a known displacement (shift + rotation + brightness and
//! contrast), borders, invalid pixels, search radius, degenerate inputs.

use splattrack::features::patterns::{self, Warp};
use splattrack::features::{
    Corner, FeatureError, GreyImage, Harris, HarrisConfig, Match, NccConfig, NccMatcher,
    VECTORIZE_GROUP_WINDOW, harris_cpu, ncc_match_cpu,
};
use splattrack::rng::Rng;

mod features_common;
use features_common::{ctx, random_points};

/// Same matches; scores within 1e-4 (f32 dot products of 81 terms in the
/// same order; the GPU may fuse multiply-adds).
fn assert_same_matches(name: &str, gpu: &[Match], cpu: &[Match]) {
    assert_eq!(gpu.len(), cpu.len(), "{name}: match counts differ");
    for (g, c) in gpu.iter().zip(cpu) {
        assert_eq!((g.a, g.b), (c.a, c.b), "{name}");
        assert!((g.score - c.score).abs() <= 1e-4, "{name}: {g:?} vs {c:?}");
    }
}

#[test]
fn gpu_matches_equal_cpu_on_random_images_and_features() {
    let mut rng = Rng::new(5);
    let a = patterns::smooth_noise(120, 90, 2.0, 21);
    let warp = Warp {
        shift: [2.3, -1.6],
        angle: 0.03,
        centre: [60.0, 45.0],
        gain: 0.9,
        bias: 0.05,
    };
    let b = warp.image(&a);
    let c = patterns::polygons(80, 100, 9, 22);
    let configs = [
        NccConfig::default(),
        NccConfig::default().with_min_score(-1.0),
        NccConfig::default()
            .with_patch(7)
            .with_search_radius(Some(12.0))
            .with_min_score(0.5),
        NccConfig::default().with_patch(11).with_min_score(0.3),
        // Wider than vectorize_group holds: a thread a window, tiled too.
        NccConfig::default()
            .with_patch(VECTORIZE_GROUP_WINDOW + 2)
            .with_min_score(0.3),
    ];
    for (ci, cfg) in configs.iter().enumerate() {
        let mut m = NccMatcher::new(ctx(), cfg.clone()).unwrap();
        // Both kernels, whatever the adapter's default.
        for ((name, ia, ib), tiled) in [("noise/warped", &a, &b), ("noise/polygons", &a, &c)]
            .into_iter()
            .flat_map(|case| [(case, true), (case, false)])
        {
            m.set_options(splattrack::features::NccOptions {
                tiled: Some(tiled),
                ..m.options()
            });
            let name = format!("{name}, tiled {tiled}");
            let name = name.as_str();
            // Random positions, with some features of B placed at the
            // images of features of A so that true matches exist.
            let fa = random_points(&mut rng, 150, ia.width, ia.height);
            let mut fb = random_points(&mut rng, 90, ib.width, ib.height);
            for p in fa.iter().take(60) {
                let q = warp.apply([p.x, p.y]);
                fb.push(Corner {
                    x: q[0],
                    y: q[1],
                    score: 1.0,
                });
            }
            let gpu = m.match_features(ia, &fa, ib, &fb).unwrap();
            let cpu = ncc_match_cpu(ia, &fa, ib, &fb, cfg).unwrap();
            if name.starts_with("noise/warped") {
                assert!(cpu.len() >= 10, "config {ci}: {} matches", cpu.len());
            }
            assert_same_matches(&format!("config {ci}, {name}"), &gpu, &cpu);
        }
    }
}

#[test]
fn known_displacement_is_recovered_by_mutual_matches() {
    let a = patterns::smooth_noise(256, 192, 2.0, 31);
    let warp = Warp {
        shift: [3.4, -2.7],
        angle: 4f32.to_radians(),
        centre: [128.0, 96.0],
        gain: 0.8,
        bias: 0.15,
    };
    let b = warp.image(&a);
    let hcfg = HarrisConfig::default().with_max_corners(400);
    let mut harris = Harris::new(ctx(), hcfg.clone()).unwrap();
    let ca = harris.detect(&a, None).unwrap();
    let cb = harris.detect(&b, None).unwrap();
    let cfg = NccConfig::default();
    let mut matcher = NccMatcher::new(ctx(), cfg.clone()).unwrap();
    let gpu = matcher.match_features(&a, &ca, &b, &cb).unwrap();
    let cpu = ncc_match_cpu(&a, &ca, &b, &cb, &cfg).unwrap();
    assert_same_matches("known displacement", &gpu, &cpu);
    let good = gpu
        .iter()
        .filter(|m| {
            let t = warp.apply([ca[m.a].x, ca[m.a].y]);
            (cb[m.b].x - t[0]).hypot(cb[m.b].y - t[1]) <= 1.0
        })
        .count();
    let frac = good as f32 / gpu.len() as f32;
    eprintln!(
        "known displacement: {} + {} corners, {} mutual matches, {good} ({:.1}%) within 1 px",
        ca.len(),
        cb.len(),
        gpu.len(),
        100.0 * frac
    );
    assert!(gpu.len() >= 50, "only {} matches", gpu.len());
    assert!(frac >= 0.9, "{:.1}% correct", 100.0 * frac);
    // Same with the CPU detector's corners, for good measure.
    let ca2 = harris_cpu(&a, &hcfg, None).unwrap();
    assert_eq!(ca2.len(), ca.len());
}

#[test]
fn windows_never_read_outside_the_image() {
    // Identical images: a feature matches itself iff its 9x9 window lies
    // inside the image (centre at least 4 px from every border).
    let img = patterns::smooth_noise(40, 30, 1.5, 41);
    let pts: Vec<Corner> = [
        (0.0, 0.0),
        (3.9, 15.0),
        (4.0, 15.0),
        (35.0, 4.0),
        (36.0, 4.0),
        (35.0, 25.0),
        (35.0, 25.1),
        (39.0, 29.0),
        (20.0, -0.5),
        (20.0, 12.5),
        (f32::NAN, 10.0),
        (1e30, 5.0),
        (-1e30, f32::INFINITY),
    ]
    .iter()
    .map(|&(x, y)| Corner { x, y, score: 1.0 })
    .collect();
    let cfg = NccConfig::default().with_min_score(0.99);
    let mut m = NccMatcher::new(ctx(), cfg.clone()).unwrap();
    let gpu = m.match_features(&img, &pts, &img, &pts).unwrap();
    let cpu = ncc_match_cpu(&img, &pts, &img, &pts, &cfg).unwrap();
    assert_same_matches("border", &gpu, &cpu);
    let matched: Vec<usize> = gpu.iter().map(|m| m.a).collect();
    assert_eq!(matched, vec![2, 3, 5, 9], "{gpu:?}");
    assert!(gpu.iter().all(|m| m.a == m.b && m.score > 0.999));
}

#[test]
fn invalid_pixels_of_a_novel_view_never_match() {
    // B is A with a NaN region (empty pixels of a rendered view): features
    // whose window touches it get no match, the others match themselves.
    let a = patterns::smooth_noise(100, 80, 1.5, 51);
    let mut b = a.clone();
    for y in 0..80 {
        for x in 50..100 {
            b.data[y * 100 + x] = f32::NAN;
        }
    }
    let pts: Vec<Corner> = (0..9)
        .flat_map(|j| (0..11).map(move |i| (8.0 + 8.5 * i as f32, 6.0 + 8.5 * j as f32)))
        .map(|(x, y)| Corner { x, y, score: 1.0 })
        .collect();
    let cfg = NccConfig::default();
    let mut m = NccMatcher::new(ctx(), cfg.clone()).unwrap();
    let gpu = m.match_features(&a, &pts, &b, &pts).unwrap();
    let cpu = ncc_match_cpu(&a, &pts, &b, &pts, &cfg).unwrap();
    assert_same_matches("NaN region", &gpu, &cpu);
    assert!(!gpu.is_empty());
    for mt in &gpu {
        assert_eq!(mt.a, mt.b);
        // The window's right edge (x + 4), bilinear neighbour included,
        // stays left of column 50.
        assert!(pts[mt.b].x + 4.0 < 49.0 + 1e-3, "{mt:?} at {:?}", pts[mt.b]);
    }
    let expected = pts.iter().filter(|p| p.x + 4.0 <= 49.0).count();
    assert_eq!(gpu.len(), expected);
}

#[test]
fn search_radius_limits_matches() {
    let a = patterns::smooth_noise(90, 90, 1.5, 61);
    let pa: Vec<Corner> = (0..5)
        .flat_map(|j| (0..5).map(move |i| (10.0 + 17.0 * i as f32, 10.0 + 17.0 * j as f32)))
        .map(|(x, y)| Corner { x, y, score: 1.0 })
        .collect();
    // B's features are A's moved by 6 px: the same content is at 6 px.
    let b = GreyImage::from_fn(90, 90, |x, y| if x >= 6 { a.get(x - 6, y) } else { 0.5 });
    let pb: Vec<Corner> = pa.iter().map(|c| Corner { x: c.x + 6.0, ..*c }).collect();
    for (radius, expect_any) in [(Some(5.0), false), (Some(7.0), true), (None, true)] {
        let cfg = NccConfig::default().with_search_radius(radius);
        let mut m = NccMatcher::new(ctx(), cfg.clone()).unwrap();
        let gpu = m.match_features(&a, &pa, &b, &pb).unwrap();
        let cpu = ncc_match_cpu(&a, &pa, &b, &pb, &cfg).unwrap();
        assert_same_matches("radius", &gpu, &cpu);
        assert_eq!(!gpu.is_empty(), expect_any, "radius {radius:?}: {gpu:?}");
        assert!(gpu.iter().all(|m| m.a == m.b));
    }
}

#[test]
fn degenerate_inputs_give_no_matches_and_no_panic() {
    let cfg = NccConfig::default();
    let mut m = NccMatcher::new(ctx(), cfg.clone()).unwrap();
    let img = patterns::smooth_noise(30, 20, 1.5, 71);
    let one = [Corner {
        x: 15.0,
        y: 10.0,
        score: 1.0,
    }];
    let cases: Vec<(GreyImage, Vec<Corner>)> = vec![
        (GreyImage::filled(0, 0, 0.0), one.to_vec()),
        (
            GreyImage::filled(1, 1, 0.5),
            vec![Corner {
                x: 0.0,
                y: 0.0,
                score: 1.0,
            }],
        ),
        (
            GreyImage::filled(5, 5, 0.5),
            vec![Corner {
                x: 2.0,
                y: 2.0,
                score: 1.0,
            }],
        ),
        (GreyImage::filled(30, 20, 0.5), one.to_vec()),
        (GreyImage::filled(30, 20, f32::NAN), one.to_vec()),
        (img.clone(), vec![]),
    ];
    for (other, pts) in &cases {
        for (ia, pa, ib, pb) in [
            (&img, &one[..], other, &pts[..]),
            (other, &pts[..], &img, &one[..]),
        ] {
            let g = m.match_features(ia, pa, ib, pb).unwrap();
            let c = ncc_match_cpu(ia, pa, ib, pb, &cfg).unwrap();
            assert!(
                g.is_empty() && c.is_empty(),
                "{}x{}",
                other.width,
                other.height
            );
        }
    }
    // Bad configurations and sizes are typed errors.
    for bad in [
        NccConfig::default().with_patch(8),
        NccConfig::default().with_min_score(1.5),
        NccConfig::default().with_search_radius(Some(f32::NAN)),
    ] {
        assert!(matches!(
            NccMatcher::new(ctx(), bad.clone()),
            Err(FeatureError::Config(_))
        ));
        assert!(matches!(
            ncc_match_cpu(&img, &one, &img, &one, &bad),
            Err(FeatureError::Config(_))
        ));
    }
    let broken = GreyImage {
        width: 3,
        height: 3,
        data: vec![0.0; 2],
    };
    assert!(matches!(
        m.match_features(&broken, &one, &img, &one),
        Err(FeatureError::ImageSize { .. })
    ));
}

/// The matcher in host mode (the tracker's on CPU adapters) gives the CPU
/// reference's matches exactly (it runs it), and only for host images.
#[test]
fn host_mode_matches_are_the_references() {
    let mut rng = Rng::new(8);
    let a = patterns::smooth_noise(120, 90, 2.0, 31);
    let b = Warp {
        shift: [1.7, 2.2],
        angle: -0.02,
        centre: [60.0, 45.0],
        gain: 1.1,
        bias: -0.02,
    }
    .image(&a);
    let cfg = NccConfig::default().with_search_radius(Some(10.0));
    let mut m = NccMatcher::new(ctx(), cfg.clone()).unwrap();
    m.set_options(splattrack::features::NccOptions {
        host: true,
        ..m.options()
    });
    assert!(m.host());
    let fa = random_points(&mut rng, 200, a.width, a.height);
    let fb = random_points(&mut rng, 200, b.width, b.height);
    let host = m.match_features(&a, &fa, &b, &fb).unwrap();
    let cpu = ncc_match_cpu(&a, &fa, &b, &fb, &cfg).unwrap();
    assert!(!cpu.is_empty());
    assert_eq!(host, cpu);
    assert!(m.last_timings().passes.is_empty());
}
