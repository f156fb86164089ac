//! Bind-group layouts, pipelines and passes: the plumbing every GPU module
//! (the splatter, Harris, NCC) builds the same way.

use super::{GpuContext, GpuError, GpuTimer};

/// A bind group layout entry for a whole buffer, visible to `visibility`.
pub fn buffer_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    ty: wgpu::BufferBindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A bind group layout entry for a compute-visible buffer.
pub fn compute_entry(binding: u32, ty: wgpu::BufferBindingType) -> wgpu::BindGroupLayoutEntry {
    buffer_entry(binding, wgpu::ShaderStages::COMPUTE, ty)
}

/// A bind group layout entry for an unfilterable 2-D float texture read
/// with `textureLoad`.
pub fn texture_entry(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// A storage buffer binding type.
pub const fn storage(read_only: bool) -> wgpu::BufferBindingType {
    wgpu::BufferBindingType::Storage { read_only }
}

impl GpuContext {
    /// A bind group layout of `entries`.
    pub fn bind_group_layout(
        &self,
        label: &str,
        entries: &[wgpu::BindGroupLayoutEntry],
    ) -> wgpu::BindGroupLayout {
        self.device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries,
            })
    }

    /// Compute pipelines of the entry points `entries` of one shader, sharing
    /// one explicit bind group layout, so that a single bind group serves
    /// every pass.
    pub fn compute_pipelines(
        &self,
        shader: &crate::shaders::Shader,
        layout: &wgpu::BindGroupLayout,
        entries: &[&str],
    ) -> Result<Vec<wgpu::ComputePipeline>, GpuError> {
        let module = self.shader(shader)?;
        let shader = shader.name;
        let pl = self.catch(shader, || {
            self.device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(shader),
                    bind_group_layouts: &[Some(layout)],
                    immediate_size: 0,
                })
        })?;
        entries
            .iter()
            .map(|entry| {
                self.catch(&format!("{shader}::{entry}"), || {
                    self.device
                        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                            label: Some(entry),
                            layout: Some(&pl),
                            module: &module,
                            entry_point: Some(entry),
                            compilation_options: Default::default(),
                            cache: None,
                        })
                })
            })
            .collect()
    }
}

/// The compute passes of a chain of stages recorded into one encoder:
/// one pass for all of them, or one a stage where stages are timed (a
/// pass's timestamps are written at its beginning and end). Each pass
/// costs the host more than its dispatches (wgpu-core records it into a
/// driver command buffer of its own, with another before it for its
/// barriers: 16.1 us a pass on lavapipe, the `features` bench's
/// `dispatches_40_in_40_passes` against `_in_1_pass`), and the GPU
/// nothing: wgpu places the same barriers between dispatches of one pass
/// as between passes. The open pass ends when the chain is dropped or
/// [`PassChain::encoder`] is asked for.
pub struct PassChain<'e> {
    enc: &'e mut wgpu::CommandEncoder,
    pass: Option<wgpu::ComputePass<'static>>,
    /// Passes begun.
    begun: usize,
    /// Whether an untimed run would have a pass open here.
    untimed_open: bool,
    /// Counted by [`GpuContext::passes`].
    health: std::sync::Arc<super::Health>,
}

impl<'e> PassChain<'e> {
    /// A chain recording into `enc`, its passes counted by `ctx`
    /// ([`GpuContext::passes`]).
    pub fn new(ctx: &GpuContext, enc: &'e mut wgpu::CommandEncoder) -> Self {
        Self {
            enc,
            pass: None,
            begun: 0,
            untimed_open: false,
            health: ctx.health.clone(),
        }
    }

    /// The pass to record stage `label` into: the open one, or a new one
    /// where there is none or `timer` times the stage.
    pub fn stage(
        &mut self,
        label: &str,
        timer: Option<&mut GpuTimer>,
    ) -> &mut wgpu::ComputePass<'static> {
        let relaxed = std::sync::atomic::Ordering::Relaxed;
        if !self.untimed_open {
            self.untimed_open = true;
            self.health.passes_untimed.fetch_add(1, relaxed);
        }
        let timestamps = timer.and_then(|t| t.compute_pass(label));
        if timestamps.is_some() || self.pass.is_none() {
            // The open pass ends before the encoder begins the next.
            self.pass = None;
            let pass = self.enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(label),
                timestamp_writes: timestamps,
            });
            self.begun += 1;
            self.health.passes.fetch_add(1, relaxed);
            self.pass = Some(pass.forget_lifetime());
        }
        self.pass.as_mut().expect("just begun")
    }

    /// The encoder, the open pass ended (for copies, clears, timestamp
    /// resolves between or after the stages).
    pub fn encoder(&mut self) -> &mut wgpu::CommandEncoder {
        self.pass = None;
        self.untimed_open = false;
        self.enc
    }

    /// How many passes the chain has begun.
    pub fn passes(&self) -> usize {
        self.begun
    }
}

/// A buffer that grows (never shrinks) to fit what it must hold, so that
/// per-frame work allocates nothing in the steady state.
pub struct GrowBuffer {
    label: &'static str,
    usage: wgpu::BufferUsages,
    buffer: Option<wgpu::Buffer>,
}

impl GrowBuffer {
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
