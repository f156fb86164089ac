//! Structs and constants shared with shaders/splat.wgsl,
//! shaders/splat_resolve.wgsl, shaders/splat_compute.wgsl and
//! shaders/camera.wgsl (`CameraUniform`), byte for byte. Each struct is
//! declared with [`wgsl_struct!`](crate::wgsl_struct) and compared member
//! by member with its WGSL twin by the tests of [`crate::shaders`]; the
//! constants reach WGSL through the prelude, from the tables here.

use crate::geometry::{Intrinsics, Pose};
use crate::gpu::WORKGROUP_1D;
use crate::shaders::{Constants, Part, Shader, WgslValue::U32};
use crate::wgsl_struct;

wgsl_struct! {
    /// One splat's geometry as the vertex shader reads it. Its colour is
    /// in a buffer of its own (one `u32` per splat, see [`pack_color`]), so
    /// that models textured by different keyframes share this buffer.
    #[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
    pub struct SplatGpu {
        /// Object-space centre, then the radius.
        pub pos_radius: [f32; 4],
        /// Object-space unit normal, w unused.
        pub normal: [f32; 4],
    }
}

/// A linear RGB colour (0..1) as the splat shader reads it: 8 bits per
/// channel, red in the low byte, alpha 255 (WGSL's `unpack4x8unorm`). The
/// keyframe store keeps colours at this precision too.
pub fn pack_color(c: [f32; 3]) -> u32 {
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u32;
    q(c[0]) | q(c[1]) << 8 | q(c[2]) << 16 | 255 << 24
}

/// The inverse of [`pack_color`] (WGSL's `unpack4x8unorm`).
pub fn unpack_color(c: u32) -> [f32; 3] {
    [c & 255, (c >> 8) & 255, (c >> 16) & 255].map(|v| v as f32 / 255.0)
}

wgsl_struct! {
    /// The camera and the splatting parameters.
    #[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
    pub struct CameraUniform {
        /// Rows of R.
        pub rot: [[f32; 4]; 3],
        /// Translation t of the pose (object to camera, model units), w
        /// unused.
        pub trans: [f32; 4],
        /// fx, fy, cx, cy.
        pub intr: [f32; 4],
        /// width, height, near, far.
        pub size: [f32; 4],
        /// epsilon (in radii, along the ray), low-pass radius (px), and
        /// the depth buffer's range: the camera-space z mapped to depth 0
        /// and to 1. A model's own render has its near and far there;
        /// an occluder's has the occluded model's, so that both write
        /// comparable depths into one buffer.
        pub params: [f32; 4],
    }
}

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
            params: [epsilon, lowpass_px, near, far],
        }
    }

    /// This view with the depth buffer's range of another (`near`, `far`
    /// of the model an occluder is splatted with); the near plane that
    /// culls stays this view's.
    pub fn with_depth_range(mut self, near: f32, far: f32) -> Self {
        self.params[2] = near;
        self.params[3] = far;
        self
    }

    /// The depth buffer's range (camera-space z at depth 0 and 1).
    pub fn depth_range(&self) -> (f32, f32) {
        (self.params[2], self.params[3])
    }
}

/// A buffer for one [`CameraUniform`] (a render's, or an occluder's).
pub(super) fn camera_buffer(ctx: &crate::gpu::GpuContext) -> wgpu::Buffer {
    ctx.buffer(
        "splat camera",
        std::mem::size_of::<CameraUniform>() as u64,
        wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    )
}

pub use crate::gpu::GATHER_STRIDE;

wgsl_struct! {
    /// Parameters of the resolve kernels.
    #[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
    pub struct ResolveParams {
        /// Target width in pixels.
        pub width: u32,
        /// Target height in pixels.
        pub height: u32,
        /// `resolve`: the attribute kind; `gather`: the number of points.
        pub kind: u32,
        /// `gather`: 0 nearest, 1 bilinear.
        pub mode: u32,
        /// `gather`: the focal length in x of the render (pixels), which
        /// turns the translation predictor du/dtx = fx / z into the depth.
        pub fx: f32,
        /// Padding to a 16-byte multiple.
        pub _pad0: u32,
        /// Padding to a 16-byte multiple.
        pub _pad1: u32,
        /// Padding to a 16-byte multiple.
        pub _pad2: u32,
    }
}

