//! The tracker on a synthetic sequence rendered by the synth CPU triangle
//! rasteriser (never by the splatter under test): accuracy of the three
//! modes against the exact ground truth, loss detection, and the typed
//! errors of bad input.
//!
//! The sequence: the `blob` object along the `fig10` trajectory at the
//! demo's speed (100 frames for the whole trajectory), 320x240, a 60k-point
//! model sampled from the mesh, the 12 synth keyframes. The window tracked is
//! frames 50..70, the rotation about the camera's x axis out to 20 degrees
//! and half way back. Measured on lavapipe with a 20k-point model, KF+IT
//! failed the 2-degree bound there (3.1 degrees, one frame lost); with 60k
//! points the largest error over the windows 0..20, 50..70 and 84..100 was
//! 1.3 degrees (84..100, the rotation about z), 0.87 degrees here.

mod tracking_common;

use splattrack::features::FeatureBackend;
use splattrack::geometry::Pose;
use splattrack::gpu::{GpuContext, shared_test_context};
use splattrack::keyframes::KeyframeStore;
use splattrack::rng::Rng;
use splattrack::tracker::{
    Execution, Modalities, Mode, Status, TrackError, Tracker, TrackerConfig,
};
use std::sync::{Arc, OnceLock};
use tracking_common::Fig10;

const FIRST: usize = 50;
const COUNT: usize = 20;

fn fixture() -> &'static Fig10 {
    static F: OnceLock<Fig10> = OnceLock::new();
    F.get_or_init(|| Fig10::blob(FIRST..FIRST + COUNT))
}

fn tracker(mode: Mode, store: Option<KeyframeStore>, initial: Pose) -> Tracker {
    tracker_with(mode, store, initial, Execution::default())
}

/// [`tracker`] on the code paths of `execution`.
fn tracker_with(
    mode: Mode,
    store: Option<KeyframeStore>,
    initial: Pose,
    execution: Execution,
) -> Tracker {
    let f = fixture();
    Tracker::builder(shared_test_context(), f.scene.model.clone(), f.scene.cam)
        .maybe_keyframes(store)
        .config(TrackerConfig {
            mode,
            ..Default::default()
        })
        .initial_pose(initial)
        .execution(execution)
        .build()
        .expect("tracker")
}

/// A tracker on `ctx` with a GPU's frame loop (features in the shaders,
/// the resident loop), texture and optionally the contour, from the
/// window's first frame, on the code paths of `execution`.
fn gpu_loop_tracker(ctx: &GpuContext, contour: bool, execution: Execution) -> Tracker {
    let f = fixture();
    Tracker::builder(ctx, f.scene.model.clone(), f.scene.cam)
        .keyframes(f.store.clone())
        .config(TrackerConfig {
            feature_backend: FeatureBackend::Gpu,
            resident: Some(true),
            modalities: Modalities {
                texture: true,
                contour,
            },
            ..Default::default()
        })
        .initial_pose(f.frames[0].pose)
        .execution(execution)
        .build()
        .expect("tracker")
}

/// Tracks the first `n` frames of the window; returns per-frame (rotation
/// deg, translation % of the diameter, status).
fn run(mode: Mode, n: usize) -> Vec<(f64, f64, Status)> {
    let f = fixture();
    let mut t = tracker(mode, Some(f.store.clone()), f.frames[0].pose);
    f.frames[..n]
        .iter()
        .map(|fr| {
            let r = t.track(&fr.image).expect("track");
            assert_eq!(r.pose.rotation, t.pose().rotation);
            (
                r.pose.rotation_error_deg(&fr.pose),
                100.0 * r.pose.translation_error(&fr.pose) / f.scene.diameter,
                r.status,
            )
        })
        .collect()
}

fn report(mode: Mode, errs: &[(f64, f64, Status)]) -> (f64, f64) {
    let rot = errs.iter().map(|e| e.0).fold(0.0, f64::max);
    let tr = errs.iter().map(|e| e.1).fold(0.0, f64::max);
    eprintln!(
        "{}: max rotation error {rot:.3} deg, max translation error {tr:.3}% of the diameter",
        mode.name()
    );
    (rot, tr)
}

#[test]
fn kf_it_stays_within_2_degrees_and_2_percent_at_every_frame() {
    // The criterion (measured: up to 0.87 deg and 0.56%).
    let errs = run(Mode::KfIt, COUNT);
    report(Mode::KfIt, &errs);
    for (i, (rot, tr, status)) in errs.iter().enumerate() {
        let frame = FIRST + i;
        assert_eq!(*status, Status::Tracking, "frame {frame}");
        assert!(
            *rot < 2.0 && *tr < 2.0,
            "frame {frame}: {rot:.3} deg, {tr:.3}% of the diameter"
        );
    }
}

