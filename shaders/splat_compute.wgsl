// The compute-shader splatter: the same EWA splatting as splat.wgsl (same
// footprint, kernel, ray-splat intersection, culling, visibility push-back
// and less-or-equal depth test), written with atomics instead of the
// rasteriser and blending (Dehais et al. 2010, sections 2.3 and 3.2;
// Botsch et al. 2005). One thread per splat walks the pixels of its
// screen-space bounding box (the quad the render pass would rasterise);
// footprints of more than `BIG_SPLAT_PIXELS` are listed instead and walked
// by a whole workgroup in 8x8 blocks (`visibility_big`, and the workgroups
// of `accumulate` beyond the splats'),
// so a large or near-plane splat does not serialise on one thread. Both
// walks call the same per-pixel functions (`splat_pixel`: `visibility_key`,
// `fragment`). (Binning large splats into 8x8 tiles, a workgroup per tile
// summing a pixel's fragments in registers, was measured slower on
// lavapipe at every threshold: docs/performance.md.)
//
// 1. `visibility`: the nearest depth, pushed back by epsilon along the ray,
//    by atomicMax on `DEPTH_ONE - bits(depth)` (an f32 in [0, 1] orders
//    like its bits; the key is 0 for the cleared depth 1.0, so the buffer
//    is cleared with zeros);
// 2. `accumulate`: fragments passing the depth test add w * attribute as
//    fixed point (FIXED_SCALE units) with atomicAdd on i32. Every value
//    added is about [-1, 1] times w: colour, the normal, and the depth as
//    z / zv and zv / z, with zv the pixel's visibility depth (a fragment
//    passes only within the push-back in front of it, so both are close to
//    1 and keep six digits at any distance or depth range). The twelve motion
//    predictors are not accumulated: the surface point seen through a pixel
//    is always on that pixel's ray, X = z d, so the translation predictors
//    are (predictor at d) / z and the rotation predictors do not depend on z
//    (eq. 5); their weighted sum is rebuilt exactly from sum(w / z) and
//    sum(w) (9 atomics per fragment instead of 16; 5 without the geometry,
//    what the tracker renders).
// 3. `finish`: one thread per pixel of the target converts the sums within
//    the splats' bounding box (found in pass 1) into the render pass's
//    RGBA32F accumulation targets and writes zeros outside it, what the
//    render pass's clear leaves there (layout in src/splat/mod.rs), so
//    the normalisation and gather kernels (splat_resolve.wgsl) serve both
//    back ends unchanged.
//
// Occluders (src/splat/occluders.rs): before the model's pass 1, each
// occluder's splats run `visibility` and `visibility_big` with its own
// camera and parameters (the model's depth range) into the same depth
// keys and bounding box; pass 2 and `finish` are the model's alone. Each
// lists its large splats at a counter of its own in `bounds` (the model's
// at 4; the occluders' alternate between 5 and 6, each zeroing the one
// its predecessor used, which that predecessor's `visibility_big`, the
// dispatch before, has finished reading). In a depth-only render the
// occluders' keys also go into the first sum of the pixel, which
// `finish_depth` compares with the depth key: the model shows only where
// its key is above every occluder's.
//
// Headroom: sums are i32 in units of 2^-20, so a pixel holds up to 2048
// full-weight contributions of the visible surface (weights are at most 1
// and at least exp(-2); a pixel of a dense model sees tens).
// The culling, screen bounds and ray-splat intersection are splat.wgsl's,
// from splat_common.wgsl (tests/splat_compute.rs compares the two back
// ends pixel by pixel).

// Twin: `ComputeParams` in src/splat/gpu_data.rs.
struct ComputeParams {
    width: u32,
    height: u32,
    // Number of splats.
    count: u32,
    // COMPUTE_GEOMETRY | COMPUTE_MOTION: which groups to accumulate.
    flags: u32,
    // The half of `bounds` this render uses (0 or 1): its last pass zeroes
    // the other half, which the next render uses (no clear of its own).
    slot: u32,
    // The entry of this render's half of `bounds` counting the large
    // splats listed (4 for the model, 5 or 6 for an occluder).
    big_at: u32,
    // An entry `visibility` zeroes (an earlier occluder's counter), or 0.
    clear_big: u32,
    pad0: u32,
}

