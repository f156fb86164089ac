//! Headless GPU context (wgpu), buffer upload/readback, the plumbing every
//! GPU module shares (bind-group layouts, pipelines, growable buffers) and
//! GPU timers.
//!
//! How it works: [`GpuContext::new`] enumerates every adapter wgpu can see
//! (Vulkan, Metal, DX12), drops those that lack a feature the pipeline needs
//! ([`wgpu::Features::FLOAT32_BLENDABLE`]: the splatter accumulates weighted
//! attributes in RGBA32F targets with additive blending), and picks by
//! [`AdapterChoice`]: by default a discrete GPU, else an integrated one, else
//! a CPU adapter (lavapipe). The device is created with the adapter's *real*
//! limits: wgpu otherwise validates against WebGPU's defaults, e.g. 32 bytes
//! of colour attachments per sample where four RGBA32F targets need 64.

mod pipeline;
pub mod selftest;
mod timer;

pub use pipeline::{GrowBuffer, buffer_entry, compute_entry, compute_pass, storage, texture_entry};
pub use timer::{GpuTimer, TimerReport};

use std::fmt;
use std::str::FromStr;
use wgpu::util::DeviceExt;

/// Environment variable read when no `--adapter` is given.
pub const ADAPTER_ENV: &str = "SPLATTRACK_ADAPTER";

/// Errors of the GPU layer.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no usable GPU adapter found{}. On Linux without a GPU, install Mesa's software Vulkan driver (lavapipe): `apt-get install mesa-vulkan-drivers`",
        rejected_note(.rejected)
    )]
    NoAdapter { rejected: Vec<String> },
    #[error("no adapter matches: wanted {wanted}; available: {}", .available.join("; "))]
    AdapterNotFound {
        wanted: String,
        available: Vec<String>,
    },
    #[error(
        "invalid adapter choice {0:?}: use auto, discrete, integrated, cpu, or part of an adapter's name"
    )]
    BadChoice(String),
    #[error("cannot create a device on {adapter}: {source}")]
    RequestDevice {
        adapter: String,
        #[source]
        source: wgpu::RequestDeviceError,
    },
    #[error("GPU readback failed: {0}")]
    Readback(String),
    #[error("GPU validation error in {context}: {message}")]
    Validation { context: String, message: String },
    #[error("shader {name} is invalid: {message}")]
    Shader { name: String, message: String },
}

fn rejected_note(rejected: &[String]) -> String {
    if rejected.is_empty() {
        String::new()
    } else {
        format!(" (rejected: {})", rejected.join("; "))
    }
}

/// Which adapter to use.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum AdapterChoice {
    /// Discrete GPU, else integrated, else virtual, else CPU.
    #[default]
    Auto,
    Discrete,
    Integrated,
    /// A CPU adapter (lavapipe): the same results on every machine, so tests
    /// prefer it.
    Cpu,
    /// The first adapter whose name contains this text (case-insensitive).
    Name(String),
}

impl FromStr for AdapterChoice {
    type Err = GpuError;
    fn from_str(s: &str) -> Result<Self, GpuError> {
        Ok(match s.trim().to_ascii_lowercase().as_str() {
            "" => return Err(GpuError::BadChoice(s.to_owned())),
            "auto" => Self::Auto,
            "discrete" | "gpu" => Self::Discrete,
            "integrated" => Self::Integrated,
            "cpu" | "lavapipe" | "llvmpipe" | "software" => Self::Cpu,
            _ => Self::Name(s.trim().to_owned()),
        })
    }
}

impl fmt::Display for AdapterChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Auto => write!(f, "auto"),
            Self::Discrete => write!(f, "a discrete GPU"),
            Self::Integrated => write!(f, "an integrated GPU"),
            Self::Cpu => write!(f, "a CPU adapter"),
            Self::Name(n) => write!(f, "an adapter named like {n:?}"),
        }
    }
}

impl AdapterChoice {
    /// The `SPLATTRACK_ADAPTER` environment variable, else `Auto`.
    pub fn from_env() -> Result<Self, GpuError> {
        match std::env::var(ADAPTER_ENV) {
            Ok(v) if !v.trim().is_empty() => v.parse(),
            _ => Ok(Self::Auto),
        }
    }
}

/// Features the pipelines cannot work without.
pub const REQUIRED_FEATURES: wgpu::Features = wgpu::Features::FLOAT32_BLENDABLE;

