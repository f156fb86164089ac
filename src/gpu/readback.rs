//! Readbacks: buffers and textures read back to the host through kept
//! staging buffers, one wait for the GPU each, and readbacks put off to
//! go with the next ([`GpuContext::read_buffer_later`]).

use super::context::GpuContext;
use super::error::GpuError;
use super::health::{Health, Rider};
use super::stats::Counters;
use super::submit::Encoder;

/// A readback put off by [`GpuContext::read_buffer_later`]: its bytes
/// come with the next readback of the thread that made it (any other
/// readback's wait then serves both), or with [`PendingRead::wait`].
/// Dropped unwaited, it is taken off its thread's list (no readback maps
/// it) and its staging buffer kept for the next.
#[must_use = "a pending read is only useful waited for"]
pub struct PendingRead {
    /// `None` once waited for.
    rider: Option<std::sync::Arc<Rider>>,
    health: std::sync::Arc<Health>,
    /// The bytes asked for (the rider reads them rounded up to 4).
    bytes: u64,
}

impl PendingRead {
    /// The bytes read: at once when a readback since has mapped them,
    /// else in a readback of their own (submitting what a batch put off).
    pub fn wait(mut self, ctx: &GpuContext) -> Result<Vec<u8>, GpuError> {
        let rider = self.rider.take().expect("waited for once");
        let mapped = rider.bytes.lock().unwrap_or_else(|p| p.into_inner()).take();
        let mut all = match mapped {
            Some(r) => r?,
            None => {
                self.health.forget_rider(&rider);
                ctx.health.submit(&ctx.queue, None);
                let r = ctx.map_read(&rider.staging, rider.size);
                if r.is_ok() {
                    ctx.health.keep_rider_staging(rider.staging.clone());
                }
                r?
            }
        };
        all.truncate(self.bytes as usize);
        Ok(all)
    }
}

impl Drop for PendingRead {
    fn drop(&mut self) {
        if let Some(rider) = self.rider.take()
            && self.health.forget_rider(&rider)
        {
            // Never mapped: its copy, if still running, comes before any
            // later use of the buffer.
            self.health.keep_rider_staging(rider.staging.clone());
        }
    }
}

impl GpuContext {
    /// A mappable staging buffer of at least `size` bytes: the kept one
    /// when it is free and large enough (grown otherwise), else a new one.
    /// Give it back with [`GpuContext::put_staging`].
    fn take_staging(&self, size: u64) -> wgpu::Buffer {
        let kept = self
            .health
            .staging
            .try_lock()
            .ok()
            .and_then(|mut s| s.take())
            .filter(|b| b.size() >= size);
        kept.unwrap_or_else(|| {
            self.buffer(
                "readback",
                size.next_power_of_two()
                    .max(4096)
                    .min(self.limits.max_buffer_size)
                    .max(size),
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            )
        })
    }

    /// Keeps `b` (unmapped) for the next readback, unless a larger one is
    /// kept.
    fn put_staging(&self, b: wgpu::Buffer) {
        if let Ok(mut s) = self.health.staging.try_lock()
            && s.as_ref().is_none_or(|k| k.size() < b.size())
        {
            *s = Some(b);
        }
    }

    /// Reads `count` values of `T` from the start of `buffer` (which needs
    /// `COPY_SRC`), waiting for all submitted work.
    #[track_caller]
    pub fn read_buffer<T: bytemuck::Pod>(
        &self,
        buffer: &wgpu::Buffer,
        count: usize,
    ) -> Result<Vec<T>, GpuError> {
        if count == 0 || std::mem::size_of::<T>() == 0 {
            return Ok(Vec::new());
        }
        let enc = self.encoder();
        self.read_buffer_after(enc, buffer, count)
    }

    /// [`GpuContext::read_buffer`] after the work recorded in `enc`: the
    /// copy is recorded behind it and both go in one submission (each
    /// submission costs the host a command buffer's recording,
    /// validation and release; [`GpuStats::submissions`](super::GpuStats::submissions)). An overread
    /// is refused before anything is submitted, `enc`'s work included.
    #[track_caller]
    pub fn read_buffer_after<T: bytemuck::Pod>(
        &self,
        enc: Encoder,
        buffer: &wgpu::Buffer,
        count: usize,
    ) -> Result<Vec<T>, GpuError> {
        let size = (count * std::mem::size_of::<T>()) as u64;
        let parts = self.read_buffers_after(enc, &[(buffer, size)])?;
        Ok(bytemuck::pod_collect_to_vec(&parts[0]))
    }