// @group(0) @binding(0): `cam`, in splat_common.wgsl.
@group(0) @binding(1) var<uniform> params: ComputeParams;
@group(0) @binding(2) var<storage, read> splats: array<SplatGpu>;
@group(0) @binding(3) var<storage, read_write> depth_key: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read_write> acc: array<atomic<i32>>;
@group(0) @binding(5) var t0: texture_storage_2d<rgba32float, write>;
@group(0) @binding(6) var t1: texture_storage_2d<rgba32float, write>;
@group(0) @binding(7) var t2: texture_storage_2d<rgba32float, write>;
@group(0) @binding(8) var t3: texture_storage_2d<rgba32float, write>;
@group(0) @binding(9) var t4: texture_storage_2d<rgba32float, write>;
// The pixels any splat may touch: COMPUTE_BOUNDS_* (the minima stored as
// 0xffffffff - x, the maxima as x + 1, so that zeros mean "none" and atomic
// max serves both), then the indirect dispatch of `finish` over them.
// [4]: the number of large splats listed in `big`.
@group(0) @binding(10) var<storage, read_write> bounds: array<atomic<u32>, 16>;
// Splats whose footprint exceeds `BIG_SPLAT_PIXELS`: a workgroup shares each.
@group(0) @binding(11) var<storage, read_write> big: array<u32>;
// One RGBA8 colour per splat (`pack_color`; a buffer of its own so that
// models textured by different keyframes share the geometry).
@group(0) @binding(12) var<storage, read> colors: array<u32>;

var<workgroup> wg_bounds: array<atomic<u32>, 4>;

// Bits of 1.0f: the cleared depth.
const DEPTH_ONE: u32 = 0x3f800000u;
// A splat after the vertex stage of splat.wgsl: camera-space centre,
// normal, radius, projected centre, colour, and the pixels whose centres
// its quad covers (lo..=hi, clipped to the image; empty when culled).
struct Setup {
    center: vec3<f32>,
    normal: vec3<f32>,
    radius: f32,
    proj: vec2<f32>,
    color: vec3<f32>,
    lo: vec2<i32>,
    hi: vec2<i32>,
}

// Twin of `vs_splat`: culling and the quad's bounds, then the pixel range
// as the rasteriser samples it (centres inside [lo, hi], OpenCV pixels).
fn setup(i: u32) -> Setup {
    var out: Setup;
    out.lo = vec2<i32>(0, 0);
    out.hi = vec2<i32>(-1, -1);
    let v = view_splat(splats[i]);
    out.center = v.center;
    out.radius = v.radius;
    out.normal = v.normal;
    out.color = unpack4x8unorm(colors[i]).xyz;
    if !v.visible {
        return out;
    }
    out.proj = v.proj;
    out.lo = vec2<i32>(max(ceil(v.lo), vec2<f32>(0.0, 0.0)));
    out.hi = vec2<i32>(min(floor(v.hi), cam.size.xy - vec2<f32>(1.0, 1.0)));
    return out;
}

// `ray_hit` at the pixel centre `uv` (OpenCV).
fn intersect(s: Setup, uv: vec2<f32>) -> Hit {
    var v: SplatView;
    v.center = s.center;
    v.normal = s.normal;
    v.radius = s.radius;
    v.proj = s.proj;
    return ray_hit(v, uv);
}

// The splat of this invocation: dispatches are 2-D when a model needs more
// than 65535 workgroups in x.
fn splat_index(id: vec3<u32>, groups: vec3<u32>) -> u32 {
    return id.y * groups.x * WORKGROUP_1D + id.x;
}

// Pixels in a splat's range.
fn footprint(s: Setup) -> u32 {
    if s.lo.x > s.hi.x || s.lo.y > s.hi.y {
        return 0u;
    }
    return u32(s.hi.x - s.lo.x + 1) * u32(s.hi.y - s.lo.y + 1);
}