#[test]
fn it_mode_tracks_with_bounded_drift() {
    // Frame to frame only: no keyframe ever corrects it, so it drifts.
    // The first 12 frames: out to the 20-degree turn and back a little
    // (measured on lavapipe: up to 1.45 deg and 0.73%; over all 20 frames
    // it reaches 3.1 deg).
    let errs = run(Mode::It, 12);
    let (rot, tr) = report(Mode::It, &errs);
    assert!(errs.iter().all(|e| e.2 == Status::Tracking));
    assert!(rot < 4.0 && tr < 2.5, "{rot:.3} deg, {tr:.3}%");
}

#[test]
fn kf_mode_tracks_without_drift() {
    // Keyframes only, the first 12 frames (measured: up to 0.91 deg and
    // 0.43%).
    let errs = run(Mode::Kf, 12);
    let (rot, tr) = report(Mode::Kf, &errs);
    assert!(errs.iter().all(|e| e.2 == Status::Tracking));
    assert!(rot < 3.0 && tr < 2.0, "{rot:.3} deg, {tr:.3}%");
}

/// Pure noise: the object is gone.
fn noise_frame(seed: u64) -> image::RgbImage {
    let cam = fixture().scene.cam;
    let mut rng = Rng::new(seed);
    image::RgbImage::from_fn(cam.width, cam.height, |_, _| {
        image::Rgb([0, 0, 0].map(|_: u8| rng.below(256) as u8))
    })
}

#[test]
fn noise_frames_are_lost_keep_the_last_good_pose_then_recover() {
    let f = fixture();
    let mut t = tracker(Mode::KfIt, Some(f.store.clone()), f.frames[0].pose);
    let mut last_good = None;
    for fr in &f.frames[..4] {
        let r = t.track(&fr.image).unwrap();
        assert_eq!(r.status, Status::Tracking);
        last_good = Some(r.pose);
    }
    let last_good = last_good.unwrap();
    let mut first_lost = None;
    for k in 0..4 {
        let r = t.track(&noise_frame(100 + k as u64)).unwrap();
        if r.status == Status::Lost {
            first_lost.get_or_insert(k);
            assert!(r.reason.is_some(), "a lost frame says why");
        }
        if first_lost.is_some() {
            assert_eq!(r.status, Status::Lost, "noise frame {k} after a loss");
            // Lost frames report the last good pose, unchanged.
            assert_eq!(r.pose.rotation, last_good.rotation, "noise frame {k}");
            assert_eq!(r.pose.translation, last_good.translation, "noise frame {k}");
        } else {
            // Not yet flagged: the pose must not have jumped.
            assert!(r.pose.rotation_error_deg(&last_good) < 2.0);
        }
    }
    let first_lost = first_lost.expect("noise frames never flagged lost");
    assert!(first_lost <= 1, "lost only at noise frame {first_lost}");
    assert_eq!(t.pose().rotation, last_good.rotation);
    // The object comes back where it was: the tracker recovers against the
    // keyframes (measured: at once, within 0.72 deg and 0.29%).
    let mut recovered = None;
    for (k, fr) in f.frames[4..8].iter().enumerate() {
        let r = t.track(&fr.image).unwrap();
        if r.status == Status::Tracking {
            recovered.get_or_insert(k);
            let rot = r.pose.rotation_error_deg(&fr.pose);
            let tr = 100.0 * r.pose.translation_error(&fr.pose) / f.scene.diameter;
            assert!(
                rot < 2.0 && tr < 2.0,
                "frame {k} after the noise: {rot:.3} deg, {tr:.3}%"
            );
        }
    }
    assert!(
        recovered.is_some_and(|k| k <= 1),
        "recovered at {recovered:?}"
    );
}

#[test]
fn wrong_frame_size_is_a_typed_error() {
    let f = fixture();
    let mut t = tracker(Mode::KfIt, Some(f.store.clone()), f.frames[0].pose);
    let small = image::RgbImage::new(160, 120);
    match t.track(&small) {
        Err(TrackError::FrameSize {
            got_w: 160,
            got_h: 120,
            want_w: 320,
            want_h: 240,
        }) => {}
        other => panic!("expected FrameSize, got {:?}", other.map(|r| r.status)),
    }
    // The tracker is still usable on a proper frame.
    let r = t.track(&f.frames[0].image).unwrap();
    assert_eq!(r.status, Status::Tracking);
}

#[test]
fn object_behind_the_camera_is_refused() {
    let f = fixture();
    let mut behind = f.frames[0].pose;
    behind.translation.z = -behind.translation.z;
    let e = Tracker::builder(shared_test_context(), f.scene.model.clone(), f.scene.cam)
        .keyframes(f.store.clone())
        .config(TrackerConfig::default())
        .initial_pose(behind)
        .build();
    assert!(
        matches!(e, Err(TrackError::ObjectNotInView)),
        "{:?}",
        e.err()
    );
    // Far off to the side (the whole object outside the image) too.
    let mut aside = f.frames[0].pose;
    aside.translation.x += 5.0;
    let e = Tracker::builder(shared_test_context(), f.scene.model.clone(), f.scene.cam)
        .config(TrackerConfig::default())
        .initial_pose(aside)
        .build();
    assert!(
        matches!(e, Err(TrackError::ObjectNotInView)),
        "{:?}",
        e.err()
    );
}

