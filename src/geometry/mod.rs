//! Camera and pose maths on the host, in `f64`: the reference that every GPU
//! kernel is tested against.
//!
//! Conventions (docs/design.md, fixed here once for the whole crate):
//! - A [`Pose`] is the object-to-camera transform `T_co`: `X_c = R X_o + t`.
//! - [`Intrinsics`] are an OpenCV pinhole camera; pixel (0,0) is the *centre*
//!   of the top-left pixel. GPU rasterisers put pixel centres at +0.5; the one
//!   place that converts is [`Intrinsics::to_framebuffer`].
//! - Pose updates are left-multiplied twists in the camera frame:
//!   `E_t = exp(xi^) E_{t-1}`, `xi = (v, w)`, translation first.
//! - The six generators `G_j` are translations along camera x, y, z, then
//!   rotations about camera x, y, z.
//!
//! The motion predictor of generator `j` at a camera-space point `X`
//! (Dehais et al. 2010, eq. 5) is the image velocity of `pi(exp(a G_j) X)` at
//! `a = 0`: `J(X) e_j` for translations and `J(X) (e_j x X)` for rotations.
//!
//! Camera files (`camera.json`, OpenCV YAML) are read in [`crate::io::camera`].

mod camera;
mod pose;

pub use camera::{Intrinsics, Undistorter, sample_bilinear_rgb};
pub use pose::{Pose, PoseError, look_at, rotation_exp, rotation_log};