// The depth key of the splat at a pixel (pass 1): `DEPTH_ONE - bits(depth)`
// of the pushed-back depth, 0 where the kernel is zero.
fn visibility_key(s: Setup, x: i32, y: i32) -> u32 {
    let hit = intersect(s, vec2<f32>(f32(x), f32(y)));
    if hit.w <= 0.0 {
        return 0u;
    }
    let d = depth_of(hit.x.z + cam.params.x * s.radius / hit.ray_len);
    return DEPTH_ONE - bitcast<u32>(d);
}

fn visibility_pixel(s: Setup, x: i32, y: i32) {
    let key = visibility_key(s, x, y);
    if key != 0u {
        let pixel = u32(y) * params.width + u32(x);
        atomicMax(&depth_key[pixel], key);
        if (params.flags & COMPUTE_OCCLUDER_KEYS) != 0u {
            // Keys are below 2^31: as i32 they order the same.
            atomicMax(&acc[pixel * ACC_STRIDE], bitcast<i32>(key));
        }
    }
}

fn fixed(v: f32) -> i32 {
    return i32(round(v * FIXED_SCALE));
}

// The fixed-point sums of one fragment (pass 2): the ACC_STRIDE values of
// a pixel in order.
struct Sums {
    w: i32,
    color: vec3<i32>,
    z: i32,
    normal: vec3<i32>,
    iz: i32,
}

// The visibility depth bits of a pixel (after pass 1).
fn pixel_vis(x: i32, y: i32) -> u32 {
    return DEPTH_ONE - atomicLoad(&depth_key[u32(y) * params.width + u32(x)]);
}

// The fragment of the splat at a pixel (pass 2): zero sums where the
// kernel is zero or the fragment fails the render pass's less-or-equal
// test against pass 1's depth (loaded only where the kernel is not zero:
// most of a small splat's box is outside its ellipse). Depths are
// relative to the pixel's visibility depth zv: every fragment passing the
// test lies within the push-back in front of it, so z / zv is about 1 at
// any distance. Sums of groups not in `params.flags` stay zero.
fn fragment(s: Setup, x: i32, y: i32) -> Sums {
    var out: Sums;
    let hit = intersect(s, vec2<f32>(f32(x), f32(y)));
    if hit.w <= 0.0 {
        return out;
    }
    let vis = pixel_vis(x, y);
    if bitcast<u32>(depth_of(hit.x.z)) > vis {
        return out;
    }
    let w = hit.w;
    out.w = fixed(w);
    out.color = vec3<i32>(fixed(w * s.color.x), fixed(w * s.color.y), fixed(w * s.color.z));
    let zv = visible_z(vis);
    if (params.flags & COMPUTE_GEOMETRY) != 0u {
        out.z = fixed(w * hit.x.z / zv);
        out.normal = vec3<i32>(fixed(w * s.normal.x), fixed(w * s.normal.y), fixed(w * s.normal.z));
    }
    if (params.flags & COMPUTE_MOTION) != 0u {
        out.iz = fixed(w * zv / hit.x.z);
    }
    return out;
}

// Adds a fragment's sums to its pixel's accumulators (nothing where the
// weight is 0: every fragment that passes has a positive weight).
fn add_to_pixel(x: i32, y: i32, f: Sums) {
    if f.w == 0 {
        return;
    }
    let base = (u32(y) * params.width + u32(x)) * ACC_STRIDE;
    atomicAdd(&acc[base], f.w);
    atomicAdd(&acc[base + 1u], f.color.x);
    atomicAdd(&acc[base + 2u], f.color.y);
    atomicAdd(&acc[base + 3u], f.color.z);
    if (params.flags & COMPUTE_GEOMETRY) != 0u {
        atomicAdd(&acc[base + 4u], f.z);
        atomicAdd(&acc[base + 5u], f.normal.x);
        atomicAdd(&acc[base + 6u], f.normal.y);
        atomicAdd(&acc[base + 7u], f.normal.z);
    }
    if (params.flags & COMPUTE_MOTION) != 0u {
        atomicAdd(&acc[base + 8u], f.iz);
    }
}

