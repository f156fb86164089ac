//! What `splattrack track` writes and prints: its outputs checked before
//! the run, the summary and the `--profile` report after it.

use super::args::Args;
use super::objects::Object;
use super::profile::profile_table;
use splattrack::app::RunStats;
use splattrack::io::guard::{check_output, check_output_dir};
use splattrack::tracker::Mode;
use std::sync::atomic::{AtomicBool, Ordering};

/// Refuses outputs that are this run's other inputs (the sequence's own
/// files are checked by the run).
pub fn check_outputs(args: &Args, objects: &[Object]) -> anyhow::Result<()> {
    let mut inputs: Vec<&std::path::Path> = Vec::new();
    for o in objects {
        inputs.push(&o.model);
        inputs.extend(o.init.as_ref().map(|(p, _)| p.as_path()));
        inputs.extend(o.keyframes.as_deref());
    }
    inputs.extend(args.video.as_deref());
    inputs.extend(args.camera.as_deref());
    check_output(&args.out, "--out", &inputs)?;
    if let Some(bop) = &args.bop {
        check_output(bop, "--bop", &inputs)?;
    }
    if let Some(refused) = &args.refused {
        check_output(refused, "--refused", &inputs)?;
        for (other, flag) in [(Some(&args.out), "--out"), (args.bop.as_ref(), "--bop")] {
            if other == Some(refused) {
                anyhow::bail!(
                    "{}: --refused and {flag} name the same file; choose another path",
                    refused.display()
                );
            }
        }
    }
    if let Some(dir) = &args.overlay {
        let protected: Vec<&std::path::Path> = objects
            .iter()
            .filter_map(|o| o.keyframes.as_deref())
            .collect();
        check_output_dir(dir, "--overlay", &protected, &inputs)?;
    }
    Ok(())
}

/// The lines after a run: frames tracked and lost, frames dropped by a
/// live source, and how the run ended when it was stopped.
pub fn print_summary(
    args: &Args,
    mode: Mode,
    ctx: &splattrack::Device,
    stats: &RunStats,
    stop: &AtomicBool,
    live: bool,
) {
    if !stats.objects.is_empty() {
        print_objects_summary(args, mode, ctx, stats);
    } else {
        print_one_summary(args, mode, ctx, stats);
    }
    let ctrl_c = stop.load(Ordering::SeqCst);
    if live {
        println!(
            "{} frames dropped (arrived while a frame was being tracked){}",
            stats.dropped,
            if ctrl_c { "; stopped by Ctrl-C" } else { "" }
        );
    }
    if stats.stopped && !ctrl_c {
        println!(
            "the live view was closed: stopped after {} frames",
            stats.frames
        );
    }
}

/// The summary of a run of several objects: frames, each object's lost
/// frames, the time per frame of all of them, and each one's cues.
fn print_objects_summary(args: &Args, mode: Mode, ctx: &splattrack::Device, stats: &RunStats) {
    let lost: Vec<String> = stats
        .objects
        .iter()
        .map(|o| format!("{} {}", o.name, o.lost))
        .collect();
    println!(
        "tracked {} frames of {} objects ({} mode, {}): lost {}; {:.1} ms per frame for all (median {:.1}); poses in {}",
        stats.frames,
        stats.objects.len(),
        mode.name(),
        ctx.describe(),
        lost.join(", "),
        stats.mean.total,
        stats.median_ms,
        args.out.display()
    );
    for o in &stats.objects {
        let Some(m) = o.modalities else { continue };
        let why = match &o.cue_choice {
            Some(c) => c.describe(),
            None => format!("{} (as given)", m.name()),
        };
        let [t, c, b] = o.held_by;
        println!(
            "cues of {}: {why}; frames held by texture {t}, contour {c}, both {b}; {:.1} ms per frame (median {:.1})",
            o.name, o.mean.total, o.median_ms
        );
    }
}

