//! Where the frame loop runs ([`Device`]): on a GPU through wgpu (any
//! Vulkan, Metal or DX12 adapter, Mesa's software lavapipe included), or
//! natively on the host's cores with no graphics driver at all (the
//! [`crate::splat::cpu`] splatter and the host paths of every step).
//!
//! [`DeviceChoice::Auto`] takes a hardware GPU adapter when one can be
//! made, else the CPU device, and logs one line saying which and why (a
//! warning when no adapter opens at all). A software adapter (lavapipe,
//! llvmpipe) found by the default adapter choice gives way to the CPU
//! device: the same maths natively measured about 4x faster a frame on
//! the real cube (docs/performance.md). An adapter asked for by name or
//! kind (`SPLATTRACK_ADAPTER=cpu`: lavapipe, which the GPU paths are
//! tested on) is taken as it is.

use crate::gpu::{AdapterChoice, GpuContext, GpuError};
use std::fmt;
use std::str::FromStr;

/// Environment variable read when no `--compute` is given: `auto`, `gpu`
/// or `cpu`.
pub const DEVICE_ENV: &str = "SPLATTRACK_DEVICE";

/// What renders, detects and matches: a wgpu context, or the host.
#[derive(Clone, Debug)]
// Made once per run and held: the context's size costs nothing.
#[allow(clippy::large_enum_variant)]
pub enum Device {
    /// A GPU adapter (lavapipe too) through wgpu.
    Gpu(GpuContext),
    /// The host's cores: no GPU object is made.
    Cpu,
}

impl Device {
    /// The device `choice` names, the adapter picked by `adapter` where it
    /// is a GPU. `Auto` falls back to [`Device::Cpu`] when no adapter can
    /// be made, or when the default adapter choice finds a software one
    /// only (module docs); `Gpu` fails where no adapter opens.
    pub fn new(choice: DeviceChoice, adapter: &AdapterChoice) -> Result<Self, GpuError> {
        match choice {
            DeviceChoice::Cpu => {
                log::info!("device: the CPU (asked for)");
                Ok(Self::Cpu)
            }
            DeviceChoice::Gpu => {
                let ctx = GpuContext::new(adapter)?;
                log::info!("device: the GPU {} (asked for)", ctx.describe());
                Ok(Self::Gpu(ctx))
            }
            DeviceChoice::Auto => Ok(Self::auto(
                GpuContext::new(adapter).map_err(|e| e.to_string()),
                adapter,
            )),
        }
    }

    /// `Auto`'s choice given the GPU context `adapter` opened (or why it
    /// did not): the context, except a software adapter that `adapter`
    /// did not name, and no context, where the CPU is taken.
    pub fn auto(context: Result<GpuContext, String>, adapter: &AdapterChoice) -> Self {
        match context {
            Ok(ctx) if ctx.is_cpu() && *adapter == AdapterChoice::Auto => {
                log::info!(
                    "device: the CPU (auto: the only adapter, {}, emulates a GPU in software; \
                         the native path is faster)",
                    ctx.describe()
                );
                Self::Cpu
            }
            Ok(ctx) => {
                log::info!(
                    "device: the GPU {} (auto: an adapter was found)",
                    ctx.describe()
                );
                Self::Gpu(ctx)
            }
            Err(e) => {
                log::warn!("device: the CPU (auto: no GPU adapter: {e})");
                Self::Cpu
            }
        }
    }

    /// [`Device::new`] from [`DEVICE_ENV`] and the adapter's own variable
    /// ([`AdapterChoice::from_env`]).
    pub fn from_env() -> Result<Self, GpuError> {
        Self::new(DeviceChoice::from_env()?, &AdapterChoice::from_env()?)
    }

    /// The GPU context, on a GPU.
    pub fn gpu(&self) -> Option<&GpuContext> {
        match self {
            Self::Gpu(ctx) => Some(ctx),
            Self::Cpu => None,
        }
    }

