//! What a context has done so far: the counters every clone of a
//! [`GpuContext`](super::GpuContext) shares, read as one [`GpuStats`]
//! snapshot ([`GpuContext::stats`](super::GpuContext::stats)).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// What a device has done so far, all clones of its context and all
/// threads together: a snapshot taken by
/// [`GpuContext::stats`](super::GpuContext::stats). Every figure only
/// grows, so the difference of two snapshots ([`GpuStats::since`], or
/// `later - earlier`) is what a stretch of work did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GpuStats {
    /// Buffers made through `GpuContext::buffer` and
    /// `GpuContext::buffer_init` (the steady frame loop makes none).
    pub buffers_created: u64,
    /// Bind groups made through `GpuContext::bind_group` (every bind
    /// group of the crate): a frame loop that keeps its bind groups makes
    /// none once its buffers have grown.
    pub bind_groups_created: u64,
    /// Uploads through `GpuContext::write_buffer` (every upload of the
    /// crate; each a staging buffer of wgpu's own: made, mapped, copied,
    /// freed once its submission is done).
    pub uploads: u64,
    /// Uploads a `Uniform` found unchanged and skipped.
    pub uploads_skipped: u64,
    /// Submissions through `GpuContext::submit` and the readbacks (each a
    /// `Queue::submit` of one or more command buffers: the host's fixed
    /// cost of GPU work).
    pub submissions: u64,
    /// Command buffers submitted (each recorded, validated and, once
    /// done, freed): one a submission where every encoder came from
    /// `GpuContext::encoder` within a batch.
    pub command_buffers: u64,
    /// Passes begun. Every compute pass of the crate is begun by a
    /// `PassChain`; the render pass splatter and the live view count
    /// their render passes too.
    pub passes: u64,
    /// The passes an untimed run would begin (a `PassChain` records its
    /// stages in one pass where untimed, in one a stage where timed).
    pub passes_untimed: u64,
    /// Readbacks (each maps a staging buffer, waiting for the GPU).
    pub readbacks: u64,
    /// Bytes read back to the host by them (padding to 4 bytes and
    /// texture rows' alignment included; a few floats per feature).
    pub bytes_read: u64,
    /// Time the host spent blocked in waits for the GPU (the readbacks'
    /// and `GpuContext::wait`'s): its work queued before them and the
    /// round trip; the rest of a frame is the host's own.
    pub wait_time: Duration,
    /// Time the host spent finishing command encoders (where wgpu encodes
    /// and validates the recorded passes).
    pub finish_time: Duration,
    /// Time the host spent in `Queue::submit`.
    pub submit_time: Duration,
}

impl GpuStats {
    /// What was done between `earlier` and this snapshot (each figure's
    /// difference, 0 where `earlier` is the later one).
    pub fn since(&self, earlier: &GpuStats) -> GpuStats {
        GpuStats {
            buffers_created: self.buffers_created.saturating_sub(earlier.buffers_created),
            bind_groups_created: self
                .bind_groups_created
                .saturating_sub(earlier.bind_groups_created),
            uploads: self.uploads.saturating_sub(earlier.uploads),
            uploads_skipped: self.uploads_skipped.saturating_sub(earlier.uploads_skipped),
            submissions: self.submissions.saturating_sub(earlier.submissions),
            command_buffers: self.command_buffers.saturating_sub(earlier.command_buffers),
            passes: self.passes.saturating_sub(earlier.passes),
            passes_untimed: self.passes_untimed.saturating_sub(earlier.passes_untimed),
            readbacks: self.readbacks.saturating_sub(earlier.readbacks),
            bytes_read: self.bytes_read.saturating_sub(earlier.bytes_read),
            wait_time: self.wait_time.saturating_sub(earlier.wait_time),
            finish_time: self.finish_time.saturating_sub(earlier.finish_time),
            submit_time: self.submit_time.saturating_sub(earlier.submit_time),
        }
    }
}

impl std::ops::Sub for GpuStats {
    type Output = GpuStats;
    /// [`GpuStats::since`]: `later - earlier`.
    fn sub(self, earlier: GpuStats) -> GpuStats {
        self.since(&earlier)
    }
}

/// The counters behind [`GpuStats`], shared by every clone of a context
/// (relaxed atomics: each figure on its own, none ordered with another).
#[derive(Default)]
pub(super) struct Counters {
    pub(super) buffers_created: AtomicU64,
    pub(super) bind_groups_created: AtomicU64,
    pub(super) uploads: AtomicU64,
    pub(super) uploads_skipped: AtomicU64,
    pub(super) submissions: AtomicU64,
    pub(super) command_buffers: AtomicU64,
    pub(super) passes: AtomicU64,
    pub(super) passes_untimed: AtomicU64,
    pub(super) readbacks: AtomicU64,
    pub(super) bytes_read: AtomicU64,
    /// Nanoseconds, as the three times of [`GpuStats`].
    pub(super) waited_ns: AtomicU64,
    pub(super) finish_ns: AtomicU64,
    pub(super) submit_ns: AtomicU64,
}

impl Counters {
    /// Adds `n` to `counter`.
    pub(super) fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }

    /// Adds the time since `t0` to `counter` (nanoseconds).
    pub(super) fn add_since(counter: &AtomicU64, t0: std::time::Instant) {
        counter.fetch_add(t0.elapsed().as_nanos() as u64, Ordering::Relaxed);
    }

    /// The figures now.
    pub(super) fn snapshot(&self) -> GpuStats {
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
        GpuStats {
            buffers_created: get(&self.buffers_created),
            bind_groups_created: get(&self.bind_groups_created),
            uploads: get(&self.uploads),
            uploads_skipped: get(&self.uploads_skipped),
            submissions: get(&self.submissions),
            command_buffers: get(&self.command_buffers),
            passes: get(&self.passes),
            passes_untimed: get(&self.passes_untimed),
            readbacks: get(&self.readbacks),
            bytes_read: get(&self.bytes_read),
            wait_time: Duration::from_nanos(get(&self.waited_ns)),
            finish_time: Duration::from_nanos(get(&self.finish_ns)),
            submit_time: Duration::from_nanos(get(&self.submit_ns)),
        }
    }
}
