//! GPU EWA surface splatting: novel views, depth, normals and dense motion
//! predictors of a point model (Dehais et al. 2010, sections 2.3, 3.1, 3.2).
//!
//! # How it works
//!
//! Each point is an oriented disc (splat) with centre `p`, normal `n` and
//! radius `r`, carrying a Gaussian reconstruction kernel (Zwicker et al.
//! 2001, "Surface splatting"). At a pose, every splat is drawn as one
//! instanced screen-space quad that bounds its projection; the fragment
//! shader intersects the pixel's ray with the splat's plane (Botsch et al.
//! 2005, "High-quality surface splatting on today's GPUs") and evaluates the
//! kernel there:
//!
//! - `rho_obj = |X - c| / r` at the intersection `X`, and
//!   `rho_scr = |x - pi(c)| / h` in pixels, with `h` the low-pass radius
//!   ([`SplatParams::lowpass_px`], 0.75 px: just above the 0.707 px that
//!   guarantees a pixel centre). The kernel is evaluated at
//!   `rho = min(rho_obj, rho_scr)`, Botsch et al.'s approximation of the EWA
//!   screen-space low-pass filter, so splats smaller than a pixel still cover
//!   one; it is truncated at `rho = 1` and `w = exp(-2 rho^2)` (a Gaussian of
//!   standard deviation `r/2`).
//! - The surface point seen through the pixel is `X` when `rho_obj <= 1` or
//!   when `X` is within `r + 3 h z / f` of the centre (the low-pass part of a
//!   splat seen at up to ~70 degrees: still on its plane, so planar surfaces
//!   get exact depth at any density); else (low-pass part of a near edge-on
//!   splat) the point of the ray at the centre's depth.
//! - Back-facing splats (`n_c . c >= 0` in camera space) are culled, as are
//!   splats whose centre is not in front of the near plane.
//!
//! Three passes (DESIGN.md section 3):
//! 1. visibility: depth only, the depth of the nearest surface pushed back
//!    by `epsilon * r` along the ray ([`SplatParams::epsilon`]);
//! 2. attributes: additive blending of `w * A` and `w` into RGBA32F targets,
//!    depth-tested (less-or-equal) against pass 1 without writing depth, so
//!    only splats of the visible surface contribute;
//! 3. normalisation: division by the summed weight, in a compute kernel that
//!    either resolves whole images ([`Splatter::read`], for the CLI and
//!    tests) or samples a few pixels ([`Splatter::gather`], for the tracker).
//!    Pixels with no weight are empty (NaN).
//!
//! Depth in the depth buffer is camera-space `z` mapped linearly from
//! `[near, far]` to `[0, 1]`, with `near`/`far` the model's bounding sphere
//! (grown by the largest splat radius and the push-back) at the pose; the
//! depth *attribute* is the true ray-plane intersection `z`, in model units.
//!
//! Attribute targets (see shaders/splat.wgsl):
//! `T0 = (w r, w g, w b, w)`, `T1 = w (z, nx, ny, nz)`,
//! `T2..T4 = w (du_tx, dv_tx, du_ty, dv_ty | tz, rx | ry, rz)`. The motion
//! predictors are computed per fragment from `X` with the formulas of
//! [`crate::geometry::Intrinsics::motion_predictors`], in pixels (OpenCV convention).
//!
//! [`cpu`] is the reference implementation of the same maths, used by tests.

mod attributes;
mod bounds;
mod compute;
pub mod cpu;
mod error;
mod gather;
pub mod gpu_data;
mod model;
mod splatter;
mod targets;
pub mod viz;
mod window;

pub use attributes::{Attribute, Attributes};
pub use bounds::{ModelBounds, bounding_sphere};
pub use error::SplatError;
pub use gather::{GatherMode, GatherSample};
pub use gpu_data::GATHER_STRIDE;
pub use model::{GpuModel, PackedModel, pack_model, spatial_order};
pub use splatter::{PendingGather, Splatter};
pub use targets::{SplatImage, SplatTargets};
pub use window::Window;
pub(crate) use window::box_corners;

/// Which splatting implementation renders. Both write the same
/// accumulation targets (so [`Splatter::read`], [`Splatter::gather`] and
/// every consumer work on either) and are tested against [`cpu`] and each
/// other (tests/splat_compute.rs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Backend {
    /// [`SPLATTER_ENV`] when set, else [`Backend::Compute`] wherever the
    /// adapter supports it (five storage textures per stage), else
    /// [`Backend::RenderPass`]; on a CPU adapter, per render, the render
    /// pass where splats are large on screen
    /// ([`AUTO_CPU_RENDER_PASS_ABOVE_PX`], [`Splatter::backend_for`]).
    /// Measured (BENCHMARKS.md): on lavapipe a KF+IT frame with a
    /// 100k-point model takes half the time with the compute splatter, the
    /// render pass is faster for sparse models of large splats; on an H100
    /// DESIGN.md section 5 measured a compute splat ~14x faster than the
    /// render pass.
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
/// through the compute splatter. Measured on lavapipe (BENCHMARKS.md,
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
        Ok(if compute::supported(ctx) {
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

/// Tunable constants of the splatting maths (shared with [`cpu`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SplatParams {
    /// Visibility push-back along the ray, in splat radii.
    pub epsilon: f32,
    /// Radius of the screen-space low-pass disc, pixels.
    pub lowpass_px: f32,
    /// Colour of models without colours (linear RGB).
    pub default_color: [f32; 3],
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
