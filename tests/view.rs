//! The live view (`splattrack::view`, `track --view`) without a display:
//! what the window shows, through the pure [`compose`] (outline where the
//! silhouette's border is, the status band, colours per status); the blit
//! that draws it into a window, on the GPU against its CPU reference; the
//! frames a run hands a sink (a fake that records them, from a short
//! synthetic run through `TrackRun`: one call per frame, in order,
//! statuses as in the CSV, the run stopped cleanly by the sink); and
//! `track --view` where there is no display (one line, non-zero exit,
//! nothing written).

mod tracking_common;

use image::{Rgb, RgbImage, RgbaImage};
use splattrack::Pose;
use splattrack::app::{AppError, TrackInputs, TrackRun};
use splattrack::draw::{self, SILHOUETTE_TINT};
use splattrack::gpu::shared_test_context;
use splattrack::io::read_poses;
use splattrack::rng::Rng;
use splattrack::tracker::{
    LostReason, Mode, Stage, StageTimes, Status, TrackResult, TrackerConfig,
};
use splattrack::view::present::{Presenter, letterbox, present_cpu};
use splattrack::view::{
    BAND_COLOUR, Flow, FrameSink, Layout, ViewError, ViewFrame, compose, status_colour,
};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;
use tracking_common::small_sequence;

fn result(status: Status) -> TrackResult {
    TrackResult {
        pose: Pose::identity(),
        inliers: 42,
        residual_px: 0.75,
        status,
        reason: (status == Status::Lost).then_some(LostReason::Untrusted {
            stage: Stage::Kf,
            inliers: 3,
            residual_px: 4.5,
            min_inliers: 8,
            max_residual_px: 3.0,
        }),
        keyframe: None,
        times: StageTimes {
            total: Duration::from_millis(101),
            ..Default::default()
        },
        verify: None,
        texture_set_aside: false,
        cues: splattrack::tracker::Modalities::TEXTURE,
        refused: None,
    }
}

/// A 320x64 frame with a gradient and a disc-shaped silhouette.
fn frame_and_mask() -> (RgbImage, Vec<bool>) {
    let (w, h) = (320u32, 64u32);
    let img = RgbImage::from_fn(w, h, |x, y| Rgb([(x * 3 / 4) as u8, (y * 3) as u8, 90]));
    let mask = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            (x - 40.0).powi(2) + (y - 30.0).powi(2) < 18.0f64.powi(2)
        })
        .collect();
    (img, mask)
}

fn view<'a>(
    img: &'a RgbImage,
    r: &'a TrackResult,
    mask: Option<&'a [bool]>,
    time_s: Option<f64>,
) -> ViewFrame<'a> {
    ViewFrame {
        index: 7,
        label: "000007",
        image: img,
        result: r,
        mask,
        objects: &[],
        time_s,
        rate_hz: None,
        mode: Mode::KfIt,
    }
}

/// Pixels of `pic` in rows `y0..y1` that are neither the band's colour.
fn ink(pic: &RgbaImage, y0: u32, y1: u32) -> Vec<[u8; 3]> {
    (y0..y1)
        .flat_map(|y| (0..pic.width()).map(move |x| (x, y)))
        .map(|(x, y)| {
            let p = pic.get_pixel(x, y).0;
            [p[0], p[1], p[2]]
        })
        .filter(|p| *p != BAND_COLOUR)
        .collect()
}

