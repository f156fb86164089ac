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
//! Three passes (docs/how-it-works.md):
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
//! [`cpu`] is the same maths on the host's cores ([`cpu::HostSplatter`]):
//! the GPU splatters' reference in the tests and the CPU device's renderer
//! ([`crate::Device::Cpu`]): there a render splats on the host at the
//! window's camera and keeps the accumulators in the [`SplatTargets`],
//! reads resolve them and gathers sample them with the GPU gather's maths.

mod accumulators;
mod attributes;
mod bounds;
mod compute;
pub mod cpu;
mod cpu_device;
mod dispatch;
mod error;
mod gather;
pub mod gpu_data;
mod host;
mod image;
mod kernel;
mod model;
mod occluders;
mod params;
mod render;
mod resolve;
mod reuse;
mod scratch;
mod splatter;
mod targets;
pub mod viz;
mod window;

pub use attributes::{Attribute, Attributes};
pub use bounds::{ModelBounds, bounding_sphere};
pub use dispatch::Splatter;
pub use error::SplatError;
pub use gather::{GatherMode, GatherSample};
pub use gpu_data::GATHER_STRIDE;
pub use image::SplatImage;
pub use model::{GpuModel, PackedModel, pack_model, spatial_order};
pub use occluders::{MAX_OCCLUDERS, Occluder};
pub use params::{AUTO_CPU_RENDER_PASS_ABOVE_PX, Backend, SPLATTER_ENV, SplatParams};
pub use resolve::PendingGather;
pub use targets::SplatTargets;
pub use window::Window;
pub(crate) use window::box_corners;
