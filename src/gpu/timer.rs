//! GPU timers from timestamp queries: per-pass durations measured on the
//! device itself, which is what benchmarks of individual passes report.

use super::{GpuContext, GpuError, PendingRead};

/// Durations of the labelled passes of one submission, in milliseconds.
#[derive(Debug, Clone, Default)]
pub struct TimerReport {
    /// Each pass's label and duration in milliseconds, in order.
    pub passes: Vec<(String, f64)>,
    /// Each pass's beginning and end on the GPU's clock, nanoseconds
    /// (one clock for every timer of a device; where the passes were read
    /// by [`Timings`]).
    pub spans: Vec<(f64, f64)>,
}

/// When the GPU worked during a set of passes ([`GpuTimeline::of`]), in
/// milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GpuTimeline {
    /// From the first pass's beginning to the last one's end.
    pub span: f64,
    /// Within it, the time some pass ran.
    pub busy: f64,
    /// The idle gaps shorter than [`GpuTimeline::SHORT_GAP_MS`] (between
    /// passes of one submission: barriers, launches).
    pub short_gaps: f64,
    /// Their count (a mean over frames is fractional).
    pub short_gap_count: f64,
    /// The longer gaps: the GPU waiting for the host (its turns between
    /// readbacks and submissions).
    pub long_gaps: f64,
}

impl GpuTimeline {
    /// Gaps up to this long count as between passes.
    pub const SHORT_GAP_MS: f64 = 0.05;

    /// Adds `other` multiplied by `k` (for means over frames).
    pub fn add_scaled(&mut self, other: &GpuTimeline, k: f64) {
        self.span += other.span * k;
        self.busy += other.busy * k;
        self.short_gaps += other.short_gaps * k;
        self.short_gap_count += other.short_gap_count * k;
        self.long_gaps += other.long_gaps * k;
    }

    /// The timeline of passes given by their spans (nanoseconds, any
    /// order; overlapping passes count once).
    pub fn of(spans: &[(f64, f64)]) -> Self {
        let mut v: Vec<(f64, f64)> = spans
            .iter()
            .copied()
            .filter(|(b, e)| b.is_finite() && e.is_finite() && e >= b)
            .collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut t = GpuTimeline::default();
        let Some(&(first, mut end)) = v.first() else {
            return t;
        };
        let mut start = first;
        for &(b, e) in &v[1..] {
            if b > end {
                t.busy += end - start;
                let gap = (b - end) * 1e-6;
                if gap <= Self::SHORT_GAP_MS {
                    t.short_gaps += gap;
                    t.short_gap_count += 1.0;
                } else {
                    t.long_gaps += gap;
                }
                start = b;
            }
            end = end.max(e);
        }
        t.busy = (t.busy + end - start) * 1e-6;
        t.span = (end - first) * 1e-6;
        t
    }
}

impl TimerReport {
    /// Sum of the passes' durations, in milliseconds.
    pub fn total_ms(&self) -> f64 {
        self.passes.iter().map(|(_, ms)| ms).sum()
    }

    /// Milliseconds of the pass named `label` (summed if repeated).
    pub fn get(&self, label: &str) -> Option<f64> {
        let v: Vec<f64> = self
            .passes
            .iter()
            .filter(|(l, _)| l == label)
            .map(|(_, ms)| *ms)
            .collect();
        (!v.is_empty()).then(|| v.iter().sum())
    }
}

/// Timestamps resolved and copied but not yet read: their bytes come with
/// the thread's next readback ([`GpuContext::copy_for_later`]), so that
/// timing the passes adds no wait for the GPU.
pub struct PendingTimes {
    labels: Vec<String>,
    read: PendingRead,
    period_ns: f64,
}

/// The timings of the passes a module ran since they were last taken:
/// read, or still to come with a readback ([`GpuTimer::resolve_later`]).
#[derive(Default)]
pub struct Timings {
    ready: TimerReport,
    pending: Vec<PendingTimes>,
}