    /// Reads the first `bytes` of each buffer (which need `COPY_SRC`) in one
    /// readback: the copies are submitted together into one staging
    /// buffer, mapped once, so the host waits for the GPU once instead of
    /// once a buffer (each wait is a round trip: about 40 us on lavapipe,
    /// `cargo bench --bench features -- readback`). Returns each part's
    /// bytes, `bytes` long.
    #[track_caller]
    pub fn read_buffers(&self, parts: &[(&wgpu::Buffer, u64)]) -> Result<Vec<Vec<u8>>, GpuError> {
        if parts.iter().all(|(_, bytes)| *bytes == 0) {
            return Ok(parts.iter().map(|_| Vec::new()).collect());
        }
        let enc = self.encoder();
        self.read_buffers_after(enc, parts)
    }

    /// [`GpuContext::read_buffers`] after the work recorded in `enc`, in
    /// one submission ([`GpuContext::read_buffer_after`]). With nothing to
    /// read, `enc` is submitted alone, without a wait.
    #[track_caller]
    pub fn read_buffers_after(
        &self,
        mut enc: Encoder,
        parts: &[(&wgpu::Buffer, u64)],
    ) -> Result<Vec<Vec<u8>>, GpuError> {
        let mut offsets = Vec::with_capacity(parts.len());
        let mut total = 0u64;
        for (buffer, bytes) in parts {
            if *bytes > buffer.size() {
                return Err(GpuError::Readback(format!(
                    "asked for {bytes} bytes of a {}-byte buffer",
                    buffer.size()
                )));
            }
            offsets.push(total);
            total += bytes.next_multiple_of(4);
        }
        if total == 0 {
            self.submit(enc);
            return Ok(parts.iter().map(|_| Vec::new()).collect());
        }
        let staging = self.take_staging(total);
        for ((buffer, bytes), &at) in parts.iter().zip(&offsets) {
            if *bytes > 0 {
                enc.copy_buffer_to_buffer(buffer, 0, &staging, at, bytes.next_multiple_of(4));
            }
        }
        self.submit_now(enc);
        // A failed map may leave the buffer pending: dropped, not kept.
        let all = self.map_read(&staging, total)?;
        self.put_staging(staging);
        Ok(parts
            .iter()
            .zip(&offsets)
            .map(|((_, bytes), &at)| all[at as usize..(at + bytes) as usize].to_vec())
            .collect())
    }

    /// Puts off reading the first `bytes` of `buffer` (which needs
    /// `COPY_SRC`) after the work recorded in `enc`: the copy is recorded
    /// behind that work (into a staging buffer of its own, so later work
    /// may reuse `buffer`) and submitted ([`GpuContext::submit`]: within a
    /// batch, put off with it), but nothing waits. The calling thread's
    /// next readback maps it with its own, so that one wait for the GPU
    /// serves both; [`PendingRead::wait`] then returns the bytes without
    /// another. An overread is refused before anything is submitted.
    #[track_caller]
    pub fn read_buffer_later(
        &self,
        mut enc: Encoder,
        buffer: &wgpu::Buffer,
        bytes: u64,
    ) -> Result<PendingRead, GpuError> {
        let read = self.copy_for_later(&mut enc, buffer, bytes)?;
        self.submit(enc);
        Ok(read)
    }

    /// [`GpuContext::read_buffer_later`] without the submission: the copy
    /// is recorded into `enc`, which the caller must submit
    /// ([`GpuContext::submit`], or a readback after it) before this
    /// thread's next readback, which maps it.
    pub fn copy_for_later(
        &self,
        enc: &mut wgpu::CommandEncoder,
        buffer: &wgpu::Buffer,
        bytes: u64,
    ) -> Result<PendingRead, GpuError> {
        if bytes > buffer.size() {
            return Err(GpuError::Readback(format!(
                "asked for {bytes} bytes of a {}-byte buffer",
                buffer.size()
            )));
        }
        let size = bytes.next_multiple_of(4).max(4);
        let kept = {
            let mut pool = self
                .health
                .rider_staging
                .lock()
                .unwrap_or_else(|p| p.into_inner());
            pool.iter()
                .position(|b| b.size() >= size)
                .map(|i| pool.swap_remove(i))
        };
        let staging = kept.unwrap_or_else(|| {
            self.buffer(
                "put-off readback",
                size.next_power_of_two().max(256),
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            )
        });
        if bytes > 0 {
            enc.copy_buffer_to_buffer(buffer, 0, &staging, 0, bytes.next_multiple_of(4));
        }
        let rider = std::sync::Arc::new(Rider {
            thread: std::thread::current().id(),
            staging,
            size,
            bytes: std::sync::Mutex::new(None),
        });
        self.health
            .riders
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(rider.clone());
        Ok(PendingRead {
            rider: Some(rider),
            health: self.health.clone(),
            bytes,
        })
    }

