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

pub use pipeline::{GrowBuffer, PassChain, buffer_entry, compute_entry, storage, texture_entry};
pub use timer::{GpuTimeline, GpuTimer, TimerReport, Timings};

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

/// What went wrong on the device outside an error scope: the first error
/// wgpu reports to the uncaptured-error handler (which would otherwise
/// panic), a size refused before allocation, and device loss. Checked by
/// [`GpuContext::check`] after every wait, so the run ends with a typed
/// error instead of a panic.
#[derive(Default)]
struct Health {
    first_error: std::sync::Mutex<Option<GpuError>>,
    lost: std::sync::Mutex<Option<String>>,
    /// Buffers made through [`GpuContext::buffer`] and
    /// [`GpuContext::buffer_init`] (the steady frame loop makes
    /// none).
    buffers_created: std::sync::atomic::AtomicU64,
    /// Bind groups made through [`GpuContext::bind_group`].
    bind_groups_created: std::sync::atomic::AtomicU64,
    /// Passes begun ([`GpuContext::passes`]): as recorded, and as an
    /// untimed run records them.
    passes: std::sync::atomic::AtomicU64,
    passes_untimed: std::sync::atomic::AtomicU64,
    /// Bytes read back to the host and the readbacks (each a wait for the
    /// GPU) that did it, through [`GpuContext::read_buffer`] and
    /// [`GpuContext::read_texture`] (a few floats per feature).
    bytes_read: std::sync::atomic::AtomicU64,
    readbacks: std::sync::atomic::AtomicU64,
    /// Nanoseconds the host spent blocked in those waits (the GPU's work
    /// and its latency as the host sees them; the rest of a frame is the
    /// host's own).
    waited_ns: std::sync::atomic::AtomicU64,
    /// Nanoseconds the host spent finishing command encoders (where wgpu
    /// encodes and validates the recorded passes) and in
    /// `Queue::submit`.
    finish_ns: std::sync::atomic::AtomicU64,
    submit_ns: std::sync::atomic::AtomicU64,
    /// Submissions through [`GpuContext::submit`] and the readbacks (each
    /// a `Queue::submit` of one or more command buffers: the host's fixed
    /// cost of GPU work).
    submissions: std::sync::atomic::AtomicU64,
    /// Command buffers submitted (each recorded, validated and, once
    /// done, freed: a batch records its work into one,
    /// [`GpuContext::encoder`]).
    command_buffers: std::sync::atomic::AtomicU64,
    /// Uploads through [`GpuContext::write_buffer`] (each a staging
    /// buffer of wgpu's own: made, mapped, copied, freed once its
    /// submission is done), and those a [`Uniform`] found unchanged and
    /// skipped.
    uploads: std::sync::atomic::AtomicU64,
    uploads_skipped: std::sync::atomic::AtomicU64,
    /// The staging buffer of readbacks, grow-only; taken while in use (a
    /// concurrent readback makes its own).
    staging: std::sync::Mutex<Option<wgpu::Buffer>>,
    /// The thread batching its submissions ([`GpuContext::batch`]).
    batch: std::sync::Mutex<BatchState>,
    /// Readbacks put off ([`GpuContext::read_buffer_later`]), to be mapped
    /// with their thread's next readback.
    riders: std::sync::Mutex<Vec<std::sync::Arc<Rider>>>,
    /// Unmapped staging buffers of put-off readbacks, for the next ones.
    rider_staging: std::sync::Mutex<Vec<wgpu::Buffer>>,
}

/// A readback put off: its copy is recorded, its bytes not yet mapped.
struct Rider {
    thread: std::thread::ThreadId,
    staging: wgpu::Buffer,
    /// Bytes to read (a multiple of 4).
    size: u64,
    /// Filled by the readback that mapped it.
    bytes: std::sync::Mutex<Option<Result<Vec<u8>, GpuError>>>,
}

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