#[test]
fn kf_mode_needs_keyframes_or_model_colours() {
    let f = fixture();
    let mut bare = f.scene.model.clone();
    bare.colors = None;
    for mode in [Mode::Kf, Mode::KfIt] {
        let e = Tracker::builder(shared_test_context(), bare.clone(), f.scene.cam)
            .config(TrackerConfig {
                mode,
                ..Default::default()
            })
            .initial_pose(f.frames[0].pose)
            .build();
        match e {
            Err(TrackError::NeedsKeyframes(name)) => assert_eq!(name, mode.name()),
            other => panic!(
                "{}: expected NeedsKeyframes, got {:?}",
                mode.name(),
                other.err()
            ),
        }
    }
    // IT needs neither; a coloured model serves as the single texture.
    tracker(Mode::It, None, f.frames[0].pose);
    let t = tracker(Mode::Kf, None, f.frames[0].pose);
    assert_eq!(t.keyframes().map(|s| s.keyframes.len()), Some(1));
}

/// Host memory: a store given by `Arc` is the tracker's own,
/// not a copy (a 1M-point model's 12 keyframes hold 156 MB of colours and
/// visibility; two would double it), and the frames
/// track as with a store moved in.
#[test]
fn a_shared_store_is_used_in_place_and_tracks_the_same() {
    let f = fixture();
    let shared = Arc::new(f.store.clone());
    let config = TrackerConfig::default();
    let mut t = Tracker::builder(shared_test_context(), f.scene.model.clone(), f.scene.cam)
        .keyframes(Arc::clone(&shared))
        .config(config.clone())
        .initial_pose(f.frames[0].pose)
        .build()
        .unwrap();
    assert!(std::ptr::eq(t.keyframes().unwrap(), &*shared));
    assert_eq!(Arc::strong_count(&shared), 2);
    let mut moved = tracker(Mode::KfIt, Some(f.store.clone()), f.frames[0].pose);
    assert!(!std::ptr::eq(moved.keyframes().unwrap(), &*shared));
    for fr in &f.frames[..3] {
        let (a, b) = (t.track(&fr.image).unwrap(), moved.track(&fr.image).unwrap());
        assert_eq!(a.pose, b.pose);
        assert_eq!(a.status, b.status);
    }
    drop(t);
    assert_eq!(Arc::strong_count(&shared), 1);
    // Searching trackers share theirs too.
    let s = Tracker::builder(shared_test_context(), f.scene.model.clone(), f.scene.cam)
        .keyframes(Arc::clone(&shared))
        .config(config)
        .build()
        .unwrap();
    assert!(std::ptr::eq(s.keyframes().unwrap(), &*shared));
}

/// The tracker confined to the object's window (renders, reads,
/// Harris, NCC, contour) against the same tracker over the whole image, on
/// the first 8 frames in KF+IT (4 with texture and contour). The windows
/// give the full image's pixels up to f32 rounding
/// (tests/splat_window.rs), which may move a corner by a rounding or flip
/// a match at its threshold: the poses agree as [`assert_same_poses`]
/// says (frame 3's two poses 0.06 degrees apart: the H200 found the
/// other one with its kernels), every status is the same. With the contour, within
/// 0.15 degrees and 0.1%: a covered pixel at a splat's very edge may flip
/// with the rounding, which moves a contour point within its cell, and
/// the frames after follow from poses 1e-5 degrees apart (measured
/// 0.04-0.08 degrees on frames 1-3 since the mixed boundary's shade, 1e-5
/// before it; over 40 frames of `plain`, contour alone, `track` against
/// `track --full-frame` parts from frame 8 before the shade and from frame
/// 17 with it, 0.02-0.57 degrees apart after).
#[test]
fn windows_give_the_poses_of_the_whole_image() {
    assert_same_poses(
        |contour| TrackerConfig {
            modalities: Modalities {
                texture: true,
                contour,
            },
            ..Default::default()
        },
        |contour| TrackerConfig {
            windows: false,
            modalities: Modalities {
                texture: true,
                contour,
            },
            ..Default::default()
        },
        [8, 4],
    );
}

/// Trackers of configurations `a(contour)` and `b(contour)` from the first
/// frame's true pose, over the first `n[0]` frames without the contour and
/// `n[1]` with it: `tracking` at every frame in both, the poses within 0.1
/// degrees and 0.05% of the diameter at every frame and 0.03 degrees on
/// average without the contour (with it 0.15 degrees and 0.1%). (Frame 3
/// of this sequence solves to one of two poses 0.06 degrees apart, 0.369
/// and 0.394 degrees from the truth, as one match falls on either side of
/// a threshold: which one depends on roundings that differ between the
/// configurations compared here, between adapters and between kernels of
/// the same arithmetic compiled differently; the frames after it come back
/// together, 0.02-0.04 degrees apart, 0.01 by frame 7.)
fn assert_same_poses(
    a: impl Fn(bool) -> TrackerConfig,
    b: impl Fn(bool) -> TrackerConfig,
    n: [usize; 2],
) {
    assert_same_poses_set(a, b, n, |_| Execution::default());
}