    /// Whether this is the host ([`Device::Cpu`]).
    pub fn is_cpu(&self) -> bool {
        matches!(self, Self::Cpu)
    }

    /// A batch of the GPU's submissions ([`GpuContext::batch`]); none on
    /// the CPU device.
    pub(crate) fn batch(&self) -> Option<crate::gpu::Batch> {
        self.gpu().map(GpuContext::batch)
    }

    /// What the GPU has done ([`GpuContext::stats`]); zeros on the CPU
    /// device.
    pub(crate) fn stats(&self) -> crate::gpu::GpuStats {
        self.gpu().map(GpuContext::stats).unwrap_or_default()
    }

    /// What it is, for logs and reports.
    pub fn describe(&self) -> String {
        match self {
            Self::Gpu(ctx) => ctx.describe(),
            Self::Cpu => "the CPU (native, no GPU driver)".to_owned(),
        }
    }
}

impl From<GpuContext> for Device {
    fn from(ctx: GpuContext) -> Self {
        Self::Gpu(ctx)
    }
}

/// A handle on the context (a cheap clone).
impl From<&GpuContext> for Device {
    fn from(ctx: &GpuContext) -> Self {
        Self::Gpu(ctx.clone())
    }
}

impl From<&Device> for Device {
    fn from(d: &Device) -> Self {
        d.clone()
    }
}

/// What the splat layer's calls run on: a [`GpuContext`] or a [`Device`]
/// (so callers holding a context pass it as before).
pub trait AsDevice {
    /// The GPU context, or `None` on the host.
    fn gpu_context(&self) -> Option<&GpuContext>;
}

impl AsDevice for GpuContext {
    fn gpu_context(&self) -> Option<&GpuContext> {
        Some(self)
    }
}

impl AsDevice for Device {
    fn gpu_context(&self) -> Option<&GpuContext> {
        self.gpu()
    }
}

impl<T: AsDevice + ?Sized> AsDevice for &T {
    fn gpu_context(&self) -> Option<&GpuContext> {
        (**self).gpu_context()
    }
}

/// Which device to run on (`--compute`, [`DEVICE_ENV`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DeviceChoice {
    /// A GPU adapter when one can be made, else the CPU.
    #[default]
    Auto,
    /// A GPU adapter, or an error.
    Gpu,
    /// The host's cores, with no GPU driver.
    Cpu,
}

impl DeviceChoice {
    /// [`DEVICE_ENV`], else `Auto`.
    pub fn from_env() -> Result<Self, GpuError> {
        match std::env::var(DEVICE_ENV) {
            Ok(v) if !v.trim().is_empty() => v.parse(),
            _ => Ok(Self::Auto),
        }
    }

    /// `auto`, `gpu` or `cpu`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Gpu => "gpu",
            Self::Cpu => "cpu",
        }
    }
}

impl FromStr for DeviceChoice {
    type Err = GpuError;
    fn from_str(s: &str) -> Result<Self, GpuError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Ok(Self::Auto),
            "gpu" => Ok(Self::Gpu),
            "cpu" | "host" => Ok(Self::Cpu),
            _ => Err(GpuError::BadDevice(s.to_owned())),
        }
    }
}

impl fmt::Display for DeviceChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn choices_parse_and_bad_ones_are_refused() {
        assert_eq!("CPU".parse::<DeviceChoice>().unwrap(), DeviceChoice::Cpu);
        assert_eq!(" gpu".parse::<DeviceChoice>().unwrap(), DeviceChoice::Gpu);
        assert_eq!("auto".parse::<DeviceChoice>().unwrap(), DeviceChoice::Auto);
        assert!("lavapipe".parse::<DeviceChoice>().is_err());
        assert!(
            Device::new(DeviceChoice::Cpu, &AdapterChoice::Auto)
                .unwrap()
                .is_cpu()
        );
    }
}
