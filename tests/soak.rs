//! Soak: 10,000 frames through one tracker (KF+IT), host and
//! GPU memory sampled every tenth of the run; both must stay flat. Ignored in
//! CI (minutes); run it with
//!
//! ```text
//! SPLATTRACK_ADAPTER=cpu cargo test --release --test soak -- --ignored --nocapture
//! ```
//!
//! (`SPLATTRACK_SOAK_FRAMES=N` for another length). The sequence is a short
//! synthetic one (120 frames of the blob at 320 x 240) played forwards and
//! backwards, so the motion stays continuous however long the run.

use splattrack::app::TrackInputs;
use splattrack::gpu::shared_test_context;
use splattrack::synth::SynthConfig;
use splattrack::tracker::{Mode, Status, Tracker, TrackerConfig};
use splattrack::{Intrinsics, synth};

/// Resident set size of this process, bytes (Linux /proc).
fn rss_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").expect("/proc/self/statm");
    let pages: u64 = statm.split_whitespace().nth(1).unwrap().parse().unwrap();
    pages * 4096
}

#[test]
#[ignore = "minutes: a 10,000-frame soak; see the module docs"]
fn ten_thousand_frames_with_flat_memory() {
    let total: usize = std::env::var("SPLATTRACK_SOAK_FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000);
    let ctx = shared_test_context();
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("soak");
    let _ = std::fs::remove_dir_all(&dir);
    let cfg = SynthConfig {
        frames: 120,
        camera: Intrinsics::new(320, 240, 300.0, 300.0, 159.5, 119.5),
        ..Default::default()
    };
    synth::sequence::write_sequence(&cfg, &dir, 5000, None).unwrap();
    let inputs = TrackInputs::load(
        ctx,
        &dir.join("model.ply"),
        &Default::default(),
        &dir,
        None,
        None,
    )
    .unwrap();
    let frames: Vec<image::RgbImage> = inputs
        .sequence
        .as_ref()
        .expect("a sequence")
        .iter_frames()
        .map(|f| f.unwrap().image)
        .collect();
    let n = frames.len();
    // 0, 1, ..., n-1, n-2, ..., 1, 0, 1, ...
    let at = |i: usize| {
        let p = i % (2 * n - 2);
        if p < n { p } else { 2 * n - 2 - p }
    };
    let config = TrackerConfig {
        mode: Mode::KfIt,
        ..Default::default()
    };
    let mut tracker = Tracker::new_shared(
        ctx,
        inputs.model.clone(),
        inputs.tracking_camera(),
        inputs.keyframes.clone(),
        config,
        inputs.init.expect("the synthetic sequence has an init.csv"),
    )
    .unwrap();
    let mut samples = Vec::new();
    let mut lost = 0;
    let start = std::time::Instant::now();
    for i in 0..total {
        let r = tracker.track(&frames[at(i)]).unwrap();
        lost += (r.status == Status::Lost) as usize;
        if (i + 1) % (total / 10).max(1) == 0 || i + 1 == total {
            let m = ctx.memory_report();
            let rss = rss_bytes();
            println!(
                "soak: frame {:>6}: RSS {:>7.1} MB; GPU {} buffers, {:.1} MB; {} textures, {:.1} MB; {} lost so far; {:.1} ms/frame",
                i + 1,
                rss as f64 / 1e6,
                m.buffers,
                m.buffer_bytes as f64 / 1e6,
                m.textures,
                m.texture_bytes as f64 / 1e6,
                lost,
                start.elapsed().as_secs_f64() * 1e3 / (i + 1) as f64
            );
            if std::env::var_os("SPLATTRACK_SOAK_DEBUG").is_some() {
                let c = ctx.device.get_internal_counters();
                println!("soak: counters {:?}", c.hal);
            }
            samples.push((rss, m));
        }
    }
    assert!(samples.len() >= 4, "run at least 4,000 frames");
    // Flat: from the sample at a quarter of the run (caches warm, buffers
    // grown to the largest corner counts of the sequence) to the last, GPU
    // objects unchanged, GPU bytes within 1 MB (a grow-only buffer meeting
    // a slightly larger corner count) and host memory within 5 % + 16 MB
    // (allocator slack), not growing with the frame count.
    let (rss0, m0) = samples[samples.len() / 4];
    let (rss1, m1) = *samples.last().unwrap();
    assert_eq!(
        (m1.buffers, m1.textures),
        (m0.buffers, m0.textures),
        "GPU objects grew"
    );
    assert!(
        m1.buffer_bytes <= m0.buffer_bytes + (1 << 20) && m1.texture_bytes <= m0.texture_bytes,
        "GPU memory grew: {m0:?} -> {m1:?}"
    );
    assert!(
        rss1 <= rss0 + rss0 / 20 + (16 << 20),
        "host memory grew: {rss0} -> {rss1} bytes"
    );
}

/// The soak's host-memory growth, isolated: the same number of GPU
/// submissions and readbacks (the self-test's one dispatch each) with no
/// tracker at all. Growth here is the driver's or wgpu's, not splattrack's.
#[test]
#[ignore = "minutes: a diagnosis for the soak; see the module docs"]
fn submissions_alone_and_host_memory() {
    let total: usize = std::env::var("SPLATTRACK_SOAK_FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000);
    let ctx = shared_test_context();
    let mut first = None;
    for i in 0..total {
        splattrack::gpu::selftest::run(ctx, 4096).unwrap();
        if (i + 1) % (total / 10).max(1) == 0 {
            let rss = rss_bytes();
            first.get_or_insert(rss);
            println!(
                "submissions: {:>6}: RSS {:>7.1} MB",
                i + 1,
                rss as f64 / 1e6
            );
        }
    }
}

/// The soak's host-memory growth, isolated further: splatter renders and
/// colour readbacks alone (the blob, 5,000 points, 320 x 240).
#[test]
#[ignore = "minutes: a diagnosis for the soak; see the module docs"]
fn renders_alone_and_host_memory() {
    use splattrack::splat::{Attribute, Attributes, GpuModel, SplatTargets, Splatter};
    let total: usize = std::env::var("SPLATTRACK_SOAK_FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000);
    let ctx = shared_test_context();
    let obj = splattrack::synth::SynthObject::blob();
    let model = obj.mesh.sample(5000, 0).unwrap();
    let cam = Intrinsics::new(320, 240, 300.0, 300.0, 159.5, 119.5);
    let pose = splattrack::synth::base_pose(0.55, 20.0, 10.0);
    let splatter = Splatter::new(ctx).unwrap();
    let gm = GpuModel::new(ctx, &model).unwrap();
    let mut targets = SplatTargets::new(ctx, cam.width, cam.height);
    for i in 0..total {
        splatter
            .render(ctx, &gm, &cam, &pose, Attributes::ALL, &mut targets)
            .unwrap();
        splatter.read(ctx, &targets, Attribute::Color).unwrap();
        if (i + 1) % (total / 10).max(1) == 0 {
            println!(
                "renders: {:>6}: RSS {:>7.1} MB",
                i + 1,
                rss_bytes() as f64 / 1e6
            );
        }
    }
}

/// Isolated further: Harris corners (GPU) of one 320 x 240 frame, and NCC
/// matching of its corners against themselves.
#[test]
#[ignore = "minutes: a diagnosis for the soak; see the module docs"]
fn features_alone_and_host_memory() {
    use splattrack::features::image::GreyImage;
    use splattrack::features::{Harris, HarrisConfig, NccConfig, NccMatcher};
    let total: usize = std::env::var("SPLATTRACK_SOAK_FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000);
    let ctx = shared_test_context();
    let mut rng = splattrack::rng::Rng::new(3);
    let img = image::RgbImage::from_fn(320, 240, |x, y| {
        let v = ((x / 9 + y / 7) % 2 * 160) as u8 + rng.below(60) as u8;
        image::Rgb([v, v, v])
    });
    let grey = GreyImage::from_rgb8(&img);
    let mut harris = Harris::new(ctx, HarrisConfig::default()).unwrap();
    let mut ncc = NccMatcher::new(ctx, NccConfig::default()).unwrap();
    let which = std::env::var("SPLATTRACK_SOAK_PART").unwrap_or_default();
    if which == "tiled" {
        ncc.set_options(splattrack::features::NccOptions {
            tiled: Some(true),
            ..ncc.options()
        });
    }
    for i in 0..total {
        let c = harris.detect_rgb8(&img, None).unwrap();
        if which != "harris" {
            ncc.match_features(&grey, &c, &grey, &c).unwrap();
        }
        if (i + 1) % (total / 10).max(1) == 0 {
            println!(
                "features: {:>6} ({} corners): RSS {:>7.1} MB",
                i + 1,
                c.len(),
                rss_bytes() as f64 / 1e6
            );
        }
    }
}