/// [`assert_same_poses`] with `set(tracker, is_b)` applied to each new
/// tracker.
fn assert_same_poses_set(
    a: impl Fn(bool) -> TrackerConfig,
    b: impl Fn(bool) -> TrackerConfig,
    n: [usize; 2],
    execution: impl Fn(bool) -> Execution,
) {
    let f = fixture();
    let make = |config: TrackerConfig, is_b: bool| {
        Tracker::builder(shared_test_context(), f.scene.model.clone(), f.scene.cam)
            .keyframes(f.store.clone())
            .config(config)
            .initial_pose(f.frames[0].pose)
            .execution(execution(is_b))
            .build()
            .expect("tracker")
    };
    for (contour, n) in [(false, n[0]), (true, n[1])] {
        let (mut ta, mut tb) = (make(a(contour), false), make(b(contour), true));
        let mut sum_rot = 0.0;
        for (i, fr) in f.frames[..n].iter().enumerate() {
            let (ra, rb) = (ta.track(&fr.image).unwrap(), tb.track(&fr.image).unwrap());
            let rot = ra.pose.rotation_error_deg(&rb.pose);
            let tr = 100.0 * ra.pose.translation_error(&rb.pose) / f.scene.diameter;
            eprintln!(
                "contour {contour}, frame {i}: {rot:.5} deg, {tr:.5}%, inliers {} / {}",
                ra.inliers, rb.inliers
            );
            assert_eq!(ra.status, Status::Tracking, "contour {contour}, frame {i}");
            assert_eq!(ra.status, rb.status, "contour {contour}, frame {i}");
            let (most_rot, most_tr) = if contour { (0.15, 0.1) } else { (0.1, 0.05) };
            assert!(
                rot < most_rot && tr < most_tr,
                "contour {contour}, frame {i}: {rot} deg, {tr}%"
            );
            sum_rot += rot;
        }
        if !contour {
            let mean = sum_rot / n as f64;
            assert!(mean < 0.03, "{mean} degrees apart on average");
        }
    }
}

/// The GPUs' kernels (workgroup tiles, split counts, a workgroup a match,
/// window or corner: `Execution::gpu_kernels`) against the CPU
/// adapters' (one thread an item) in the GPU frame loop (resident, features
/// in the shaders), on lavapipe whatever its defaults: the same poses.
#[test]
fn the_gpus_kernels_give_the_cpu_adapters_poses() {
    let gpu_loop = |contour| TrackerConfig {
        resident: Some(true),
        feature_backend: FeatureBackend::Gpu,
        modalities: Modalities {
            texture: true,
            contour,
        },
        ..Default::default()
    };
    assert_same_poses_set(gpu_loop, gpu_loop, [6, 4], |is_b| Execution {
        gpu_kernels: Some(!is_b),
        ..Default::default()
    });
}

/// The GPUs' corner selection in one workgroup a pass (the default for
/// the loop's detections of a few hundred candidates) against the same
/// selection split over workgroups, in the GPU frame loop on lavapipe:
/// the same corners, so the same poses bit for bit, with the contour and
/// without.
#[test]
fn the_selection_in_one_workgroup_gives_the_split_selections_poses() {
    let f = fixture();
    let ctx = shared_test_context();
    for (contour, n) in [(false, 5), (true, 3)] {
        let make = |small: bool| {
            gpu_loop_tracker(
                ctx,
                contour,
                Execution {
                    gpu_kernels: Some(true),
                    harris_small_selection: Some(small),
                    ..Default::default()
                },
            )
        };
        let (mut one, mut split) = (make(true), make(false));
        for (i, fr) in f.frames[..n].iter().enumerate() {
            let (a, b) = (
                one.track(&fr.image).unwrap(),
                split.track(&fr.image).unwrap(),
            );
            let at = format!("contour {contour}, frame {i}");
            assert_eq!(a.status, Status::Tracking, "{at}");
            assert_eq!((a.status, a.inliers), (b.status, b.inliers), "{at}");
            assert_eq!(a.pose.rotation, b.pose.rotation, "{at}");
            assert_eq!(a.pose.translation, b.pose.translation, "{at}");
        }
    }
}

#[test]
fn the_windowed_silhouette_is_the_whole_frame_one() {
    // Overlays and the live view splat only the window the model can cover.
    let f = fixture();
    let make = |windows: bool| {
        Tracker::builder(shared_test_context(), f.scene.model.clone(), f.scene.cam)
            .config(TrackerConfig {
                windows,
                ..Default::default()
            })
            .initial_pose(f.frames[0].pose)
            .build()
            .expect("tracker")
    };
    let (mut windowed, mut whole) = (make(true), make(false));
    let same = |a: &[bool], b: &[bool]| {
        let covered = b.iter().filter(|v| **v).count();
        assert!(covered > 2000, "{covered} pixels covered");
        let differ = a.iter().zip(b).filter(|(x, y)| x != y).count();
        assert_eq!(differ, 0, "{differ} of {covered} pixels differ");
    };
    for fr in &f.frames[..3] {
        let a = windowed.silhouette(&fr.pose).unwrap();
        let b = whole.silhouette(&fr.pose).unwrap();
        same(&a, &b);
        // At a tracked pose: the coverage of the check's render, kept.
        let r = windowed.track(&fr.image).unwrap();
        assert_eq!(r.status, Status::Tracking);
        let a = windowed.silhouette(&r.pose).unwrap();
        let b = whole.silhouette(&r.pose).unwrap();
        same(&a, &b);
    }
}

