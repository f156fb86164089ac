//! The context: a device and queue with what is known about the adapter
//! behind them, and what every GPU module asks of it (shaders, pipelines,
//! bind groups, buffers, uploads, checks against the adapter's limits).
//! Made in [`super::adapter`]; submissions and readbacks are in
//! [`super::submit`] and [`super::readback`].

use super::error::{GpuError, LimitExceeded};
use super::health::Health;
use super::memory::{GpuMemory, human_bytes};
use super::stats::{Counters, GpuStats};
use std::fmt;
use wgpu::util::DeviceExt;

/// A device and queue with what is known about the adapter behind them.
/// Cloning is cheap: wgpu's device and queue are shared handles.
///
/// The instance and adapter are kept so that the live view can present
/// with the tracker's own device (`instance.create_surface(os_window)`,
/// checked with `adapter.is_surface_supported`: `view::DisplaySink`): on
/// Vulkan, Metal and DX12 a surface needs no display handle at instance
/// creation, so the headless context serves a display as it is.
#[derive(Clone)]
pub struct GpuContext {
    /// The wgpu instance the adapter came from (for creating surfaces).
    pub instance: wgpu::Instance,
    /// The adapter behind the device.
    pub adapter: wgpu::Adapter,
    /// The logical device.
    pub device: wgpu::Device,
    /// The device's queue.
    pub queue: wgpu::Queue,
    /// The adapter's name, type and back end.
    pub info: wgpu::AdapterInfo,
    /// The adapter's own limits, which the device was created with.
    pub limits: wgpu::Limits,
    /// The features enabled on the device.
    pub features: wgpu::Features,
    /// Whether wgpu checks every indirect dispatch's arguments on the GPU
    /// first (see [`VALIDATE_INDIRECT_ENV`](super::VALIDATE_INDIRECT_ENV)).
    pub validates_indirect: bool,
    pub(super) health: std::sync::Arc<Health>,
}

impl fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "GpuContext({})", self.describe())
    }
}

/// "name (type, backend)" of an adapter.
pub(super) fn describe_info(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?}, {:?})", info.name, info.device_type, info.backend)
}

