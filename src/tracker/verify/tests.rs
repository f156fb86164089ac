//! The check's scores and rules on known scenes and values.

use super::*;

/// A frame with a bright textured square on a flat background, and the
/// square's coverage mask shifted by `dx`.
fn scene(dx: usize) -> (GreyImage, Vec<bool>, Vec<f32>) {
    let (w, h) = (64, 48);
    let inside =
        |x: usize, y: usize, off: usize| (16 + off..40 + off).contains(&x) && (12..36).contains(&y);
    let tex = |x: usize, y: usize| 0.6 + 0.2 * (((x * 7 + y * 3) % 5) as f32 / 4.0);
    let frame = GreyImage::from_fn(w, h, |x, y| if inside(x, y, 0) { tex(x, y) } else { 0.2 });
    let covered: Vec<bool> = (0..w * h).map(|i| inside(i % w, i / w, dx)).collect();
    let view: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if inside(x, y, dx) {
                tex(x - dx, y) * 0.5 + 0.1
            } else {
                0.0
            }
        })
        .collect();
    (frame, covered, view)
}

#[test]
fn the_right_pose_scores_high_and_passes() {
    let cfg = VerifyConfig::default();
    let (frame, covered, view) = scene(0);
    let s = score(&frame, &covered, Some(&view), 1.0, 4, &cfg);
    assert_eq!(s.covered_px, 24 * 24);
    // Gain and offset do not matter.
    assert!((s.zncc.unwrap() - 1.0).abs() < 1e-9, "{s:?}");
    assert!((s.edge_support.unwrap() - 1.0).abs() < 1e-12, "{s:?}");
    judge(&s, &cfg).unwrap();
}

#[test]
fn a_shifted_pose_loses_edges_and_correlation() {
    let cfg = VerifyConfig::default();
    let (frame, covered, view) = scene(8);
    let s = score(&frame, &covered, Some(&view), 1.0, 4, &cfg);
    // Only the top and bottom edges' overlap (16 of 24 columns) and the
    // left edge are still on frame edges: well under the strong level.
    let e = s.edge_support.unwrap();
    assert!(e < cfg.strong_edge_support, "{s:?}");
    assert!(s.zncc.unwrap() < cfg.min_zncc, "{s:?}");
    assert!(matches!(
        judge(&s, &cfg),
        Err(Unverified::Appearance { .. })
    ));
}

#[test]
fn out_of_view_and_tiny_objects_fail_first() {
    let cfg = VerifyConfig::default();
    let s = VerifyScores {
        visible: 0.2,
        covered_px: 10_000,
        zncc: Some(0.9),
        edge_support: Some(0.9),
        view_texture: None,
        shading_rms: None,
    };
    assert_eq!(
        judge(&s, &cfg).unwrap_err().to_string(),
        "object not in view: 20% of it in front of the camera and in the image (need 50%)"
    );
    let s = VerifyScores {
        visible: 1.0,
        covered_px: 20,
        ..s
    };
    assert_eq!(
        judge(&s, &cfg).unwrap_err().to_string(),
        "object covers 20 px (need 150)"
    );
    let nan = VerifyScores {
        visible: f64::NAN,
        ..s
    };
    assert!(matches!(
        judge(&nan, &cfg),
        Err(Unverified::NotInView { .. })
    ));
}

/// Scores of an object in full view, 1000 pixels covered.
fn s(zncc: Option<f64>, edge: f64) -> VerifyScores {
    VerifyScores {
        visible: 1.0,
        covered_px: 1000,
        zncc,
        edge_support: Some(edge),
        view_texture: None,
        shading_rms: None,
    }
}

#[test]
fn with_a_texture_both_must_hold_without_one_strong_edges() {
    let cfg = VerifyConfig::default();
    judge(&s(None, 0.8), &cfg).unwrap();
    judge(&s(Some(0.5), 0.4), &cfg).unwrap();
    assert!(judge(&s(Some(0.1), 0.4), &cfg).is_err());
    // The 30-degree turned blob: strong edges, no correlation.
    assert!(judge(&s(Some(-0.03), 0.84), &cfg).is_err());
    assert!(judge(&s(Some(0.9), 0.3), &cfg).is_err());
    assert!(judge(&s(None, 0.5), &cfg).is_err());
    assert_eq!(
        judge(&s(Some(0.1), 0.4), &cfg).unwrap_err().to_string(),
        "model does not match the image: ZNCC 0.10, contour edge support 0.40"
    );
}

