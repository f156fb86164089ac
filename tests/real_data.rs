//! The tracker on real data: the first frames of the ViSP picture-cube
//! sequence (`visp_rbt_cube` in the folder `SPLATTRACK_DATA` names), KF+IT
//! with the default settings, against the refined ground truth.
//!
//! The data stays outside the repository. Without `SPLATTRACK_DATA` these
//! tests say in one line that they did not run.

mod tracking_common;

use splattrack::geometry::Pose;
use splattrack::gpu::shared_test_context;
use splattrack::io::read_poses;
use splattrack::tracker::{Mode, Status, TrackResult, Tracker, TrackerConfig};
use std::collections::HashMap;
use tracking_common::RealSequence;

/// `frame -> gt_ok` from gt_quality.csv.
fn gt_ok(path: &std::path::Path) -> HashMap<usize, bool> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let fi = header.iter().position(|h| *h == "frame").unwrap();
    let oi = header.iter().position(|h| *h == "gt_ok").unwrap();
    lines
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (c[fi].parse().unwrap(), c[oi].trim() == "1")
        })
        .collect()
}

/// A frame's result and, for gt_ok frames, its rotation error (degrees) and
/// translation error (% of the diameter).
type Tracked = (TrackResult, Option<(f64, f64)>);

/// Loads sequence `name` and tracks its first `frames` frames with the
/// default settings in `mode`: per frame, the result and (gt_ok frames only)
/// the rotation error (degrees) and translation error (% of the diameter).
fn track_first_frames(name: &str, mode: Mode, frames: usize) -> Option<Vec<Tracked>> {
    let config = TrackerConfig {
        mode,
        ..Default::default()
    };
    track_first_frames_with(name, config, frames)
}

/// [`track_first_frames`] with `config`.
fn track_first_frames_with(
    name: &str,
    config: TrackerConfig,
    frames: usize,
) -> Option<Vec<Tracked>> {
    track_first_frames_from(name, config, frames, |p| p)
}

/// [`track_first_frames_with`] from `start` applied to the sequence's
/// initial pose.
fn track_first_frames_from(
    name: &str,
    config: TrackerConfig,
    frames: usize,
    start: impl Fn(Pose) -> Pose,
) -> Option<Vec<Tracked>> {
    let RealSequence {
        dir,
        model,
        seq,
        store,
        gt,
    } = RealSequence::load(name)?;
    let ctx = shared_test_context();
    let cam = seq.camera;
    assert!(!cam.has_distortion(), "the ViSP camera has no distortion");
    let init: Pose = start(read_poses(&seq.init_path()).unwrap()[0].pose);
    let ok = gt_ok(&dir.join("gt_quality.csv"));
    let diameter = model.diameter() as f64;
    let mut tracker = Tracker::builder(ctx, model, cam)
        .keyframes(store)
        .config(config)
        .initial_pose(init)
        .build()
        .unwrap();
    let mut out = Vec::new();
    for (i, g) in gt.iter().enumerate().take(frames) {
        assert_eq!(g.frame_index(), Some(i));
        let frame = image::open(&seq.frames[i]).unwrap().to_rgb8();
        let r = tracker.track(&frame).unwrap();
        let err = ok[&i].then(|| {
            (
                r.pose.rotation_error_deg(&g.pose),
                100.0 * r.pose.translation_error(&g.pose) / diameter,
            )
        });
        eprintln!(
            "{name} frame {i}: {} ({} inliers) {err:?} {}",
            r.status.name(),
            r.inliers,
            r.reason
                .as_ref()
                .map(ToString::to_string)
                .unwrap_or_default()
        );
        out.push((r, err));
    }
    Some(out)
}

/// KF+IT on frames 0-15 of the cube: every frame tracked, and every frame
/// with trustworthy ground truth within 1.5 degrees and 2.5% of the
/// diameter. Measured with the defaults (lavapipe): at most 0.6 degrees and
/// 1.2% (1.8 mm, mostly along the optical axis); the ground truth itself is
/// good to ~1 px, ~0.5-1 degree.
#[test]
fn cube_first_frames_kf_it_within_bounds() {
    let Some(run) = track_first_frames("visp_rbt_cube", Mode::KfIt, 16) else {
        return;
    };
    let (mut worst_rot, mut worst_tr) = (0.0f64, 0.0f64);
    for (i, (r, err)) in run.iter().enumerate() {
        assert_eq!(r.status, Status::Tracking, "frame {i}: {:?}", r.reason);
        let Some((rot, tr)) = *err else { continue };
        assert!(rot < 1.5, "frame {i}: rotation error {rot:.3} deg");
        assert!(
            tr < 2.5,
            "frame {i}: translation error {tr:.3}% of the diameter"
        );
        worst_rot = worst_rot.max(rot);
        worst_tr = worst_tr.max(tr);
    }
    eprintln!("worst: {worst_rot:.3} deg, {worst_tr:.3}%");
}