#[test]
fn the_steady_loop_allocates_no_gpu_buffers() {
    steady_loop_allocates_nothing(false);
}

#[test]
fn the_steady_loop_allocates_no_gpu_buffers_with_everything_resident() {
    // The GPU's default: the check scored and the matching done on the GPU
    // (resident frames, the view left on the GPU, refinement there).
    steady_loop_allocates_nothing(true);
}

fn steady_loop_allocates_nothing(resident: bool) {
    // Read/gather outputs, staging buffers, Harris and NCC
    // buffers and render targets (one set per window size) are kept and
    // reused across frames, and the bind groups made on them too.
    // Resident: a GPU's defaults (corners and matches in the shaders
    // too); else a CPU adapter's (on the host). Frames 0..8 and back:
    // going back, every window size has been seen (and is still kept:
    // three spare sets) and every buffer has grown, so no frame
    // allocates or binds anew. A context of its own, so that other
    // tests' buffers are not counted.
    use splattrack::gpu::own_test_context;
    let f = fixture();
    let ctx = own_test_context();
    let mut t = Tracker::builder(&ctx, f.scene.model.clone(), f.scene.cam)
        .keyframes(f.store.clone())
        .config(TrackerConfig {
            feature_backend: if resident {
                FeatureBackend::Gpu
            } else {
                FeatureBackend::Host
            },
            // Both the matching and the check (TrackerConfig::resident).
            resident: Some(resident),
            ..Default::default()
        })
        .initial_pose(f.frames[0].pose)
        .build()
        .expect("tracker");
    let order: Vec<usize> = (0..8).chain((0..7).rev()).collect();
    let made: Vec<(u64, u64)> = order
        .iter()
        .map(|&i| {
            let before = (ctx.stats().buffers_created, ctx.stats().bind_groups_created);
            let r = t.track(&f.frames[i].image).expect("track");
            assert_eq!(r.status, Status::Tracking, "frame {i}");
            (
                ctx.stats().buffers_created - before.0,
                ctx.stats().bind_groups_created - before.1,
            )
        })
        .collect();
    eprintln!("GPU buffers and bind groups made per frame, 0..8 and back: {made:?}");
    assert!(made[0].0 > 0, "the first frame makes the buffers: {made:?}");
    assert!(made[0].1 > 0, "and binds them: {made:?}");
    assert!(
        made[8..].iter().all(|&n| n == (0, 0)),
        "frames seen before allocate or bind: {made:?}"
    );
}

/// Tracks the fixture's first 6 frames with `gpu` and `host` (checked on
/// the GPU and on the host): the same statuses and covered pixels, the
/// scores to f32 rounding (tests/verify_gpu.rs), the same poses.
fn same_checks(mut gpu: Tracker, mut host: Tracker) {
    let f = fixture();
    for (i, fr) in f.frames[..6].iter().enumerate() {
        let (a, b) = (
            gpu.track(&fr.image).unwrap(),
            host.track(&fr.image).unwrap(),
        );
        assert_eq!(a.status, b.status, "frame {i}");
        let (sa, sb) = (a.verify.expect("checked"), b.verify.expect("checked"));
        assert_eq!(sa.covered_px, sb.covered_px, "frame {i}");
        let d = |x: Option<f64>, y: Option<f64>| (x.unwrap() - y.unwrap()).abs();
        assert!(d(sa.zncc, sb.zncc) < 1e-4, "frame {i}: {sa:?} vs {sb:?}");
        assert!(
            d(sa.edge_support, sb.edge_support) < 0.01,
            "frame {i}: {sa:?} vs {sb:?}"
        );
        assert!(a.pose.rotation_error_deg(&b.pose) < 1e-4, "frame {i}");
    }
}

#[test]
fn the_resident_check_gives_the_host_checks_poses() {
    // The pose check scored on the GPU (shaders/verify.wgsl) or on the
    // host from a readback (the default on CPU adapters): the same
    // statuses and poses (the scores agree to f32 rounding:
    // tests/verify_gpu.rs).
    let f = fixture();
    let make = |resident: bool| {
        tracker_with(
            Mode::KfIt,
            Some(f.store.clone()),
            f.frames[0].pose,
            Execution {
                resident_check: Some(resident),
                ..Default::default()
            },
        )
    };
    same_checks(make(true), make(false));
}