impl Timings {
    /// Appends `other`'s passes after these; of the reads still to come,
    /// the last [`Timings::KEPT`] are kept (timings never taken do not
    /// pile up).
    pub fn append(&mut self, other: Timings) {
        self.ready.passes.extend(other.ready.passes);
        self.ready.spans.extend(other.ready.spans);
        self.pending.extend(other.pending);
        let extra = self.pending.len().saturating_sub(Self::KEPT);
        self.pending.drain(..extra);
    }

    /// Reads of timestamps kept by [`Timings::append`].
    pub const KEPT: usize = 8;

    /// The durations, in the order the passes were timed: at once where a
    /// readback since has mapped their timestamps, else after a wait of
    /// their own (one for all).
    pub fn try_wait(self, ctx: &GpuContext) -> Result<TimerReport, GpuError> {
        let mut report = self.ready;
        for p in self.pending {
            let ticks: Vec<u64> = bytemuck::pod_collect_to_vec(&p.read.wait(ctx)?);
            report
                .passes
                .extend(p.labels.into_iter().enumerate().map(|(i, l)| {
                    let dt = ticks[2 * i + 1].wrapping_sub(ticks[2 * i]);
                    (l, dt as f64 * p.period_ns * 1e-6)
                }));
            report.spans.extend(
                ticks
                    .chunks_exact(2)
                    .map(|t| (t[0] as f64 * p.period_ns, t[1] as f64 * p.period_ns)),
            );
        }
        Ok(report)
    }

    /// [`Timings::try_wait`], a failed read logged and reported as no
    /// passes: timings never fail the work they time.
    pub fn wait(self, ctx: &GpuContext) -> TimerReport {
        self.try_wait(ctx).unwrap_or_else(|e| {
            log::warn!("GPU timer: {e}");
            TimerReport::default()
        })
    }
}

/// Hands out begin/end timestamp slots for compute and render passes, then
/// resolves and reads them. Without `TIMESTAMP_QUERY` it hands out `None`
/// and reports nothing, so callers need no special case.
pub struct GpuTimer {
    query_set: Option<wgpu::QuerySet>,
    resolve: Option<wgpu::Buffer>,
    capacity: u32,
    labels: Vec<String>,
    period_ns: f64,
}