/// Who batches submissions, how many guards deep, and the work put off:
/// recorded into one open encoder, lent to one caller at a time
/// ([`GpuContext::encoder`]), or finished already (`pending`, before the
/// open encoder's work).
#[derive(Default)]
struct BatchState {
    thread: Option<std::thread::ThreadId>,
    depth: usize,
    pending: Vec<wgpu::CommandBuffer>,
    open: Option<wgpu::CommandEncoder>,
    /// The open encoder is lent (its work is in the borrower's hands).
    lent: bool,
    /// The open encoder holds only work put off to go with the next
    /// submission ([`GpuContext::encoder_for_next`]): a batch's end leaves
    /// it open instead of submitting it alone.
    open_deferred: bool,
    /// Submissions that left none of the work given back to the context
    /// unsubmitted (no encoder lent): work given back before one of them
    /// is on the GPU's queue ([`GpuContext::submitted_since`]).
    drains: u64,
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

impl Health {
    /// Takes `rider` off the list of put-off readbacks; whether it was on
    /// it (not yet mapped).
    fn forget_rider(&self, rider: &std::sync::Arc<Rider>) -> bool {
        let mut riders = self.riders.lock().unwrap_or_else(|p| p.into_inner());
        let before = riders.len();
        riders.retain(|r| !std::sync::Arc::ptr_eq(r, rider));
        riders.len() < before
    }

    /// Keeps an unmapped staging buffer of a put-off readback for the next
    /// (a few at most).
    fn keep_rider_staging(&self, b: wgpu::Buffer) {
        let mut pool = self.rider_staging.lock().unwrap_or_else(|p| p.into_inner());
        // A profiled frame puts off a read of timestamps a step.
        if pool.len() < 24 {
            pool.push(b);
        }
    }

    /// Submits the work a batch put off and then `last`, in one counted
    /// submission (none when there is nothing). The list keeps its
    /// allocation: no allocation a submission.
    fn submit(&self, queue: &wgpu::Queue, last: Option<wgpu::CommandEncoder>) {
        let mut b = self.batch_state();
        if let Some(open) = b.open.take() {
            b.pending.push(self.finish(open));
        }
        if let Some(last) = last {
            b.pending.push(self.finish(last));
        }
        if !b.lent {
            b.drains += 1;
        }
        if b.pending.is_empty() {
            return;
        }
        let relaxed = std::sync::atomic::Ordering::Relaxed;
        self.submissions.fetch_add(1, relaxed);
        self.command_buffers
            .fetch_add(b.pending.len() as u64, relaxed);
        let t0 = std::time::Instant::now();
        queue.submit(b.pending.drain(..));
        self.submit_ns
            .fetch_add(t0.elapsed().as_nanos() as u64, relaxed);
    }

    /// Finishes `enc` (wgpu encodes its passes), timed.
    fn finish(&self, enc: wgpu::CommandEncoder) -> wgpu::CommandBuffer {
        let t0 = std::time::Instant::now();
        let done = enc.finish();
        self.finish_ns.fetch_add(
            t0.elapsed().as_nanos() as u64,
            std::sync::atomic::Ordering::Relaxed,
        );
        done
    }

