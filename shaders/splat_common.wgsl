// What the two splatters share (composed, after camera.wgsl, into
// splat.wgsl, the render pass, and splat_compute.wgsl, the compute
// shader): the splat as stored, the view uniform, the vertex stage's
// culling and screen bounds, and the ray-splat intersection. One copy, so
// the back ends cannot drift apart; src/splat/cpu.rs is their CPU twin.

// Twin: `SplatGpu` in src/splat/gpu_data.rs.
struct SplatGpu {
    pos_radius: vec4<f32>,
    normal: vec4<f32>,
}

@group(0) @binding(0) var<uniform> cam: CameraUniform;

fn project(x: vec3<f32>) -> vec2<f32> {
    return vec2<f32>(cam.intr.x * x.x / x.z + cam.intr.z, cam.intr.y * x.y / x.z + cam.intr.w);
}

// A unit vector orthogonal to n, built from the axis least aligned with it.
fn tangent(n: vec3<f32>) -> vec3<f32> {
    let a = abs(n);
    var axis = vec3<f32>(1.0, 0.0, 0.0);
    if a.y <= a.x && a.y <= a.z {
        axis = vec3<f32>(0.0, 1.0, 0.0);
    } else if a.z <= a.x && a.z <= a.y {
        axis = vec3<f32>(0.0, 0.0, 1.0);
    }
    return normalize(cross(n, axis));
}

// A splat seen from the camera: camera-space centre, unit normal and
// radius, projected centre, and the screen-space box (OpenCV pixels, half
// a pixel of margin, clamped to just outside the image) that bounds (a)
// the projection of the square bounding the splat's disc and (b) the
// low-pass disc around the projected centre. `visible` false: culled
// (centre not in front of the near plane, back-facing, or no radius).
struct SplatView {
    center: vec3<f32>,
    normal: vec3<f32>,
    radius: f32,
    proj: vec2<f32>,
    lo: vec2<f32>,
    hi: vec2<f32>,
    visible: bool,
}

fn view_splat(s: SplatGpu) -> SplatView {
    var out: SplatView;
    let r = s.pos_radius.w;
    let c = to_camera(cam, s.pos_radius.xyz);
    let m = normalize(rotate(cam, s.normal.xyz));
    out.center = c;
    out.radius = r;
    out.normal = m;
    let near = cam.size.z;
    out.visible = !(c.z <= near || dot(m, c) >= 0.0 || !(r > 0.0));
    if !out.visible {
        return out;
    }
    let pc = project(c);
    out.proj = pc;
    let h = cam.params.y;
    var lo = pc - vec2<f32>(h, h);
    var hi = pc + vec2<f32>(h, h);
    let tu = tangent(m) * r;
    let tv = cross(m, tangent(m)) * r;
    let k0 = c + tu + tv;
    let k1 = c + tu - tv;
    let k2 = c - tu + tv;
    let k3 = c - tu - tv;
    if min(min(k0.z, k1.z), min(k2.z, k3.z)) <= near {
        // The disc reaches the near plane: cover the whole image and let
        // the per-pixel test decide.
        lo = vec2<f32>(-1.0, -1.0);
        hi = cam.size.xy;
    } else {
        let q0 = project(k0);
        let q1 = project(k1);
        let q2 = project(k2);
        let q3 = project(k3);
        lo = min(lo, min(min(q0, q1), min(q2, q3)));
        hi = max(hi, max(max(q0, q1), max(q2, q3)));
    }
    out.lo = clamp(lo - vec2<f32>(0.5, 0.5), vec2<f32>(-1.0, -1.0), cam.size.xy);
    out.hi = clamp(hi + vec2<f32>(0.5, 0.5), vec2<f32>(-1.0, -1.0), cam.size.xy);
    return out;
}

struct Hit {
    // Camera-space surface point seen through this pixel.
    x: vec3<f32>,
    // Gaussian weight; 0 when the pixel is outside the splat's support.
    w: f32,
    // Length of the unnormalised ray (u', v', 1), for the push-back.
    ray_len: f32,
}

// The ray of pixel centre `uv` (OpenCV pixels) against the plane of the
// splat `v`. rho_obj = |X - c| / r in the splat's plane; rho_scr =
// |x - pi(c)| / h in pixels; the kernel is evaluated at rho = min(rho_obj,
// rho_scr) (Botsch et al. 2005's approximation of the EWA screen-space
// low-pass filter), so a sub-pixel splat still covers at least one pixel
// centre. Truncated at rho = 1; w = exp(-2 rho^2), i.e. a Gaussian of
// sigma = r/2 (or h/2).
fn ray_hit(v: SplatView, uv: vec2<f32>) -> Hit {
    var hit: Hit;
    hit.w = 0.0;
    let d = vec3<f32>((uv.x - cam.intr.z) / cam.intr.x, (uv.y - cam.intr.w) / cam.intr.y, 1.0);
    hit.ray_len = length(d);
    let near = cam.size.z;
    let c = v.center;
    let m = v.normal;
    let denom = dot(m, d);
    var rho_obj2 = 1e30;
    var x = d * c.z;
    if abs(denom) > 1e-12 {
        let s = dot(m, c) / denom;
        if s > near {
            let xi = d * s;
            let q = xi - c;
            rho_obj2 = dot(q, q) / (v.radius * v.radius);
            // Inside the disc, or within reach of the low-pass disc (3 of
            // its radii at the centre's depth, i.e. incidence up to ~70
            // degrees): the intersection is on the splat's plane, exact for
            // planar surfaces. Farther (near edge-on splats) it is
            // meaningless and the centre's depth is used instead.
            let reach = v.radius + 3.0 * cam.params.y * c.z / min(cam.intr.x, cam.intr.y);
            if rho_obj2 <= 1.0 || dot(q, q) <= reach * reach {
                x = xi;
            }
        }
    }
    let e = (uv - v.proj) / cam.params.y;
    let rho_scr2 = dot(e, e);
    let rho2 = min(rho_obj2, rho_scr2);
    if rho2 > 1.0 || x.z <= near {
        return hit;
    }
    hit.x = x;
    hit.w = exp(-2.0 * rho2);
    return hit;
}

// Camera-space z -> [0, 1] depth, linear over the depth buffer's range
// (clamped: an occluder nearer than the model's range writes 0, which
// hides the model, as it is in front of all of it).
fn depth_of(z: f32) -> f32 {
    return clamp((z - cam.params.z) / (cam.params.w - cam.params.z), 0.0, 1.0);
}
