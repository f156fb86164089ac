// The camera of the splatters (splat.wgsl, splat_compute.wgsl), composed
// before splat_common.wgsl (src/splat/gpu_data.rs declares the part).
// Checked against its Rust twin by the tests of src/shaders.rs.

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
    // low-pass radius h (px), and the depth buffer's range: the z at depth
    // 0 and 1 (size.zw for a model's own render, the occluded model's for
    // an occluder, so that both write comparable depths; size.z still
    // culls).
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
