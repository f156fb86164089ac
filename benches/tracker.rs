//! Time per tracked frame, per mode, at 640x480 on whichever adapter is
//! present (`SPLATTRACK_ADAPTER`): a synthetic blob sequence (60k-point
//! model, 12 keyframes) rendered by the CPU rasteriser; each iteration
//! tracks the next frame (cycling through 30). Also prints the mean time
//! per stage (features, IT, KF) from `TrackResult::times`.
//!
//! `cargo bench --bench tracker`

use criterion::{Criterion, criterion_group, criterion_main};
use splattrack::gpu::GpuContext;
use splattrack::keyframes::{KeyframeConfig, KeyframeStore};
use splattrack::splat::Splatter;
use splattrack::synth::{
    SynthConfig, SynthObject, background, keyframe_images, render_frame, sequence::sample_model,
};
use splattrack::tracker::{Mode, Tracker, TrackerConfig};
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let ctx = GpuContext::from_env().expect("a GPU adapter (lavapipe will do)");
    eprintln!("adapter: {}", ctx.describe());
    let cfg = SynthConfig {
        frames: 120,
        ..Default::default()
    };
    let object = SynthObject::blob();
    let model = sample_model(&object, 60_000, cfg.seed).unwrap();
    let bg = background(&cfg.camera, cfg.seed);
    let frames: Vec<_> = (0..30)
        .map(|i| render_frame(&cfg, &object, &bg, i))
        .collect();
    let kfs = keyframe_images(&cfg, &object, &bg);
    let splatter = Splatter::new(&ctx).unwrap();
    let store = KeyframeStore::build(
        &ctx,
        &splatter,
        &model,
        &cfg.camera,
        &kfs,
        &KeyframeConfig::default(),
    )
    .unwrap();
    let mut group = c.benchmark_group("track_640x480");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(8));
    for mode in Mode::ALL {
        let config = TrackerConfig {
            mode,
            ..Default::default()
        };
        let mut tracker = Tracker::new(
            &ctx,
            model.clone(),
            cfg.camera,
            Some(store.clone()),
            config,
            frames[0].pose,
        )
        .unwrap();
        let mut i = 0usize;
        let mut stages = [0.0f64; 3];
        let mut n = 0usize;
        group.bench_function(mode.name(), |b| {
            b.iter(|| {
                // Restart at frame 0 after the 30 frames, from its true pose.
                if i.is_multiple_of(frames.len()) {
                    tracker = Tracker::new(
                        &ctx,
                        model.clone(),
                        cfg.camera,
                        Some(store.clone()),
                        TrackerConfig {
                            mode,
                            ..Default::default()
                        },
                        frames[0].pose,
                    )
                    .unwrap();
                }
                let r = tracker.track(&frames[i % frames.len()].image).unwrap();
                i += 1;
                n += 1;
                for (s, d) in stages
                    .iter_mut()
                    .zip([r.times.features, r.times.it, r.times.kf])
                {
                    *s += d.as_secs_f64() * 1e3;
                }
            })
        });
        eprintln!(
            "{}: mean per frame: features {:.1} ms, IT {:.1} ms, KF {:.1} ms",
            mode.name(),
            stages[0] / n as f64,
            stages[1] / n as f64,
            stages[2] / n as f64
        );
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