/// The summary of a run of one object.
fn print_one_summary(args: &Args, mode: Mode, ctx: &splattrack::Device, stats: &RunStats) {
    let aside = match stats.texture_set_aside {
        0 => String::new(),
        n => format!(" ({n} tracked by the contour alone, their texture set aside)"),
    };
    println!(
        "tracked {} frames ({} mode, {}): {} lost{aside}; {:.1} ms per frame (median {:.1}); poses in {}",
        stats.frames,
        mode.name(),
        ctx.describe(),
        stats.lost,
        stats.mean.total,
        stats.median_ms,
        args.out.display()
    );
    print_cues(args, mode, stats);
}

/// The line on the cues: which the run used and why (the automatic choice,
/// frame to frame for want of keyframes), and how many frames each held.
fn print_cues(args: &Args, mode: Mode, stats: &RunStats) {
    let Some(m) = stats.modalities else {
        return;
    };
    let why = match &stats.cue_choice {
        Some(c) => c.describe(),
        None => format!("{} (as given)", m.name()),
    };
    let fallback = match (args.mode, mode) {
        (None, Mode::It) => "; mode it: no keyframes and no model colours for the KF step",
        _ => "",
    };
    let [t, c, b] = stats.held_by;
    println!(
        "cues: {why}{fallback}; frames held by texture {t}, contour {c}, both {b} (the poses' cues column)"
    );
}

/// `--profile`'s report: the frame source's time, the stage table, the
/// splatting's GPU memory and the time end to end (`wall`: seconds;
/// `viewed`: a live view ran).
pub fn print_profile(ctx: &splattrack::Device, stats: &RunStats, wall: f64, viewed: bool) {
    println!(
        "frame source: {:.1} ms per frame (reading or decoding, waiting for it; outside the tracker's total)",
        stats.source_ms
    );
    if stats.objects.is_empty() {
        print_stages(ctx, &stats.mean_stages, stats.gpu_memory, "");
    } else {
        // Each object's own stages and memory, then the whole frame's.
        for o in &stats.objects {
            println!(
                "object {}: {:.1} ms per frame (median {:.1})",
                o.name, o.mean.total, o.median_ms
            );
            print_stages(ctx, &o.mean_stages, o.gpu_memory, "  ");
        }
        println!(
            "all {} objects: {:.1} ms per frame (median {:.1}); {}",
            stats.objects.len(),
            stats.mean.total,
            stats.median_ms,
            memory_line(ctx, stats.gpu_memory)
        );
    }
    println!(
        "end to end (tracking, outputs{}): {:.1} ms per frame, {:.2} frames/s",
        if viewed { ", live view" } else { "" },
        wall * 1e3 / stats.frames as f64,
        stats.frames as f64 / wall
    );
}

/// The stage table of a tracker and its splatting's memory, each line
/// after `indent`.
fn print_stages(
    ctx: &splattrack::Device,
    stages: &splattrack::tracker::StageTimes,
    memory: Option<splattrack::tracker::GpuMemoryUse>,
    indent: &str,
) {
    let table = profile_table(
        stages,
        ctx.gpu().is_none_or(|c| c.is_cpu()),
        ctx.gpu().is_some_and(|c| c.validates_indirect),
    );
    for line in table.lines() {
        // The CPU device has no GPU: its readbacks, waits and submissions
        // are all zero.
        let gpu_line = ["read back from the GPU", "waiting for the GPU", "GPU work"]
            .iter()
            .any(|p| line.trim_start().starts_with(p));
        if !(ctx.is_cpu() && gpu_line) {
            println!("{indent}{line}");
        }
    }
    if memory.is_some() {
        println!("{indent}{}", memory_line(ctx, memory));
    }
}

/// The splatting's memory, as `--profile` says it.
fn memory_line(
    ctx: &splattrack::Device,
    memory: Option<splattrack::tracker::GpuMemoryUse>,
) -> String {
    let Some(m) = memory else {
        return String::new();
    };
    let mb = |b: u64| b as f64 / (1u64 << 20) as f64;
    format!(
        "{} memory of the splatting: {:.1} MB (model {:.1}, keyframe colours {:.1}, render targets {:.1})",
        if ctx.is_cpu() { "host" } else { "GPU" },
        mb(m.total()),
        mb(m.model),
        mb(m.keyframe_colors),
        mb(m.targets)
    )
}