    /// Reads a whole 2-D texture (which needs `COPY_SRC`) as tightly packed
    /// rows of `bytes_per_pixel` bytes.
    pub fn read_texture(
        &self,
        texture: &wgpu::Texture,
        bytes_per_pixel: u32,
    ) -> Result<Vec<u8>, GpuError> {
        let (w, h) = (texture.width(), texture.height());
        let row = w * bytes_per_pixel;
        let padded = row.next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let staging = self.buffer(
            "texture readback",
            (padded * h) as u64,
            wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        );
        let mut enc = self.encoder();
        enc.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(h),
                },
            },
            texture.size(),
        );
        self.submit_now(enc);
        let bytes = self.map_read(&staging, (padded * h) as u64)?;
        let mut out = Vec::with_capacity((row * h) as usize);
        for y in 0..h as usize {
            let start = y * padded as usize;
            out.extend_from_slice(&bytes[start..start + row as usize]);
        }
        Ok(out)
    }

    /// Maps `staging` (whose copies are submitted) and reads its first
    /// `size` bytes, one wait for the GPU, counted as a readback; the
    /// calling thread's put-off readbacks ([`GpuContext::read_buffer_later`])
    /// are mapped in the same wait.
    fn map_read(&self, staging: &wgpu::Buffer, size: u64) -> Result<Vec<u8>, GpuError> {
        let me = std::thread::current().id();
        // This thread's put-off readbacks, taken off the list (which keeps
        // its allocation; none is made when there are none).
        let mut riders: Vec<std::sync::Arc<Rider>> = Vec::new();
        self.health
            .riders
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .retain(|r| {
                let mine = r.thread == me;
                if mine {
                    riders.push(r.clone());
                }
                !mine
            });
        let slice = staging.slice(..size.next_multiple_of(4));
        let rider_bytes: u64 = riders.iter().map(|r| r.size).sum();
        Counters::add(
            &self.health.counts.bytes_read,
            size.next_multiple_of(4) + rider_bytes,
        );
        Counters::add(&self.health.counts.readbacks, 1);
        log::trace!(
            "readback of {size} bytes{}",
            if riders.is_empty() {
                String::new()
            } else {
                format!(" and {} put off ({rider_bytes} bytes)", riders.len())
            }
        );
        let mapped: Vec<_> = riders
            .iter()
            .map(|r| {
                let (tx, rx) = std::sync::mpsc::channel();
                r.staging
                    .slice(..r.size)
                    .map_async(wgpu::MapMode::Read, move |m| {
                        let _ = tx.send(m);
                    });
                rx
            })
            .collect();
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        let waited = self.poll_wait();
        let read = |rx: std::sync::mpsc::Receiver<Result<(), wgpu::BufferAsyncError>>,
                    slice: wgpu::BufferSlice<'_>|
         -> Result<Vec<u8>, GpuError> {
            rx.recv_timeout(std::time::Duration::from_secs(10))
                .map_err(|e| GpuError::Readback(e.to_string()))?
                .map_err(|e| GpuError::Readback(e.to_string()))?;
            let bytes = slice
                .get_mapped_range()
                .map_err(|e| GpuError::Readback(e.to_string()))?
                .to_vec();
            Ok(bytes)
        };
        for (r, rx) in riders.iter().zip(mapped) {
            let got = match &waited {
                Ok(()) => read(rx, r.staging.slice(..r.size)),
                Err(e) => Err(GpuError::Readback(e.to_string())),
            };
            let ok = got.is_ok();
            *r.bytes.lock().unwrap_or_else(|p| p.into_inner()) = Some(got);
            // A failed map may leave the buffer pending: dropped, not kept.
            if ok {
                r.staging.unmap();
                self.health.keep_rider_staging(r.staging.clone());
            }
        }
        waited?;
        let bytes = read(rx, slice)?;
        staging.unmap();
        Ok(bytes)
    }
}