fn accumulate_pixel(s: Setup, x: i32, y: i32) {
    add_to_pixel(x, y, fragment(s, x, y));
}

// Which pass `splat_pixel` serves.
const PASS_VISIBILITY: u32 = 0u;
const PASS_ACCUMULATE: u32 = 1u;

// The work of one pass at one pixel of a splat's footprint, made of
// atomics: the walks by a thread and by a workgroup.
fn splat_pixel(s: Setup, x: i32, y: i32, stage: u32) {
    if stage == PASS_VISIBILITY {
        visibility_pixel(s, x, y);
    } else {
        accumulate_pixel(s, x, y);
    }
}

// One thread walks a whole footprint, row by row, in one loop over its
// pixels rather than two nested ones: the lanes of a vector (the CPU
// adapters' SIMD lanes, a GPU's warp) then run as many iterations as the
// largest footprint among them, not the widest row times the tallest
// column (on lavapipe the attribute pass 10% faster; the same pixels in
// the same order, so the same sums).
fn walk_thread(s: Setup, stage: u32) {
    let n = footprint(s);
    var x = s.lo.x;
    var y = s.lo.y;
    for (var k = 0u; k < n; k++) {
        splat_pixel(s, x, y, stage);
        x += 1;
        if x > s.hi.x {
            x = s.lo.x;
            y += 1;
        }
    }
}

// The splats of `big`, one workgroup per splat at a time, its
// lanes laid out as 8x8 blocks over the footprint (no integer division: it
// is scalarised on CPU adapters). Dispatched directly, a fixed number of
// workgroups striding over however many pass 1 listed (none leaves them
// idle at once): no pass sizing them on the GPU first.
fn walk_big(li: u32, wg: u32, groups: u32, stage: u32) {
    let n = atomicLoad(&bounds[bound(params.big_at)]);
    let lane = vec2<i32>(i32(li & 7u), i32(li >> 3u));
    for (var j = wg; j < n; j += groups) {
        let s = setup(big[j]);
        for (var by = s.lo.y; by <= s.hi.y; by += 8) {
            for (var bx = s.lo.x; bx <= s.hi.x; bx += 8) {
                let q = vec2<i32>(bx, by) + lane;
                if q.x <= s.hi.x && q.y <= s.hi.y {
                    splat_pixel(s, q.x, q.y, stage);
                }
            }
        }
    }
}

@compute @workgroup_size(WORKGROUP_1D)
fn visibility_big(
    @builtin(local_invocation_index) li: u32,
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    walk_big(li, wg.x, groups.x, PASS_VISIBILITY);
}

@compute @workgroup_size(WORKGROUP_1D)
fn visibility(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    if li < 4u {
        atomicStore(&wg_bounds[li], 0u);
    }
    if params.clear_big != 0u && id.x == 0u && id.y == 0u {
        atomicStore(&bounds[bound(params.clear_big)], 0u);
    }
    workgroupBarrier();
    let i = splat_index(id, groups);
    if i < params.count {
        let s = setup(i);
        if s.lo.x <= s.hi.x && s.lo.y <= s.hi.y {
            atomicMax(&wg_bounds[0], 0xffffffffu - u32(s.lo.x));
            atomicMax(&wg_bounds[1], 0xffffffffu - u32(s.lo.y));
            atomicMax(&wg_bounds[2], u32(s.hi.x) + 1u);
            atomicMax(&wg_bounds[3], u32(s.hi.y) + 1u);
        }
        if footprint(s) > BIG_SPLAT_PIXELS {
            // Too long a walk for one thread: a workgroup shares it.
            big[atomicAdd(&bounds[bound(params.big_at)], 1u)] = i;
        } else {
            walk_thread(s, PASS_VISIBILITY);
        }
    }
    // One global atomic per workgroup and bound, not one per splat.
    workgroupBarrier();
    if li < 4u {
        let b = atomicLoad(&wg_bounds[li]);
        if b != 0u {
            atomicMax(&bounds[bound(li)], b);
        }
    }
}

