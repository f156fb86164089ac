// EWA surface splatting with per-fragment ray-splat intersection
// (Botsch et al. 2005; Zwicker et al. 2001; Dehais et al. 2010, sections
// 2.3 and 3.2). Two render passes share this file: `fs_visibility` writes
// the nearest depth pushed back by epsilon along the ray, the `fs_attr_*`
// entry points accumulate Gaussian-weighted attributes with additive
// blending. The division by the summed weight is in splat_resolve.wgsl.
// The CPU reference in src/splat/cpu.rs implements the same maths line by
// line; change both together.

// `CameraUniform` is in common.wgsl (composed before this file by
// src/shaders.rs).

// Twin: `SplatGpu` in src/splat/gpu_data.rs.
struct SplatGpu {
    pos_radius: vec4<f32>,
    normal: vec4<f32>,
}

@group(0) @binding(0) var<uniform> cam: CameraUniform;
@group(0) @binding(1) var<storage, read> splats: array<SplatGpu>;
// One RGBA8 colour per splat (`pack_color`), a buffer of its own so that
// models textured by different keyframes share the geometry.
@group(0) @binding(2) var<storage, read> colors: array<u32>;

struct VsOut {
    @builtin(position) position: vec4<f32>,
    // Camera-space centre and normal, radius, projected centre (OpenCV px).
    @location(0) @interpolate(flat) center: vec3<f32>,
    @location(1) @interpolate(flat) radius: f32,
    @location(2) @interpolate(flat) normal: vec3<f32>,
    @location(3) @interpolate(flat) proj: vec2<f32>,
    @location(4) @interpolate(flat) color: vec3<f32>,
}

fn project(x: vec3<f32>) -> vec2<f32> {
    return vec2<f32>(cam.intr.x * x.x / x.z + cam.intr.z, cam.intr.y * x.y / x.z + cam.intr.w);
}

