//! Renders of the model a frame ([`StageTimes::renders`]) and the steps
//! that stand in for one, on a synthetic sequence rendered by the synth
//! CPU triangle rasteriser: the blob along the Fig. 10 trajectory, frames
//! 50..58 at 320x240, with its 12 keyframes.

mod tracking_common;

use splattrack::gpu::shared_test_context;
use splattrack::tracker::{
    ContourConfig, Modalities, Mode, StageTimes, Status, TrackResult, Tracker, TrackerConfig,
};
use std::sync::OnceLock;
use tracking_common::Fig10;

fn fixture() -> &'static Fig10 {
    static F: OnceLock<Fig10> = OnceLock::new();
    F.get_or_init(|| Fig10::blob(50..58))
}

/// Every frame's result and its rotation error, degrees.
fn track(config: TrackerConfig) -> Vec<(TrackResult, f64)> {
    let f = fixture();
    let mut t = Tracker::builder(shared_test_context(), f.scene.model.clone(), f.scene.cam)
        .keyframes(f.store.clone())
        .config(config)
        .initial_pose(f.frames[0].pose)
        .build()
        .expect("tracker");
    f.frames
        .iter()
        .map(|frame| {
            let r = t.track(&frame.image).expect("track");
            let e = r.pose.rotation_error_deg(&frame.pose);
            (r, e)
        })
        .collect()
}

fn renders(results: &[(TrackResult, f64)]) -> Vec<f64> {
    results.iter().map(|(r, _)| r.times.renders).collect()
}

fn mean_error(results: &[(TrackResult, f64)]) -> f64 {
    results.iter().map(|(_, e)| e).sum::<f64>() / results.len() as f64
}

fn all_tracking(results: &[(TrackResult, f64)], what: &str) {
    for (i, (r, _)) in results.iter().enumerate() {
        assert_eq!(r.status, Status::Tracking, "{what}: frame {i}");
    }
}

/// KF+IT renders the novel view and the check's view (the next frame's IT
/// step takes the check's over); IT alone renders the check's view only
/// (after the first frame, whose IT step has no previous frame). Means
/// over frames add up.
#[test]
fn each_frame_counts_its_renders() {
    let kf_it = track(TrackerConfig::default());
    all_tracking(&kf_it, "KF+IT");
    assert_eq!(renders(&kf_it), vec![2.0; kf_it.len()], "KF+IT");
    let it = track(TrackerConfig {
        mode: Mode::It,
        ..Default::default()
    });
    all_tracking(&it, "IT");
    assert_eq!(renders(&it), vec![1.0; it.len()], "IT");
    let mut mean = StageTimes::default();
    for (r, _) in &kf_it {
        mean.add_scaled(&r.times, 1.0 / kf_it.len() as f64);
    }
    assert!((mean.renders - 2.0).abs() < 1e-9, "{}", mean.renders);
}

/// With [`TrackerConfig::reuse_render_px`], a KF step whose correction
/// moved the model less than that scores the check on its novel view, and
/// the next IT step takes that view over: fewer renders, every frame
/// still tracking, about as accurate (on the real cube at 1 px: 1.2
/// renders a frame instead of 2, and 0.380 degrees against 0.349, which is
/// why it is off by default).
#[test]
fn a_near_novel_view_stands_for_the_checks_render() {
    let base = track(TrackerConfig::default());
    let reused = track(TrackerConfig {
        reuse_render_px: 2.0,
        ..Default::default()
    });
    all_tracking(&reused, "reused");
    let (n0, n): (f64, f64) = (renders(&base).iter().sum(), renders(&reused).iter().sum());
    let (e0, e) = (mean_error(&base), mean_error(&reused));
    eprintln!("renders {n0} -> {n}; rotation error {e0:.3} -> {e:.3} deg");
    assert!(n < n0, "{:?}", renders(&reused));
    assert!(e <= e0 + 0.1, "{e0} -> {e}");
}

/// The contour alone (no texture step renders): the previous check's
/// render, at the pose the frame starts from, seeds the contour's first
/// round, which then renders only when its correction is large. Against
/// the contour's own renders every round (`seed_render` off): fewer
/// renders, every frame tracking, as accurate.
#[test]
fn the_checks_render_seeds_the_contour_alone() {
    let run = |seed_render: bool| {
        track(TrackerConfig {
            modalities: Modalities::CONTOUR,
            contour: ContourConfig {
                seed_render,
                ..Default::default()
            },
            ..Default::default()
        })
    };
    let (own, seeded) = (run(false), run(true));
    all_tracking(&own, "own renders");
    all_tracking(&seeded, "seeded");
    let (n0, n): (f64, f64) = (renders(&own).iter().sum(), renders(&seeded).iter().sum());
    let (e0, e) = (mean_error(&own), mean_error(&seeded));
    eprintln!("renders {n0} -> {n}; rotation error {e0:.3} -> {e:.3} deg");
    assert!(n < n0, "{:?} against {:?}", renders(&seeded), renders(&own));
    for (r, _) in &seeded {
        assert!(
            r.times.renders <= r.times.contour_renders + 1.0,
            "{:?}",
            r.times
        );
    }
    assert!(e <= e0 + 0.05, "{e0} -> {e}");
}