impl GpuTimer {
    /// A timer for up to `max_passes` passes per submission.
    pub fn new(ctx: &GpuContext, max_passes: u32) -> Self {
        let capacity = max_passes * 2;
        let (query_set, resolve) = if ctx.has_timestamps() && capacity > 0 {
            let qs = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("gpu timer"),
                ty: wgpu::QueryType::Timestamp,
                count: capacity,
            });
            let buf = ctx.buffer(
                "gpu timer resolve",
                capacity as u64 * 8,
                wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            );
            (Some(qs), Some(buf))
        } else {
            (None, None)
        };
        Self {
            query_set,
            resolve,
            capacity,
            labels: Vec::new(),
            period_ns: ctx.queue.get_timestamp_period() as f64,
        }
    }

    /// Whether timestamps are recorded (the device supports them).
    pub fn enabled(&self) -> bool {
        self.query_set.is_some()
    }

    fn slot(&mut self, label: &str) -> Option<(&wgpu::QuerySet, u32)> {
        let qs = self.query_set.as_ref()?;
        let i = self.labels.len() as u32;
        if 2 * i + 2 > self.capacity {
            log::warn!("GPU timer full: pass {label:?} is not timed");
            return None;
        }
        self.labels.push(label.to_owned());
        Some((qs, 2 * i))
    }

    /// Timestamp writes for a compute pass named `label`.
    pub fn compute_pass(&mut self, label: &str) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        self.slot(label)
            .map(|(qs, i)| wgpu::ComputePassTimestampWrites {
                query_set: qs,
                beginning_of_pass_write_index: Some(i),
                end_of_pass_write_index: Some(i + 1),
            })
    }

    /// Timestamp writes for a render pass named `label`.
    pub fn render_pass(&mut self, label: &str) -> Option<wgpu::RenderPassTimestampWrites<'_>> {
        self.slot(label)
            .map(|(qs, i)| wgpu::RenderPassTimestampWrites {
                query_set: qs,
                beginning_of_pass_write_index: Some(i),
                end_of_pass_write_index: Some(i + 1),
            })
    }

    /// Records the resolve of all timestamps written so far; call once,
    /// after the timed passes, in the same or a later encoder.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        self.resolve_labelled(encoder, self.labels.len());
    }

    /// Records the resolve of the first `passes` passes' timestamps.
    fn resolve_labelled(&self, encoder: &mut wgpu::CommandEncoder, passes: usize) {
        if let (Some(qs), Some(buf)) = (&self.query_set, &self.resolve) {
            let n = 2 * passes as u32;
            if n > 0 {
                encoder.resolve_query_set(qs, 0..n, buf, 0);
            }
        }
    }

    /// Records into `enc` the resolve of the timestamps written so far and
    /// the copy of their values for a later read, and clears the labels
    /// for the next passes; the caller submits `enc` before its thread's
    /// next readback, which maps them ([`GpuContext::copy_for_later`]).
    pub fn resolve_later(
        &mut self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
    ) -> Result<Timings, GpuError> {
        let labels = std::mem::take(&mut self.labels);
        let Some(buf) = &self.resolve else {
            return Ok(Timings::default());
        };
        if labels.is_empty() {
            return Ok(Timings::default());
        }
        self.resolve_labelled(enc, labels.len());
        let read = ctx.copy_for_later(enc, buf, 16 * labels.len() as u64)?;
        Ok(Timings {
            ready: TimerReport::default(),
            pending: vec![PendingTimes {
                labels,
                read,
                period_ns: self.period_ns,
            }],
        })
    }

    /// [`GpuTimer::resolve_later`] recorded to go with the next
    /// submission ([`GpuContext::encoder_for_next`]): after the timed
    /// passes' work, submitted or put off before, and without a
    /// submission of its own.
    pub fn read_later(&mut self, ctx: &GpuContext) -> Result<Timings, GpuError> {
        if self.resolve.is_none() || self.labels.is_empty() {
            self.labels.clear();
            return Ok(Timings::default());
        }
        let mut enc = ctx.encoder_for_next();
        let t = self.resolve_later(ctx, &mut enc);
        ctx.defer(enc);
        t
    }

    /// Reads the durations of the passes timed so far (in a readback of
    /// their own) and clears the labels for the next submission.
    pub fn read(&mut self, ctx: &GpuContext) -> Result<TimerReport, GpuError> {
        self.read_later(ctx)?.try_wait(ctx)
    }
}

#[cfg(test)]
mod tests {
    use super::GpuTimeline;

    #[test]
    fn the_timeline_merges_overlaps_and_sorts_the_gaps() {
        // Nanoseconds: [0, 10 us] and [5, 20 us] overlap (busy 20 us), a
        // gap of 30 us (short), [50, 60 us], a gap of 1 ms (long), then
        // [1060, 1070 us]; given out of order, with one reversed span
        // ignored.
        let us = 1e3;
        let t = GpuTimeline::of(&[
            (1060.0 * us, 1070.0 * us),
            (5.0 * us, 20.0 * us),
            (0.0, 10.0 * us),
            (50.0 * us, 60.0 * us),
            (9.0, 3.0),
        ]);
        let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
        assert!(close(t.span, 1.07), "{t:?}");
        assert!(close(t.busy, 0.04), "{t:?}");
        assert!(
            close(t.short_gaps, 0.03) && t.short_gap_count == 1.0,
            "{t:?}"
        );
        assert!(close(t.long_gaps, 1.0), "{t:?}");
        assert!(close(t.span, t.busy + t.short_gaps + t.long_gaps));
        assert_eq!(GpuTimeline::of(&[]), GpuTimeline::default());
    }
}
