//! Submission: command encoders ([`GpuContext::encoder`]), batches of
//! submissions ([`GpuContext::batch`]), and the waits for the GPU
//! ([`GpuContext::wait`], bounded by [`GpuContext::timeout_s`]).

use super::context::GpuContext;
use super::error::{DEFAULT_TIMEOUT_S, GpuError, TIMEOUT_ENV};
use super::health::{BatchState, Health};
use super::stats::Counters;

/// A batch of submissions ([`GpuContext::batch`]); dropping it submits
/// what it put off.
#[must_use = "the batch ends when the guard is dropped"]
pub struct Batch {
    /// The context's state and queue; `None`: another thread batches, and
    /// this guard does nothing.
    ctx: Option<(std::sync::Arc<Health>, wgpu::Queue)>,
}

impl Drop for Batch {
    fn drop(&mut self) {
        let Some((health, queue)) = self.ctx.take() else {
            return;
        };
        let mut b = health.batch.lock().unwrap_or_else(|p| p.into_inner());
        b.depth = b.depth.saturating_sub(1);
        if b.depth > 0 {
            return;
        }
        b.thread = None;
        if b.pending.is_empty() && b.open_deferred {
            // Nothing of the batch's own: what was put off for the next
            // submission waits for it.
            return;
        }
        drop(b);
        health.submit(&queue, None);
    }
}

/// A point in a context's submissions ([`GpuContext::submission_mark`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SubmissionMark(u64);

/// A command encoder from [`GpuContext::encoder`], which dereferences to
/// [`wgpu::CommandEncoder`]. Within a batch of the calling thread it is
/// the batch's one encoder, lent with the work recorded before; it goes
/// back with [`GpuContext::submit`] or a readback after it, or when
/// dropped (its work then goes with the batch's). Elsewhere it is a fresh
/// encoder.
pub struct Encoder {
    /// `None` once submitted.
    enc: Option<wgpu::CommandEncoder>,
    /// The batch it is lent by.
    lent: Option<std::sync::Arc<Health>>,
    /// Lent by [`GpuContext::encoder_for_next`] with only such work
    /// before.
    deferred: bool,
}

impl std::ops::Deref for Encoder {
    type Target = wgpu::CommandEncoder;
    fn deref(&self) -> &wgpu::CommandEncoder {
        self.enc.as_ref().expect("an encoder until submitted")
    }
}

impl std::ops::DerefMut for Encoder {
    fn deref_mut(&mut self) -> &mut wgpu::CommandEncoder {
        self.enc.as_mut().expect("an encoder until submitted")
    }
}

impl Encoder {
    /// The encoder, given back to its batch as lent no more (its work is
    /// the caller's to submit).
    fn take(mut self) -> wgpu::CommandEncoder {
        if let Some(h) = self.lent.take() {
            h.batch_state().lent = false;
        }
        self.enc.take().expect("an encoder until submitted")
    }
}

impl Drop for Encoder {
    fn drop(&mut self) {
        if let (Some(enc), Some(h)) = (self.enc.take(), self.lent.take()) {
            let mut b = h.batch_state();
            b.lent = false;
            match b.open.take() {
                None => {
                    b.open = Some(enc);
                    b.open_deferred = self.deferred;
                }
                // Never with one encoder lent at a time; its work is
                // kept, before the newer, all the same.
                Some(newer) => {
                    b.pending.push(h.finish(enc));
                    b.open = Some(newer);
                }
            }
        }
    }
}

impl GpuContext {
    /// Seconds [`GpuContext::wait`] waits at most ([`TIMEOUT_ENV`]).
    pub fn timeout_s() -> u64 {
        std::env::var(TIMEOUT_ENV)
            .ok()
            .and_then(|v| v.trim().parse::<u64>().ok())
            .filter(|&s| s > 0)
            .unwrap_or(DEFAULT_TIMEOUT_S)
    }

    /// Waits for the submitted work, at most [`GpuContext::timeout_s`]
    /// seconds, then reports any failure the device saw ([`GpuContext::check`]).
    pub(super) fn poll_wait(&self) -> Result<(), GpuError> {
        let secs = Self::timeout_s();
        let t0 = std::time::Instant::now();
        let r = self.device.poll(wgpu::PollType::Wait {
            submission_index: None,
            timeout: Some(std::time::Duration::from_secs(secs)),
        });
        Counters::add_since(&self.health.counts.waited_ns, t0);
        self.check()?;
        match r {
            Ok(_) => Ok(()),
            Err(wgpu::PollError::Timeout) => Err(GpuError::Timeout(secs)),
            Err(e) => Err(GpuError::Readback(e.to_string())),
        }
    }

    /// A mark of the work given back to the context so far (submitted, or
    /// put off by a batch): [`GpuContext::submitted_since`] says when all
    /// of it is on the GPU's queue.
    pub fn submission_mark(&self) -> SubmissionMark {
        SubmissionMark(self.batch_state().drains)
    }

    /// Whether all the work given back before `mark` was taken has been
    /// submitted since (a batch's put-off work included): a
    /// `Queue::write_buffer` now no longer reaches it.
    pub fn submitted_since(&self, mark: SubmissionMark) -> bool {
        self.batch_state().drains > mark.0
    }

