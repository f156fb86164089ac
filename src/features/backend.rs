//! Where the features of the tracker run: the shaders or the host.

#[cfg(doc)]
use super::{HarrisGpuOptions, NccOptions, harris_host, ncc_match_cpu};

/// Where the tracker detects corners ([`HarrisGpuOptions::host`]) and
/// matches them on host images ([`NccOptions::host`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum FeatureBackend {
    /// The host on a CPU adapter (lavapipe: its shader loads are gathers,
    /// and the host measured faster, docs/performance.md), else the GPU.
    #[default]
    Auto,
    /// The compute shaders (`shaders/harris_*.wgsl`, `shaders/ncc_*.wgsl`).
    Gpu,
    /// Corners by [`harris_host`] (the CPU reference's arithmetic,
    /// vectorised, on every core; a view rendered on the GPU comes back
    /// as colour) and matches by [`ncc_match_cpu`].
    Host,
}

impl FeatureBackend {
    /// Whether detection runs on the host on `device`: always on the CPU
    /// device, else as [`FeatureBackend::host_on`] says.
    pub fn host_on_device(self, device: &crate::Device) -> bool {
        device.gpu().is_none_or(|ctx| self.host_on(ctx))
    }

    /// Whether detection runs on the host with adapter `ctx`.
    pub fn host_on(self, ctx: &crate::gpu::GpuContext) -> bool {
        match self {
            Self::Auto => ctx.is_cpu(),
            Self::Gpu => false,
            Self::Host => true,
        }
    }
}

impl std::str::FromStr for FeatureBackend {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Self::Auto),
            "gpu" => Ok(Self::Gpu),
            "host" => Ok(Self::Host),
            _ => Err(format!("{s:?}: expected gpu, host or auto")),
        }
    }
}

impl std::fmt::Display for FeatureBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Auto => "auto",
            Self::Gpu => "gpu",
            Self::Host => "host",
        })
    }
}