    fn batch_state(&self) -> std::sync::MutexGuard<'_, BatchState> {
        self.batch.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn record(&self, e: GpuError) {
        let mut slot = self.first_error.lock().unwrap_or_else(|p| p.into_inner());
        if slot.is_none() {
            *slot = Some(e);
        }
    }
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
///
/// The instance and adapter are kept so that a window can present with
/// the tracker's own device (`instance.create_surface(window)`, checked
/// with `adapter.is_surface_supported`: the live view,
/// [`crate::view::WindowSink`]): on Vulkan, Metal and DX12 a surface needs
/// no display handle at instance creation, so the headless context serves
/// a window as it is.
#[derive(Clone)]
pub struct GpuContext {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    pub features: wgpu::Features,
    /// Whether wgpu checks every indirect dispatch's arguments on the GPU
    /// first (see [`VALIDATE_INDIRECT_ENV`]).
    pub validates_indirect: bool,
    health: std::sync::Arc<Health>,
}

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
            ctx.health
                .uploads_skipped
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            return false;
        }
        ctx.write_buffer(&self.buffer, 0, bytes);
        self.last.clear();
        self.last.extend_from_slice(bytes);
        true
    }

    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }
}

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
    fn poll_wait(&self) -> Result<(), GpuError> {
        let secs = Self::timeout_s();
        let t0 = std::time::Instant::now();
        let r = self.device.poll(wgpu::PollType::Wait {
            submission_index: None,
            timeout: Some(std::time::Duration::from_secs(secs)),
        });
        self.health.waited_ns.fetch_add(
            t0.elapsed().as_nanos() as u64,
            std::sync::atomic::Ordering::Relaxed,
        );
        self.check()?;
        match r {
            Ok(_) => Ok(()),
            Err(wgpu::PollError::Timeout) => Err(GpuError::Timeout(secs)),
            Err(e) => Err(GpuError::Readback(e.to_string())),
        }
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

    /// Makes a bind group, counted by [`GpuContext::bind_groups_created`]
    /// (every bind group of the crate is made here).
    pub fn bind_group(&self, desc: &wgpu::BindGroupDescriptor) -> wgpu::BindGroup {
        self.health
            .bind_groups_created
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.device.create_bind_group(desc)
    }

    /// How many bind groups [`GpuContext::bind_group`] has made on this
    /// device so far (all clones of this context together): a frame loop
    /// that keeps its bind groups makes none once its buffers have grown.
    pub fn bind_groups_created(&self) -> u64 {
        self.health
            .bind_groups_created
            .load(std::sync::atomic::Ordering::Relaxed)
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
        self.health
            .buffers_created
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// How many buffers [`GpuContext::buffer`] and
    /// [`GpuContext::buffer_init`] have made on this device so far (all
    /// clones of this context together): the difference over a stretch of
    /// work is what it allocated.
    pub fn buffers_created(&self) -> u64 {
        self.health
            .buffers_created
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Bytes read back to the host so far (all clones of this context
    /// together; padding to 4 bytes and texture rows' alignment included):
    /// the difference over a stretch of work is what it read back.
    pub fn bytes_read(&self) -> u64 {
        self.health
            .bytes_read
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Readbacks so far (each maps a staging buffer, waiting for the GPU),
    /// counted as [`GpuContext::bytes_read`].
    pub fn readbacks(&self) -> u64 {
        self.health
            .readbacks
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// The host's time so far finishing command encoders (where wgpu
    /// encodes and validates the passes recorded) and in `Queue::submit`:
    /// the fixed cost of GPU work on the host (all threads).
    pub fn encoding(&self) -> (std::time::Duration, std::time::Duration) {
        let get = |a: &std::sync::atomic::AtomicU64| {
            std::time::Duration::from_nanos(a.load(std::sync::atomic::Ordering::Relaxed))
        };
        (get(&self.health.finish_ns), get(&self.health.submit_ns))
    }

    /// The time the host has spent so far blocked in those readbacks'
    /// waits for the GPU (all threads): its work queued before them and
    /// the round trip.
    pub fn waited(&self) -> std::time::Duration {
        std::time::Duration::from_nanos(
            self.health
                .waited_ns
                .load(std::sync::atomic::Ordering::Relaxed),
        )
    }

    /// `Queue::write_buffer`, counted ([`GpuContext::uploads`]): every
    /// upload of the crate goes through here.
    pub fn write_buffer(&self, buffer: &wgpu::Buffer, offset: u64, data: &[u8]) {
        self.health
            .uploads
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.queue.write_buffer(buffer, offset, data);
    }

    /// Uploads so far ([`GpuContext::write_buffer`]) and those skipped
    /// as unchanged ([`Uniform::write`]), all clones of this context
    /// together.
    pub fn uploads(&self) -> (u64, u64) {
        let relaxed = std::sync::atomic::Ordering::Relaxed;
        (
            self.health.uploads.load(relaxed),
            self.health.uploads_skipped.load(relaxed),
        )
    }

    /// Submissions so far through [`GpuContext::submit`] (all clones of
    /// this context together), counted as [`GpuContext::readbacks`].
    pub fn submissions(&self) -> u64 {
        self.health
            .submissions
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Passes recorded so far (all clones of this context together):
    /// those begun, and those an untimed run would begin (a
    /// [`PassChain`] records its stages in one pass where untimed, in one
    /// a stage where timed). Every compute pass of the crate is begun by
    /// a [`PassChain`]; the render pass splatter counts its render passes
    /// too.
    pub fn passes(&self) -> (u64, u64) {
        let relaxed = std::sync::atomic::Ordering::Relaxed;
        (
            self.health.passes.load(relaxed),
            self.health.passes_untimed.load(relaxed),
        )
    }

    /// Counts `n` passes begun outside a [`PassChain`] (render passes),
    /// the same timed or not.
    pub(crate) fn count_passes(&self, n: u64) {
        let relaxed = std::sync::atomic::Ordering::Relaxed;
        self.health.passes.fetch_add(n, relaxed);
        self.health.passes_untimed.fetch_add(n, relaxed);
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

    /// Command buffers submitted so far (all clones of this context
    /// together), counted as [`GpuContext::submissions`]: one a submission
    /// where every encoder came from [`GpuContext::encoder`] within a
    /// batch.
    pub fn command_buffers(&self) -> u64 {
        self.health
            .command_buffers
            .load(std::sync::atomic::Ordering::Relaxed)
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
    /// [`GpuContext::submissions`], together with any work a batch put off
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
    fn submit_now(&self, enc: Encoder) {
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
    /// validation and release; [`GpuContext::submissions`]). An overread
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
        let relaxed = std::sync::atomic::Ordering::Relaxed;
        let rider_bytes: u64 = riders.iter().map(|r| r.size).sum();
        self.health
            .bytes_read
            .fetch_add(size.next_multiple_of(4) + rider_bytes, relaxed);
        self.health.readbacks.fetch_add(1, relaxed);
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

    /// Waits until the GPU has finished all submitted work (and any a
    /// batch put off, submitted first).
    pub fn wait(&self) -> Result<(), GpuError> {
        self.health.submit(&self.queue, None);
        self.poll_wait()
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

/// Figures of [`GpuContext::memory_report`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GpuMemory {
    /// Live buffers (0 when wgpu is built without its counters).
    pub buffers: isize,
    /// Live textures (likewise).
    pub textures: isize,
    /// Bytes of buffer memory (likewise).
    pub buffer_bytes: isize,
    /// Bytes of texture memory (likewise).
    pub texture_bytes: isize,
    /// Bytes the allocator holds for resources, where reported.
    pub allocated_bytes: Option<u64>,
    /// Bytes it reserved from the driver, where reported.
    pub reserved_bytes: Option<u64>,
}

/// `bytes` as "12.3 MB" (powers of 1000).
pub fn human_bytes(bytes: u64) -> String {
    let units = ["B", "kB", "MB", "GB", "TB", "PB", "EB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1000.0 && u + 1 < units.len() {
        v /= 1000.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.1} {}", units[u])
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

/// Floats per gathered point: 12 predictors, depth, validity (the stride
/// of `gather`'s output in shaders/splat_resolve.wgsl; the NCC gate,
/// shaders/ncc_gate.wgsl, reads the validity).
pub const GATHER_STRIDE: usize = 14;

/// Number of workgroups of `size` threads covering `n` items.
pub fn workgroups(n: u32, size: u32) -> u32 {
    n.div_ceil(size)
}

/// Bind groups kept for as long as the buffers they bind are the same
/// ones (wgpu buffers compare by identity): a pass whose inputs are
/// grow-only buffers, or buffers lent by another stage, binds anew only
/// when one of them was replaced. The last two sets are kept, so that a
/// pass fed in turn by two stages (Harris's export, into IT's matching
/// and then KF's, each frame) binds nothing anew either.
pub struct BindCache<const N: usize> {
    /// The most recently used first.
    held: Vec<([wgpu::Buffer; N], wgpu::BindGroup)>,
    /// How many sets are kept.
    keep: usize,
}

impl<const N: usize> Default for BindCache<N> {
    fn default() -> Self {
        Self::keeping(2)
    }
}

impl<const N: usize> BindCache<N> {
    /// A cache of the bind groups of the last `keep` sets of buffers (at
    /// least one).
    pub fn keeping(keep: usize) -> Self {
        let keep = keep.max(1);
        Self {
            held: Vec::with_capacity(keep),
            keep,
        }
    }

    /// The bind group of `buffers`: a held one when it binds these, else
    /// `bind(&buffers)`'s, held from now on (in place of the least
    /// recently used).
    pub fn get<E>(
        &mut self,
        buffers: [wgpu::Buffer; N],
        bind: impl FnOnce(&[wgpu::Buffer; N]) -> Result<wgpu::BindGroup, E>,
    ) -> Result<&wgpu::BindGroup, E> {
        match self.held.iter().position(|(held, _)| *held == buffers) {
            Some(i) => self.held[..=i].rotate_right(1),
            None => {
                let group = bind(&buffers)?;
                self.held.truncate(self.keep - 1);
                self.held.insert(0, (buffers, group));
            }
        }
        Ok(&self.held[0].1)
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