impl GpuContext {
    /// The first GPU failure seen outside an error scope since the last
    /// check (a validation or out-of-memory error, a size refused by
    /// [`GpuContext::check_buffer_size`] inside [`GpuContext::buffer`]) or
    /// device loss, as an error; `Ok` while the device is healthy. Called
    /// after every wait on the device.
    pub fn check(&self) -> Result<(), GpuError> {
        if let Some(reason) = self
            .health
            .lost
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
        {
            return Err(GpuError::DeviceLost(reason));
        }
        match self
            .health
            .first_error
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take()
        {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// Refuses a buffer of `bytes` above the adapter's `max_buffer_size`
    /// (and, for storage buffers, `max_storage_buffer_binding_size`),
    /// before anything is allocated.
    pub fn check_buffer_size(
        &self,
        what: &str,
        bytes: u64,
        usage: wgpu::BufferUsages,
    ) -> Result<(), GpuError> {
        let mut checks = vec![("max_buffer_size", self.limits.max_buffer_size)];
        if usage.contains(wgpu::BufferUsages::STORAGE) {
            checks.push((
                "max_storage_buffer_binding_size",
                self.limits.max_storage_buffer_binding_size,
            ));
        }
        if usage.contains(wgpu::BufferUsages::UNIFORM) {
            checks.push((
                "max_uniform_buffer_binding_size",
                self.limits.max_uniform_buffer_binding_size,
            ));
        }
        for (limit_name, limit) in checks {
            if bytes > limit {
                return Err(GpuError::TooLarge(Box::new(LimitExceeded {
                    what: what.to_owned(),
                    asked: format!("a {} buffer", human_bytes(bytes)),
                    limit_name,
                    limit,
                    adapter: self.describe(),
                })));
            }
        }
        Ok(())
    }

    /// Refuses a `width x height` 2-D texture above the adapter's
    /// `max_texture_dimension_2d`, before anything is allocated.
    pub fn check_texture_size(&self, what: &str, width: u32, height: u32) -> Result<(), GpuError> {
        let limit = self.limits.max_texture_dimension_2d;
        if width > limit || height > limit || width == 0 || height == 0 {
            return Err(GpuError::TooLarge(Box::new(LimitExceeded {
                what: what.to_owned(),
                asked: format!("a {width} x {height} texture"),
                limit_name: "max_texture_dimension_2d",
                limit: limit as u64,
                adapter: self.describe(),
            })));
        }
        Ok(())
    }

    /// "name (type, backend)".
    pub fn describe(&self) -> String {
        describe_info(&self.info)
    }

    /// Whether the adapter is a CPU (software) one, such as lavapipe.
    pub fn is_cpu(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// Whether GPU timestamp queries are available.
    pub fn has_timestamps(&self) -> bool {
        self.features.contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    /// Compiles one of the crate's WGSL shaders (see [`crate::shaders`]).
    pub fn shader(&self, shader: &crate::shaders::Shader) -> Result<wgpu::ShaderModule, GpuError> {
        let (source, _) = shader.validate().map_err(|message| GpuError::Shader {
            name: shader.name.to_owned(),
            message,
        })?;
        Ok(self
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(shader.name),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            }))
    }

    /// A compute pipeline with an automatically derived layout.
    pub fn compute_pipeline(
        &self,
        shader: &crate::shaders::Shader,
        entry_point: &str,
    ) -> Result<wgpu::ComputePipeline, GpuError> {
        let module = self.shader(shader)?;
        self.catch(&format!("{}::{entry_point}", shader.name), || {
            self.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry_point),
                    layout: None,
                    module: &module,
                    entry_point: Some(entry_point),
                    compilation_options: Default::default(),
                    cache: None,
                })
        })
    }

    /// Runs `f` inside a validation error scope and turns a wgpu validation
    /// error into a [`GpuError`] rather than wgpu's default panic.
    pub fn catch<T>(&self, context: &str, f: impl FnOnce() -> T) -> Result<T, GpuError> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = f();
        let validation = pollster::block_on(scope.pop());
        let oom = pollster::block_on(oom.pop());
        if let Some(e) = oom {
            return Err(GpuError::OutOfMemory {
                context: context.to_owned(),
                message: e.to_string(),
            });
        }
        match validation {
            None => Ok(out),
            Some(e) => Err(GpuError::Validation {
                context: context.to_owned(),
                message: e.to_string(),
            }),
        }
    }

    /// A bind group whose binding `i` is the whole of `buffers[i]`, created
    /// inside a validation scope.
    pub fn bind_buffers(
        &self,
        label: &str,
        layout: &wgpu::BindGroupLayout,
        buffers: &[&wgpu::Buffer],
    ) -> Result<wgpu::BindGroup, GpuError> {
        let numbered: Vec<(u32, &wgpu::Buffer)> = (0u32..).zip(buffers.iter().copied()).collect();
        self.bind_buffers_at(label, layout, &numbered)
    }

    /// [`GpuContext::bind_buffers`] with each buffer's binding given.
    pub fn bind_buffers_at(
        &self,
        label: &str,
        layout: &wgpu::BindGroupLayout,
        buffers: &[(u32, &wgpu::Buffer)],
    ) -> Result<wgpu::BindGroup, GpuError> {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .map(|&(binding, b)| wgpu::BindGroupEntry {
                binding,
                resource: b.as_entire_binding(),
            })
            .collect();
        self.catch(&format!("{label} bind group"), || {
            self.bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout,
                entries: &entries,
            })
        })
    }

    /// Makes a bind group, counted ([`GpuStats::bind_groups_created`]):
    /// every bind group of the crate is made here.
    pub fn bind_group(&self, desc: &wgpu::BindGroupDescriptor) -> wgpu::BindGroup {
        Counters::add(&self.health.counts.bind_groups_created, 1);
        self.device.create_bind_group(desc)
    }

    /// A buffer initialised with `data`.
    pub fn buffer_init<T: bytemuck::NoUninit>(
        &self,
        label: &str,
        data: &[T],
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        if let Err(e) = self.check_buffer_size(label, bytes.len() as u64, usage) {
            self.health.record(e);
            return self.buffer(label, 16, usage);
        }
        self.count_buffer();
        // wgpu rejects zero-sized bindings: keep at least 16 bytes.
        if bytes.len() < 16 {
            let mut padded = bytes.to_vec();
            padded.resize(16, 0);
            return self
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: &padded,
                    usage,
                });
        }
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage,
            })
    }

    /// An uninitialised buffer of `size` bytes (at least 16). A size above
    /// the adapter's limits ([`GpuContext::check_buffer_size`]) is not
    /// allocated: the error is recorded, a 16-byte stand-in returned, and
    /// the next wait on the device ([`GpuContext::check`]) reports it.
    pub fn buffer(&self, label: &str, size: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
        let size = match self.check_buffer_size(label, size, usage) {
            Ok(()) => size,
            Err(e) => {
                self.health.record(e);
                16
            }
        };
        self.count_buffer();
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: size.max(16).next_multiple_of(4),
            usage,
            mapped_at_creation: false,
        })
    }

    fn count_buffer(&self) {
        Counters::add(&self.health.counts.buffers_created, 1);
    }

    /// `Queue::write_buffer`, counted ([`GpuStats::uploads`]): every
    /// upload of the crate goes through here.
    pub fn write_buffer(&self, buffer: &wgpu::Buffer, offset: u64, data: &[u8]) {
        Counters::add(&self.health.counts.uploads, 1);
        self.queue.write_buffer(buffer, offset, data);
    }

    /// Counts an upload a `Uniform` skipped as unchanged
    /// ([`GpuStats::uploads_skipped`]).
    pub(super) fn count_upload_skipped(&self) {
        Counters::add(&self.health.counts.uploads_skipped, 1);
    }

    /// Counts `n` passes begun outside a `PassChain` (render passes),
    /// the same timed or not ([`GpuStats::passes`]).
    pub(crate) fn count_passes(&self, n: u64) {
        Counters::add(&self.health.counts.passes, n);
        Counters::add(&self.health.counts.passes_untimed, n);
    }

    /// What this device has done so far, all clones of this context and
    /// all threads together: buffers and bind groups made, uploads,
    /// submissions, passes, readbacks, and the host's time waiting,
    /// finishing encoders and submitting. The difference of two snapshots
    /// ([`GpuStats::since`]) is what the work between them did.
    pub fn stats(&self) -> GpuStats {
        self.health.stats()
    }

    /// [`GpuContext::buffer`], refusing a size above the adapter's limits
    /// at once.
    pub fn try_buffer(
        &self,
        label: &str,
        size: u64,
        usage: wgpu::BufferUsages,
    ) -> Result<wgpu::Buffer, GpuError> {
        self.check_buffer_size(label, size, usage)?;
        self.catch(label, || self.buffer(label, size, usage))
    }

    /// Host-visible figures of the device's memory: live buffers and
    /// textures (wgpu's internal counters, when compiled in) and the
    /// allocator's report where the backend gives one.
    pub fn memory_report(&self) -> GpuMemory {
        let c = self.device.get_internal_counters();
        let report = self.device.generate_allocator_report();
        GpuMemory {
            buffers: c.hal.buffers.read(),
            textures: c.hal.textures.read(),
            buffer_bytes: c.hal.buffer_memory.read(),
            texture_bytes: c.hal.texture_memory.read(),
            allocated_bytes: report.as_ref().map(|r| r.total_allocated_bytes),
            reserved_bytes: report.as_ref().map(|r| r.total_reserved_bytes),
        }
    }
}