/// The cube from a first pose turned 50 degrees about the camera's y
/// axis: found again within a few frames, and never reported `tracking`
/// far off. From this start the KF step reaches a pose 69 degrees off
/// whose view correlates with the frame at ZNCC 0.48-0.54 (edge support
/// about 0.5), which the usual check passes: it was reported `tracking`
/// for 22 frames before starts needed a ZNCC of 0.7
/// (`VerifyConfig::recovery_zncc`). Measured (CPU device): `tracking`
/// within 1.5 degrees from frame 1 on.
#[test]
fn cube_started_50_degrees_off_comes_back_and_is_never_wrong() {
    let turn = |p: Pose| {
        let r =
            nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::y_axis(), 50f64.to_radians());
        Pose::new(r.matrix() * p.rotation, p.translation).unwrap()
    };
    let Some(run) = track_first_frames_from("visp_rbt_cube", TrackerConfig::default(), 12, turn)
    else {
        return;
    };
    let mut first = None;
    for (i, (r, err)) in run.iter().enumerate() {
        let Some((rot, _)) = *err else { continue };
        if r.status == Status::Tracking {
            assert!(rot < 10.0, "frame {i}: tracking {rot:.1} deg off");
            if rot < 5.0 {
                first.get_or_insert(i);
            }
        }
    }
    assert!(
        first.is_some_and(|f| f <= 6),
        "tracking within 5 degrees from frame {first:?}"
    );
}

/// The weakly textured dragon: the KF step finds almost no matches against
/// its novel views, so KF+IT runs on IT alone for a few frames and then
/// says `lost`. Whatever it reports as `tracking` must be right (within 2
/// degrees and 2.5% of the diameter): a lost track must say so, never
/// report a wrong pose. (Measured: frames 0-4 tracked within 0.35 degrees,
/// then lost.)
#[test]
fn dragon_kf_it_tracking_frames_are_right() {
    let Some(run) = track_first_frames("visp_rbt_dragon", Mode::KfIt, 12) else {
        return;
    };
    for (i, (r, err)) in run.iter().enumerate() {
        if r.status == Status::Lost {
            assert!(r.reason.is_some(), "frame {i}: lost without a reason");
            continue;
        }
        let Some((rot, tr)) = *err else { continue };
        assert!(rot < 2.0, "frame {i}: tracking, but {rot:.3} deg off");
        assert!(tr < 2.5, "frame {i}: tracking, but {tr:.3}% off");
    }
}

/// The dragon by its outline alone (`--modalities contour`), frames 0-11,
/// against the refined ground truth. What lies behind it changes along
/// its outline (its head against an orange model, its body against the
/// white table): with colour histograms per sector of directions (the
/// default, 8) every frame is tracked and the gt_ok frames are 1.9
/// degrees off at most on average, against one pair of histograms for
/// the whole object, at least half a degree worse. Measured: 1.45 degrees
/// with sectors, 2.61 without (3 s on lavapipe).
#[test]
fn dragon_contour_sectors_weigh_each_side_against_its_background() {
    let contour = |sectors: usize| {
        let mut config = TrackerConfig {
            modalities: splattrack::tracker::Modalities {
                texture: false,
                contour: true,
            },
            ..Default::default()
        };
        config.contour.sectors = sectors;
        track_first_frames_with("visp_rbt_dragon", config, 12)
    };
    let mean = |run: &[Tracked]| {
        let errs: Vec<f64> = run.iter().filter_map(|(_, e)| e.map(|e| e.0)).collect();
        assert!(errs.len() >= 10, "{} gt_ok frames", errs.len());
        errs.iter().sum::<f64>() / errs.len() as f64
    };
    assert_eq!(splattrack::tracker::ContourConfig::default().sectors, 8);
    let Some(sectors) = contour(8) else {
        return;
    };
    for (i, (r, _)) in sectors.iter().enumerate() {
        assert_eq!(r.status, Status::Tracking, "frame {i}: {:?}", r.reason);
    }
    let one = contour(0).expect("the data was there a moment ago");
    let (with, without) = (mean(&sectors), mean(&one));
    eprintln!("mean rotation error: {with:.3} deg with sectors, {without:.3} without");
    assert!(with < 1.9, "with sectors {with:.3} deg");
    assert!(
        with < without - 0.5,
        "with sectors {with:.3} deg, without {without:.3}"
    );
}
