// Shared by every shader: src/shaders.rs composes each one as
//   the generated prelude (every constant shared with Rust, written from the
//   Rust constants: PIXEL_VALID, NO_SCORE, NCC_TILE, GATHER_STRIDE, the
//   workgroup sizes, ...) + this file + the shader's own file.
// Structs here and in the shaders that have a Rust twin of the same name
// (declared with `wgsl_struct!`) are checked member by member, offsets and
// sizes included, by the tests of src/shaders.rs.

// The camera and the splatting parameters (twin: `CameraUniform` in
// src/splat/gpu_data.rs).
struct CameraUniform {
    // Rows of the object-to-camera rotation R (w unused).
    rot: array<vec4<f32>, 3>,
    // Translation t (w unused): X_c = R X_o + t.
    trans: vec4<f32>,
    // fx, fy, cx, cy (OpenCV: pixel (0,0) is the centre of the top-left pixel).
    intr: vec4<f32>,
    // width, height, near, far (camera-space z, model units).
    size: vec4<f32>,
    // epsilon (visibility push-back, in splat radii along the ray),
    // low-pass radius h (px), unused, unused.
    params: vec4<f32>,
}

// Object to camera space: R x + t.
fn to_camera(cam: CameraUniform, x: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(cam.rot[0].xyz, x), dot(cam.rot[1].xyz, x), dot(cam.rot[2].xyz, x)) + cam.trans.xyz;
}

// Object to camera space for a direction: R n.
fn rotate(cam: CameraUniform, n: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(cam.rot[0].xyz, n), dot(cam.rot[1].xyz, n), dot(cam.rot[2].xyz, n));
}

// A grey pixel of the feature kernels (twin: `Pixel` in
// src/features/gpu_data.rs); `flags` holds PIXEL_VALID and PIXEL_ALLOWED.
struct Pixel {
    value: f32,
    flags: u32,
}

// The value is finite and usable.
fn pixel_valid(p: Pixel) -> bool {
    return (p.flags & PIXEL_VALID) != 0u;
}

// An invalid pixel that is a pinhole (tolerated by Harris and NCC).
fn pixel_hole(p: Pixel) -> bool {
    return (p.flags & PIXEL_HOLE) != 0u;
}

// A corner may be reported here (inside the mask).
fn pixel_allowed(p: Pixel) -> bool {
    return (p.flags & PIXEL_ALLOWED) != 0u;
}
