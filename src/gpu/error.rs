//! The GPU layer's errors ([`GpuError`]) and the wait's time limit they
//! name.

/// Errors of the GPU layer.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter wgpu can see has the features the pipelines need.
    #[error(
        "no usable GPU adapter found{}. On Linux without a GPU, install Mesa's software Vulkan driver (lavapipe): `apt-get install mesa-vulkan-drivers`, or use the CPU device (`--compute cpu` on the command line, `Device::Cpu` in the library)",
        rejected_note(.rejected)
    )]
    NoAdapter {
        /// Each adapter seen but rejected, with the features it lacks.
        rejected: Vec<String>,
    },
    /// No usable adapter matches the [`AdapterChoice`](super::AdapterChoice).
    #[error("no adapter matches: wanted {wanted}; available: {}", .available.join("; "))]
    AdapterNotFound {
        /// The adapter asked for, in words.
        wanted: String,
        /// The usable adapters, as "name (type, backend)".
        available: Vec<String>,
    },
    /// An adapter choice given as text is empty.
    #[error(
        "invalid adapter choice {0:?}: use auto, discrete, integrated, cpu, or part of an adapter's name"
    )]
    BadChoice(String),
    /// A device choice given as text is not one ([`crate::DeviceChoice`]).
    #[error("invalid device {0:?}: use auto, gpu or cpu")]
    BadDevice(String),
    /// The adapter refused to create a device.
    #[error("cannot create a device on {adapter}: {source}")]
    RequestDevice {
        /// The adapter, as "name (type, backend)".
        adapter: String,
        /// wgpu's error.
        #[source]
        source: wgpu::RequestDeviceError,
    },
    /// A readback of GPU results failed, could not be set up, or returned
    /// unusable data.
    #[error("GPU readback failed: {0}")]
    Readback(String),
    /// wgpu reported a validation error while creating or running something.
    #[error("GPU validation error in {context}: {message}")]
    Validation {
        /// What was being done.
        context: String,
        /// wgpu's message.
        message: String,
    },
    /// A WGSL shader failed naga's validation.
    #[error("shader {name} is invalid: {message}")]
    Shader {
        /// The shader's name.
        name: String,
        /// naga's message.
        message: String,
    },
    /// The device ran out of memory.
    #[error("GPU out of memory in {context}: {message}")]
    OutOfMemory {
        /// What was being done.
        context: String,
        /// wgpu's message.
        message: String,
    },
    /// A buffer or texture would exceed one of the adapter's limits; refused
    /// before allocation.
    #[error("{0}")]
    TooLarge(Box<LimitExceeded>),
    /// A GPU error outside any error scope, other than out-of-memory.
    #[error("GPU error: {0}")]
    Uncaptured(String),
    /// The device was lost (driver reset, crash); carries wgpu's reason.
    #[error("the GPU device was lost ({0}); every frame finished before it is on disk")]
    DeviceLost(String),
    /// The GPU did not finish within the time limit, in seconds
    /// ([`TIMEOUT_ENV`]).
    #[error("the GPU did not finish its work within {0} s (set {TIMEOUT_ENV} to wait longer)")]
    Timeout(u64),
}

/// A size above one of the adapter's limits ([`GpuError::TooLarge`]).
#[derive(Debug, thiserror::Error)]
#[error("{what} needs {asked}, above this adapter's {limit_name} of {limit} ({adapter})")]
pub struct LimitExceeded {
    /// What was to be allocated.
    pub what: String,
    /// Its size, in words ("a 16.0 GB buffer").
    pub asked: String,
    /// The wgpu limit's name.
    pub limit_name: &'static str,
    /// The limit's value.
    pub limit: u64,
    /// The adapter.
    pub adapter: String,
}

/// Environment variable: seconds to wait for the GPU to finish submitted
/// work before giving up with [`GpuError::Timeout`] (default
/// [`DEFAULT_TIMEOUT_S`]).
pub const TIMEOUT_ENV: &str = "SPLATTRACK_GPU_TIMEOUT";

/// Seconds the host waits for the GPU at most, unless [`TIMEOUT_ENV`] says.
pub const DEFAULT_TIMEOUT_S: u64 = 300;

fn rejected_note(rejected: &[String]) -> String {
    if rejected.is_empty() {
        String::new()
    } else {
        format!(" (rejected: {})", rejected.join("; "))
    }
}