#[test]
fn the_check_on_the_resident_frame_gives_the_host_checks_scores() {
    // The GPU loop (frames resident): the check resolves the view, cuts
    // the frame's window on the GPU and scores it in one chain of stages
    // (`GpuCheck::score_prepared`); against the same loop checked
    // on the host, the same scores to f32 rounding and the same statuses
    // (fails when the frame's window is not cut: stale values).
    let f = fixture();
    let make = |resident_check: bool| {
        Tracker::builder(shared_test_context(), f.scene.model.clone(), f.scene.cam)
            .keyframes(f.store.clone())
            .config(TrackerConfig {
                mode: Mode::KfIt,
                feature_backend: FeatureBackend::Gpu,
                resident: Some(true),
                ..Default::default()
            })
            .initial_pose(f.frames[0].pose)
            .execution(Execution {
                resident_check: Some(resident_check),
                ..Default::default()
            })
            .build()
            .expect("tracker")
    };
    same_checks(make(true), make(false));
}

#[test]
fn resident_matching_gives_the_host_paths_poses_with_fewer_bytes_read_back() {
    // NCC on the GPU-resident frame and novel view, the mutual check and
    // the KF refinement on the GPU (the default on GPUs), against host
    // crops, the view's grey levels read back and the refinement on the
    // host (the default on CPU adapters): from the same pose, the same
    // statuses and inliers and poses within f32 rounding of the refined
    // points (tests/features_resident.rs: within 1e-3 px; here within
    // 3e-5 px), over a KF-only frame and a KF+IT frame. (Over a longer
    // run the two drift apart by such roundings until a threshold flips:
    // the real cube's 99 frames end within 3.4e-4 of each other in every
    // pose entry, 4 frames with other inlier counts, the same errors.)
    // Only a few values per feature come back instead of the view.
    // Features in the shaders, as on a GPU (with Harris on the host the
    // view's colour comes back either way). A context of its own, so that other tests'
    // readbacks are not counted.
    use splattrack::gpu::own_test_context;
    let f = fixture();
    let ctx = own_test_context();
    let make = |resident: bool, start: usize| {
        Tracker::builder(&ctx, f.scene.model.clone(), f.scene.cam)
            .keyframes(f.store.clone())
            .config(TrackerConfig {
                feature_backend: FeatureBackend::Gpu,
                ..Default::default()
            })
            .initial_pose(f.frames[start].pose)
            .execution(Execution {
                resident_matching: Some(resident),
                ..Default::default()
            })
            .build()
            .expect("tracker")
    };
    let (mut read_gpu, mut read_host) = (0u64, 0u64);
    for start in [0, 2, 4] {
        let (mut gpu, mut host) = (make(true, start), make(false, start));
        for (i, fr) in f.frames[start..start + 2].iter().enumerate() {
            let r0 = ctx.stats().bytes_read;
            let a = gpu.track(&fr.image).unwrap();
            let r1 = ctx.stats().bytes_read;
            let b = host.track(&fr.image).unwrap();
            read_gpu += r1 - r0;
            read_host += ctx.stats().bytes_read - r1;
            let at = format!("frames from {start}, frame {i}");
            assert_eq!((a.status, a.inliers), (b.status, b.inliers), "{at}");
            let e = a.pose.rotation_error_deg(&b.pose);
            assert!(e < 1e-3, "{at}: {e} degrees apart");
            let dt = (a.pose.translation - b.pose.translation).norm();
            assert!(dt < 1e-5, "{at}: {dt} apart");
            assert!(a.times.readbacks < b.times.readbacks, "{at}");
            assert_eq!(a.times.readback_bytes as u64, r1 - r0, "{at}");
        }
    }
    // The host path reads back the view's grey levels (4 bytes a pixel of
    // its window) at every KF step, 20% of what the step reads back here.
    assert!(
        (read_gpu as f64) < 0.9 * read_host as f64,
        "{read_gpu} bytes read back against {read_host}"
    );
}

/// Corners and matches on the host (the default on CPU adapters) against
/// the shaders (a GPU's), KF+IT with texture and contour, on the first 6
/// frames: the host detector is the CPU reference bit for bit
/// (tests/features_harris.rs) and the host matcher is the reference, which
/// the shaders match to f32 rounding (Harris responses within 1e-5,
/// corners within 1e-3 px; NCC scores within 1e-5), so the statuses are
/// the same and the poses agree as [`assert_same_poses`] says (on
/// lavapipe at most 6e-5 degrees apart; with the GPU loop's kernels, as
/// on the H200, frame 3 may fall on its other pose, 0.06 degrees away).
#[test]
fn features_on_the_host_give_the_shaders_poses() {
    let on = |feature_backend: FeatureBackend| {
        move |contour| TrackerConfig {
            feature_backend,
            modalities: Modalities {
                texture: true,
                contour,
            },
            ..Default::default()
        }
    };
    assert_same_poses(on(FeatureBackend::Host), on(FeatureBackend::Gpu), [6, 4]);
}

