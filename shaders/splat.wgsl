// EWA surface splatting with per-fragment ray-splat intersection
// (Botsch et al. 2005; Zwicker et al. 2001; Dehais et al. 2010, sections
// 2.3 and 3.2). Two render passes share this file: `fs_visibility` writes
// the nearest depth pushed back by epsilon along the ray, the `fs_attr_*`
// entry points accumulate Gaussian-weighted attributes with additive
// blending. The division by the summed weight is in splat_resolve.wgsl.
// The CPU reference in src/splat/cpu.rs implements the same maths line by
// line; change both together.

// `CameraUniform` is in camera.wgsl; `SplatGpu`, `cam`, the culling and
// screen bounds (`view_splat`) and the intersection (`ray_hit`) are in
// splat_common.wgsl, shared with the compute splatter (both composed
// before this file, src/splat/splatter.rs declares the parts).

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

// OpenCV pixel coordinates -> clip space. The +0.5 is the pixel-centre
// convention of `Intrinsics::to_framebuffer`.
fn to_clip(p: vec2<f32>) -> vec4<f32> {
    let fb = p + vec2<f32>(0.5, 0.5);
    return vec4<f32>(fb.x / cam.size.x * 2.0 - 1.0, 1.0 - fb.y / cam.size.y * 2.0, 0.5, 1.0);
}

// One instanced quad (a 4-vertex triangle strip) per splat, covering the
// screen-space bounding box of (a) the projection of the square that bounds
// the splat's disc and (b) the low-pass disc around the projected centre.
@vertex
fn vs_splat(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> VsOut {
    var out: VsOut;
    let v = view_splat(splats[ii]);
    out.center = v.center;
    out.radius = v.radius;
    out.normal = v.normal;
    out.color = unpack4x8unorm(colors[ii]).xyz;
    if !v.visible {
        out.position = vec4<f32>(-2.0, -2.0, 0.5, 1.0);
        out.proj = vec2<f32>(0.0, 0.0);
        return out;
    }
    out.proj = v.proj;
    let corner = vec2<f32>(f32(vi & 1u), f32(vi >> 1u));
    out.position = to_clip(mix(v.lo, v.hi, corner));
    return out;
}

// The ray of fragment `frag` (framebuffer coordinates) against the splat
// (`ray_hit` in splat_common.wgsl).
fn intersect(in: VsOut, frag: vec4<f32>) -> Hit {
    var v: SplatView;
    v.center = in.center;
    v.normal = in.normal;
    v.radius = in.radius;
    v.proj = in.proj;
    return ray_hit(v, frag.xy - vec2<f32>(0.5, 0.5));
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

// The visibility pass of a depth-only render (`Splatter::render_depth`):
// the same depth as `fs_visibility`, and the colour of the fragment that
// wins the depth test (written without blending, so the nearest one
// stays): a weight of 1 in T0 and the pushed-back camera-space z in T1,
// what the normalisation reads as the depth. One pass over the splats
// instead of two.
struct OutVisDepth {
    @builtin(frag_depth) depth: f32,
    @location(0) t0: vec4<f32>,
    @location(1) t1: vec4<f32>,
}

@fragment
fn fs_visibility_depth(in: VsOut) -> OutVisDepth {
    let hit = intersect(in, in.position);
    if hit.w <= 0.0 {
        discard;
    }
    let z = hit.x.z + cam.params.x * in.radius / hit.ray_len;
    var out: OutVisDepth;
    out.depth = depth_of(z);
    out.t0 = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    out.t1 = vec4<f32>(z, 0.0, 0.0, 0.0);
    return out;
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