#[test]
fn the_outline_is_drawn_where_the_silhouette_ends() {
    let (img, mask) = frame_and_mask();
    let (w, h) = img.dimensions();
    for status in [Status::Tracking, Status::Lost] {
        let r = result(status);
        let pic = compose(&view(&img, &r, Some(&mask), None));
        let band = Layout::for_width(w).band;
        assert_eq!(pic.dimensions(), (w, h + band));
        let colour = status_colour(status);
        let at = |x: u32, y: u32| {
            let p = pic.get_pixel(x, y + band).0;
            [p[0], p[1], p[2]]
        };
        let inside = |x: i64, y: i64| {
            x >= 0 && y >= 0 && x < w as i64 && y < h as i64 && mask[(y * w as i64 + x) as usize]
        };
        let border = |x: i64, y: i64| {
            inside(x, y)
                && [(-1, 0), (1, 0), (0, -1), (0, 1)]
                    .iter()
                    .any(|(dx, dy)| !inside(x + dx, y + dy))
        };
        let (mut outline, mut tinted, mut untouched) = (0, 0, 0);
        for y in 0..h {
            for x in 0..w {
                let (xi, yi) = (x as i64, y as i64);
                let drawn = border(xi, yi) || border(xi - 1, yi) || border(xi, yi - 1);
                let orig = img.get_pixel(x, y).0;
                if drawn {
                    assert_eq!(at(x, y), colour, "outline at {x},{y}");
                    outline += 1;
                } else if inside(xi, yi) {
                    let mut want = RgbImage::from_pixel(1, 1, Rgb(orig));
                    draw::blend(&mut want, 0, 0, colour, SILHOUETTE_TINT);
                    assert_eq!(at(x, y), want.get_pixel(0, 0).0, "inside at {x},{y}");
                    assert_ne!(at(x, y), orig);
                    tinted += 1;
                } else {
                    assert_eq!(at(x, y), orig, "outside at {x},{y}");
                    untouched += 1;
                }
            }
        }
        // A disc of radius 18: an outline of about 2 x 2 pi 18 pixels.
        assert!((150..350).contains(&outline), "{outline}");
        assert!(tinted > 700 && untouched > 4000, "{tinted} {untouched}");
    }
    // Without a mask the frame is shown as it is.
    let r = result(Status::Tracking);
    let pic = compose(&view(&img, &r, None, None));
    let band = Layout::for_width(w).band;
    for (x, y, p) in img.enumerate_pixels() {
        assert_eq!(&pic.get_pixel(x, y + band).0[..3], &p.0[..]);
    }
}

#[test]
fn the_status_band_says_tracking_or_lost_and_why() {
    let (img, mask) = frame_and_mask();
    let w = img.width();
    let l = Layout::for_width(w);
    let line = |k: u32| (l.line_top(k), l.line_top(k) + 8 * l.scale);
    let tracking = result(Status::Tracking);
    let lost = result(Status::Lost);
    let pt = compose(&view(&img, &tracking, Some(&mask), None));
    let pl = compose(&view(&img, &lost, Some(&mask), None));
    // Nothing but text on the band's colour, and text on every line it
    // should be: line 0 (mode, frame) white, line 1 (status) in the
    // status colour, line 2 (why) white on a lost frame only.
    for (pic, status) in [(&pt, Status::Tracking), (&pl, Status::Lost)] {
        let all = ink(pic, 0, l.band);
        let colour = status_colour(status);
        assert!(
            all.iter().all(|p| *p == draw::WHITE || *p == colour),
            "{status}"
        );
        let (a, b) = line(0);
        assert!(ink(pic, a, b).iter().all(|p| *p == draw::WHITE));
        assert!(ink(pic, a, b).len() > 50);
        let (a, b) = line(1);
        let status_ink = ink(pic, a, b);
        assert!(status_ink.len() > 50 && status_ink.iter().all(|p| *p == colour));
    }
    let (a, b) = line(2);
    assert!(ink(&pt, a, b).is_empty());
    let why = ink(&pl, a, b);
    assert!(why.len() > 50 && why.iter().all(|p| *p == draw::WHITE));
    // The two statuses differ in colour, and the words differ.
    assert_ne!(status_colour(Status::Tracking), status_colour(Status::Lost));
    // A timestamp adds text to the first line.
    let timed = compose(&view(&img, &tracking, Some(&mask), Some(12.5)));
    let (a, b) = line(0);
    assert!(ink(&timed, a, b).len() > ink(&pt, a, b).len());
    // The lines: what the band says, in words.
    let lines = splattrack::view::status_lines(&view(&img, &lost, None, Some(1.0)));
    assert_eq!(lines[0], "kf+it  frame 7 (000007)  t 1.000 s");
    assert_eq!(lines[1], "lost  42 inliers  0.75 px  101 ms");
    let rated = ViewFrame {
        rate_hz: Some(2.94),
        ..view(&img, &tracking, None, None)
    };
    assert_eq!(
        splattrack::view::status_lines(&rated)[1],
        "tracking  42 inliers  0.75 px  101 ms  2.9 frames/s"
    );
    assert!(lines[2].starts_with("why: KF: 3 inliers"), "{}", lines[2]);
    assert_eq!(splattrack::view::status_lines(&rated)[2], "");
    let aside = TrackResult {
        texture_set_aside: true,
        ..tracking.clone()
    };
    assert_eq!(
        splattrack::view::status_lines(&view(&img, &aside, None, None))[2],
        "contour alone: the texture's pose did not look like the frame"
    );
}