#[test]
fn the_chained_kf_step_gives_the_two_step_poses_bit_for_bit_with_one_wait_less() {
    // The KF step's detection on the novel view, its matching
    // and the gather at its corners chained on the GPU (the corners go
    // from Harris to NCC and the gather there; one wait) against the
    // detection read back first, then the matching and the gather (two):
    // the same corners, matches and samples, so the same poses, bit for
    // bit, with texture and with the contour, and one readback a KF step
    // fewer (the views here keep fewer corners than even a first
    // detection's readback brings, 64: every step chains; the fallbacks
    // are tested in tests/features_resident.rs). Features in the
    // shaders, as on a GPU. A context of its own, so that other tests'
    // readbacks are not counted.
    use splattrack::gpu::own_test_context;
    let f = fixture();
    let ctx = own_test_context();
    let make = |chained: bool, contour: bool| {
        gpu_loop_tracker(
            &ctx,
            contour,
            Execution {
                chained_kf: chained,
                ..Default::default()
            },
        )
    };
    for (contour, n) in [(false, 6), (true, 4)] {
        let (mut one, mut two) = (make(true, contour), make(false, contour));
        let mut fewer = Vec::new();
        for (i, fr) in f.frames[..n].iter().enumerate() {
            let r0 = ctx.stats().readbacks;
            let a = one.track(&fr.image).unwrap();
            let r1 = ctx.stats().readbacks;
            let b = two.track(&fr.image).unwrap();
            let at = format!("contour {contour}, frame {i}");
            assert_eq!(a.status, Status::Tracking, "{at}");
            assert_eq!((a.status, a.inliers), (b.status, b.inliers), "{at}");
            assert_eq!(a.pose.rotation, b.pose.rotation, "{at}");
            assert_eq!(a.pose.translation, b.pose.translation, "{at}");
            assert_eq!(a.residual_px, b.residual_px, "{at}");
            assert_eq!(a.times.readbacks as u64, r1 - r0, "{at}");
            fewer.push(b.times.readbacks as i64 - a.times.readbacks as i64);
        }
        eprintln!("contour {contour}: readbacks fewer a frame {fewer:?}");
        // One KF step a frame (kf_iterations 1): one wait fewer.
        assert!(
            fewer.iter().all(|&d| d == 1),
            "contour {contour}: {fewer:?}"
        );
    }
}

/// `--profile`'s GPU timing (`Execution::gpu_timing`) reads its
/// timestamps with the frame's own readbacks: a timed frame loop waits
/// for the GPU and submits work as often as an untimed one, gives the
/// same poses bit for bit, and reports the passes of every stage (the
/// contour's outline found on the GPU). A context of its own, so that
/// other tests' readbacks are not counted.
#[test]
fn timing_the_passes_adds_no_wait_and_changes_no_pose() {
    use splattrack::gpu::own_test_context;
    let f = fixture();
    let ctx = own_test_context();
    for (contour, n) in [(false, 4), (true, 3)] {
        let make = |timed: bool| {
            gpu_loop_tracker(
                &ctx,
                contour,
                Execution {
                    resident_outline: Some(true),
                    gpu_timing: timed,
                    ..Default::default()
                },
            )
        };
        let (mut timed, mut plain) = (make(true), make(false));
        for (i, fr) in f.frames[..n].iter().enumerate() {
            let (r0, s0) = (ctx.stats().readbacks, ctx.stats().submissions);
            let a = timed.track(&fr.image).unwrap();
            let (r1, s1) = (ctx.stats().readbacks, ctx.stats().submissions);
            let b = plain.track(&fr.image).unwrap();
            let (r2, s2) = (ctx.stats().readbacks, ctx.stats().submissions);
            let at = format!("contour {contour}, frame {i}");
            assert_eq!(a.status, Status::Tracking, "{at}");
            assert_eq!(a.pose.rotation, b.pose.rotation, "{at}");
            assert_eq!(a.pose.translation, b.pose.translation, "{at}");
            assert_eq!(
                (r1 - r0, s1 - s0),
                (r2 - r1, s2 - s1),
                "{at}: readbacks, submissions"
            );
            assert_eq!(a.times.readbacks as u64, r1 - r0, "{at}");
            assert!(b.times.gpu.is_empty(), "{at}");
            // The passes on the GPU's clock: busy within the frame's span.
            let g = a.times.gpu_timeline;
            assert!(g.busy > 0.0 && g.span >= g.busy, "{at}: {g:?}");
            let mut want = vec!["features harris", "KF splat", "KF harris", "KF ncc"];
            want.extend(["check splat", "check score"]);
            if i > 0 {
                want.push("IT ncc");
            }
            if contour {
                want.push("contour outline");
            }
            for stage in want {
                let passes: Vec<f64> = a
                    .times
                    .gpu
                    .iter()
                    .filter(|(l, _)| l.starts_with(stage))
                    .map(|(_, ms)| *ms)
                    .collect();
                assert!(
                    !passes.is_empty() && passes.iter().all(|ms| ms.is_finite() && *ms >= 0.0),
                    "{at}: {stage}: {:?}",
                    a.times.gpu
                );
            }
        }
    }
}

