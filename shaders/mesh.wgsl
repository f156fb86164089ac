// An ordinary triangle rasteriser: colour, camera-space depth and normal of
// a mesh. Independent of the splatter (it shares only the camera layout), so
// that tests can compare splatted point models with the surface they were
// sampled from, and synthetic sequences can be rendered without the renderer
// under test (DESIGN.md section 7).

// Keep in sync with `CameraUniform` in src/splat/gpu_data.rs (params unused).
struct Camera {
    rot0: vec4<f32>,
    rot1: vec4<f32>,
    rot2: vec4<f32>,
    trans: vec4<f32>,
    intr: vec4<f32>,
    size: vec4<f32>,
    params: vec4<f32>,
}

@group(0) @binding(0) var<uniform> cam: Camera;

// Keep in sync with `MeshVertex` in src/splat/mesh.rs.
struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec3<f32>,
}

struct VsOut {
    @builtin(position) position: vec4<f32>,
    @location(0) z: f32,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec3<f32>,
}

@vertex
fn vs_mesh(v: VertexIn) -> VsOut {
    let p = v.position;
    let c = vec3<f32>(dot(cam.rot0.xyz, p), dot(cam.rot1.xyz, p), dot(cam.rot2.xyz, p)) + cam.trans.xyz;
    let n = v.normal;
    var out: VsOut;
    // Clip coordinates with w = z: x_ndc = 2 (u + 0.5) / W - 1 for the OpenCV
    // pixel u = fx x/z + cx (the +0.5 is the pixel-centre convention), and
    // depth (z - near) far / ((far - near) z) in [0, 1].
    let w = cam.size.x;
    let h = cam.size.y;
    let near = cam.size.z;
    let far = cam.size.w;
    out.position = vec4<f32>(
        2.0 * (cam.intr.x * c.x + (cam.intr.z + 0.5) * c.z) / w - c.z,
        c.z - 2.0 * (cam.intr.y * c.y + (cam.intr.w + 0.5) * c.z) / h,
        (c.z - near) * far / (far - near),
        c.z,
    );
    out.z = c.z;
    out.normal = vec3<f32>(dot(cam.rot0.xyz, n), dot(cam.rot1.xyz, n), dot(cam.rot2.xyz, n));
    out.color = v.color;
    return out;
}

struct FsOut {
    // (r, g, b, 1): alpha 0 marks empty pixels.
    @location(0) color: vec4<f32>,
    // (z, nx, ny, nz), camera space.
    @location(1) geometry: vec4<f32>,
}

@fragment
fn fs_mesh(in: VsOut) -> FsOut {
    var out: FsOut;
    out.color = vec4<f32>(in.color, 1.0);
    // z is affine on the triangle, so perspective-correct interpolation gives
    // the exact depth of the triangle's plane at this pixel.
    out.geometry = vec4<f32>(in.z, normalize(in.normal));
    return out;
}