#[test]
fn the_blit_on_the_gpu_matches_its_cpu_reference() {
    let ctx = shared_test_context();
    let mut presenter = Presenter::new(ctx, wgpu::TextureFormat::Rgba8Unorm).unwrap();
    let mut rng = Rng::new(14);
    let picture = RgbaImage::from_fn(37, 23, |_, _| {
        image::Rgba([
            rng.below(256) as u8,
            rng.below(256) as u8,
            rng.below(256) as u8,
            255,
        ])
    });
    // The same size, larger (not a whole factor), smaller, and shapes
    // that letterbox left-right and top-bottom.
    for dst in [(37, 23), (83, 52), (20, 13), (120, 40), (30, 70)] {
        let gpu = presenter.render_offscreen(ctx, &picture, dst).unwrap();
        let cpu = present_cpu(&picture, dst);
        let worst = gpu
            .pixels()
            .zip(cpu.pixels())
            .flat_map(|(g, c)| g.0.iter().zip(c.0).map(|(a, b)| a.abs_diff(b)))
            .max()
            .unwrap();
        assert!(worst <= 1, "{dst:?}: worst difference {worst}");
        if dst == (37, 23) {
            assert_eq!(gpu, picture, "same size: a copy");
        }
        let [x0, y0, x1, y1] = letterbox((37, 23), dst);
        for (x, y, p) in gpu.enumerate_pixels() {
            if x < x0 || y < y0 || x >= x1 || y >= y1 {
                assert_eq!(
                    p.0,
                    splattrack::view::present::BACKGROUND,
                    "{dst:?} {x},{y}"
                );
            }
        }
    }
}

const FRAMES: usize = 4;

/// 4 frames of the blob at 160x120, a 4000-point model, keyframes.
fn sequence() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| small_sequence("view_seq", FRAMES))
}

fn workdir(name: &str) -> PathBuf {
    tracking_common::workdir("view", name)
}

/// What a fake sink saw of one frame.
#[derive(Debug)]
struct Seen {
    index: usize,
    label: String,
    status: Status,
    size: (u32, u32),
    mask_len: Option<usize>,
    mask_on: usize,
    picture: (u32, u32),
    rate_hz: Option<f64>,
}

/// A sink that records every frame and stops after `stop_after` frames.
struct Recorder {
    seen: Vec<Seen>,
    stop_after: Option<usize>,
    mask: bool,
    fail: bool,
}

impl Recorder {
    fn new() -> Self {
        Self {
            seen: vec![],
            stop_after: None,
            mask: true,
            fail: false,
        }
    }
}

impl FrameSink for Recorder {
    fn wants_mask(&self) -> bool {
        self.mask
    }
    fn frame(&mut self, f: &ViewFrame<'_>) -> Result<Flow, ViewError> {
        if self.fail {
            return Err(ViewError::Open("the fake window broke".into()));
        }
        self.seen.push(Seen {
            index: f.index,
            label: f.label.to_owned(),
            status: f.result.status,
            size: f.image.dimensions(),
            mask_len: f.mask.map(<[bool]>::len),
            mask_on: f.mask.map_or(0, |m| m.iter().filter(|v| **v).count()),
            picture: compose(f).dimensions(),
            rate_hz: f.rate_hz,
        });
        Ok(match self.stop_after {
            Some(n) if self.seen.len() >= n => Flow::Stop,
            _ => Flow::Continue,
        })
    }
}