#[test]
fn without_texture_strong_contour_edges_override_a_low_zncc() {
    let cfg = VerifyConfig::default();
    assert!(judge(&s(Some(0.24), 0.92), &cfg).is_err());
    judge_with_contour(&s(Some(0.24), 0.92), &cfg).unwrap();
    judge_with_contour(&s(None, 0.8), &cfg).unwrap();
    assert!(judge_with_contour(&s(Some(0.24), 0.5), &cfg).is_err());
    let hidden = VerifyScores {
        visible: 0.2,
        ..s(Some(0.9), 0.95)
    };
    assert!(matches!(
        judge_with_contour(&hidden, &cfg),
        Err(Unverified::NotInView { .. })
    ));
}

#[test]
fn a_textured_view_keeps_the_zncc_veto_against_strong_edges() {
    let cfg = VerifyConfig::default();
    // The textured blob turned by 60 degrees (tests/verify.rs).
    let turned = VerifyScores {
        view_texture: Some(0.32),
        ..s(Some(0.15), 0.89)
    };
    assert!(matches!(
        judge_with_contour(&turned, &cfg),
        Err(Unverified::Appearance { .. })
    ));
    // The untextured object's shading under another light.
    let shaded = VerifyScores {
        view_texture: Some(0.09),
        ..s(Some(0.24), 0.92)
    };
    judge_with_contour(&shaded, &cfg).unwrap();
    assert!(judge(&shaded, &cfg).is_err());
}

#[test]
fn an_outline_candidate_without_texture_needs_strong_edges_or_shading() {
    let cfg = VerifyConfig::default();
    let flat = |zncc, edge| VerifyScores {
        view_texture: Some(0.05),
        ..s(Some(zncc), edge)
    };
    // A distractor of the object's colour over clutter (plainbox, 49
    // degrees off): passes the plain rule, not the candidate's.
    judge(&flat(0.77, 0.57), &cfg).unwrap();
    assert!(judge_outline_candidate(&flat(0.77, 0.57), &cfg).is_err());
    judge_outline_candidate(&flat(0.74, 0.86), &cfg).unwrap();
    judge_outline_candidate(&flat(0.9, 0.6), &cfg).unwrap();
    assert!(judge_outline_candidate(&flat(0.9, 0.3), &cfg).is_err());
    // A textured view keeps the plain rule.
    let textured = VerifyScores {
        view_texture: Some(0.3),
        ..s(Some(0.5), 0.45)
    };
    judge_outline_candidate(&textured, &cfg).unwrap();
}

/// A contour-alone pose of an object of shading only: over clutter (a
/// loose fit) its outline needs the shading level of edges, which the
/// slipped poses of `plain` over clutter miss (frame 13: ZNCC 0.79, edges
/// 0.79, residual 0.90 px, 24 degrees off); a tight fit (`plainbox` on a
/// plain background at its right pose: edges 0.75, 0.2 px), an object
/// not of shading only, a textured view or a view without any texture
/// (no ZNCC) keep the rules before.
#[test]
fn a_loose_contour_of_an_object_of_shading_only_needs_more_edges() {
    let cfg = VerifyConfig::default();
    let flat = |zncc: Option<f64>, edge| VerifyScores {
        view_texture: Some(0.06),
        ..s(zncc, edge)
    };
    let slipped = flat(Some(0.79), 0.79);
    judge_with_contour(&slipped, &cfg).unwrap();
    let e = judge_contour_alone(&slipped, &cfg, true, 0.90).unwrap_err();
    assert!(matches!(e, Unverified::ShadingOnly { .. }), "{e:?}");
    let text = e.to_string();
    assert!(text.contains("0.79") && text.contains("0.85"), "{text}");
    judge_contour_alone(&flat(Some(0.95), 0.90), &cfg, true, 0.90).unwrap();
    judge_contour_alone(&flat(Some(0.6), 0.75), &cfg, true, 0.2).unwrap();
    judge_contour_alone(&slipped, &cfg, false, 0.90).unwrap();
    judge_contour_alone(&slipped, &cfg, true, f64::NAN).unwrap();
    judge_contour_alone(&flat(None, 0.75), &cfg, true, 0.90).unwrap();
    let textured = VerifyScores {
        view_texture: Some(0.3),
        ..s(Some(0.79), 0.79)
    };
    judge_contour_alone(&textured, &cfg, true, 0.90).unwrap();
    // What failed before still fails as it did.
    let weak = flat(Some(0.3), 0.5);
    assert_eq!(
        judge_contour_alone(&weak, &cfg, true, 0.2),
        judge_with_contour(&weak, &cfg)
    );
}

