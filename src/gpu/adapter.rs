//! The adapter choice and the context's creation: [`GpuContext::new`]
//! enumerates every adapter wgpu can see (Vulkan, Metal, DX12), drops
//! those that lack a feature the pipeline needs ([`REQUIRED_FEATURES`]),
//! picks by [`AdapterChoice`] and creates the device with the adapter's
//! real limits.

use super::context::{GpuContext, describe_info};
use super::error::GpuError;
use super::health::Health;
use std::fmt;
use std::str::FromStr;

/// Environment variable read when no `--adapter` is given.
pub const ADAPTER_ENV: &str = "SPLATTRACK_ADAPTER";

/// Which adapter to use.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum AdapterChoice {
    /// Discrete GPU, else integrated, else virtual, else CPU.
    #[default]
    Auto,
    /// A discrete GPU.
    Discrete,
    /// An integrated GPU.
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

/// Set (to anything but 0: wgpu's own variable), wgpu validates each
/// indirect dispatch's arguments against the device's limits before it
/// runs: one more dispatch of its own, two barriers and the pass's
/// bindings set again, so one more dependent step on the GPU each time.
/// Unset, it does not, except on DX12 (whose shaders get
/// `num_workgroups` from that step): every kernel here that writes a
/// dispatch's arguments keeps them within the limits itself (65535
/// workgroups a dimension: `select_sizes` in shaders/harris.wgsl,
/// asserted beside its dispatches; the splatter dispatches directly).
pub const VALIDATE_INDIRECT_ENV: &str = "WGPU_VALIDATION_INDIRECT_CALL";

/// An instance with wgpu's flags and the environment's `WGPU_*` settings,
/// validating indirect dispatches when `validate` only.
fn new_instance(validate: bool) -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle().with_env();
    desc.flags
        .set(wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL, validate);
    wgpu::Instance::new(desc)
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

impl GpuContext {
    /// Creates a headless device on the adapter `choice` selects.
    pub fn new(choice: &AdapterChoice) -> Result<Self, GpuError> {
        pollster::block_on(Self::new_async(choice))
    }

    /// [`GpuContext::new`] with the choice from `SPLATTRACK_ADAPTER`.
    pub fn from_env() -> Result<Self, GpuError> {
        Self::new(&AdapterChoice::from_env()?)
    }

    /// [`GpuContext::new`] for async callers; honours [`VALIDATE_INDIRECT_ENV`].
    pub async fn new_async(choice: &AdapterChoice) -> Result<Self, GpuError> {
        // wgpu's own reading of its variable: anything but "0" sets it.
        let asked = std::env::var(VALIDATE_INDIRECT_ENV).ok().map(|v| v != "0");
        Self::create(choice, asked).await
    }

    /// [`GpuContext::new`] with wgpu's validation of indirect dispatches
    /// on or off whatever the back end and the environment (on DX12, off
    /// leaves `num_workgroups` at zero in indirect dispatches, which the
    /// kernels here read; [`VALIDATE_INDIRECT_ENV`] says more).
    pub fn with_indirect_validation(
        choice: &AdapterChoice,
        validate: bool,
    ) -> Result<Self, GpuError> {
        pollster::block_on(Self::create(choice, Some(validate)))
    }

    async fn create(choice: &AdapterChoice, asked: Option<bool>) -> Result<Self, GpuError> {
        let instance = new_instance(asked.unwrap_or(false));
        let adapter = Self::pick(&instance, choice).await?;
        if asked.is_some() || adapter.get_info().backend != wgpu::Backend::Dx12 {
            return Self::from_adapter(&instance, &adapter, asked.unwrap_or(false)).await;
        }
        // DX12 has no native `num_workgroups`: wgpu's validation of
        // indirect dispatches supplies it, so that back end keeps it (the
        // same adapter from an instance that validates).
        let info = adapter.get_info();
        let instance = new_instance(true);
        let same = instance
            .enumerate_adapters(wgpu::Backends::DX12)
            .await
            .into_iter()
            .find(|a| a.get_info() == info)
            .ok_or_else(|| GpuError::AdapterNotFound {
                wanted: describe_info(&info),
                available: Vec::new(),
            })?;
        Self::from_adapter(&instance, &same, true).await
    }

    /// The adapter `choice` selects among `instance`'s usable ones.
    async fn pick(
        instance: &wgpu::Instance,
        choice: &AdapterChoice,
    ) -> Result<wgpu::Adapter, GpuError> {
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
        match pick {
            Some(a) => Ok(a.clone()),
            None => Err(GpuError::AdapterNotFound {
                wanted: choice.to_string(),
                available: usable
                    .iter()
                    .map(|a| describe_info(&a.get_info()))
                    .collect(),
            }),
        }
    }

    async fn from_adapter(
        instance: &wgpu::Instance,
        adapter: &wgpu::Adapter,
        validates_indirect: bool,
    ) -> Result<Self, GpuError> {
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
        let health = std::sync::Arc::new(Health::default());
        let h = health.clone();
        device.on_uncaptured_error(std::sync::Arc::new(move |e: wgpu::Error| {
            log::error!("GPU: {e}");
            h.record(match e {
                wgpu::Error::OutOfMemory { .. } => GpuError::OutOfMemory {
                    context: "GPU work".into(),
                    message: e.to_string(),
                },
                other => GpuError::Uncaptured(other.to_string()),
            });
        }));
        let h = health.clone();
        device.set_device_lost_callback(move |reason, message| {
            let mut lost = h.lost.lock().unwrap_or_else(|p| p.into_inner());
            *lost = Some(format!("{reason:?}: {message}"));
        });
        Ok(Self {
            instance: instance.clone(),
            adapter: adapter.clone(),
            device,
            queue,
            info,
            limits,
            features,
            validates_indirect,
            health,
        })
    }
}

/// One device shared by every test in a test binary
/// ([`own_test_context`]'s adapter).
#[doc(hidden)]
pub fn shared_test_context() -> &'static GpuContext {
    static CTX: std::sync::OnceLock<GpuContext> = std::sync::OnceLock::new();
    CTX.get_or_init(own_test_context)
}

/// A device of its own for a test that counts what its device does
/// (readbacks, allocations), on the adapter named by `SPLATTRACK_ADAPTER`,
/// else a CPU adapter (lavapipe: identical results on every machine), else
/// any. Panics with instructions when there is no adapter at all: GPU
/// tests never skip silently.
#[doc(hidden)]
pub fn own_test_context() -> GpuContext {
    let choice = AdapterChoice::from_env().unwrap_or_else(|e| panic!("{e}"));
    let ctx = if choice == AdapterChoice::Auto {
        GpuContext::new(&AdapterChoice::Cpu).or_else(|_| GpuContext::new(&AdapterChoice::Auto))
    } else {
        GpuContext::new(&choice)
    };
    ctx.unwrap_or_else(|e| panic!("GPU tests need a GPU adapter and found none usable: {e}"))
}