#[test]
fn the_chained_it_step_gives_the_two_step_poses_bit_for_bit_with_one_wait_less() {
    // IT's matching chained behind the frame's Harris on the GPU
    // (`Execution::chained_it`): the same poses, inliers and residuals
    // bit for bit as detecting, then matching, and one readback fewer on
    // every frame IT runs (from the second on), with the contour or
    // without. Features in the shaders, as on a GPU. A context of its
    // own, so that other tests' readbacks are not counted.
    use splattrack::gpu::own_test_context;
    let f = fixture();
    let ctx = own_test_context();
    let make = |chained: bool, contour: bool, host_selects: bool| {
        gpu_loop_tracker(
            &ctx,
            contour,
            Execution {
                chained_it: chained,
                harris_select_limit: host_selects.then_some(0),
                ..Default::default()
            },
        )
    };
    // Where the host selects the corners (a select limit of 0), the chain
    // falls back to matching from the host's corners: the same poses, no
    // wait saved.
    for (contour, n, host_selects) in [(false, 6, false), (true, 4, false), (false, 3, true)] {
        let (mut one, mut two) = (
            make(true, contour, host_selects),
            make(false, contour, host_selects),
        );
        let mut fewer = Vec::new();
        for (i, fr) in f.frames[..n].iter().enumerate() {
            let r0 = ctx.stats().readbacks;
            let a = one.track(&fr.image).unwrap();
            let r1 = ctx.stats().readbacks;
            let b = two.track(&fr.image).unwrap();
            let at = format!("contour {contour}, host {host_selects}, frame {i}");
            assert_eq!(a.status, Status::Tracking, "{at}");
            assert_eq!((a.status, a.inliers), (b.status, b.inliers), "{at}");
            assert_eq!(a.pose.rotation, b.pose.rotation, "{at}");
            assert_eq!(a.pose.translation, b.pose.translation, "{at}");
            assert_eq!(a.residual_px, b.residual_px, "{at}");
            assert_eq!(a.times.readbacks as u64, r1 - r0, "{at}");
            fewer.push(b.times.readbacks as i64 - a.times.readbacks as i64);
        }
        eprintln!("contour {contour}: readbacks fewer a frame {fewer:?}");
        if host_selects {
            assert!(fewer.iter().all(|&d| d == 0), "{fewer:?}");
            continue;
        }
        // No IT on the first frame; one wait fewer on every other.
        assert_eq!(fewer[0], 0, "contour {contour}: {fewer:?}");
        assert!(
            fewer[1..].iter().all(|&d| d == 1),
            "contour {contour}: {fewer:?}"
        );
    }
}

#[test]
fn the_tracker_shares_the_callers_model_unless_it_changes_the_radii() {
    // A caller's model (an `Arc`) is the tracker's own where the radii
    // need no change (no floor above them, no gap to close): no copy of
    // 40 bytes a point. Where the tracker raises or grows them it splats
    // a copy, and the caller's model keeps its radii.
    let f = fixture();
    let given = Arc::new(f.scene.model.clone());
    let make = |config: TrackerConfig| {
        Tracker::builder(shared_test_context(), given.clone(), f.scene.cam)
            .keyframes(Arc::new(f.store.clone()))
            .config(config)
            .initial_pose(f.frames[0].pose)
            .build()
            .expect("tracker")
    };
    let kept = make(TrackerConfig {
        min_splat_radius_px: 0.0,
        close_gaps: false,
        ..Default::default()
    });
    assert!(Arc::ptr_eq(kept.model(), &given), "copied without a change");
    // A floor of 50 pixels raises every radius.
    let raised = make(TrackerConfig {
        min_splat_radius_px: 50.0,
        close_gaps: false,
        ..Default::default()
    });
    assert!(!Arc::ptr_eq(raised.model(), &given));
    assert_eq!(
        given.radii, f.scene.model.radii,
        "the caller's radii changed"
    );
    assert!(
        raised
            .model()
            .radii
            .iter()
            .zip(&given.radii)
            .all(|(r, g)| r > g),
        "not raised"
    );
    assert_eq!(raised.model().positions, given.positions);
    // Radii shrunk to a third leave gaps, which the tracker closes on
    // its copy.
    let mut gapped = f.scene.model.clone();
    gapped.radii.iter_mut().for_each(|r| *r /= 3.0);
    let gapped = Arc::new(gapped);
    let closed = Tracker::builder(shared_test_context(), gapped.clone(), f.scene.cam)
        .keyframes(Arc::new(f.store.clone()))
        .config(TrackerConfig {
            min_splat_radius_px: 0.0,
            ..Default::default()
        })
        .initial_pose(f.frames[0].pose)
        .build()
        .expect("tracker");
    assert!(!Arc::ptr_eq(closed.model(), &gapped));
    let grown = closed
        .model()
        .radii
        .iter()
        .zip(&gapped.radii)
        .filter(|(r, g)| r > g)
        .count();
    assert!(
        grown * 2 > gapped.len(),
        "{grown} of {} grown",
        gapped.len()
    );
    assert!(
        gapped
            .radii
            .iter()
            .zip(&f.scene.model.radii)
            .all(|(g, r)| *g == *r / 3.0),
        "the caller's gapped radii changed"
    );
}
