//! Time per tracked frame (the whole `Tracker::track` step, read-backs
//! included) on whichever adapter is present (`SPLATTRACK_ADAPTER`): a
//! synthetic blob sequence rendered by the CPU rasteriser (12 keyframes);
//! each iteration tracks the next frame, cycling through 16 and restarting
//! from frame 0's true pose (the restart is not timed).
//!
//! - `track/MODE/auto/640x480/100000`: the three modes (IT, KF, KF+IT) with
//!   the adapter's default splatter;
//! - `track/kf+it/BACKEND/WxH/POINTS`: KF+IT with either splatter, models of
//!   10k and 100k points (1M with `SPLATTRACK_BENCH_1M=1`), at 640x480 and
//!   1280x720;
//! - `track/kf+it+contour/auto/WxH/POINTS`: KF+IT with the contour modality
//!   too (`--modalities texture,contour`), at 100k points (and 1M);
//! - `track/kf+it/compute/direct-selection/640x480/100000` (GPUs only):
//!   the corner selection one thread an item instead of tiled;
//! - `track/kf+it/compute/split-selection/640x480/100000` (GPUs only):
//!   tiled and split over workgroups even for the loop's few hundred
//!   candidates, instead of in one workgroup a pass.
//!
//! The loop is the tracker's as it runs (windows, render reuse, the pose
//! check, the default splatter where `auto`). Each case also prints the GPU
//! memory of the tracker's splatting after its frames
//! (`Tracker::gpu_memory`).
//!
//! Each case also prints the mean time per stage (features, IT, KF, contour,
//! the rest: the check of the pose and bookkeeping) from
//! `TrackResult::times`: the paper's Fig. 9.
//!
//! `cargo bench --bench tracker`

use criterion::{Criterion, criterion_group, criterion_main};
use splattrack::geometry::Intrinsics;
use splattrack::gpu::GpuContext;
use splattrack::keyframes::{KeyframeConfig, KeyframeStore};
use splattrack::model::PointModel;
use splattrack::splat::{Backend, Splatter};
use splattrack::synth::{
    SynthConfig, SynthObject, background, keyframe_images, render_frame, sequence::sample_model,
};
use splattrack::tracker::{Execution, Modalities, Mode, Tracker, TrackerConfig};
use std::time::{Duration, Instant};

const FRAMES: usize = 16;

fn model_sizes() -> Vec<usize> {
    let mut n = vec![10_000, 100_000];
    if std::env::var("SPLATTRACK_BENCH_1M").is_ok_and(|v| v != "0") {
        n.push(1_000_000);
    }
    n
}

struct Scene {
    cfg: SynthConfig,
    frames: Vec<splattrack::synth::SynthFrame>,
    keyframes: Vec<(String, image::RgbImage, splattrack::geometry::Pose)>,
}

/// The frames and keyframe images at one image size (the same field of
/// view at every size).
fn scene(w: u32, h: u32, object: &SynthObject) -> Scene {
    let f = 600.0 * w as f64 / 640.0;
    let cfg = SynthConfig {
        frames: 120,
        camera: Intrinsics::new(w, h, f, f, (w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0),
        ..Default::default()
    };
    let bg = background(&cfg.camera, cfg.seed);
    let frames: Vec<_> = (0..FRAMES)
        .map(|i| render_frame(&cfg, object, &bg, i))
        .collect();
    let keyframes = keyframe_images(&cfg, object, &bg);
    Scene {
        cfg,
        frames,
        keyframes,
    }
}

fn store(ctx: &GpuContext, scene: &Scene, model: &PointModel) -> KeyframeStore {
    let splatter = Splatter::new(ctx).unwrap();
    KeyframeStore::build(
        ctx,
        &splatter,
        model,
        &scene.cfg.camera,
        &scene.keyframes,
        &KeyframeConfig::default(),
    )
    .unwrap()
}

/// What every case of a scene and model shares.
struct Cases<'a> {
    ctx: &'a GpuContext,
    scene: &'a Scene,
    model: &'a PointModel,
    store: &'a KeyframeStore,
}

/// The corner selection a case forces (else the adapter's default).
#[derive(Clone, Copy)]
enum Selection {
    Default,
    /// One thread an item (CPU adapters' default).
    Direct,
    /// Tiled and split over workgroups whatever the count.
    Split,
}

