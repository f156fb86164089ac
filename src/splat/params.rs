//! What a splatter is made with: the back end that renders ([`Backend`])
//! and the constants of the splatting maths ([`SplatParams`]).

use super::error::SplatError;
use super::gpu_data::compute_supported;

/// Which splatting implementation renders. Both write the same
/// accumulation targets (so [`Splatter::read`](super::Splatter::read), [`Splatter::gather`](super::Splatter::gather) and
/// every consumer work on either) and are tested against [`cpu`](super::cpu) and each
/// other (tests/splat_compute.rs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Backend {
    /// [`SPLATTER_ENV`] when set, else [`Backend::Compute`] wherever the
    /// adapter supports it (five storage textures per stage), else
    /// [`Backend::RenderPass`]; on a CPU adapter, per render, the render
    /// pass where splats are large on screen
    /// ([`AUTO_CPU_RENDER_PASS_ABOVE_PX`], [`Splatter::backend_for`](super::Splatter::backend_for)).
    /// Measured (docs/benchmarks.md): on lavapipe a KF+IT frame with a
    /// 100k-point model takes half the time with the compute splatter, the
    /// render pass is faster for sparse models of large splats; on an H100
    /// a compute splat measured ~14x faster than the render pass
    /// (docs/performance.md).
    #[default]
    Auto,
    /// Instanced quads through the rasteriser, additive blending.
    RenderPass,
    /// Compute kernels: depth by atomic max on inverted depth bits,
    /// attributes by fixed-point atomic adds (module docs of
    /// shaders/splat_compute.wgsl).
    Compute,
}

/// [`Backend::Auto`] on a CPU adapter (lavapipe): renders whose typical
/// splat (the model's median radius at the depth of its centre) is wider
/// than this many pixels in radius go through the render pass, the others
/// through the compute splatter. Measured on lavapipe (docs/benchmarks.md,
/// `cargo bench --bench splat`, colour + predictors, criterion medians): a
/// 10k-point sphere (median splat radius 6.5 px at 640x480, 13 px at
/// 1280x720) splats 1.9x and 2.0x faster through the render pass, where
/// one thread walks a large footprint; 100k points (2.1 and 4.1 px) 2.2x
/// and 1.3x faster through the compute splatter, 1M points (0.65 and
/// 1.3 px) 5.5x and 3.3x, where the rasteriser's per-splat setup
/// dominates.
pub const AUTO_CPU_RENDER_PASS_ABOVE_PX: f64 = 5.0;

/// Environment variable that overrides [`Backend::Auto`]:
/// `render`, `compute` or `auto`.
pub const SPLATTER_ENV: &str = "SPLATTRACK_SPLATTER";

impl Backend {
    /// Parses `render`, `compute` or `auto` (the `--splatter` flag).
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Some(Self::Auto),
            "render" | "render-pass" | "renderpass" => Some(Self::RenderPass),
            "compute" => Some(Self::Compute),
            _ => None,
        }
    }

    /// The name the `--splatter` flag takes.
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::RenderPass => "render",
            Self::Compute => "compute",
        }
    }

    /// The back end that renders on `ctx`: `self` unless it is
    /// [`Backend::Auto`], which takes [`SPLATTER_ENV`] when set, else the
    /// compute splatter where the adapter supports it.
    pub fn resolve(self, ctx: &crate::gpu::GpuContext) -> Result<Self, SplatError> {
        if self != Self::Auto {
            return Ok(self);
        }
        if let Ok(v) = std::env::var(SPLATTER_ENV) {
            if !v.trim().is_empty() {
                let b = Self::parse(&v).ok_or_else(|| {
                    SplatError::Unsupported(format!(
                        "{SPLATTER_ENV}={v:?}: expected render, compute or auto"
                    ))
                })?;
                if b != Self::Auto {
                    return Ok(b);
                }
            }
        }
        Ok(if compute_supported(ctx) {
            Self::Compute
        } else {
            Self::RenderPass
        })
    }
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Backend {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::parse(s).ok_or_else(|| format!("{s:?}: expected render, compute or auto"))
    }
}

/// Tunable constants of the splatting maths (shared with [`cpu`](super::cpu)).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SplatParams {
    /// Visibility push-back along the ray, in splat radii.
    pub epsilon: f32,
    /// Radius of the screen-space low-pass disc, pixels.
    pub lowpass_px: f32,
    /// Colour of models without colours (linear RGB).
    pub default_color: [f32; 3],
    /// Which splatting implementation renders.
    pub backend: Backend,
}

impl Default for SplatParams {
    fn default() -> Self {
        Self {
            epsilon: 1.0,
            lowpass_px: 0.75,
            default_color: [0.75, 0.75, 0.75],
            backend: Backend::Auto,
        }
    }
}