fn inputs() -> TrackInputs {
    let seq = sequence();
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

#[test]
fn a_run_hands_the_sink_every_frame_in_order_and_stops_when_told() {
    let ctx = shared_test_context();
    let inputs = inputs();
    let d = workdir("sink");
    let config = TrackerConfig {
        mode: Mode::KfIt,
        ..Default::default()
    };
    let poses = d.join("poses.csv");
    let mut rec = Recorder::new();
    let stats = TrackRun::new(ctx, &inputs, config.clone())
        .poses(&poses)
        .sink(&mut rec)
        .run(|_, _| {})
        .unwrap();
    assert!(!stats.stopped);
    assert_eq!(stats.frames, FRAMES);
    let rows = read_poses(&poses).unwrap();
    assert_eq!(rec.seen.len(), FRAMES, "{:?}", rec.seen);
    let band = Layout::for_width(160).band;
    for (k, (s, row)) in rec.seen.iter().zip(&rows).enumerate() {
        assert_eq!(s.index, k);
        assert_eq!(s.label, row.frame);
        assert_eq!(s.status.name(), row.extra[2].1, "frame {k}");
        assert_eq!(s.size, (160, 120));
        assert_eq!(s.mask_len, Some(160 * 120));
        // The blob covers a good part of the frame at the tracked pose.
        assert!(s.mask_on > 500, "frame {k}: {} pixels", s.mask_on);
        assert_eq!(s.picture, (160, 120 + band));
        // The run's rate, from the second frame on.
        assert_eq!(s.rate_hz.is_some(), k > 0, "frame {k}");
        assert!(s.rate_hz.is_none_or(|f| f > 0.0 && f.is_finite()));
    }

    // Stopped after the second frame: as at the end of a 2-frame
    // sequence, the pose file complete for the frames tracked.
    let mut rec = Recorder {
        stop_after: Some(2),
        mask: false,
        ..Recorder::new()
    };
    let stats = TrackRun::new(ctx, &inputs, config.clone())
        .poses(&poses)
        .sink(&mut rec)
        .run(|_, _| {})
        .unwrap();
    assert!(stats.stopped);
    assert_eq!(stats.frames, 2);
    assert!(stats.mean.total > 0.0 && stats.mean.total.is_finite());
    assert_eq!(read_poses(&poses).unwrap().len(), 2);
    assert!(!splattrack::io::atomic::partial_path(&poses).exists());
    assert_eq!(rec.seen.len(), 2);
    assert!(rec.seen.iter().all(|s| s.mask_len.is_none()));

    // A sink that fails ends the run with its error, and no pose file
    // that looks complete.
    let broken = d.join("broken.csv");
    let mut rec = Recorder {
        fail: true,
        ..Recorder::new()
    };
    let e = TrackRun::new(ctx, &inputs, config)
        .poses(&broken)
        .sink(&mut rec)
        .run(|_, _| {})
        .unwrap_err();
    assert!(matches!(e, AppError::View(_)), "{e}");
    assert!(e.to_string().contains("the fake window broke"), "{e}");
    assert!(!broken.exists());
}

#[test]
fn track_view_without_a_display_says_so_and_writes_nothing() {
    let seq = sequence();
    let out = workdir("cli").join("poses.csv");
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_splattrack"));
    if std::env::var_os("SPLATTRACK_ADAPTER").is_none() {
        c.env("SPLATTRACK_ADAPTER", "cpu");
    }
    let o = c
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("WAYLAND_SOCKET")
        .args(["track", "--model"])
        .arg(seq.join("model.ply"))
        .arg("--sequence")
        .arg(seq)
        .arg("--out")
        .arg(&out)
        .arg("--view")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("--view needs a display"), "{err}");
    assert!(err.contains("DISPLAY"), "{err}");
    assert!(!out.exists() && !splattrack::io::atomic::partial_path(&out).exists());
    assert!(String::from_utf8_lossy(&o.stdout).is_empty());
}

/// The window itself, where a display exists (by hand, or in CI under
/// Xvfb): `DISPLAY=:1 cargo test --release --test view -- --ignored`.
/// Fails (never skips) without a display.
#[test]
#[ignore = "needs a display (X11 or Wayland; Xvfb will do)"]
fn a_window_shows_every_frame_it_is_given() {
    let ctx = shared_test_context();
    let mut window = splattrack::view::DisplaySink::open(ctx, "splattrack tests/view.rs").unwrap();
    let (img, mask) = frame_and_mask();
    for (k, status) in [Status::Tracking, Status::Lost, Status::Tracking]
        .into_iter()
        .enumerate()
    {
        let r = result(status);
        let f = ViewFrame {
            index: k,
            ..view(&img, &r, Some(&mask), Some(k as f64 / 30.0))
        };
        assert_eq!(window.frame(&f).unwrap(), Flow::Continue);
    }
    let s = window.stats();
    assert_eq!(s.shown + s.skipped, 3);
    assert!(s.shown >= 2, "{s:?}");
}