/// One case: `config` tracked over the scene's frames as `id`, with the
/// corner selection `selection`.
fn case(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    on: &Cases,
    config: TrackerConfig,
    id: String,
    selection: Selection,
) {
    let Cases {
        ctx,
        scene,
        model,
        store,
    } = *on;
    let execution = match selection {
        Selection::Default => Execution::default(),
        Selection::Direct => Execution {
            harris_tiled_selection: Some(false),
            ..Default::default()
        },
        Selection::Split => Execution {
            harris_tiled_selection: Some(true),
            harris_small_selection: Some(false),
            ..Default::default()
        },
    };
    let new = || {
        Tracker::builder(ctx, model.clone(), scene.cfg.camera)
            .keyframes(store.clone())
            .config(config.clone())
            .initial_pose(scene.frames[0].pose)
            .execution(execution)
            .build()
            .unwrap()
    };
    let mut tracker = new();
    let mut i = 0usize;
    // features, IT, KF, contour, total (ms, summed).
    let mut stages = [0.0f64; 5];
    let mut n = 0usize;
    // Only the steps are timed: the restart every FRAMES frames (a new
    // tracker: model upload, pipelines) is setup, not a frame's work (on
    // an H200 it was most of the time measured per frame when counted).
    group.bench_function(&id, |b| {
        b.iter_custom(|iters| {
            let mut timed = Duration::ZERO;
            for _ in 0..iters {
                if i > 0 && i.is_multiple_of(FRAMES) {
                    tracker = new();
                }
                let start = Instant::now();
                let r = tracker.track(&scene.frames[i % FRAMES].image).unwrap();
                timed += start.elapsed();
                i += 1;
                n += 1;
                let t = r.times;
                for (s, d) in stages
                    .iter_mut()
                    .zip([t.features, t.it, t.kf, t.contour, t.total])
                {
                    *s += d.as_secs_f64() * 1e3;
                }
            }
            timed
        })
    });
    let m = stages.map(|s| s / n.max(1) as f64);
    let mem = tracker.gpu_memory();
    let mb = |b: u64| b as f64 / (1u64 << 20) as f64;
    eprintln!(
        "gpu memory {id}: model {:.1} MB, keyframe colours {:.1} MB, targets {:.1} MB, total {:.1} MB",
        mb(mem.model),
        mb(mem.keyframe_colors),
        mb(mem.targets),
        mb(mem.total())
    );
    eprintln!(
        "stages {id}: features {:.1} ms, IT {:.1} ms, KF {:.1} ms, contour {:.1} ms, rest {:.1} ms, total {:.1} ms (mean of {n} frames)",
        m[0],
        m[1],
        m[2],
        m[3],
        m[4] - m[0] - m[1] - m[2] - m[3],
        m[4]
    );
}

fn bench(c: &mut Criterion) {
    let ctx = GpuContext::from_env().expect("a GPU adapter (lavapipe will do)");
    eprintln!("adapter: {}", ctx.describe());
    let object = SynthObject::blob();
    let mut group = c.benchmark_group("track");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(5));
    let seed = SynthConfig::default().seed;
    for (w, h) in [(640u32, 480u32), (1280, 720)] {
        let scene = scene(w, h, &object);
        for n in model_sizes() {
            let model = sample_model(&object, n, seed).unwrap();
            let store = store(&ctx, &scene, &model);
            let on = Cases {
                ctx: &ctx,
                scene: &scene,
                model: &model,
                store: &store,
            };
            if (w, n) == (640, 100_000) {
                for mode in [Mode::It, Mode::Kf] {
                    let config = TrackerConfig {
                        mode,
                        ..Default::default()
                    };
                    let id = format!("{}/auto/{w}x{h}/{n}", mode.name());
                    case(&mut group, &on, config, id, Selection::Default);
                }
            }
            if n >= 100_000 {
                let config = TrackerConfig {
                    mode: Mode::KfIt,
                    modalities: Modalities {
                        texture: true,
                        contour: true,
                    },
                    ..Default::default()
                };
                let id = format!("kf+it+contour/auto/{w}x{h}/{n}");
                case(&mut group, &on, config, id, Selection::Default);
            }
            for backend in [Backend::RenderPass, Backend::Compute] {
                let config = TrackerConfig {
                    mode: Mode::KfIt,
                    splatter: backend,
                    ..Default::default()
                };
                let id = format!("kf+it/{backend}/{w}x{h}/{n}");
                case(&mut group, &on, config, id, Selection::Default);
            }
            // On GPUs the corner selection runs tiled, the loop's few
            // hundred candidates in one workgroup a pass; the same frames
            // with it one thread an item (what CPU adapters run) and split
            // over workgroups, to compare the three in the loop.
            if (w, n) == (640, 100_000) && !ctx.is_cpu() {
                for (name, selection) in
                    [("direct", Selection::Direct), ("split", Selection::Split)]
                {
                    let config = TrackerConfig {
                        mode: Mode::KfIt,
                        splatter: Backend::Compute,
                        ..Default::default()
                    };
                    let id = format!("kf+it/compute/{name}-selection/{w}x{h}/{n}");
                    case(&mut group, &on, config, id, selection);
                }
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
