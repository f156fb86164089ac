//! The application layer (`splattrack::app`) on a tiny synthetic sequence
//! written by `synth::sequence::write_sequence`: the keyframe store loaded
//! when it matches the model and rebuilt when stale, and a tracking run
//! writing poses, BOP rows and overlays, reporting progress and each frame.

mod tracking_common;

use splattrack::PointModel;
use splattrack::app::{
    AppError, KeyframeOrigin, TrackInputs, TrackRun, load_keyframes, load_or_build_keyframes,
};
use splattrack::gpu::shared_test_context;
use splattrack::io::read_poses;
use splattrack::progress::{ProgressEvent, ProgressFn};
use splattrack::tracker::{Mode, TrackerConfig};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};
use tracking_common::small_sequence;

const FRAMES: usize = 4;

/// The sequence directory, written once: 4 frames of the blob at 160x120,
/// a 4000-point model, 12 keyframes.
fn sequence() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| small_sequence("app_seq", FRAMES))
}

fn workdir(name: &str) -> PathBuf {
    tracking_common::workdir("app", name)
}

#[test]
fn load_or_build_reuses_a_matching_store_and_rebuilds_a_stale_one() {
    let ctx = shared_test_context();
    let seq = sequence();
    let d = workdir("store");
    let cache = d.join("object.stkf");
    let model = PointModel::load(seq.join("model.ply")).unwrap();
    let cam = splattrack::io::Sequence::open(seq).unwrap().camera;
    let kf_dir = seq.join("keyframes");

    let (built, origin) = load_or_build_keyframes(ctx, &model, &cam, &kf_dir, &cache).unwrap();
    assert_eq!(origin, KeyframeOrigin::Built);
    assert!(cache.is_file());
    assert!(!d.join("object.stkf.partial").exists());
    assert_eq!(built.keyframes.len(), 12);

    let (loaded, origin) = load_or_build_keyframes(ctx, &model, &cam, &kf_dir, &cache).unwrap();
    assert_eq!(origin, KeyframeOrigin::Loaded);
    assert_eq!(loaded.fingerprint, built.fingerprint);
    assert_eq!(loaded.keyframes.len(), built.keyframes.len());

    // The same model with one point moved: the cache is stale, rebuilt
    // for the new model and saved over the old one.
    let mut other = model.clone();
    other.positions[0].x += 1e-3;
    let (rebuilt, origin) = load_or_build_keyframes(ctx, &other, &cam, &kf_dir, &cache).unwrap();
    assert_eq!(origin, KeyframeOrigin::Built);
    assert_ne!(rebuilt.fingerprint, built.fingerprint);
    load_keyframes(ctx, &other, &cam, &cache).unwrap();
    // An explicit store for another model is refused, not rebuilt.
    let e = load_keyframes(ctx, &model, &cam, &cache).unwrap_err();
    assert!(e.to_string().contains("another model"), "{e}");
    // Neither a store nor a keyframe directory.
    let e = load_keyframes(ctx, &model, &cam, &d).unwrap_err();
    assert!(matches!(e, AppError::NotKeyframes(_)), "{e}");
}

#[test]
fn a_run_writes_every_output_reports_progress_and_each_frame() {
    let ctx = shared_test_context();
    let seq = sequence();
    let d = workdir("run");
    let inputs = TrackInputs::load(
        ctx,
        &seq.join("model.ply"),
        &Default::default(),
        seq,
        None,
        None,
    )
    .unwrap();
    assert_eq!(inputs.keyframes.as_ref().unwrap().keyframes.len(), 12);
    let events = Arc::new(Mutex::new(Vec::<ProgressEvent>::new()));
    let sink = events.clone();
    let progress: ProgressFn = Arc::new(move |e| sink.lock().unwrap().push(e));
    let (poses, bop, overlays) = (d.join("poses.csv"), d.join("bop.csv"), d.join("overlays"));
    let config = TrackerConfig {
        mode: Mode::KfIt,
        ..Default::default()
    };
    let mut seen = Vec::new();
    let stats = TrackRun::new(ctx, &inputs, config.clone())
        .poses(&poses)
        .bop(&bop, 7)
        .overlays(&overlays, 2)
        .progress(Some(progress))
        .run(|frame, r| {
            // Nothing is in place while the run goes on.
            assert!(!poses.exists() && !bop.exists());
            seen.push((frame.index, frame.label.clone(), r.status));
        })
        .unwrap();
    assert_eq!(stats.frames, FRAMES);
    assert_eq!(
        seen.iter().map(|s| s.0).collect::<Vec<_>>(),
        (0..FRAMES).collect::<Vec<_>>()
    );
    assert!(seen.iter().all(|(i, label, _)| *label == i.to_string()));

    let rows = read_poses(&poses).unwrap();
    assert_eq!(rows.len(), FRAMES);
    let header = std::fs::read_to_string(&poses).unwrap();
    assert!(header.starts_with("frame,r11,"), "{header}");
    assert!(
        header
            .lines()
            .next()
            .unwrap()
            .ends_with(",inliers,residual_px,status,cues")
    );
    for (row, (i, _, status)) in rows.iter().zip(&seen) {
        assert_eq!(row.frame, i.to_string());
        assert_eq!(row.extra[2].1, status.name());
    }
    let bop_text = std::fs::read_to_string(&bop).unwrap();
    assert_eq!(bop_text.lines().count(), FRAMES + 1);
    assert!(
        bop_text.lines().nth(2).unwrap().starts_with("0,1,7,"),
        "{bop_text}"
    );
    for i in 0..FRAMES {
        let p = overlays.join(format!("{i:06}.png"));
        assert_eq!(p.exists(), i % 2 == 0, "{}", p.display());
    }
    let partials: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".partial"))
        .collect();
    assert!(partials.is_empty(), "{partials:?}");

    let events = events.lock().unwrap();
    assert_eq!(events.len(), FRAMES + 1);
    for (k, e) in events.iter().enumerate() {
        assert_eq!((e.done, e.total), (k as u64, FRAMES as u64));
    }

    // A limit tracks the first frames only; an empty range is refused.
    let short = d.join("short.csv");
    let stats = TrackRun::new(ctx, &inputs, config.clone())
        .limit(Some(2))
        .poses(&short)
        .run(|_, _| {})
        .unwrap();
    assert_eq!(stats.frames, 2);
    assert_eq!(read_poses(&short).unwrap().len(), 2);
    let e = TrackRun::new(ctx, &inputs, config)
        .limit(Some(0))
        .run(|_, _| {})
        .unwrap_err();
    assert!(matches!(e, AppError::NoFrames), "{e}");
}
