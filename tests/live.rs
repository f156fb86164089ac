//! Live sources (`splattrack::io::live`) through fakes and through ffmpeg
//! replaying a file at its own rate in place of a camera (no /dev/video
//! exists on CI): frames that arrive while one is tracked are dropped and
//! counted, memory stays bounded, every tracked frame's row is on disk
//! before the next frame, a stop flag ends the run cleanly, and ffmpeg is
//! reaped on every path (no child left, not even a zombie).
//!
//! Needs the `ffmpeg` program (CI installs it); without it the tests fail
//! saying so.

mod cli_common;

use cli_common::*;
use splattrack::Intrinsics;
use splattrack::app::{TrackInputs, TrackRun};
use splattrack::gpu::shared_test_context;
use splattrack::io::ffmpeg::{Ffmpeg, VideoError};
use splattrack::io::live::{LiveSource, Producer, Stamp};
use splattrack::io::source::{FrameSource, Start};
use splattrack::io::video::VideoSource;
use splattrack::io::{Sequence, read_poses};
use splattrack::synth::{SynthConfig, sequence::write_sequence};
use splattrack::tracker::{Mode, TrackerConfig};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};
use std::time::Duration;

/// The tests look for leftover ffmpeg children of this process: one at a
/// time.
fn serial() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|p| p.into_inner())
}

/// A sequence of 20 frames of the blob at 160x120 (4000 points) and the
/// same frames as an H.264 MP4 at 15 frames/s, made once.
fn fixture() -> &'static (PathBuf, PathBuf) {
    static F: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    F.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("live");
        let _ = std::fs::remove_dir_all(&dir);
        let seq = dir.join("seq");
        let cfg = SynthConfig {
            frames: 20,
            camera: Intrinsics::new(160, 120, 150.0, 150.0, 79.5, 59.5),
            ..Default::default()
        };
        write_sequence(&cfg, &seq, 4000, None).expect("write the sequence");
        let mp4 = dir.join("seq.mp4");
        ffmpeg(&[
            "-framerate",
            "15",
            "-i",
            s(&seq.join("frames/%06d.png")),
            "-c:v",
            "libx264",
            "-pix_fmt",
            "yuv420p",
            "-crf",
            "18",
            s(&mp4),
        ]);
        (seq, mp4)
    })
}

/// Processes (zombies included) whose parent is this test process and
/// whose name is ffmpeg.
fn ffmpeg_children() -> Vec<String> {
    let me = std::process::id().to_string();
    let mut found = Vec::new();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(stat) = std::fs::read_to_string(e.path().join("stat")) else {
            continue;
        };
        // pid (comm) state ppid ...
        let (Some(a), Some(b)) = (stat.find('('), stat.rfind(')')) else {
            continue;
        };
        let comm = &stat[a + 1..b];
        let rest: Vec<&str> = stat[b + 1..].split_whitespace().collect();
        if comm.starts_with("ffmpeg") && rest.get(1) == Some(&me.as_str()) {
            found.push(format!("{} {comm} state {}", &stat[..a], rest[0]));
        }
    }
    found
}