/// `ResolveParams.kind` of `resolve`: which attribute to normalise.
pub const RESOLVE_COLOR: u32 = 0;
/// `ResolveParams.kind`: camera-space depth `z`.
pub const RESOLVE_DEPTH: u32 = 1;
/// `ResolveParams.kind`: camera-space unit normal.
pub const RESOLVE_NORMAL: u32 = 2;
/// `ResolveParams.kind`: the 12 motion predictors.
pub const RESOLVE_MOTION: u32 = 3;
/// The raw summed weight.
pub const RESOLVE_WEIGHT: u32 = 4;
/// The depth of a render without geometry, from its translation predictor
/// (`fx / (du/dtx)`, what `gather` gives).
pub const RESOLVE_DEPTH_MOTION: u32 = 5;

/// `ResolveParams.mode` of `gather`: the nearest pixel...
pub const GATHER_NEAREST: u32 = 0;
/// ...or bilinear where all four pixels are covered.
pub const GATHER_BILINEAR: u32 = 1;

/// Workgroup edge of `resolve` (8x8 pixels per workgroup).
pub const RESOLVE_WORKGROUP: u32 = 8;

wgsl_struct! {
    /// Parameters of the compute splatter (shaders/splat_compute.wgsl).
    #[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
    pub struct ComputeParams {
        /// Target width in pixels.
        pub width: u32,
        /// Target height in pixels.
        pub height: u32,
        /// Number of splats.
        pub count: u32,
        /// [`COMPUTE_GEOMETRY`] | [`COMPUTE_MOTION`].
        pub flags: u32,
        /// The half of the bounds buffer this render uses (0 or 1): its
        /// last pass zeroes the other half for the next render.
        pub slot: u32,
        /// The entry of that half counting the large splats listed:
        /// [`COMPUTE_BIG_MODEL`] for the model, [`COMPUTE_BIG_OCCLUDER`]
        /// and the one after, alternately, for occluders.
        pub big_at: u32,
        /// An entry `visibility` zeroes (the previous occluder's
        /// counter), or 0 for none.
        pub clear_big: u32,
        /// Padding to a 16-byte multiple.
        pub pad0: u32,
    }
}

/// `ComputeParams.big_at` of the model.
pub const COMPUTE_BIG_MODEL: u32 = 4;
/// `ComputeParams.big_at` of the first occluder (the next is one more).
pub const COMPUTE_BIG_OCCLUDER: u32 = 5;

/// `ComputeParams.flags`: accumulate depth and normal.
pub const COMPUTE_GEOMETRY: u32 = 1;
/// `ComputeParams.flags`: accumulate what the motion predictors need.
pub const COMPUTE_MOTION: u32 = 2;
/// `ComputeParams.flags` of an occluder in a depth-only render: its
/// depth keys also go into the pixel's first sum.
pub const COMPUTE_OCCLUDER_KEYS: u32 = 4;
/// `ComputeParams.flags` of the model in a depth-only render behind
/// occluders: `finish_depth` shows the model only where its key is above
/// the occluders' (and clears theirs).
pub const COMPUTE_OCCLUDED: u32 = 8;
/// Fixed-point sums per pixel of the compute splatter: w, w r, w g, w b,
/// w z / zv, w nx, w ny, w nz, w zv / z (zv: the pixel's visibility depth).
pub const ACC_STRIDE: u32 = 9;
/// Units per 1.0 of the compute splatter's fixed-point sums (2^20): a
/// resolution of 1e-6 and room for 2048 full-weight contributions.
pub const FIXED_SCALE: f32 = 1_048_576.0;

/// Footprints above this many pixels (32 x 32) are walked by a whole
/// workgroup in 8x8 blocks (`visibility_big`, `accumulate`'s last groups), not by one
/// thread: splats of a dense model stay one per thread, a huge or
/// near-plane splat no longer serialises on one. Measured on lavapipe
/// (docs/performance.md): thresholds of 64 and 256 pixels, and binning large
/// splats into 8x8 tiles of the image instead, were slower.
pub const BIG_SPLAT_PIXELS: u32 = 1024;

