//! Harris corners (Harris & Stephens 1988; Dehais et al. 2010, section
//! 4.2): the configuration and the host steps that the GPU detector
//! ([`Harris`] in `gpu.rs`, `shaders/harris_*.wgsl`) and its CPU reference
//! ([`harris_cpu`] in `cpu.rs`) share (kernel taps, pixel packing, spread
//! selection, merging of refined duplicates). Both import from here and never from each other.
//! The host detector for CPU adapters ([`harris_host`] in `host.rs`, which
//! [`Harris`] runs in its host mode) is the reference's arithmetic in
//! faster loops: it shares the reference's NMS and refinement. See the
//! module docs of [`super`] for how it works.

mod config;
mod cpu;
mod gpu;
mod host;
mod shared;

pub use config::{Corner, HarrisConfig};
pub(crate) use config::{gaussian_taps, radius};
pub use cpu::{harris_cpu, harris_response_cpu};
#[cfg(test)]
pub(crate) use gpu::SHADER;
pub use gpu::{Detected, ExportPlace, Harris, HarrisGpuOptions, PendingCorners};
pub(crate) use host::HostHarris;
pub use host::{harris_host, harris_response_host};
pub(crate) use shared::{merge, pack_pixels, select_spread, selected_starts};
