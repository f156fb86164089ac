//! The GPU layer's errors ([`GpuError`]) and the wait's time limit they
//! name.

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
    #[error("GPU out of memory in {context}: {message}")]
    OutOfMemory { context: String, message: String },
    #[error("{0}")]
    TooLarge(Box<LimitExceeded>),
    #[error("GPU error: {0}")]
    Uncaptured(String),
    #[error("the GPU device was lost ({0}); every frame finished before it is on disk")]
    DeviceLost(String),
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