// The splats a thread each (the first ceil(count / WORKGROUP_1D)
// workgroups, in dispatch order), and the listed large splats by the
// workgroups after them, striding: one dispatch, since the two add into the
// same sums independently (integer atomics: in any order the same sums).
@compute @workgroup_size(WORKGROUP_1D)
fn accumulate(
    @builtin(local_invocation_index) li: u32,
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let g = wg.y * groups.x + wg.x;
    let splat_groups = (params.count + WORKGROUP_1D - 1u) / WORKGROUP_1D;
    if g >= splat_groups {
        walk_big(li, g - splat_groups, groups.x * groups.y - splat_groups, PASS_ACCUMULATE);
        return;
    }
    let i = g * WORKGROUP_1D + li;
    if i >= params.count {
        return;
    }
    let s = setup(i);
    if footprint(s) > BIG_SPLAT_PIXELS {
        return; // a workgroup beyond the splats' walks it
    }
    walk_thread(s, PASS_ACCUMULATE);
}

// Camera-space z of a visibility depth (bits of the [0, 1] depth): the
// inverse of depth_of, the same in `accumulate` and `finish`.
fn visible_z(bits: u32) -> f32 {
    return cam.params.z + bitcast<f32>(bits) * (cam.params.w - cam.params.z);
}

// J(X) v at X = d (z = 1): splat.wgsl's `jac` with the 1 / z factored out.
fn jac1(d: vec3<f32>, v: vec3<f32>) -> vec2<f32> {
    return vec2<f32>(cam.intr.x * (v.x - d.x * v.z), cam.intr.y * (v.y - d.y * v.z));
}

fn sum(base: u32, k: u32) -> f32 {
    return f32(atomicLoad(&acc[base + k])) / FIXED_SCALE;
}

// Whether pixel `id` lies in the splats' bounding box (pass 1): outside
// it no splat touched the depth keys or the sums.
fn in_bounds(id: vec2<u32>) -> bool {
    let lo = vec2<u32>(0xffffffffu - atomicLoad(&bounds[bound(0u)]), 0xffffffffu - atomicLoad(&bounds[bound(1u)]));
    let hi = vec2<u32>(atomicLoad(&bounds[bound(2u)]), atomicLoad(&bounds[bound(3u)]));
    return all(id >= lo) && all(id < hi);
}

// Index of entry k (the box's four bounds, then the counts of large
// splats: the model's, two for occluders) in this render's half of
// `bounds`.
fn bound(k: u32) -> u32 {
    return params.slot * 8u + k;
}

// The other half, zeroed for the next render by one thread of the last
// pass (every pass of the previous render that read it came before).
fn clear_next_bounds(gid: vec3<u32>) {
    if gid.x == 0u && gid.y == 0u {
        let other = (1u - params.slot) * 8u;
        for (var k = 0u; k < 8u; k++) {
            atomicStore(&bounds[other + k], 0u);
        }
    }
}

// Zeros in the targets a render writes (T0 always; T1 with the geometry,
// T2..T4 with the predictors), as the render pass's clear leaves them.
fn store_zeros(p: vec2<i32>, geometry: bool, motion: bool) {
    let zero = vec4<f32>(0.0, 0.0, 0.0, 0.0);
    textureStore(t0, p, zero);
    if geometry {
        textureStore(t1, p, zero);
    }
    if motion {
        textureStore(t2, p, zero);
        textureStore(t3, p, zero);
        textureStore(t4, p, zero);
    }
}