// OpenCV pixel coordinates -> clip space. The +0.5 is the pixel-centre
// convention of `Intrinsics::to_framebuffer`.
fn to_clip(p: vec2<f32>) -> vec4<f32> {
    let fb = p + vec2<f32>(0.5, 0.5);
    return vec4<f32>(fb.x / cam.size.x * 2.0 - 1.0, 1.0 - fb.y / cam.size.y * 2.0, 0.5, 1.0);
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

// One instanced quad (a 4-vertex triangle strip) per splat, covering the
// screen-space bounding box of (a) the projection of the square that bounds
// the splat's disc and (b) the low-pass disc around the projected centre.
@vertex
fn vs_splat(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> VsOut {
    var out: VsOut;
    let s = splats[ii];
    let p = s.pos_radius.xyz;
    let r = s.pos_radius.w;
    let c = to_camera(cam, p);
    let m = normalize(rotate(cam, s.normal.xyz));
    out.center = c;
    out.radius = r;
    out.normal = m;
    out.color = unpack4x8unorm(colors[ii]).xyz;
    let near = cam.size.z;
    // Culled: centre not in front of the near plane, or back-facing.
    if c.z <= near || dot(m, c) >= 0.0 || !(r > 0.0) {
        out.position = vec4<f32>(-2.0, -2.0, 0.5, 1.0);
        out.proj = vec2<f32>(0.0, 0.0);
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
        // The disc reaches the near plane: cover the whole image and let the
        // fragment stage decide.
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
    // Half a pixel of margin, clamped to just outside the image.
    lo = clamp(lo - vec2<f32>(0.5, 0.5), vec2<f32>(-1.0, -1.0), cam.size.xy);
    hi = clamp(hi + vec2<f32>(0.5, 0.5), vec2<f32>(-1.0, -1.0), cam.size.xy);
    let corner = vec2<f32>(f32(vi & 1u), f32(vi >> 1u));
    out.position = to_clip(mix(lo, hi, corner));
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

// The ray of pixel `frag` (framebuffer coords) against the splat's plane.
// rho_obj = |X - c| / r in the splat's plane; rho_scr = |x - pi(c)| / h in
// pixels; the kernel is evaluated at rho = min(rho_obj, rho_scr) (Botsch et
// al. 2005's approximation of the EWA screen-space low-pass filter), so a
// sub-pixel splat still covers at least one pixel centre. Truncated at
// rho = 1; w = exp(-2 rho^2), i.e. a Gaussian of sigma = r/2 (or h/2).
fn intersect(in: VsOut, frag: vec4<f32>) -> Hit {
    var hit: Hit;
    hit.w = 0.0;
    let uv = frag.xy - vec2<f32>(0.5, 0.5);
    let d = vec3<f32>((uv.x - cam.intr.z) / cam.intr.x, (uv.y - cam.intr.w) / cam.intr.y, 1.0);
    hit.ray_len = length(d);
    let near = cam.size.z;
    let c = in.center;
    let m = in.normal;
    let denom = dot(m, d);
    var rho_obj2 = 1e30;
    var x = d * c.z;
    if abs(denom) > 1e-12 {
        let s = dot(m, c) / denom;
        if s > near {
            let xi = d * s;
            let q = xi - c;
            rho_obj2 = dot(q, q) / (in.radius * in.radius);
            // Inside the disc, or within reach of the low-pass disc (3 of
            // its radii at the centre's depth, i.e. incidence up to ~70
            // degrees): the intersection is on the splat's plane, exact for
            // planar surfaces. Farther (near edge-on splats) it is
            // meaningless and the centre's depth is used instead.
            let reach = in.radius + 3.0 * cam.params.y * c.z / min(cam.intr.x, cam.intr.y);
            if rho_obj2 <= 1.0 || dot(q, q) <= reach * reach {
                x = xi;
            }
        }
    }
    let e = (uv - in.proj) / cam.params.y;
    let rho_scr2 = dot(e, e);
    let rho2 = min(rho_obj2, rho_scr2);
    if rho2 > 1.0 || x.z <= near {
        return hit;
    }
    hit.x = x;
    hit.w = exp(-2.0 * rho2);
    return hit;
}

// Camera-space z -> [0, 1] depth, linear between near and far.
fn depth_of(z: f32) -> f32 {
    return clamp((z - cam.size.z) / (cam.size.w - cam.size.z), 0.0, 1.0);
}

@fragment
fn fs_visibility(in: VsOut) -> @builtin(frag_depth) f32 {
    let hit = intersect(in, in.position);
    if hit.w <= 0.0 {
        discard;
    }
    // Push back by epsilon * r along the ray (distance), i.e. by
    // epsilon * r / |d| in z, so neighbouring splats of the same surface pass
    // the attribute pass's depth test.
    return depth_of(hit.x.z + cam.params.x * in.radius / hit.ray_len);
}

// Motion predictors l_1..l_6 at X (Dehais et al. 2010, eq. 5; the same
// formulas as `Intrinsics::motion_predictors`): translation j: J(X) e_j;
// rotation j: J(X) (e_j x X).
fn jac(x: vec3<f32>, v: vec3<f32>) -> vec2<f32> {
    let iz = 1.0 / x.z;
    return vec2<f32>(
        cam.intr.x * iz * (v.x - x.x * iz * v.z),
        cam.intr.y * iz * (v.y - x.y * iz * v.z),
    );
}

struct Motion {
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
}

fn motion(x: vec3<f32>) -> Motion {
    let tx = jac(x, vec3<f32>(1.0, 0.0, 0.0));
    let ty = jac(x, vec3<f32>(0.0, 1.0, 0.0));
    let tz = jac(x, vec3<f32>(0.0, 0.0, 1.0));
    let rx = jac(x, vec3<f32>(0.0, -x.z, x.y));
    let ry = jac(x, vec3<f32>(x.z, 0.0, -x.x));
    let rz = jac(x, vec3<f32>(-x.y, x.x, 0.0));
    var out: Motion;
    out.a = vec4<f32>(tx, ty);
    out.b = vec4<f32>(tz, rx);
    out.c = vec4<f32>(ry, rz);
    return out;
}

// Attribute targets (weighted sums; the weight itself is in T0.w):
//   location 0: (w r, w g, w b, w)        colour and weight, always
//   location 1: (w z, w nx, w ny, w nz)   geometry: depth and normal
//   locations 2-4: w * (du_tx, dv_tx, du_ty, dv_ty), (tz, rx), (ry, rz)
fn t_color(in: VsOut, w: f32) -> vec4<f32> {
    return vec4<f32>(in.color * w, w);
}

fn t_geom(in: VsOut, hit: Hit) -> vec4<f32> {
    return vec4<f32>(hit.x.z, in.normal) * hit.w;
}

struct OutC {
    @builtin(frag_depth) depth: f32,
    @location(0) t0: vec4<f32>,
}

struct OutCG {
    @builtin(frag_depth) depth: f32,
    @location(0) t0: vec4<f32>,
    @location(1) t1: vec4<f32>,
}

struct OutCM {
    @builtin(frag_depth) depth: f32,
    @location(0) t0: vec4<f32>,
    @location(2) t2: vec4<f32>,
    @location(3) t3: vec4<f32>,
    @location(4) t4: vec4<f32>,
}

struct OutCGM {
    @builtin(frag_depth) depth: f32,
    @location(0) t0: vec4<f32>,
    @location(1) t1: vec4<f32>,
    @location(2) t2: vec4<f32>,
    @location(3) t3: vec4<f32>,
    @location(4) t4: vec4<f32>,
}

@fragment
fn fs_attr_c(in: VsOut) -> OutC {
    let hit = intersect(in, in.position);
    if hit.w <= 0.0 {
        discard;
    }
    var out: OutC;
    out.depth = depth_of(hit.x.z);
    out.t0 = t_color(in, hit.w);
    return out;
}

@fragment
fn fs_attr_cg(in: VsOut) -> OutCG {
    let hit = intersect(in, in.position);
    if hit.w <= 0.0 {
        discard;
    }
    var out: OutCG;
    out.depth = depth_of(hit.x.z);
    out.t0 = t_color(in, hit.w);
    out.t1 = t_geom(in, hit);
    return out;
}

@fragment
fn fs_attr_cm(in: VsOut) -> OutCM {
    let hit = intersect(in, in.position);
    if hit.w <= 0.0 {
        discard;
    }
    var out: OutCM;
    out.depth = depth_of(hit.x.z);
    out.t0 = t_color(in, hit.w);
    let l = motion(hit.x);
    out.t2 = l.a * hit.w;
    out.t3 = l.b * hit.w;
    out.t4 = l.c * hit.w;
    return out;
}

@fragment
fn fs_attr_cgm(in: VsOut) -> OutCGM {
    let hit = intersect(in, in.position);
    if hit.w <= 0.0 {
        discard;
    }
    var out: OutCGM;
    out.depth = depth_of(hit.x.z);
    out.t0 = t_color(in, hit.w);
    out.t1 = t_geom(in, hit);
    let l = motion(hit.x);
    out.t2 = l.a * hit.w;
    out.t3 = l.b * hit.w;
    out.t4 = l.c * hit.w;
    return out;
}
