//! The `--profile` table of `splattrack track`: the mean time per frame of
//! every stage, its parts and its waits for the GPU, the GPU's work and
//! its passes.

use splattrack::tracker::StageTimes;
use std::time::Duration;

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// The `--profile` table: every stage of the step, its parts, and what
/// the stages leave over (grey conversion, decisions, bookkeeping).
/// `cpu_adapter`: the GPU passes ran on a CPU adapter, whose timestamps of
/// the feature passes are not to be trusted (said under them).
/// `validated`: wgpu checks indirect dispatches on the GPU (said beside
/// the submissions: a dispatch and two barriers more each).
pub fn profile_table(t: &StageTimes, cpu_adapter: bool, validated: bool) -> String {
    let rows = stage_rows(t);
    // No wait at all (the CPU device): no brackets to explain.
    let waited = rows.iter().any(|(_, _, w)| w.is_some_and(|d| !d.is_zero()));
    let mut out = String::from(if waited {
        "per frame (mean; in brackets the wait for the GPU):\n"
    } else {
        "per frame (mean):\n"
    });
    for (name, v, wait) in rows {
        out += &format!("  {name:<26} {v:8.1} ms");
        if let Some(d) = wait.filter(|d| !d.is_zero()) {
            out += &format!("  ({:.1} waiting)", ms(d));
        }
        out += "\n";
    }
    out += &gpu_work(t, cpu_adapter, validated);
    out += &format!("  {:<26} {:8.2}\n", "renders of the model", t.renders);
    if t.contour_rounds > 0.0 {
        out += &format!(
            "  {:<26} {:8.2} ({:.2} renders)\n",
            "contour rounds", t.contour_rounds, t.contour_renders
        );
    }
    if !t.colour_learning.is_zero() {
        out += &format!(
            "  {:<26} {:8.1} ms (on a thread of its own, beside the next frame's steps)\n",
            "contour colour learning",
            ms(t.colour_learning)
        );
    }
    if !t.gpu.is_empty() {
        out += &gpu_passes(t, cpu_adapter);
    }
    out
}

/// The table's rows: a stage or a part, its milliseconds, and for a stage
/// its wait for the GPU.
fn stage_rows(t: &StageTimes) -> Vec<(&'static str, f64, Option<Duration>)> {
    let rest =
        |whole: Duration, parts: &[Duration]| ms(whole) - parts.iter().map(|d| ms(*d)).sum::<f64>();
    let w = &t.waits;
    let mut rows = vec![
        ("features (frame Harris)", ms(t.features), Some(w.features)),
        ("IT", ms(t.it), Some(w.it)),
        ("  render + gather", ms(t.it_render), None),
        ("  NCC", ms(t.it_ncc), None),
        ("  solve", rest(t.it, &[t.it_render, t.it_ncc]), None),
        ("KF", ms(t.kf), Some(w.kf)),
        ("  render + read", ms(t.kf_render), None),
        ("  Harris", ms(t.kf_harris), None),
        ("  NCC + gather + refine", ms(t.kf_ncc), None),
        (
            "  solve",
            rest(t.kf, &[t.kf_render, t.kf_harris, t.kf_ncc]),
            None,
        ),
        ("contour", ms(t.contour), Some(w.contour)),
        ("pose check", ms(t.verify), Some(w.verify)),
        ("search", ms(t.search), Some(w.search)),
        (
            "other",
            rest(
                t.total,
                &[t.features, t.it, t.kf, t.contour, t.verify, t.search],
            ),
            None,
        ),
        ("total", ms(t.total), Some(t.gpu_wait)),
    ];
    if t.contour_rounds > 0.0 {
        let at = rows.iter().position(|(n, ..)| *n == "contour").unwrap_or(0) + 1;
        rows.insert(at, ("  waiting for its colours", ms(t.colour_wait), None));
    }
    rows
}

/// The lines on readbacks, waits, submissions and passes.
fn gpu_work(t: &StageTimes, cpu_adapter: bool, validated: bool) -> String {
    let mut out = format!(
        "  {:<26} {:8.0} bytes in {:.1} readbacks\n",
        "read back from the GPU", t.readback_bytes, t.readbacks
    );
    out += &format!(
        "  {:<26} {:8.1} ms in those waits (the GPU's work and latency); the host's own work {:.1} ms, of which {:.1} finishing command buffers (wgpu encoding the passes) and {:.1} submitting{}\n",
        "waiting for the GPU",
        ms(t.gpu_wait),
        ms(t.total) - ms(t.gpu_wait),
        ms(t.gpu_finish),
        ms(t.gpu_submit),
        if cpu_adapter {
            " (a CPU adapter runs the GPU's work inside submissions too: the split says little there)"
        } else {
            ""
        }
    );
    out += &format!(
        "  {:<26} {:8.1} submissions, {:.1} command buffers, {:.1} uploads ({:.1} unchanged parameters skipped), {:.1} passes ({:.1} timed apart); indirect dispatches {}\n",
        "GPU work",
        t.submissions,
        t.command_buffers,
        t.uploads,
        t.uploads_skipped,
        t.passes_untimed,
        t.passes,
        if validated {
            "checked by wgpu first (WGPU_VALIDATION_INDIRECT_CALL or DX12)"
        } else {
            "as they are"
        }
    );
    out
}

/// The GPU's timeline and its passes, from timestamp queries.
fn gpu_passes(t: &StageTimes, cpu_adapter: bool) -> String {
    let g = &t.gpu_timeline;
    let mut out = format!(
        "GPU timeline per frame (mean): {:.3} ms from the first pass to the last, {:.3} busy; idle {:.3} in {:.1} gaps of at most {} ms between passes, {:.3} in longer ones (the host's turns)\n",
        g.span,
        g.busy,
        g.short_gaps,
        g.short_gap_count,
        splattrack::gpu::GpuTimeline::SHORT_GAP_MS,
        g.long_gaps
    );
    out += "GPU passes per frame (mean, timestamp queries):\n";
    for (name, v) in &t.gpu {
        out += &format!("  {name:<26} {v:8.3} ms\n");
    }
    let features_timed = t
        .gpu
        .iter()
        .any(|(name, _)| name.contains(" harris ") || name.contains(" ncc "));
    if cpu_adapter && features_timed {
        out += "  (a CPU adapter: its timestamps of the Harris and NCC passes under-report, by 10-30x on lavapipe; the stage times above are the measure)\n";
    }
    out
}