/// A device and queue with what is known about the adapter behind them.
/// Cloning is cheap: wgpu's device and queue are shared handles.
#[derive(Clone)]
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    pub features: wgpu::Features,
}

impl fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "GpuContext({})", self.describe())
    }
}

fn type_rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    }
}

fn describe_info(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?}, {:?})", info.name, info.device_type, info.backend)
}

impl GpuContext {
    /// Creates a headless device on the adapter `choice` selects.
    pub fn new(choice: &AdapterChoice) -> Result<Self, GpuError> {
        pollster::block_on(Self::new_async(choice))
    }

    /// [`GpuContext::new`] with the choice from `SPLATTRACK_ADAPTER`.
    pub fn from_env() -> Result<Self, GpuError> {
        Self::new(&AdapterChoice::from_env()?)
    }

    pub async fn new_async(choice: &AdapterChoice) -> Result<Self, GpuError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapters = instance.enumerate_adapters(wgpu::Backends::all()).await;
        let mut usable = Vec::new();
        let mut rejected = Vec::new();
        for a in adapters {
            let info = a.get_info();
            let missing = REQUIRED_FEATURES - a.features();
            if missing.is_empty() {
                usable.push(a);
            } else {
                rejected.push(format!("{} lacks {missing:?}", describe_info(&info)));
            }
        }
        if usable.is_empty() {
            return Err(GpuError::NoAdapter { rejected });
        }
        // Vulkan first among equals: it is the backend tested here.
        usable.sort_by_key(|a| {
            let i = a.get_info();
            (type_rank(i.device_type), i.backend != wgpu::Backend::Vulkan)
        });
        let pick = match choice {
            AdapterChoice::Auto => usable.first(),
            AdapterChoice::Discrete => usable
                .iter()
                .find(|a| a.get_info().device_type == wgpu::DeviceType::DiscreteGpu),
            AdapterChoice::Integrated => usable
                .iter()
                .find(|a| a.get_info().device_type == wgpu::DeviceType::IntegratedGpu),
            AdapterChoice::Cpu => usable
                .iter()
                .find(|a| a.get_info().device_type == wgpu::DeviceType::Cpu),
            AdapterChoice::Name(n) => {
                let n = n.to_ascii_lowercase();
                usable
                    .iter()
                    .find(|a| a.get_info().name.to_ascii_lowercase().contains(&n))
            }
        };
        let Some(adapter) = pick else {
            return Err(GpuError::AdapterNotFound {
                wanted: choice.to_string(),
                available: usable
                    .iter()
                    .map(|a| describe_info(&a.get_info()))
                    .collect(),
            });
        };
        Self::from_adapter(adapter).await
    }

    async fn from_adapter(adapter: &wgpu::Adapter) -> Result<Self, GpuError> {
        let info = adapter.get_info();
        let optional = wgpu::Features::TIMESTAMP_QUERY
            | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS
            | wgpu::Features::TIMESTAMP_QUERY_INSIDE_PASSES;
        let features = REQUIRED_FEATURES | (adapter.features() & optional);
        let limits = adapter.limits();
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("splattrack"),
                required_features: features,
                required_limits: limits.clone(),
                experimental_features: wgpu::ExperimentalFeatures::disabled(),
                memory_hints: wgpu::MemoryHints::Performance,
                trace: wgpu::Trace::Off,
            })
            .await
            .map_err(|source| GpuError::RequestDevice {
                adapter: describe_info(&info),
                source,
            })?;
        Ok(Self {
            device,
            queue,
            info,
            limits,
            features,
        })
    }

    /// "name (type, backend)".
    pub fn describe(&self) -> String {
        describe_info(&self.info)
    }

    pub fn is_cpu(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    pub fn has_timestamps(&self) -> bool {
        self.features.contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    /// Compiles one of the crate's WGSL shaders (see [`crate::shaders`]).
    pub fn shader(&self, name: &str) -> Result<wgpu::ShaderModule, GpuError> {
        let source = crate::shaders::source(name).ok_or_else(|| GpuError::Shader {
            name: name.to_owned(),
            message: "no such shader in shaders/".into(),
        })?;
        crate::shaders::validate(name, source).map_err(|message| GpuError::Shader {
            name: name.to_owned(),
            message,
        })?;
        Ok(self
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(name),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            }))
    }

    /// A compute pipeline with an automatically derived layout.
    pub fn compute_pipeline(
        &self,
        shader: &str,
        entry_point: &str,
    ) -> Result<wgpu::ComputePipeline, GpuError> {
        let module = self.shader(shader)?;
        self.catch(&format!("{shader}::{entry_point}"), || {
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
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = f();
        match pollster::block_on(scope.pop()) {
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
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        self.catch(&format!("{label} bind group"), || {
            self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout,
                entries: &entries,
            })
        })
    }

    /// A buffer initialised with `data`.
    pub fn buffer_init<T: bytemuck::NoUninit>(
        &self,
        label: &str,
        data: &[T],
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let bytes: &[u8] = bytemuck::cast_slice(data);
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

    /// An uninitialised buffer of `size` bytes (at least 16).
    pub fn buffer(&self, label: &str, size: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: size.max(16).next_multiple_of(4),
            usage,
            mapped_at_creation: false,
        })
    }

    /// Reads `count` values of `T` from the start of `buffer` (which needs
    /// `COPY_SRC`), waiting for all submitted work.
    pub fn read_buffer<T: bytemuck::Pod>(
        &self,
        buffer: &wgpu::Buffer,
        count: usize,
    ) -> Result<Vec<T>, GpuError> {
        let size = (count * std::mem::size_of::<T>()) as u64;
        if size == 0 {
            return Ok(Vec::new());
        }
        if size > buffer.size() {
            return Err(GpuError::Readback(format!(
                "asked for {size} bytes of a {}-byte buffer",
                buffer.size()
            )));
        }
        let staging = self.buffer(
            "readback",
            size,
            wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        );
        let mut enc = self.device.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(buffer, 0, &staging, 0, size.next_multiple_of(4));
        self.queue.submit([enc.finish()]);
        let bytes = self.map_read(&staging, size)?;
        Ok(bytemuck::pod_collect_to_vec(&bytes[..size as usize]))
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
        let mut enc = self.device.create_command_encoder(&Default::default());
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
        self.queue.submit([enc.finish()]);
        let bytes = self.map_read(&staging, (padded * h) as u64)?;
        let mut out = Vec::with_capacity((row * h) as usize);
        for y in 0..h as usize {
            let start = y * padded as usize;
            out.extend_from_slice(&bytes[start..start + row as usize]);
        }
        Ok(out)
    }

    fn map_read(&self, staging: &wgpu::Buffer, size: u64) -> Result<Vec<u8>, GpuError> {
        let slice = staging.slice(..size.next_multiple_of(4));
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        rx.recv()
            .map_err(|e| GpuError::Readback(e.to_string()))?
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        let bytes = slice
            .get_mapped_range()
            .map_err(|e| GpuError::Readback(e.to_string()))?
            .to_vec();
        staging.unmap();
        Ok(bytes)
    }

    /// Waits until the GPU has finished all submitted work.
    pub fn wait(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Readback(e.to_string()))
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

