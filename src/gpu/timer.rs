//! GPU timers from timestamp queries: per-pass durations measured on the
//! device itself, which is what benchmarks of individual passes report.

use super::{GpuContext, GpuError};

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
        if let (Some(qs), Some(buf)) = (&self.query_set, &self.resolve) {
            let n = 2 * self.labels.len() as u32;
            if n > 0 {
                encoder.resolve_query_set(qs, 0..n, buf, 0);
            }
        }
    }

    /// Reads the durations (after the submission that resolved them) and
    /// clears the labels for the next submission.
    pub fn read(&mut self, ctx: &GpuContext) -> Result<TimerReport, GpuError> {
        let labels = std::mem::take(&mut self.labels);
        let Some(buf) = &self.resolve else {
            return Ok(TimerReport::default());
        };
        if labels.is_empty() {
            return Ok(TimerReport::default());
        }
        let ticks: Vec<u64> = ctx.read_buffer(buf, 2 * labels.len())?;
        let passes = labels
            .into_iter()
            .enumerate()
            .map(|(i, l)| {
                let dt = ticks[2 * i + 1].wrapping_sub(ticks[2 * i]);
                (l, dt as f64 * self.period_ns * 1e-6)
            })
            .collect();
        Ok(TimerReport { passes })
    }
}