/// Known answers of the view's texture: zero on a linear ramp (any
/// shading that varies linearly), and on a square wave of amplitude
/// `a` and period twice the step along x each pixel's Laplacian is
/// `4 v` (its two neighbours along x the opposite value, along y the
/// same), so the RMS is exactly `4 a`. Pixels nearer the silhouette's
/// edge than the step are left out.
#[test]
fn view_texture_is_zero_on_a_ramp_and_known_on_a_square_wave() {
    let (w, h) = (40, 30);
    let frame = GreyImage::from_fn(w, h, |x, y| 0.3 + 0.01 * ((x * y) % 7) as f32);
    let d = 4;
    // Covered: a rectangle one pixel inside the image.
    let covered: Vec<bool> = (0..w * h)
        .map(|i| (1..w - 1).contains(&(i % w)) && (1..h - 1).contains(&(i / w)))
        .collect();
    let cfg = VerifyConfig::default();
    let ramp: Vec<f32> = (0..w * h)
        .map(|i| 0.2 + 0.01 * (i % w) as f32 + 0.005 * (i / w) as f32)
        .collect();
    let t = score(&frame, &covered, Some(&ramp), 1.0, d, &cfg)
        .view_texture
        .unwrap();
    assert!(t < 1e-5, "{t}");
    let a = 0.05;
    let wave: Vec<f32> = (0..w * h)
        .map(|i| {
            if (i % w) % (2 * d) < d {
                0.5 + a
            } else {
                0.5 - a
            }
        })
        .collect();
    let t = score(&frame, &covered, Some(&wave), 1.0, d, &cfg)
        .view_texture
        .unwrap();
    assert!((t - 4.0 * a as f64).abs() < 1e-5, "{t}");
    // Without a view, or with too few pixels far enough inside: none.
    assert_eq!(
        score(&frame, &covered, None, 1.0, d, &cfg).view_texture,
        None
    );
    let sliver: Vec<bool> = (0..w * h).map(|i| i / w == h / 2).collect();
    assert_eq!(
        score(&frame, &sliver, Some(&wave), 1.0, d, &cfg).view_texture,
        None
    );
}

#[test]
fn the_texture_step_follows_the_objects_size() {
    assert_eq!(texture_step(60.0), 2);
    assert_eq!(texture_step(120.0), 4);
    assert_eq!(texture_step(10.0), 1);
    assert_eq!(texture_step(1e4), 8);
    assert_eq!(texture_step(-50.0), 1);
    assert_eq!(texture_step(f64::NAN), 1);
    assert_eq!(texture_step(f64::INFINITY), 1);
}

/// Known answers of one contour pixel's rule, the gradient along the
/// normal given at each offset (search 2, band 8: the level from 4 to
/// 8 px on either side).
#[test]
fn an_edge_must_pass_the_floor_and_stand_out_from_the_quieter_side() {
    let cfg = VerifyConfig::default();
    let profile = |peak: f64, left: f64, right: f64| {
        move |s: i64| {
            Some(match s {
                1 => peak,
                -8..=-3 => left,
                3..=8 => right,
                _ => 0.001,
            })
        }
    };
    // 0.015 (under the old fixed 0.02) on a quiet surface: an edge.
    assert!(edge_hit(profile(0.015, 0.004, 0.003), &cfg));
    // The same where one side is busy: the quieter side decides.
    assert!(edge_hit(profile(0.015, 0.004, 0.05), &cfg));
    // Not 3 times the level of either side: clutter, no edge.
    assert!(!edge_hit(profile(0.05, 0.02, 0.03), &cfg));
    assert!(edge_hit(profile(0.061, 0.02, 0.03), &cfg));
    // Under the floor, however quiet.
    assert!(!edge_hit(profile(0.007, 0.0, 0.0), &cfg));
    // A side outside the image: the other one's level.
    let half = |s: i64| (s > -3).then_some(if s == 0 { 0.03 } else { 0.011 });
    assert!(!edge_hit(half, &cfg));
    let half = |s: i64| (s > -3).then_some(if s == 0 { 0.034 } else { 0.011 });
    assert!(edge_hit(half, &cfg));
    // No level beyond the search: the floor alone (the fixed rule).
    let fixed = VerifyConfig {
        edge_band_px: 3,
        ..cfg.clone()
    };
    assert!(edge_hit(profile(0.009, 0.5, 0.5), &fixed));
    assert!(!edge_hit(profile(0.009, 0.5, 0.5), &cfg));
}

#[test]
fn zncc_is_none_without_contrast_or_samples() {
    assert_eq!(zncc_of((0..100).map(|i| (1.0, i as f64))), None);
    assert_eq!(zncc_of((0..10).map(|i| (i as f64, i as f64))), None);
    // A textured view against a flat frame: no match.
    assert_eq!(zncc_of((0..100).map(|i| (i as f64, 0.5))), Some(0.0));
    let anti = zncc_of((0..100).map(|i| (i as f64, -2.0 * i as f64 + 3.0))).unwrap();
    assert!((anti + 1.0).abs() < 1e-9);
}
