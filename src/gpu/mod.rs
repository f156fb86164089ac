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
//!
//! The files: `error` ([`GpuError`]), `adapter` (the choice of adapter and
//! the context's creation), `context` ([`GpuContext`]: shaders, pipelines,
//! bind groups, buffers, uploads), `submit` (encoders, batches, waits),
//! `readback` (staging buffers, readbacks now and put off), `stats` (what
//! a device has done: [`GpuStats`]), `memory` ([`GpuMemory`]), `buffers`
//! ([`Uniform`], [`GrowBuffer`]), `pipeline` (layouts, [`PassChain`],
//! [`BindCache`], workgroups), `timer` (GPU timestamps), `health` (the
//! state every clone of a context shares).

mod adapter;
mod buffers;
mod context;
mod error;
mod health;
mod memory;
mod pipeline;
mod readback;
pub mod selftest;
mod stats;
mod submit;
mod timer;

pub use adapter::{
    ADAPTER_ENV, AdapterChoice, REQUIRED_FEATURES, VALIDATE_INDIRECT_ENV, own_test_context,
    shared_test_context,
};
pub use buffers::{GrowBuffer, STORAGE_IN, STORAGE_OUT, Uniform};
pub use context::GpuContext;
pub use error::{DEFAULT_TIMEOUT_S, GpuError, LimitExceeded, TIMEOUT_ENV};
pub use memory::{GpuMemory, human_bytes};
pub use pipeline::{
    BindCache, GATHER_STRIDE, PassChain, WORKGROUP_1D, WORKGROUP_2D, buffer_entry, compute_entry,
    storage, texture_entry, workgroups,
};
pub use readback::PendingRead;
pub use stats::GpuStats;
pub use submit::{Batch, Encoder, SubmissionMark};
pub use timer::{GpuTimeline, GpuTimer, TimerReport, Timings};
