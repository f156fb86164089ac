//! GPU timers from timestamp queries: per-pass durations measured on the
//! device itself, which is what benchmarks of individual passes report.

use super::{GpuContext, GpuError, PendingRead};

/// Durations of the labelled passes of one submission, in milliseconds.
#[derive(Debug, Clone, Default)]
pub struct TimerReport {
    pub passes: Vec<(String, f64)>,
}

impl TimerReport {
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