    /// An encoder to record GPU work into, for [`GpuContext::submit`] or a
    /// readback after it ([`GpuContext::read_buffers_after`]). Within a
    /// batch of the calling thread ([`GpuContext::batch`]) it is the
    /// batch's one encoder, lent with the work put off so far: a batch's
    /// passes then cost the host one command buffer, not one each (each
    /// is validated, tracked and, once done, freed: 0.3-0.5 ms of the
    /// host's a frame on lavapipe for the resident loop's 20 or so,
    /// docs/performance.md).
    ///
    /// One encoder is lent at a time: submit (or drop) it before asking
    /// for another on the same thread, and before the batch's guard is
    /// dropped. A second one asked for meanwhile is refused with a panic,
    /// as its work could not be ordered after the work already in the
    /// lent one.
    #[track_caller]
    pub fn encoder(&self) -> Encoder {
        let mut b = self.batch_state();
        if b.depth > 0 && b.thread == Some(std::thread::current().id()) {
            if b.lent {
                drop(b);
                panic!(
                    "GpuContext::encoder at {}: the batch's encoder is lent already (submit it first)",
                    std::panic::Location::caller()
                );
            }
            b.lent = true;
            let open = b.open.take();
            drop(b);
            return Encoder {
                enc: Some(open.unwrap_or_else(|| self.fresh_encoder())),
                lent: Some(self.health.clone()),
                deferred: false,
            };
        }
        drop(b);
        Encoder {
            enc: Some(self.fresh_encoder()),
            lent: None,
            deferred: false,
        }
    }

    /// An encoder whose work goes with this thread's next submission,
    /// not in one of its own: the batch's encoder ([`GpuContext::encoder`])
    /// or, outside any batch, one kept open for the next submission of
    /// any thread (work that must only come after work already
    /// submitted, such as a resolve of timestamps). Give it back with
    /// [`GpuContext::defer`]. Where another thread batches, a fresh
    /// encoder, which `defer` submits.
    pub fn encoder_for_next(&self) -> Encoder {
        let mut b = self.batch_state();
        let mine = b.thread.is_none_or(|t| t == std::thread::current().id());
        if mine && !b.lent {
            b.lent = true;
            let open = b.open.take();
            let deferred = open.is_none() || b.open_deferred;
            drop(b);
            return Encoder {
                enc: Some(open.unwrap_or_else(|| self.fresh_encoder())),
                lent: Some(self.health.clone()),
                deferred,
            };
        }
        drop(b);
        self.encoder()
    }

    /// Gives back an encoder from [`GpuContext::encoder_for_next`]: its
    /// work goes with the next submission (submitted now only where it
    /// is not the batch's or the kept one).
    #[track_caller]
    pub fn defer(&self, enc: Encoder) {
        if enc.lent.is_some() {
            drop(enc);
        } else {
            self.submit(enc);
        }
    }

    fn fresh_encoder(&self) -> wgpu::CommandEncoder {
        self.device.create_command_encoder(&Default::default())
    }

    /// Submits the work recorded in `enc`, counted by
    /// [`GpuStats::submissions`](super::GpuStats::submissions), together with any work a batch put off
    /// ([`GpuContext::batch`]). Every submission of the crate goes through
    /// here. Within a batch of the calling thread the work is put off
    /// instead, to go with the next readback or the batch's end: the
    /// batch's encoder is given back, still open.
    #[track_caller]
    pub fn submit(&self, enc: Encoder) {
        {
            let mut b = self.batch_state();
            if b.depth > 0 && b.thread == Some(std::thread::current().id()) {
                log::trace!("put off at {}", std::panic::Location::caller());
                if enc.lent.is_some() {
                    drop(b);
                    // Dropped, a lent encoder goes back open.
                    drop(enc);
                } else {
                    // Made before the batch began: after the batch's work
                    // so far.
                    let enc = enc.take();
                    if let Some(open) = b.open.take() {
                        b.pending.push(self.health.finish(open));
                    }
                    b.pending.push(self.health.finish(enc));
                }
                return;
            }
        }
        self.submit_now(enc);
    }

    /// Submits `enc` at once, after the work a batch put off (one
    /// submission). Readbacks submit here: their copies must run before
    /// they wait.
    #[track_caller]
    pub(super) fn submit_now(&self, enc: Encoder) {
        log::trace!("submit at {}", std::panic::Location::caller());
        let enc = enc.take();
        self.health.submit(&self.queue, Some(enc));
    }

    fn batch_state(&self) -> std::sync::MutexGuard<'_, BatchState> {
        self.health.batch_state()
    }

    /// Batches this thread's submissions until the guard is dropped: work
    /// submitted through [`GpuContext::submit`] is recorded, and goes to
    /// the GPU with the next readback's (or when the guard is dropped), in
    /// one submission: a chain of passes ending in a readback costs the
    /// host one submission instead of one a pass (about 46 us each on
    /// lavapipe, `cargo bench --bench features -- submission`), and, its
    /// encoders taken from [`GpuContext::encoder`], one command buffer.
    ///
    /// Only for chains whose passes read parameters from buffers of their
    /// own: a `Queue::write_buffer` takes effect before the submission it
    /// precedes, so one to a buffer that work already put off reads would
    /// reach that work too. Guards nest; other threads' submissions are
    /// not batched.
    pub fn batch(&self) -> Batch {
        let mut b = self.batch_state();
        let me = std::thread::current().id();
        let mine = b.thread.is_none_or(|t| t == me);
        if mine {
            b.thread = Some(me);
            b.depth += 1;
        }
        Batch {
            ctx: mine.then(|| (self.health.clone(), self.queue.clone())),
        }
    }

    /// Submits the work this thread's batch put off, without waiting.
    pub fn flush(&self) {
        let mine = {
            let b = self.batch_state();
            b.thread == Some(std::thread::current().id())
        };
        if mine {
            self.health.submit(&self.queue, None);
        }
    }

    /// Waits until the GPU has finished all submitted work (and any a
    /// batch put off, submitted first).
    pub fn wait(&self) -> Result<(), GpuError> {
        self.health.submit(&self.queue, None);
        self.poll_wait()
    }
}
