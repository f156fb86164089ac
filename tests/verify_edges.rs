//! The pose check's edge test on synthetic scenes (no GPU: the CPU
//! reference `verify::score`): the right pose passes, wrong ones fail, on
//! a cluttered background (coloured blotches, pixel noise, thin line
//! segments) and on a plain one with an outline of little contrast.
//!
//! Wrong poses: the near-symmetric silhouette turned by 30 degrees,
//! shifted by 6 px, 15 px and one object width (80 px), and placed on a
//! distractor of the same shape. With a texture the ZNCC and the edges
//! are both checked (`judge`); without one the edges alone decide, at the
//! strong level (`judge` without a view, `judge_with_contour` of an
//! untextured view).

mod verify_common;

use splattrack::features::GreyImage;
use splattrack::tracker::verify::{
    Unverified, VerifyConfig, VerifyScores, judge, judge_with_contour, score,
};
use verify_common::{At, Background, Fill, frame, view};

const W: usize = 240;
const H: usize = 180;

fn scores(frame: &GreyImage, at: At, textured: bool, cfg: &VerifyConfig) -> VerifyScores {
    let (covered, grey) = view(W, H, at);
    let view = textured.then_some(grey.as_slice());
    score(frame, &covered, view, 1.0, 2, cfg)
}

/// The old rule: any gradient of 0.02 along the normal within 2 px.
fn fixed_rule() -> VerifyConfig {
    VerifyConfig {
        edge_gradient: 0.02,
        edge_contrast: 0.0,
        ..Default::default()
    }
}

fn edges(s: &VerifyScores) -> f64 {
    s.edge_support.expect("a contour")
}

/// The wrong poses of an object at `at`.
fn wrong(at: At) -> [(&'static str, At); 4] {
    [
        ("turned 30 deg", at.turned(30.0)),
        ("shifted 6 px", at.shifted(6.0)),
        ("shifted 15 px", at.shifted(15.0)),
        ("shifted one width", at.shifted(80.0)),
    ]
}

#[test]
fn a_textured_object_in_clutter_passes_only_at_its_pose() {
    let cfg = VerifyConfig::default();
    let at = At::new(110.0, 90.0, 10.0);
    let f = frame(W, H, Background::Clutter, &[(at, Fill::Textured)], 1);
    let s = scores(&f, at, true, &cfg);
    let old = scores(&f, at, true, &fixed_rule());
    eprintln!("right: {s:?} (the fixed rule {:.3})", edges(&old));
    assert!(s.zncc.unwrap() > 0.9, "{s:?}");
    // Where the object's texture meets clutter of the same grey, there is
    // no edge to find: the textured rule needs less.
    assert!(edges(&s) >= 0.55, "{s:?}");
    judge(&s, &cfg).unwrap();
    for (what, pose) in wrong(at) {
        let s = scores(&f, pose, true, &cfg);
        let bare = scores(&f, pose, false, &cfg);
        let old = scores(&f, pose, false, &fixed_rule());
        eprintln!(
            "{what}: {s:?}; edges alone {:.3} (the fixed rule {:.3})",
            edges(&bare),
            edges(&old)
        );
        assert!(
            matches!(judge(&s, &cfg), Err(Unverified::Appearance { .. })),
            "{what}: {s:?}"
        );
        // The outline alone does not pass it either.
        assert!(judge(&bare, &cfg).is_err(), "{what}: {bare:?}");
        assert!(edges(&bare) < cfg.strong_edge_support, "{what}: {bare:?}");
    }
}

#[test]
fn an_untextured_object_in_clutter_passes_only_at_its_pose() {
    let cfg = VerifyConfig::default();
    let at = At::new(120.0, 85.0, -20.0);
    let f = frame(W, H, Background::Clutter, &[(at, Fill::Plain(0.8))], 2);
    let s = scores(&f, at, false, &cfg);
    let old = scores(&f, at, false, &fixed_rule());
    eprintln!("right: {s:?} (the fixed rule {:.3})", edges(&old));
    assert!(edges(&s) >= 0.9, "{s:?}");
    judge(&s, &cfg).unwrap();
    for (what, pose) in wrong(at) {
        let s = scores(&f, pose, false, &cfg);
        let old = scores(&f, pose, false, &fixed_rule());
        eprintln!("{what}: {s:?} (the fixed rule {:.3})", edges(&old));
        assert!(edges(&s) < cfg.strong_edge_support, "{what}: {s:?}");
        assert!(judge(&s, &cfg).is_err(), "{what}: {s:?}");
        assert!(judge_with_contour(&s, &cfg).is_err(), "{what}: {s:?}");
    }
}

#[test]
fn a_distractor_of_the_same_shape_fails_on_its_texture() {
    // The same outline elsewhere: its edges support it fully, and only
    // the texture tells it from the object (plain, or under no contrast
    // at all: the frame shows nothing of the view's texture there).
    let cfg = VerifyConfig::default();
    let at = At::new(65.0, 90.0, 0.0);
    let other = At::new(175.0, 90.0, 0.0);
    for fill in [Fill::Plain(0.85), Fill::Plain(0.2)] {
        let f = frame(
            W,
            H,
            Background::Clutter,
            &[(at, Fill::Textured), (other, fill)],
            3,
        );
        judge(&scores(&f, at, true, &cfg), &cfg).unwrap();
        let s = scores(&f, other, true, &cfg);
        eprintln!("{fill:?}: {s:?}");
        assert!(edges(&s) >= 0.9, "{s:?}");
        assert!(
            matches!(judge(&s, &cfg), Err(Unverified::Appearance { .. })),
            "{s:?}"
        );
        // A frame without any contrast there correlates 0 with a textured
        // view, never "no texture to compare" (which would leave the
        // outline alone to decide).
        assert_eq!(s.zncc, Some(0.0), "{s:?}");
    }
}

#[test]
fn a_faint_outline_on_a_plain_surface_supports_its_pose_only() {
    let cfg = VerifyConfig::default();
    let at = At::new(120.0, 90.0, 15.0);
    // Grey 0.55 on 0.50, the camera's noise +-0.02; and fainter, 0.53 on
    // 0.50 with noise +-0.01, where a fixed threshold of 0.02 fails the
    // right pose (its outline's gradient is about 0.015).
    for (object, noise, seed) in [(0.55, 0.02, 4), (0.53, 0.01, 5)] {
        let bg = Background::Plain { grey: 0.5, noise };
        let f = frame(W, H, bg, &[(at, Fill::Plain(object))], seed);
        let s = scores(&f, at, false, &cfg);
        let old = scores(&f, at, false, &fixed_rule());
        eprintln!(
            "{object} on 0.5, noise {noise}: right {s:?} (the fixed rule {:.3})",
            edges(&old)
        );
        assert!(edges(&s) >= 0.9, "{s:?}");
        judge(&s, &cfg).unwrap();
        if object < 0.54 {
            assert!(edges(&old) < cfg.strong_edge_support, "{old:?}");
        }
        for (what, pose) in wrong(at) {
            let s = scores(&f, pose, false, &cfg);
            eprintln!("{what}: {s:?}");
            assert!(edges(&s) < cfg.strong_edge_support, "{what}: {s:?}");
            assert!(judge(&s, &cfg).is_err(), "{what}: {s:?}");
        }
    }
}