/// The splatters' camera (`CameraUniform`), composed first into both.
pub(crate) const CAMERA_WGSL: Part = crate::wgsl_file!("camera.wgsl");

/// What the two splatters share (the splat, the view uniform, culling,
/// screen bounds, the ray-splat intersection), composed after the camera.
pub(crate) const SPLAT_COMMON_WGSL: Part = crate::wgsl_file!("splat_common.wgsl");

/// The constants of shaders/splat_resolve.wgsl.
pub(crate) const RESOLVE_CONSTANTS: Constants = &[
    ("WORKGROUP_1D", U32(WORKGROUP_1D)),
    ("GATHER_STRIDE", U32(GATHER_STRIDE as u32)),
    ("RESOLVE_WORKGROUP", U32(RESOLVE_WORKGROUP)),
    ("RESOLVE_COLOR", U32(RESOLVE_COLOR)),
    ("RESOLVE_DEPTH", U32(RESOLVE_DEPTH)),
    ("RESOLVE_NORMAL", U32(RESOLVE_NORMAL)),
    ("RESOLVE_MOTION", U32(RESOLVE_MOTION)),
    ("RESOLVE_WEIGHT", U32(RESOLVE_WEIGHT)),
    ("RESOLVE_DEPTH_MOTION", U32(RESOLVE_DEPTH_MOTION)),
    ("GATHER_NEAREST", U32(GATHER_NEAREST)),
    ("GATHER_BILINEAR", U32(GATHER_BILINEAR)),
];

/// The constants of shaders/splat_compute.wgsl.
pub(crate) const COMPUTE_CONSTANTS: Constants = &[
    ("WORKGROUP_1D", U32(WORKGROUP_1D)),
    ("RESOLVE_WORKGROUP", U32(RESOLVE_WORKGROUP)),
    ("COMPUTE_GEOMETRY", U32(COMPUTE_GEOMETRY)),
    ("COMPUTE_MOTION", U32(COMPUTE_MOTION)),
    ("COMPUTE_OCCLUDER_KEYS", U32(COMPUTE_OCCLUDER_KEYS)),
    ("COMPUTE_OCCLUDED", U32(COMPUTE_OCCLUDED)),
    ("ACC_STRIDE", U32(ACC_STRIDE)),
    ("FIXED_SCALE", crate::shaders::WgslValue::F32(FIXED_SCALE)),
    ("BIG_SPLAT_PIXELS", U32(BIG_SPLAT_PIXELS)),
];

/// The render splatter's shader (`Splatter`).
pub(crate) static SPLAT_SHADER: Shader = Shader {
    name: "splat",
    parts: &[
        CAMERA_WGSL,
        SPLAT_COMMON_WGSL,
        crate::wgsl_file!("splat.wgsl"),
    ],
    constants: &[],
};

/// The resolve and gather kernels of the render splatter.
pub(crate) static RESOLVE_SHADER: Shader = Shader {
    name: "splat_resolve",
    parts: &[crate::wgsl_file!("splat_resolve.wgsl")],
    constants: &[RESOLVE_CONSTANTS],
};

/// The compute splatter's shader (`ComputeSplatter`).
pub(crate) static COMPUTE_SHADER: Shader = Shader {
    name: "splat_compute",
    parts: &[
        CAMERA_WGSL,
        SPLAT_COMMON_WGSL,
        crate::wgsl_file!("splat_compute.wgsl"),
    ],
    constants: &[COMPUTE_CONSTANTS],
};

/// The accumulation targets of a render (T0..T4, module docs of
/// [`super`]).
pub(super) const TARGETS: usize = 5;

/// Whether the adapter can run the compute back end (it writes the five
/// accumulation targets as storage textures in one pass).
pub(super) fn compute_supported(ctx: &crate::gpu::GpuContext) -> bool {
    ctx.limits.max_storage_textures_per_shader_stage >= TARGETS as u32
}
