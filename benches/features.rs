//! Harris and NCC matching, GPU against the CPU reference (the paper's
//! Fig. 7 comparison): Harris at 640x480 and 1280x720 (and the host
//! detector the tracker runs on CPU adapters, `harris_host`), matching
//! 900 x 900 features with 9x9 windows, one readback's round trip (what
//! each of the frame loop's sync points costs) and a submission's host
//! cost (work and its readback submitted apart or together). Run with
//! `cargo bench --bench features` (adapter: `SPLATTRACK_ADAPTER`, default
//! auto). Besides criterion's report it prints a summary of medians and
//! the CPU/GPU ratio of each.

use criterion::{Criterion, criterion_group, criterion_main};
use splattrack::features::patterns::{self, Warp};
use splattrack::features::{
    Corner, GreyImage, Harris, HarrisConfig, NccConfig, NccMatcher, harris_cpu, harris_host,
    ncc_match_cpu,
};
use splattrack::gpu::GpuContext;
use splattrack::rng::Rng;
use std::hint::black_box;
use std::time::{Duration, Instant};

fn median_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..runs)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Per-pass GPU times, the median of 11 timed runs after 20 untimed ones
/// (a GPU idle during the CPU benches before may still be clocking up:
/// the H200's single timed detection measured 16.7 ms where criterion
/// measured 4.4).
fn pass_medians(mut run: impl FnMut() -> Vec<(String, f64)>) -> Vec<(String, f64)> {
    for _ in 0..20 {
        run();
    }
    let runs: Vec<_> = (0..11).map(|_| run()).collect();
    let Some(first) = runs.first() else {
        return Vec::new();
    };
    (0..first.len())
        .map(|i| {
            let mut v: Vec<f64> = runs.iter().filter_map(|r| r.get(i).map(|p| p.1)).collect();
            v.sort_by(f64::total_cmp);
            (first[i].0.clone(), v[v.len() / 2])
        })
        .collect()
}