fn no_ffmpeg_children() {
    // A killed child is reaped by the drop that killed it; give the kernel
    // a moment to remove the entry.
    for _ in 0..50 {
        if ffmpeg_children().is_empty() {
            return;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    panic!("ffmpeg children left: {:?}", ffmpeg_children());
}

fn inputs(seq: &Path) -> TrackInputs {
    TrackInputs::load(
        shared_test_context(),
        &seq.join("model.ply"),
        &Default::default(),
        seq,
        None,
        None,
    )
    .unwrap()
}

fn config() -> TrackerConfig {
    TrackerConfig {
        mode: Mode::KfIt,
        ..Default::default()
    }
}

#[test]
fn a_fast_fake_camera_drops_frames_and_every_tracked_row_is_on_disk_at_once() {
    let _g = serial();
    let (seq_dir, _) = fixture();
    let seq = Sequence::open(seq_dir).unwrap();
    let inputs = inputs(seq_dir);
    // The camera films a still object (frame 0, whose pose init.csv
    // holds), a frame every half millisecond: far faster than tracking.
    // (The tracker reports a frozen picture as lost; only the bookkeeping
    // is tested here.)
    let still = seq.frame(0).unwrap().image;
    let produced = Arc::new(Mutex::new(0usize));
    let count = produced.clone();
    let fake: Producer = Box::new(move |buf: &mut image::RgbImage| {
        std::thread::sleep(Duration::from_micros(500));
        buf.copy_from_slice(&still);
        let mut n = count.lock().unwrap();
        *n += 1;
        Ok(Some(Stamp {
            index: *n - 1,
            time_s: (*n - 1) as f64 * 5e-4,
        }))
    });
    let mut live = LiveSource::from_producer(Path::new("fake-camera"), &seq.camera, fake);
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("live/fake");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let out = d.join("poses.csv");
    let partial = d.join("poses.csv.partial");
    let mut labels = Vec::new();
    let stats = TrackRun::new(shared_test_context(), &inputs, config())
        .source(Box::new(&mut live))
        .limit(Some(6))
        .poses(&out)
        .run(|frame, _| {
            // The row of this frame is on disk before the next frame.
            let text = std::fs::read_to_string(&partial).unwrap();
            let last = text.lines().last().unwrap();
            assert_eq!(text.lines().count(), labels.len() + 2, "{text}");
            assert!(last.starts_with(&format!("{},", frame.label)), "{last}");
            assert!(
                last.ends_with(&format!("{:.6}", frame.time_s.unwrap())),
                "{last}"
            );
            labels.push(frame.index);
        })
        .unwrap();
    let c = live.counts();
    assert_eq!((stats.frames, c.taken), (6, 6));
    // The frames tracked are numbered as produced; the gaps between them
    // are frames dropped while the one before was tracked (the run also
    // counts those dropped while the last was tracked; the camera goes on
    // dropping until it is closed).
    assert!(labels.windows(2).all(|w| w[0] < w[1]), "{labels:?}");
    let gaps = labels.windows(2).map(|w| w[1] - w[0] - 1).sum::<usize>() as u64;
    assert!(gaps > 0, "{labels:?}");
    assert!(
        gaps <= stats.dropped && stats.dropped <= c.dropped,
        "{gaps} {stats:?} {c:?}"
    );
    assert!(c.produced <= c.taken + c.dropped + c.skipped + 1, "{c:?}");
    // Bounded memory: a buffer per frame tracked and at most two more,
    // though hundreds of frames were produced.
    assert!(c.produced > 50 && c.buffers <= c.taken + 2, "{c:?}");
    let rows = read_poses(&out).unwrap();
    assert_eq!(rows.len(), 6);
    assert!(!partial.exists());
    assert_eq!(rows[0].extra.last().unwrap().0, "time_s");
    drop(live);

    // A stop flag ends the run after the frame being tracked: every
    // finished frame in place, nothing partial, no error.
    let stop = Arc::new(AtomicBool::new(false));
    let mut n = 0;
    let fake: Producer = Box::new(move |buf: &mut image::RgbImage| {
        std::thread::sleep(Duration::from_millis(1));
        buf.copy_from_slice(&seq.frame(0).unwrap().image);
        n += 1;
        Ok(Some(Stamp {
            index: n - 1,
            time_s: 0.0,
        }))
    });
    let live = LiveSource::from_producer(Path::new("fake-camera"), &inputs.camera, fake)
        .stop_on(stop.clone());
    let mut seen = 0;
    let stats = TrackRun::new(shared_test_context(), &inputs, config())
        .source(Box::new(live))
        .stop_on(stop.clone())
        .poses(&out)
        .run(|_, _| {
            seen += 1;
            if seen == 3 {
                stop.store(true, Ordering::SeqCst);
            }
        })
        .unwrap();
    assert!(stats.stopped);
    assert_eq!(stats.frames, 3);
    assert_eq!(read_poses(&out).unwrap().len(), 3);
    assert!(!partial.exists());
}

#[test]
fn ffmpeg_replaying_a_file_at_its_rate_is_read_as_a_camera() {
    let _g = serial();
    let (seq_dir, mp4) = fixture();
    let inputs = inputs(seq_dir);
    let mut live = LiveSource::replay(mp4, &inputs.camera, &seq_dir.join("camera.json")).unwrap();
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("live/replay.csv");
    let stats = TrackRun::new(shared_test_context(), &inputs, config())
        .source(Box::new(&mut live))
        .poses(&out)
        .run(|_, _| {})
        .unwrap();
    let c = live.counts();
    // Every frame of the video was delivered, and either tracked,
    // dropped while another was tracked, or replaced before the first.
    assert_eq!(c.produced, 20, "{c:?}");
    assert_eq!(c.produced, c.taken + c.dropped + c.skipped, "{c:?}");
    assert_eq!((stats.frames as u64, stats.dropped), (c.taken, c.dropped));
    let rows = read_poses(&out).unwrap();
    assert_eq!(rows.len() as u64, c.taken);
    let mut last = None;
    for r in &rows {
        let i: usize = r.frame.parse().unwrap();
        assert!(last.is_none_or(|l| i > l), "frames out of order");
        last = Some(i);
        // H.264 in MP4 at 15 frames/s: exact timestamps (time base 1/15360).
        let t: f64 = r.extra.last().unwrap().1.parse().unwrap();
        assert!((t - i as f64 / 15.0).abs() < 1e-6, "frame {i} at {t} s");
    }
    eprintln!(
        "replay at 15 frames/s: {c:?}, {:.1} ms per frame",
        stats.mean_ms[3]
    );
    drop(live);
    no_ffmpeg_children();
}

#[test]
fn ffmpeg_is_reaped_on_every_path_and_a_killed_one_is_an_error_naming_the_file() {
    let _g = serial();
    let (seq_dir, mp4) = fixture();
    let cam = Intrinsics::load(&seq_dir.join("camera.json")).unwrap();
    let cam_path = seq_dir.join("camera.json");

    // Dropped part way.
    let mut v = VideoSource::open(mp4, &cam, &cam_path, Start::Frame(0)).unwrap();
    assert_eq!(v.next_frame().unwrap().unwrap().index, 0);
    assert!(!ffmpeg_children().is_empty());
    drop(v);
    no_ffmpeg_children();

    // Read to the end: 20 frames, then None, the child reaped.
    let mut v = VideoSource::open(mp4, &cam, &cam_path, Start::Seconds(1.0)).unwrap();
    let mut n = Vec::new();
    while let Some(f) = v.next_frame().unwrap() {
        n.push(f.index);
    }
    assert_eq!(n, (15..20).collect::<Vec<_>>());
    no_ffmpeg_children();
    drop(v);

    // Killed while decoding (as if it crashed): the next read fails with
    // one line naming the file.
    let mut ff = Ffmpeg::spawn(mp4, &["-i".into(), mp4.as_os_str().to_owned()]).unwrap();
    let (w, h) = ff.size();
    let mut buf = vec![0u8; (w * h * 3) as usize];
    ff.read_frame(&mut buf).unwrap().unwrap();
    ff.killer().kill();
    let e = loop {
        match ff.read_frame(&mut buf) {
            Ok(Some(_)) => continue,
            Ok(None) => panic!("a killed ffmpeg ended cleanly"),
            Err(e) => break e,
        }
    };
    assert!(matches!(e, VideoError::Died { .. }), "{e}");
    let msg = e.to_string();
    assert!(msg.contains("seq.mp4") && !msg.contains('\n'), "{msg}");
    drop(ff);
    no_ffmpeg_children();

    // A replay starts when asked for its first frame, and is dropped while
    // ffmpeg is blocked on its pipe.
    let mut live = LiveSource::replay(mp4, &cam, &cam_path).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    assert!(ffmpeg_children().is_empty());
    assert_eq!(live.next_frame().unwrap().unwrap().index, 0);
    std::thread::sleep(Duration::from_millis(200));
    drop(live);
    no_ffmpeg_children();
    // A replay of the wrong size says so at the first frame.
    let wrong = Intrinsics::new(320, 240, 300.0, 300.0, 159.5, 119.5);
    let mut live = LiveSource::replay(mp4, &wrong, Path::new("wrong.json")).unwrap();
    let e = live.next_frame().unwrap_err().to_string();
    assert!(e.contains("160x120") && e.contains("wrong.json"), "{e}");
    drop(live);
    no_ffmpeg_children();

    // Refused at open: no child left either.
    let e = VideoSource::open(mp4, &wrong, Path::new("wrong.json"), Start::Frame(0))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("160x120") && e.contains("320x240") && e.contains("wrong.json"),
        "{e}"
    );
    no_ffmpeg_children();
}