@compute @workgroup_size(RESOLVE_WORKGROUP, RESOLVE_WORKGROUP)
fn finish(@builtin(global_invocation_id) gid: vec3<u32>) {
    // Dispatched over the whole target: no clear beforehand, no
    // indirect dispatch sized by pass 1.
    clear_next_bounds(gid);
    let id = gid.xy;
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let p = vec2<i32>(id.xy);
    if !in_bounds(id) {
        store_zeros(p, (params.flags & COMPUTE_GEOMETRY) != 0u, (params.flags & COMPUTE_MOTION) != 0u);
        return;
    }
    let pixel = id.y * params.width + id.x;
    let base = pixel * ACC_STRIDE;
    let w = sum(base, 0u);
    let empty = atomicLoad(&acc[base]) <= 0;
    let zero = vec4<f32>(0.0, 0.0, 0.0, 0.0);
    textureStore(t0, p, select(vec4<f32>(sum(base, 1u), sum(base, 2u), sum(base, 3u), w), zero, empty));
    let zv = visible_z(DEPTH_ONE - atomicLoad(&depth_key[pixel]));
    if (params.flags & COMPUTE_GEOMETRY) != 0u {
        let g = vec4<f32>(zv * sum(base, 4u), sum(base, 5u), sum(base, 6u), sum(base, 7u));
        textureStore(t1, p, select(g, zero, empty));
    }
    if (params.flags & COMPUTE_MOTION) != 0u {
        // sum(w l) = sum(w / z) * (translation predictors at d)
        //          + sum(w) * (rotation predictors at d).
        let d = vec3<f32>((f32(id.x) - cam.intr.z) / cam.intr.x, (f32(id.y) - cam.intr.w) / cam.intr.y, 1.0);
        let wiz = sum(base, 8u) / zv;
        let tx = jac1(d, vec3<f32>(1.0, 0.0, 0.0)) * wiz;
        let ty = jac1(d, vec3<f32>(0.0, 1.0, 0.0)) * wiz;
        let tz = jac1(d, vec3<f32>(0.0, 0.0, 1.0)) * wiz;
        let rx = jac1(d, vec3<f32>(0.0, -d.z, d.y)) * w;
        let ry = jac1(d, vec3<f32>(d.z, 0.0, -d.x)) * w;
        let rz = jac1(d, vec3<f32>(-d.y, d.x, 0.0)) * w;
        textureStore(t2, p, select(vec4<f32>(tx, ty), zero, empty));
        textureStore(t3, p, select(vec4<f32>(tz, rx), zero, empty));
        textureStore(t4, p, select(vec4<f32>(ry, rz), zero, empty));
    }
    // Leave the scratch cleared for the next render: every pixel a splat
    // touched is in this box, so no full-image clear is needed.
    atomicStore(&depth_key[pixel], 0u);
    for (var k = 0u; k < ACC_STRIDE; k++) {
        atomicStore(&acc[base + k], 0);
    }
}

// The last kernel of a depth-only render (`Splatter::render_depth`), in
// place of `accumulate` and `finish`: over the whole target, a weight of 1
// in T0 and the visibility depth (camera-space z, pushed back as pass 1
// wrote it) in T1 where a splat covers the pixel, what the normalisation
// reads as the depth, zeros elsewhere; the depth keys are cleared for the
// next render (the sums were never touched, but for the occluders' keys
// behind COMPUTE_OCCLUDED: there the pixel is the model's only where its
// key is above theirs, and they are cleared too).
@compute @workgroup_size(RESOLVE_WORKGROUP, RESOLVE_WORKGROUP)
fn finish_depth(@builtin(global_invocation_id) gid: vec3<u32>) {
    clear_next_bounds(gid);
    let id = gid.xy;
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let p = vec2<i32>(id.xy);
    let pixel = id.y * params.width + id.x;
    var key = 0u;
    if in_bounds(id) {
        key = atomicLoad(&depth_key[pixel]);
        if (params.flags & COMPUTE_OCCLUDED) != 0u {
            let hidden = bitcast<u32>(atomicLoad(&acc[pixel * ACC_STRIDE]));
            atomicStore(&acc[pixel * ACC_STRIDE], 0);
            if key <= hidden {
                atomicStore(&depth_key[pixel], 0u);
                key = 0u;
            }
        }
    }
    if key == 0u {
        store_zeros(p, true, false);
        return;
    }
    textureStore(t0, p, vec4<f32>(0.0, 0.0, 0.0, 1.0));
    textureStore(t1, p, vec4<f32>(visible_z(DEPTH_ONE - key), 0.0, 0.0, 0.0));
    atomicStore(&depth_key[pixel], 0u);
}
