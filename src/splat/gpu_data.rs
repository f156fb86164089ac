//! Structs shared with the WGSL shaders, byte for byte.
//!
//! Keep every field order in sync with shaders/splat.wgsl and
//! shaders/splat_resolve.wgsl: a mismatch is a silent GPU bug, so each struct
//! has a size assertion here.

use crate::geometry::{Intrinsics, Pose};

/// One splat as the vertex shader reads it (`Splat` in shaders/splat.wgsl).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SplatGpu {
    /// Object-space centre, then the radius.
    pub pos_radius: [f32; 4],
    /// Object-space unit normal, w unused.
    pub normal: [f32; 4],
    /// Linear RGB, w unused.
    pub color: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<SplatGpu>() == 48);

/// The camera and the splatting parameters (`Camera` in shaders/splat.wgsl).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct CameraUniform {
    /// Rows of R.
    pub rot: [[f32; 4]; 3],
    pub trans: [f32; 4],
    /// fx, fy, cx, cy.
    pub intr: [f32; 4],
    /// width, height, near, far.
    pub size: [f32; 4],
    /// epsilon (in radii, along the ray), low-pass radius (px), 0, 0.
    pub params: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<CameraUniform>() == 112);

impl CameraUniform {
    /// The uniform for a view: the pose and intrinsics rounded to f32 once,
    /// here, so that the CPU reference sees exactly what the GPU sees.
    pub fn new(
        cam: &Intrinsics,
        pose: &Pose,
        near: f32,
        far: f32,
        epsilon: f32,
        lowpass_px: f32,
    ) -> Self {
        let r = pose.rotation;
        let t = pose.translation;
        Self {
            rot: std::array::from_fn(|i| {
                [r[(i, 0)] as f32, r[(i, 1)] as f32, r[(i, 2)] as f32, 0.0]
            }),
            trans: [t.x as f32, t.y as f32, t.z as f32, 0.0],
            intr: [cam.fx as f32, cam.fy as f32, cam.cx as f32, cam.cy as f32],
            size: [cam.width as f32, cam.height as f32, near, far],
            params: [epsilon, lowpass_px, 0.0, 0.0],
        }
    }
}

/// Parameters of the resolve kernels (`Params` in shaders/splat_resolve.wgsl).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ResolveParams {
    pub width: u32,
    pub height: u32,
    /// `resolve`: the attribute kind; `gather`: the number of points.
    pub kind: u32,
    /// `gather`: 0 nearest, 1 bilinear.
    pub mode: u32,
}
const _: () = assert!(std::mem::size_of::<ResolveParams>() == 16);