fn points(rng: &mut Rng, n: usize, img: &GreyImage) -> Vec<Corner> {
    (0..n)
        .map(|_| Corner {
            x: rng.uniform(5.0, img.width as f64 - 6.0) as f32,
            y: rng.uniform(5.0, img.height as f64 - 6.0) as f32,
            score: 1.0,
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let ctx = GpuContext::from_env().expect("the benchmarks need a GPU adapter (or lavapipe)");
    eprintln!("adapter: {}", ctx.describe());
    let mut summary = Vec::new();
    let mut g = c.benchmark_group("features");
    g.sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));

    let cfg = HarrisConfig::default();
    let mut harris = Harris::new(&ctx, cfg.clone()).unwrap();
    let mut host_rows = Vec::new();
    let mut host_harris = Harris::new(&ctx, cfg.clone()).unwrap();
    host_harris.set_options(splattrack::features::HarrisGpuOptions {
        host: true,
        ..host_harris.options()
    });
    for (w, h) in [(640usize, 480usize), (1280, 720)] {
        let img = patterns::smooth_noise(w, h, 1.5, w as u64);
        g.bench_function(format!("harris_gpu_{w}x{h}"), |b| {
            b.iter(|| black_box(harris.detect(&img, None).unwrap()))
        });
        g.bench_function(format!("harris_cpu_{w}x{h}"), |b| {
            b.iter(|| black_box(harris_cpu(&img, &cfg, None).unwrap()))
        });
        // The host detector as the tracker runs it (`Harris` in host mode,
        // its images kept between calls).
        g.bench_function(format!("harris_host_{w}x{h}"), |b| {
            b.iter(|| black_box(host_harris.detect(&img, None).unwrap()))
        });
        let n = harris.detect(&img, None).unwrap().len();
        // Warmed up first: after the CPU benches an idle GPU may still be
        // clocking up (the H200's unwarmed median: 16.7 ms, criterion's 4.4).
        for _ in 0..20 {
            black_box(harris.detect(&img, None).unwrap());
        }
        let gpu = median_ms(10, || {
            black_box(harris.detect(&img, None).unwrap());
        });
        let cpu = median_ms(5, || {
            black_box(harris_cpu(&img, &cfg, None).unwrap());
        });
        summary.push((format!("Harris {w}x{h} ({n} corners)"), gpu, cpu));
        assert_eq!(
            host_harris.detect(&img, None).unwrap(),
            harris_host(&img, &cfg, None).unwrap()
        );
        let host = median_ms(10, || {
            black_box(host_harris.detect(&img, None).unwrap());
        });
        host_rows.push((format!("Harris {w}x{h}"), gpu, host, cpu));
    }
    // The selection's O(n^2) passes tiled in workgroup memory (the default
    // on GPUs) and one thread an item (on CPU adapters).
    let img = patterns::smooth_noise(640, 480, 1.5, 640);
    let mut direct = Harris::new(&ctx, cfg.clone()).unwrap();
    direct.set_options(splattrack::features::HarrisGpuOptions {
        tiled_selection: Some(false),
        ..direct.options()
    });
    g.bench_function("harris_gpu_direct_selection_640x480", |b| {
        b.iter(|| black_box(direct.detect(&img, None).unwrap()))
    });
    // The four filter passes, and the one pass of tiles (the default on
    // GPUs; CPU adapters run the four).
    for (name, fuse) in [("four_passes", false), ("fused_passes", true)] {
        let mut h = Harris::new(&ctx, cfg.clone()).unwrap();
        h.set_options(splattrack::features::HarrisGpuOptions {
            fused_maps: Some(fuse),
            ..h.options()
        });
        g.bench_function(format!("harris_gpu_640x480_{name}"), |b| {
            b.iter(|| black_box(h.detect(&img, None).unwrap()))
        });
    }
    // The whole image's merge split over workgroups too (the default on
    // GPUs merges its at most max_corners slots in one workgroup).
    let mut split_merge = Harris::new(&ctx, cfg.clone()).unwrap();
    split_merge.set_options(splattrack::features::HarrisGpuOptions {
        tiled_selection: Some(true),
        small_selection: Some(false),
        ..split_merge.options()
    });
    assert_eq!(
        split_merge.detect(&img, None).unwrap(),
        harris.detect(&img, None).unwrap()
    );
    g.bench_function("harris_gpu_640x480_split_merge", |b| {
        b.iter(|| black_box(split_merge.detect(&img, None).unwrap()))
    });
    harris.set_options(splattrack::features::HarrisGpuOptions {
        timing: true,
        ..harris.options()
    });
    direct.set_options(splattrack::features::HarrisGpuOptions {
        timing: true,
        ..direct.options()
    });
    split_merge.set_options(splattrack::features::HarrisGpuOptions {
        timing: true,
        ..split_merge.options()
    });
    let timed = |h: &mut Harris| {
        pass_medians(|| {
            h.detect(&img, None).unwrap();
            h.last_timings().passes.clone()
        })
    };
    let passes = timed(&mut harris);
    let passes_direct = timed(&mut direct);
    let passes_split_merge = timed(&mut split_merge);
    // A window the size of the frame loop's (a few hundred candidates):
    // the selection split over workgroups, or in one workgroup a pass
    // (the default there on GPUs: four dispatches a detection instead of
    // fourteen). Both tiled, as on GPUs.
    let window = patterns::smooth_noise(200, 160, 1.5, 200);
    let mut split = Harris::new(&ctx, cfg.clone()).unwrap();
    let mut small = Harris::new(&ctx, cfg.clone()).unwrap();
    for (h, one) in [(&mut split, false), (&mut small, true)] {
        h.set_options(splattrack::features::HarrisGpuOptions {
            tiled_selection: Some(true),
            small_selection: Some(one),
            ..h.options()
        });
    }
    let window_corners = split.detect(&window, None).unwrap();
    assert_eq!(window_corners, small.detect(&window, None).unwrap());
    g.bench_function("harris_gpu_200x160_split_selection", |b| {
        b.iter(|| black_box(split.detect(&window, None).unwrap()))
    });
    g.bench_function("harris_gpu_200x160_small_selection", |b| {
        b.iter(|| black_box(small.detect(&window, None).unwrap()))
    });
    split.set_options(splattrack::features::HarrisGpuOptions {
        timing: true,
        ..split.options()
    });
    small.set_options(splattrack::features::HarrisGpuOptions {
        timing: true,
        ..small.options()
    });
    let timed_window = |h: &mut Harris| {
        pass_medians(|| {
            h.detect(&window, None).unwrap();
            h.last_timings().passes.clone()
        })
    };
    let passes_split = timed_window(&mut split);
    let passes_small = timed_window(&mut small);

    let a = patterns::smooth_noise(640, 480, 2.0, 7);
    let warp = Warp {
        shift: [3.4, -2.7],
        angle: 0.05,
        centre: [320.0, 240.0],
        gain: 0.9,
        bias: 0.05,
    };
    let b = warp.image(&a);
    let mut rng = Rng::new(3);
    let (pa, pb) = (points(&mut rng, 900, &a), points(&mut rng, 900, &b));
    let ncfg = NccConfig::default();
    let mut matcher = NccMatcher::new(&ctx, ncfg.clone()).unwrap();
    g.bench_function("ncc_gpu_900x900_9x9", |bn| {
        bn.iter(|| black_box(matcher.match_features(&a, &pa, &b, &pb).unwrap()))
    });
    g.bench_function("ncc_cpu_900x900_9x9", |bn| {
        bn.iter(|| black_box(ncc_match_cpu(&a, &pa, &b, &pb, &ncfg).unwrap()))
    });
    // One readback's round trip: a copy submitted, the staging buffer
    // mapped and waited for, 16 bytes back. Every sync point of the frame
    // loop costs this besides its work (`track --profile` counts them).
    let tiny = ctx.buffer(
        "bench readback",
        16,
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
    );
    g.bench_function("readback_16B", |bn| {
        bn.iter(|| black_box(ctx.read_buffer::<u32>(&tiny, 4).unwrap()))
    });
    // A pass's work (here a clear) and its readback, submitted apart (two
    // submissions) or together (`read_buffer_after`, one): the difference
    // is one submission's host cost.
    let work = || {
        let mut enc = ctx.encoder();
        enc.clear_buffer(&tiny, 0, Some(8));
        enc
    };
    let apart = || {
        ctx.submit(work());
        black_box(ctx.read_buffer::<u32>(&tiny, 4).unwrap())
    };
    let together = || black_box(ctx.read_buffer_after::<u32>(work(), &tiny, 4).unwrap());
    g.bench_function("work_then_readback_2_submissions", |bn| bn.iter(&apart));
    g.bench_function("work_with_readback_1_submission", |bn| bn.iter(&together));
    // A pass's host cost: 40 dispatches of one small workgroup each, in
    // 40 compute passes or in one, with their readback (the frame loop
    // records about 40 passes a frame, `track --profile`).
    let saxpy = splattrack::gpu::selftest::Saxpy::new(&ctx, 1.0, &[1.0; 64], &[0.0; 64]).unwrap();
    let dispatches = |passes: usize| {
        let mut enc = ctx.encoder();
        for _ in 0..passes {
            let mut pass = enc.begin_compute_pass(&Default::default());
            for _ in 0..40 / passes {
                saxpy.dispatch(&mut pass);
            }
        }
        black_box(ctx.read_buffer_after::<u32>(enc, &tiny, 4).unwrap())
    };
    g.bench_function("dispatches_40_in_40_passes", |bn| {
        bn.iter(|| dispatches(40))
    });
    g.bench_function("dispatches_40_in_1_pass", |bn| bn.iter(|| dispatches(1)));
    g.finish();
    let passes40_us = 1e3 * median_ms(200, || drop(dispatches(40)));
    let passes1_us = 1e3 * median_ms(200, || drop(dispatches(1)));
    let readback_us = 1e3
        * median_ms(200, || {
            black_box(ctx.read_buffer::<u32>(&tiny, 4).unwrap());
        });
    let apart_us = 1e3 * median_ms(200, || drop(apart()));
    let together_us = 1e3 * median_ms(200, || drop(together()));
    for _ in 0..20 {
        black_box(matcher.match_features(&a, &pa, &b, &pb).unwrap());
    }
    let gpu = median_ms(10, || {
        black_box(matcher.match_features(&a, &pa, &b, &pb).unwrap());
    });
    let cpu = median_ms(5, || {
        black_box(ncc_match_cpu(&a, &pa, &b, &pb, &ncfg).unwrap());
    });
    summary.push(("NCC 900 x 900, 9x9, all pairs".into(), gpu, cpu));
    matcher.set_options(splattrack::features::NccOptions {
        timing: true,
        ..matcher.options()
    });
    let ncc_passes = pass_medians(|| {
        matcher.match_features(&a, &pa, &b, &pb).unwrap();
        matcher.last_timings().passes.clone()
    });
    let rcfg = ncfg.clone().with_search_radius(Some(30.0));
    let cpu30 = median_ms(5, || {
        black_box(ncc_match_cpu(&a, &pa, &b, &pb, &rcfg).unwrap());
    });
    summary.push(("NCC 900 x 900, 9x9, CPU within 30 px".into(), gpu, cpu30));

    println!("\nadapter: {}", ctx.describe());
    println!("| step | GPU median (ms) | CPU median (ms) | CPU / GPU |");
    println!("|---|---|---|---|");
    for (name, gpu, cpu) in &summary {
        println!("| {name} | {gpu:.2} | {cpu:.2} | {:.2} |", cpu / gpu);
    }
    println!(
        "\n| step | GPU median (ms) | host median (ms, `Harris` in host mode, {} threads) | CPU reference (ms) | GPU / host |",
        std::thread::available_parallelism().map_or(1, |n| n.get().min(8))
    );
    println!("|---|---|---|---|---|");
    for (name, gpu, host, cpu) in &host_rows {
        println!(
            "| {name} | {gpu:.2} | {host:.2} | {cpu:.2} | {:.2} |",
            gpu / host
        );
    }
    println!("\nreadback round trip (16 bytes, 200 runs): {readback_us:.1} us median");
    println!(
        "a clear and its readback (200 runs, medians): {apart_us:.1} us in two submissions, \
         {together_us:.1} us in one"
    );
    println!(
        "40 small dispatches and a readback (200 runs, medians): {passes40_us:.1} us in 40 \
         compute passes, {passes1_us:.1} us in one ({:.2} us a pass)",
        (passes40_us - passes1_us) / 39.0
    );
    for (name, passes) in [
        ("Harris 640x480", &passes),
        ("Harris 640x480, direct selection", &passes_direct),
        ("Harris 640x480, merge split too", &passes_split_merge),
        (
            &format!(
                "Harris 200x160 ({} corners), selection split",
                window_corners.len()
            ),
            &passes_split,
        ),
        ("Harris 200x160, selection in one workgroup", &passes_small),
        ("NCC 900 x 900", &ncc_passes),
    ] {
        if !passes.is_empty() {
            println!("\n{name} GPU passes (timestamp queries, median of 11 after 20):");
            for (label, ms) in passes {
                println!("  {label}: {ms:.3} ms");
            }
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
