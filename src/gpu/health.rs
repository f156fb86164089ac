//! The state every clone of a [`GpuContext`](super::GpuContext) shares: the device's
//! health (the first error, device loss), the counters of [`GpuStats`],
//! the readbacks' staging buffers, the batch of submissions and the
//! readbacks put off.

use super::error::GpuError;
use super::stats::{Counters, GpuStats};

/// What went wrong on the device outside an error scope: the first error
/// wgpu reports to the uncaptured-error handler (which would otherwise
/// panic), a size refused before allocation, and device loss. Checked by
/// [`GpuContext::check`](super::GpuContext::check) after every wait, so the run ends with a typed
/// error instead of a panic. With it, the rest of the state the clones of
/// a context share.
#[derive(Default)]
pub(super) struct Health {
    pub(super) first_error: std::sync::Mutex<Option<GpuError>>,
    pub(super) lost: std::sync::Mutex<Option<String>>,
    /// What the device has done ([`GpuContext::stats`](super::GpuContext::stats)).
    pub(super) counts: Counters,
    /// The staging buffer of readbacks, grow-only; taken while in use (a
    /// concurrent readback makes its own).
    pub(super) staging: std::sync::Mutex<Option<wgpu::Buffer>>,
    /// The thread batching its submissions ([`GpuContext::batch`](super::GpuContext::batch)).
    pub(super) batch: std::sync::Mutex<BatchState>,
    /// Readbacks put off ([`GpuContext::read_buffer_later`](super::GpuContext::read_buffer_later)), to be mapped
    /// with their thread's next readback.
    pub(super) riders: std::sync::Mutex<Vec<std::sync::Arc<Rider>>>,
    /// Unmapped staging buffers of put-off readbacks, for the next ones.
    pub(super) rider_staging: std::sync::Mutex<Vec<wgpu::Buffer>>,
}

/// A readback put off: its copy is recorded, its bytes not yet mapped.
pub(super) struct Rider {
    pub(super) thread: std::thread::ThreadId,
    pub(super) staging: wgpu::Buffer,
    /// Bytes to read (a multiple of 4).
    pub(super) size: u64,
    /// Filled by the readback that mapped it.
    pub(super) bytes: std::sync::Mutex<Option<Result<Vec<u8>, GpuError>>>,
}

/// Who batches submissions, how many guards deep, and the work put off:
/// recorded into one open encoder, lent to one caller at a time
/// ([`GpuContext::encoder`](super::GpuContext::encoder)), or finished already (`pending`, before the
/// open encoder's work).
#[derive(Default)]
pub(super) struct BatchState {
    pub(super) thread: Option<std::thread::ThreadId>,
    pub(super) depth: usize,
    pub(super) pending: Vec<wgpu::CommandBuffer>,
    pub(super) open: Option<wgpu::CommandEncoder>,
    /// The open encoder is lent (its work is in the borrower's hands).
    pub(super) lent: bool,
    /// The open encoder holds only work put off to go with the next
    /// submission ([`GpuContext::encoder_for_next`](super::GpuContext::encoder_for_next)): a batch's end leaves
    /// it open instead of submitting it alone.
    pub(super) open_deferred: bool,
    /// Submissions that left none of the work given back to the context
    /// unsubmitted (no encoder lent): work given back before one of them
    /// is on the GPU's queue ([`GpuContext::submitted_since`](super::GpuContext::submitted_since)).
    pub(super) drains: u64,
}

impl Health {
    /// Takes `rider` off the list of put-off readbacks; whether it was on
    /// it (not yet mapped).
    pub(super) fn forget_rider(&self, rider: &std::sync::Arc<Rider>) -> bool {
        let mut riders = self.riders.lock().unwrap_or_else(|p| p.into_inner());
        let before = riders.len();
        riders.retain(|r| !std::sync::Arc::ptr_eq(r, rider));
        riders.len() < before
    }

    /// Keeps an unmapped staging buffer of a put-off readback for the next
    /// (a few at most).
    pub(super) fn keep_rider_staging(&self, b: wgpu::Buffer) {
        let mut pool = self.rider_staging.lock().unwrap_or_else(|p| p.into_inner());
        // A profiled frame puts off a read of timestamps a step.
        if pool.len() < 24 {
            pool.push(b);
        }
    }

    /// Submits the work a batch put off and then `last`, in one counted
    /// submission (none when there is nothing). The list keeps its
    /// allocation: no allocation a submission.
    pub(super) fn submit(&self, queue: &wgpu::Queue, last: Option<wgpu::CommandEncoder>) {
        let mut b = self.batch_state();
        if let Some(open) = b.open.take() {
            b.pending.push(self.finish(open));
        }
        if let Some(last) = last {
            b.pending.push(self.finish(last));
        }
        if !b.lent {
            b.drains += 1;
        }
        if b.pending.is_empty() {
            return;
        }
        Counters::add(&self.counts.submissions, 1);
        Counters::add(&self.counts.command_buffers, b.pending.len() as u64);
        let t0 = std::time::Instant::now();
        queue.submit(b.pending.drain(..));
        Counters::add_since(&self.counts.submit_ns, t0);
    }

    /// Finishes `enc` (wgpu encodes its passes), timed.
    pub(super) fn finish(&self, enc: wgpu::CommandEncoder) -> wgpu::CommandBuffer {
        let t0 = std::time::Instant::now();
        let done = enc.finish();
        Counters::add_since(&self.counts.finish_ns, t0);
        done
    }

    pub(super) fn batch_state(&self) -> std::sync::MutexGuard<'_, BatchState> {
        self.batch.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// What the device has done so far.
    pub(super) fn stats(&self) -> GpuStats {
        self.counts.snapshot()
    }

    pub(super) fn record(&self, e: GpuError) {
        let mut slot = self.first_error.lock().unwrap_or_else(|p| p.into_inner());
        if slot.is_none() {
            *slot = Some(e);
        }
    }
}
