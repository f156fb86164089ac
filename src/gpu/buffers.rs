//! Buffers every GPU module shares the making of: the usages of storage
//! buffers, uniforms uploaded only when they change, buffers that grow.

use super::context::GpuContext;

/// A uniform buffer uploaded only when its bytes change: each
/// `Queue::write_buffer` costs a staging buffer of wgpu's own (made,
/// mapped, copied, freed with its submission), and most of the frame
/// loop's parameters are those of the frame before. Skipping is safe
/// whatever the batching: a write takes effect before the next
/// submission, so the buffer then holds the last bytes written. Only for
/// buffers the GPU never writes, written only through here.
#[derive(Debug)]
pub struct Uniform {
    buffer: wgpu::Buffer,
    last: Vec<u8>,
}

impl Uniform {
    /// A uniform buffer of `size` bytes (also a copy destination).
    pub fn new(ctx: &GpuContext, label: &str, size: u64) -> Self {
        Self::with_usage(ctx, label, size, wgpu::BufferUsages::UNIFORM)
    }

    /// The same with other usages (a read-only storage buffer of
    /// parameters); always a copy destination.
    pub fn with_usage(ctx: &GpuContext, label: &str, size: u64, usage: wgpu::BufferUsages) -> Self {
        Self {
            buffer: ctx.buffer(label, size, usage | wgpu::BufferUsages::COPY_DST),
            last: Vec::new(),
        }
    }

    /// Uploads `bytes` at offset 0 unless they are the last written;
    /// whether it did.
    pub fn write(&mut self, ctx: &GpuContext, bytes: &[u8]) -> bool {
        if !self.last.is_empty() && self.last == bytes {
            ctx.count_upload_skipped();
            return false;
        }
        ctx.write_buffer(&self.buffer, 0, bytes);
        self.last.clear();
        self.last.extend_from_slice(bytes);
        true
    }

    /// The GPU buffer.
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }
}

/// Storage buffer usages for data the host writes and the GPU reads.
pub const STORAGE_IN: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE
    .union(wgpu::BufferUsages::COPY_DST)
    .union(wgpu::BufferUsages::COPY_SRC);

/// Storage buffer usages for GPU results that may be read back.
pub const STORAGE_OUT: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE
    .union(wgpu::BufferUsages::COPY_SRC)
    .union(wgpu::BufferUsages::COPY_DST);

/// A buffer that grows (never shrinks) to fit what it must hold, so that
/// per-frame work allocates nothing in the steady state.
pub struct GrowBuffer {
    label: &'static str,
    usage: wgpu::BufferUsages,
    buffer: Option<wgpu::Buffer>,
}

impl GrowBuffer {
    /// An empty buffer with this label and usage; nothing is allocated until
    /// [`GrowBuffer::ensure`].
    pub fn new(label: &'static str, usage: wgpu::BufferUsages) -> Self {
        Self {
            label,
            usage,
            buffer: None,
        }
    }

    /// Ensures at least `size` bytes; true when the buffer was (re)created,
    /// so bind groups referencing it must be rebuilt. Grows to the next
    /// power of two (within the adapter's limit), so that sizes that vary
    /// from frame to frame stop reallocating after a few frames.
    pub fn ensure(&mut self, ctx: &GpuContext, size: u64) -> bool {
        let size = size.max(16).next_multiple_of(16);
        if self.buffer.as_ref().is_some_and(|b| b.size() >= size) {
            return false;
        }
        let grown = size
            .next_power_of_two()
            .min(
                ctx.limits
                    .max_buffer_size
                    .min(ctx.limits.max_storage_buffer_binding_size)
                    / 16
                    * 16,
            )
            .max(size);
        self.buffer = Some(ctx.buffer(self.label, grown, self.usage));
        true
    }

    /// Bytes allocated now (0 before the first [`GrowBuffer::ensure`]).
    pub fn size(&self) -> u64 {
        self.buffer.as_ref().map_or(0, |b| b.size())
    }

    /// The buffer; panics before the first [`GrowBuffer::ensure`].
    pub fn get(&self) -> &wgpu::Buffer {
        self.buffer.as_ref().expect("GrowBuffer used before ensure")
    }
}