/// Workgroup size of the kernels that run one thread per item (Harris's
/// refinement, NCC's vectorisation and reductions, the splatter's gather,
/// the self-test), a power of two (the NCC reductions halve it).
pub const WORKGROUP_1D: u32 = 64;

/// Workgroup edge of the kernels that run one thread per pixel in
/// `WORKGROUP_2D x WORKGROUP_2D` tiles (Harris's image passes).
pub const WORKGROUP_2D: u32 = 16;

/// Number of workgroups of `size` threads covering `n` items.
pub fn workgroups(n: u32, size: u32) -> u32 {
    n.div_ceil(size)
}

/// One device shared by every test in a test binary, on the adapter named
/// by `SPLATTRACK_ADAPTER`, else a CPU adapter (lavapipe: identical results
/// on every machine), else any. Panics with instructions when there is no
/// adapter at all: GPU tests never skip silently.
#[doc(hidden)]
pub fn shared_test_context() -> &'static GpuContext {
    static CTX: std::sync::OnceLock<GpuContext> = std::sync::OnceLock::new();
    CTX.get_or_init(|| {
        let choice = AdapterChoice::from_env().unwrap_or_else(|e| panic!("{e}"));
        let ctx = if choice == AdapterChoice::Auto {
            GpuContext::new(&AdapterChoice::Cpu).or_else(|_| GpuContext::new(&AdapterChoice::Auto))
        } else {
            GpuContext::new(&choice)
        };
        ctx.unwrap_or_else(|e| panic!("GPU tests need a GPU adapter and found none usable: {e}"))
    })
}
