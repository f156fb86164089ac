// Harris corners (Harris & Stephens 1988; Dehais et al. 2010, section 4.2).
// Host code and the CPU reference that mirrors every pass, operation for
// operation: src/features/harris/gpu.rs and src/features/harris/cpu.rs.
// Composed after the prelude and pixel.wgsl (src/shaders.rs): the
// constants (PIXEL_VALID, INVALID_RESPONSE, MAX_TAPS, workgroup sizes) and
// `Pixel` come from there.
//
// Passes (one dispatch each, WORKGROUP_2D^2 threads per workgroup, one
// thread per pixel, or per HARRIS_BLOCK pixels in the filter passes): grey
// (only for RGB input: Rec. 601 luma of packed RGBA8, the alpha byte
// carrying the mask), deriv_h -> deriv_v (Gaussian-derivative gradients),
// integrate_h -> integrate_v (structure tensor smoothed by a Gaussian, then the
// response det - k trace^2), nms (3x3 non-maximum suppression, threshold,
// compaction into `candidates`), then the selection of the corners among
// the candidates, their refinement and their merge (see "The selection"
// below), or, when the host selected (more than SELECT_MAX candidates),
// refine (one thread per selected corner: gradient-orthogonality
// sub-pixel refinement).
//
// The derivative passes carry a validity flag, the minimum over their
// support: 1 valid, 0 a pinhole in it (PIXEL_HOLE: an isolated invalid
// pixel), -1 it leaves the image or touches another invalid pixel (the
// empty surroundings of an object). The
// integration passes weight each gradient by its validity (1 or 0) and
// also sum the weights, so the structure tensor is the Gaussian-weighted
// mean of the valid gradients of its window; a window leaving the image
// or touching hard invalid pixels (weight -1) stays invalid. A response is
// valid where its own pixel is valid and at least min_weight of its
// window's weight is (a pinhole then voids only the gradients that touch
// it, not every corner within the tensor's support).

// Twin: HarrisParams in src/features/gpu_data.rs.
struct HarrisParams {
    width: u32,
    height: u32,
    rd: u32,
    ri: u32,
    k: f32,
    rel_threshold: f32,
    min_response: f32,
    capacity: u32,
    refine_radius: u32,
    refine_iterations: u32,
    refine_inv_2s2: f32,
    n_corners: u32,
    max_shift: f32,
    min_weight: f32,
    max_corners: u32,
    grid_cell: u32,
    // The merge radius, squared (f32, as the host squares it).
    merge_r2: f32,
    // 1: refine the selected corners; 0: keep them at their pixel.
    refine: u32,
    // The most candidates selected here (at most SELECT_MAX).
    select_limit: u32,
    pad2: u32,
    // g_d[0..2rd+1], g'_d[0..2rd+1], g_i[0..2ri+1], packed by fours.
    weights: array<vec4<f32>, MAX_TAPS / 4u>,
}

// Twins of the structs of the same names in src/features/gpu_data.rs.
struct Candidate {
    x: u32,
    y: u32,
    score: f32,
    pad: u32,
}

struct Counters {
    max_bits: atomic<u32>,
    count: atomic<u32>,
    // The corners the selection on the GPU kept (merge_compact_scan).
    selected: atomic<u32>,
    // The corners the merge's rounds left undecided (merge_compact_scan).
    undecided: atomic<u32>,
}

// A corner being refined; status 1: refined, 0: kept at its start.
struct RefineCorner {
    x: f32,
    y: f32,
    score: f32,
    status: f32,
}

@group(0) @binding(0) var<uniform> params: HarrisParams;
// Written by the host, or by the grey pass from `rgba`.
@group(0) @binding(1) var<storage, read_write> pixels: array<Pixel>;
// deriv_h writes (I*g'_x, I*g_x, valid, 0); integrate_h writes (Sxx, Syy, Sxy, valid).
@group(0) @binding(2) var<storage, read_write> tmp: array<vec4<f32>>;
// (Ix, Iy, valid, 0): kept for the refinement.
@group(0) @binding(3) var<storage, read_write> grad: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> response: array<f32>;
@group(0) @binding(5) var<storage, read_write> counters: Counters;
@group(0) @binding(6) var<storage, read_write> candidates: array<Candidate>;
@group(0) @binding(7) var<storage, read_write> corners: array<RefineCorner>;
// RGB input packed as RGBA8 (alpha 0: outside the mask).
@group(0) @binding(8) var<storage, read> rgba: array<u32>;

fn weight(i: u32) -> f32 {
    return params.weights[i / 4u][i % 4u];
}

// True for the threads of the last workgroups that overhang the image.
fn outside(id: vec3<u32>) -> bool {
    return id.x >= params.width || id.y >= params.height;
}

// Row-major index of the thread's pixel.
fn index(id: vec3<u32>) -> u32 {
    return id.y * params.width + id.x;
}

// The filter passes (deriv_*, integrate_*) run one invocation per
// HARRIS_BLOCK consecutive pixels along the filter's direction (a row for
// *_h, a column for *_v): each loads the window of HARRIS_BLOCK + 2r
// pixels its outputs read once, into private memory, then computes every
// output from it with exactly the operations (and order) of one output per
// invocation. The thread's line (row or column), its first pixel along
// the line, and the line's length:
struct Block {
    line: u32,
    first: u32,
    length: u32,
    count: u32,
}

// None (count 0) for the threads of the last workgroups that overhang the
// image.
fn block(id: vec3<u32>, horizontal: bool) -> Block {
    let length = select(params.height, params.width, horizontal);
    let lines = select(params.width, params.height, horizontal);
    let line = select(id.x, id.y, horizontal);
    let first = select(id.y, id.x, horizontal) * HARRIS_BLOCK;
    if (line >= lines || first >= length) {
        return Block(0u, 0u, 0u, 0u);
    }
    return Block(line, first, length, min(HARRIS_BLOCK, length - first));
}

// Row-major index of the pixel at `p` along the block's line.
fn along(b: Block, p: u32, horizontal: bool) -> u32 {
    return select(p * params.width + b.line, b.line * params.width + p, horizontal);
}

// Whether the pixel `p` (signed) along the line lies in the image.
fn on_line(b: Block, p: i32) -> bool {
    return p >= 0 && p < i32(b.length);
}

// Rec. 601 luma, the same weights and order as GreyImage::from_rgb8.
@compute @workgroup_size(WORKGROUP_2D, WORKGROUP_2D)
fn grey(@builtin(global_invocation_id) id: vec3<u32>) {
    if (outside(id)) {
        return;
    }
    let i = index(id);
    let c = unpack4x8unorm(rgba[i]);
    let luma = 0.299 * c.x + 0.587 * c.y + 0.114 * c.z;
    var flags = PIXEL_VALID;
    if (c.w > 0.5) {
        flags = flags | PIXEL_ALLOWED;
    }
    pixels[i] = Pixel(luma, flags);
}

// A splatted view's colour is resolved on the GPU (3 floats a pixel, NaN
// where empty; bound as `rgba`, read as f32 bits). NaN is tested on the
// bits: WGSL need not keep NaN through arithmetic.
fn is_nan_bits(v: f32) -> bool {
    let b = bitcast<u32>(v);
    return (b & 0x7f800000u) == 0x7f800000u && (b & 0x007fffffu) != 0u;
}

// The grey level of resolved pixel j: Rec. 601 luma, NaN where any
// channel is NaN (as GreyImage::from_rgb_f32).
fn grey_at(j: u32) -> f32 {
    let c = vec3<f32>(
        bitcast<f32>(rgba[3u * j]),
        bitcast<f32>(rgba[3u * j + 1u]),
        bitcast<f32>(rgba[3u * j + 2u]),
    );
    let empty = is_nan_bits(c.x) || is_nan_bits(c.y) || is_nan_bits(c.z);
    let luma = LUMA_R * c.x + LUMA_G * c.y + LUMA_B * c.z;
    return select(luma, bitcast<f32>(0x7fc00000u), empty);
}

// The view's grey levels (into `response`, free until the integration
// passes, for Harris::detect_resolved's copy) packed as the host packs a
// GreyImage (pack_with_holes without a mask): NaN pixels invalid, and
// pinholes (an invalid pixel off the border with at least
// PINHOLE_NEIGHBOURS valid 8-neighbours) flagged PIXEL_HOLE, the
// neighbours' grey levels computed again from their colours (one pass
// where a grey pass, then a packing pass, were two dependent ones).
@compute @workgroup_size(WORKGROUP_2D, WORKGROUP_2D)
fn grey_pack_f32(@builtin(global_invocation_id) id: vec3<u32>) {
    if (outside(id)) {
        return;
    }
    let i = index(id);
    let v = grey_at(i);
    response[i] = v;
    if (!is_nan_bits(v)) {
        pixels[i] = Pixel(v, PIXEL_VALID | PIXEL_ALLOWED);
        return;
    }
    var flags = PIXEL_ALLOWED;
    let w = params.width;
    let h = params.height;
    if (id.x > 0u && id.y > 0u && id.x + 1u < w && id.y + 1u < h) {
        var n = 0u;
        for (var dy = 0u; dy < 3u; dy++) {
            for (var dx = 0u; dx < 3u; dx++) {
                let j = (id.y + dy - 1u) * w + id.x + dx - 1u;
                if ((dx != 1u || dy != 1u) && !is_nan_bits(grey_at(j))) {
                    n += 1u;
                }
            }
        }
        if (n >= PINHOLE_NEIGHBOURS) {
            flags = flags | PIXEL_HOLE;
        }
    }
    pixels[i] = Pixel(0.0, flags);
}

// The Gaussian-derivative pass along x (`horizontal`: from the pixels,
// writing (I*g'_x, I*g_x, valid, 0) to `tmp`) or along y (from deriv_h's
// output, writing (Ix, Iy, valid, 0) to `grad`). A tap off the image makes
// the output invalid (-1) and adds nothing.
fn derive(id: vec3<u32>, horizontal: bool) {
    let b = block(id, horizontal);
    if (b.count == 0u) {
        return;
    }
    let rd = i32(params.rd);
    let nd = 2u * params.rd + 1u;
    // Pixel `first + m - rd` of the line at `m`: (a, b, validity).
    var win: array<vec3<f32>, HARRIS_BLOCK + 2u * MAX_DERIV_RADIUS>;
    for (var m = 0; m < i32(HARRIS_BLOCK) + 2 * rd; m++) {
        let p = i32(b.first) + m - rd;
        if (on_line(b, p)) {
            let j = along(b, u32(p), horizontal);
            if (horizontal) {
                win[m] = pixel_sample(pixels[j]);
            } else {
                win[m] = tmp[j].xyz;
            }
        }
    }
    for (var k = 0; k < i32(HARRIS_BLOCK); k++) {
        var acc = vec3<f32>(0.0, 0.0, 1.0);
        for (var t = -rd; t <= rd; t++) {
            if (on_line(b, i32(b.first) + k + t)) {
                // g' then g along x; g then g' along y.
                let kt = u32(t + rd);
                let wa = weight(select(kt, nd + kt, horizontal));
                let wc = weight(select(nd + kt, kt, horizontal));
                deriv_tap(&acc, win[k + t + rd], wa, wc);
            } else {
                acc.z = -1.0;
            }
        }
        let a = acc.x;
        let c = acc.y;
        let ok = acc.z;
        if (u32(k) < b.count) {
            let j = along(b, b.first + u32(k), horizontal);
            if (horizontal) {
                tmp[j] = vec4<f32>(a, c, ok, 0.0);
            } else {
                grad[j] = vec4<f32>(a, c, ok, 0.0);
            }
        }
    }
}

// The Gaussian smoothing of the structure tensor along x (`horizontal`:
// from the gradients, writing (Sxx, Syy, Sxy, valid) to `tmp`) or along y
// (from integrate_h's output, then the response: `respond`).
fn integrate(id: vec3<u32>, horizontal: bool) {
    let b = block(id, horizontal);
    if (b.count == 0u) {
        return;
    }
    let ri = i32(params.ri);
    let base = 2u * (2u * params.rd + 1u);
    // Pixel `first + m - ri` of the line at `m`, as read (grad or tmp).
    var win: array<vec4<f32>, HARRIS_BLOCK + 2u * MAX_INTEGRATION_RADIUS>;
    // The largest response of the block allowed a corner (integrate_v).
    var block_max = 0.0;
    for (var m = 0; m < i32(HARRIS_BLOCK) + 2 * ri; m++) {
        let p = i32(b.first) + m - ri;
        if (on_line(b, p)) {
            let j = along(b, u32(p), horizontal);
            if (horizontal) {
                win[m] = grad[j];
            } else {
                win[m] = tmp[j];
            }
        }
    }
    for (var k = 0; k < i32(HARRIS_BLOCK); k++) {
        var sum = vec4<f32>(0.0, 0.0, 0.0, 0.0);
        var outside_image = false;
        for (var t = -ri; t <= ri; t++) {
            if (on_line(b, i32(b.first) + k + t)) {
                let g = win[k + t + ri];
                var s: vec4<f32>;
                if (horizontal) {
                    let v = select(0.0, 1.0, g.z > 0.5);
                    outside_image = outside_image || g.z < -0.5;
                    s = vec4<f32>(g.x * g.x * v, g.y * g.y * v, g.x * g.y * v, v);
                } else {
                    s = g;
                    outside_image = outside_image || s.w < 0.0;
                }
                tensor_tap(&sum, s, weight(base + u32(t + ri)));
            } else {
                outside_image = true;
            }
        }
        if (u32(k) < b.count) {
            let st = vec4<f32>(sum.x, sum.y, sum.z, select(sum.w, -1.0, outside_image));
            let j = along(b, b.first + u32(k), horizontal);
            if (horizontal) {
                tmp[j] = st;
            } else {
                block_max = max(block_max, respond(j, st));
            }
        }
    }
    // Positive floats order like their bit patterns: an integer atomicMax
    // finds the largest response for the relative threshold (one atomic a
    // block instead of one a pixel).
    if (block_max > 0.0) {
        atomicMax(&counters.max_bits, bitcast<u32>(block_max));
    }
}

// Writes the Harris response det - k trace^2 of the smoothed tensor `st`
// at pixel `i`; returns it where a corner may be reported there and it is
// positive (for the relative threshold), else 0.
fn respond(i: u32, st: vec4<f32>) -> f32 {
    let wsum = st.w;
    let px = pixels[i];
    // The taps sum to 1: a full window's weight is 1 up to rounding.
    if (!(wsum >= params.min_weight * (1.0 - 1.0e-5)) || !pixel_valid(px)) {
        response[i] = INVALID_RESPONSE;
        return 0.0;
    }
    var scale = 1.0;
    if (wsum < 1.0 - 1.0e-5) {
        scale = 1.0 / wsum;
    }
    let sxx = st.x * scale;
    let syy = st.y * scale;
    let sxy = st.z * scale;
    let tr = sxx + syy;
    let r = (sxx * syy - sxy * sxy) - params.k * (tr * tr);
    response[i] = r;
    return select(0.0, r, r > 0.0 && pixel_allowed(px));
}

@compute @workgroup_size(WORKGROUP_2D, WORKGROUP_2D)
fn deriv_h(@builtin(global_invocation_id) id: vec3<u32>) {
    derive(id, true);
}

@compute @workgroup_size(WORKGROUP_2D, WORKGROUP_2D)
fn deriv_v(@builtin(global_invocation_id) id: vec3<u32>) {
    derive(id, false);
}

@compute @workgroup_size(WORKGROUP_2D, WORKGROUP_2D)
fn integrate_h(@builtin(global_invocation_id) id: vec3<u32>) {
    integrate(id, true);
}

@compute @workgroup_size(WORKGROUP_2D, WORKGROUP_2D)
fn integrate_v(@builtin(global_invocation_id) id: vec3<u32>) {
    integrate(id, false);
}

// ---- The four filter passes in one (GPUs, radii that fit the tile) ----
// deriv_h, deriv_v, integrate_h and integrate_v for a WORKGROUP_2D-square
// tile of outputs, their intermediate lines in workgroup memory instead
// of `tmp`: one dispatch where the four passes were four dependent ones.
// Each stage computes every value the next reads (the tile and its halo,
// rd + ri rows above and below, ri columns either side), each value with
// the taps, weights and order of the pass it replaces (`derive`,
// `integrate`), so the gradients (into `grad`, for the refinement) and
// the responses are those of the four passes. Needs rd + ri <= FUSED_HALO
// and 6 * FUSED_LINES^2 * 4 bytes of workgroup memory (the host checks
// both and otherwise runs the four passes).
const FUSED_LINES: u32 = WORKGROUP_2D + 2u * FUSED_HALO;
// deriv_h's (a, c, ok) a pixel, FUSED_LINES to a row; then integrate_h's
// (Sxx, Syy | Sxy, wsum) in halves, WORKGROUP_2D to a row.
var<workgroup> fused_a: array<f32, FUSED_LINES * FUSED_LINES>;
var<workgroup> fused_c: array<f32, FUSED_LINES * FUSED_LINES>;
var<workgroup> fused_ok: array<f32, FUSED_LINES * FUSED_LINES>;
// deriv_v's (Ix, Iy, valid) a pixel, FUSED_LINES to a row.
var<workgroup> fused_gx: array<f32, FUSED_LINES * FUSED_LINES>;
var<workgroup> fused_gy: array<f32, FUSED_LINES * FUSED_LINES>;
var<workgroup> fused_gv: array<f32, FUSED_LINES * FUSED_LINES>;
var<workgroup> fused_max: atomic<u32>;

// Whether (x, y) lies in the image.
fn in_image(x: i32, y: i32) -> bool {
    return x >= 0 && y >= 0 && x < i32(params.width) && y < i32(params.height);
}

// Item k of a stage of `cols` columns whose first pixel is `first`: its
// row and column in the stage, and its pixel (x, y).
fn stage_item(k: u32, cols: u32, first: vec2<i32>) -> vec4<i32> {
    let r = i32(k / cols);
    let c = i32(k % cols);
    return vec4<i32>(r, c, first.x + c, first.y + r);
}

// One tap of the tensor's smoothing (`integrate`'s sums, in its order):
// (Sxx, Syy, Sxy, weight) += s * cw.
fn tensor_tap(sum: ptr<function, vec4<f32>>, s: vec4<f32>, cw: f32) {
    (*sum).x = (*sum).x + s.x * cw;
    (*sum).y = (*sum).y + s.y * cw;
    (*sum).z = (*sum).z + s.z * cw;
    (*sum).w = (*sum).w + s.w * cw;
}

// One tap of the derivative passes (`derive`'s sums, in its order) on a
// sample (value for a, value for c, validity): (a, c, ok) in `acc`.
fn deriv_tap(acc: ptr<function, vec3<f32>>, s: vec3<f32>, wa: f32, wc: f32) {
    (*acc).z = min((*acc).z, s.z);
    (*acc).x = (*acc).x + s.x * wa;
    (*acc).y = (*acc).y + s.y * wc;
}

// A pixel as deriv_h samples it: its value twice and its validity (1
// valid, 0 a pinhole, tolerated, -1 hard invalid, as if outside).
fn pixel_sample(px: Pixel) -> vec3<f32> {
    var v = -1.0;
    if (pixel_valid(px)) {
        v = 1.0;
    } else if (pixel_hole(px)) {
        v = 0.0;
    }
    return vec3<f32>(px.value, px.value, v);
}

@compute @workgroup_size(WORKGROUP_2D, WORKGROUP_2D)
fn maps_fused(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let w = i32(params.width);
    let h = i32(params.height);
    let rd = i32(params.rd);
    let ri = i32(params.ri);
    let nd = 2u * params.rd + 1u;
    let base = 2u * nd;
    let tile = i32(WORKGROUP_2D);
    let threads = WORKGROUP_2D * WORKGROUP_2D;
    let x0 = i32(wid.x) * tile;
    let y0 = i32(wid.y) * tile;
    let halo = rd + ri;
    // Columns of the first two stages (x0 - ri ..), rows of the first
    // (y0 - rd - ri ..) and of the next two (y0 - ri ..).
    let cols = u32(tile + 2 * ri);
    let rows1 = u32(tile + 2 * halo);
    let rows2 = cols;
    let line = i32(FUSED_LINES);

    // deriv_h (derive(.., true)), the pixel's row.
    for (var k = lid; k < rows1 * cols; k += threads) {
        let at = stage_item(k, cols, vec2<i32>(x0 - ri, y0 - halo));
        let x = at.z;
        let y = at.w;
        if (!in_image(x, y)) {
            continue;
        }
        var acc = vec3<f32>(0.0, 0.0, 1.0);
        for (var t = -rd; t <= rd; t++) {
            let p = x + t;
            if (p >= 0 && p < w) {
                let kt = u32(t + rd);
                let s = pixel_sample(pixels[u32(y * w + p)]);
                deriv_tap(&acc, s, weight(nd + kt), weight(kt));
            } else {
                acc.z = -1.0;
            }
        }
        let i = at.x * line + at.y;
        fused_a[i] = acc.x;
        fused_c[i] = acc.y;
        fused_ok[i] = acc.z;
    }
    workgroupBarrier();

    // deriv_v (derive(.., false)): the gradients, into `grad` in the tile.
    for (var k = lid; k < rows2 * cols; k += threads) {
        let at = stage_item(k, cols, vec2<i32>(x0 - ri, y0 - ri));
        let r = at.x;
        let c = at.y;
        let x = at.z;
        let y = at.w;
        if (!in_image(x, y)) {
            continue;
        }
        var acc = vec3<f32>(0.0, 0.0, 1.0);
        for (var t = -rd; t <= rd; t++) {
            let q = y + t;
            if (q >= 0 && q < h) {
                // deriv_h's row of q: q - (y0 - rd - ri).
                let j = (r + rd + t) * line + c;
                let kt = u32(t + rd);
                let s = vec3<f32>(fused_a[j], fused_c[j], fused_ok[j]);
                deriv_tap(&acc, s, weight(kt), weight(nd + kt));
            } else {
                acc.z = -1.0;
            }
        }
        let a = acc.x;
        let cc = acc.y;
        let ok = acc.z;
        let i = r * line + c;
        fused_gx[i] = a;
        fused_gy[i] = cc;
        fused_gv[i] = ok;
        if (r >= ri && r < ri + tile && c >= ri && c < ri + tile) {
            grad[u32(y * w + x)] = vec4<f32>(a, cc, ok, 0.0);
        }
    }
    workgroupBarrier();

    // integrate_h (integrate(.., true)), the tile's columns only; into
    // the first stage's memory (no longer read).
    let half = FUSED_LINES * FUSED_LINES / 2u;
    for (var k = lid; k < rows2 * WORKGROUP_2D; k += threads) {
        let at = stage_item(k, WORKGROUP_2D, vec2<i32>(x0, y0 - ri));
        let r = at.x;
        let c = at.y;
        let x = at.z;
        if (!in_image(x, at.w)) {
            continue;
        }
        var sum = vec4<f32>(0.0, 0.0, 0.0, 0.0);
        var outside_image = false;
        for (var t = -ri; t <= ri; t++) {
            let p = x + t;
            if (p >= 0 && p < w) {
                // deriv_v's column of p: p - (x0 - ri).
                let j = r * line + c + ri + t;
                let gx = fused_gx[j];
                let gy = fused_gy[j];
                let gz = fused_gv[j];
                let v = select(0.0, 1.0, gz > 0.5);
                outside_image = outside_image || gz < -0.5;
                let s = vec4<f32>(gx * gx * v, gy * gy * v, gx * gy * v, v);
                tensor_tap(&sum, s, weight(base + u32(t + ri)));
            } else {
                outside_image = true;
            }
        }
        let i = u32(r) * WORKGROUP_2D + u32(c);
        fused_a[i] = sum.x;
        fused_a[half + i] = sum.y;
        fused_c[i] = sum.z;
        fused_c[half + i] = select(sum.w, -1.0, outside_image);
    }
    workgroupBarrier();

    // integrate_v (integrate(.., false)) and the response: a pixel a
    // thread; the tile's largest response allowed a corner, then one
    // global atomic a tile.
    if (lid == 0u) {
        atomicStore(&fused_max, 0u);
    }
    workgroupBarrier();
    let best = fused_response(x0, y0, i32(lid % WORKGROUP_2D), i32(lid / WORKGROUP_2D));
    if (best > 0.0) {
        atomicMax(&fused_max, bitcast<u32>(best));
    }
    workgroupBarrier();
    if (lid == 0u) {
        let m = atomicLoad(&fused_max);
        if (m != 0u) {
            atomicMax(&counters.max_bits, m);
        }
    }
}

// The response at the tile's pixel (c, r) from integrate_h's lines in
// workgroup memory (`respond`'s return: 0 where no corner may be).
fn fused_response(x0: i32, y0: i32, c: i32, r: i32) -> f32 {
    let h = i32(params.height);
    let ri = i32(params.ri);
    let base = 2u * (2u * params.rd + 1u);
    let half = FUSED_LINES * FUSED_LINES / 2u;
    let x = x0 + c;
    let y = y0 + r;
    if (!in_image(x, y)) {
        return 0.0;
    }
    var sum = vec4<f32>(0.0, 0.0, 0.0, 0.0);
    var outside_image = false;
    for (var t = -ri; t <= ri; t++) {
        let q = y + t;
        if (q >= 0 && q < h) {
            // integrate_h's row of q: q - (y0 - ri).
            let i = u32(r + ri + t) * WORKGROUP_2D + u32(c);
            let s = vec4<f32>(fused_a[i], fused_a[half + i], fused_c[i], fused_c[half + i]);
            outside_image = outside_image || s.w < 0.0;
            tensor_tap(&sum, s, weight(base + u32(t + ri)));
        } else {
            outside_image = true;
        }
    }
    let st = vec4<f32>(sum.x, sum.y, sum.z, select(sum.w, -1.0, outside_image));
    return respond(u32(y * i32(params.width) + x), st);
}

@compute @workgroup_size(WORKGROUP_2D, WORKGROUP_2D)
fn nms(@builtin(global_invocation_id) id: vec3<u32>) {
    if (outside(id)) {
        return;
    }
    let w = params.width;
    let h = params.height;
    let i = index(id);
    let r = response[i];
    if (r <= INVALID_RESPONSE || !pixel_allowed(pixels[i])) {
        return;
    }
    let max_r = bitcast<f32>(atomicLoad(&counters.max_bits));
    let threshold = max(params.rel_threshold * max_r, params.min_response);
    if (!(r > 0.0 && r >= threshold)) {
        return;
    }
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let x = i32(id.x) + dx;
            let y = i32(id.y) + dy;
            if ((dx == 0 && dy == 0) || x < 0 || y < 0 || x >= i32(w) || y >= i32(h)) {
                continue;
            }
            let j = u32(y) * w + u32(x);
            let rn = response[j];
            // Strict maximum; equal neighbours: the lower raster index wins,
            // so a plateau yields one maximum, never two adjacent ones.
            if (rn > r || (rn == r && j < i)) {
                return;
            }
        }
    }
    let slot = atomicAdd(&counters.count, 1u);
    if (slot < params.capacity) {
        candidates[slot] = Candidate(id.x, id.y, r, 0u);
    }
}

// Gradient-orthogonality refinement (the principle of OpenCV's
// cornerSubPix): at the true corner q, every gradient g(p) of the window is
// orthogonal to p - q, so q solves sum w g g^T (p - q) = 0 in least squares.
// The window is re-centred on the estimate and the solve repeated.
// A corner from `start`, with its score carried along.
fn refined(start: vec2<f32>, score: f32) -> RefineCorner {
    var q = start;
    var status = 0.0;
    let rw = i32(params.refine_radius);
    let w = i32(params.width);
    let h = i32(params.height);
    for (var it = 0u; it < params.refine_iterations; it++) {
        let cx = i32(floor(q.x + 0.5));
        let cy = i32(floor(q.y + 0.5));
        var a11 = 0.0;
        var a12 = 0.0;
        var a22 = 0.0;
        var b1 = 0.0;
        var b2 = 0.0;
        for (var dy = -rw; dy <= rw; dy++) {
            for (var dx = -rw; dx <= rw; dx++) {
                let px = cx + dx;
                let py = cy + dy;
                if (px < 0 || py < 0 || px >= w || py >= h) {
                    continue;
                }
                let g = grad[u32(py) * u32(w) + u32(px)];
                if (g.z < 0.5) {
                    continue;
                }
                let ox = f32(px) - q.x;
                let oy = f32(py) - q.y;
                let wt = exp(-(ox * ox + oy * oy) * params.refine_inv_2s2);
                let gxx = wt * g.x * g.x;
                let gxy = wt * g.x * g.y;
                let gyy = wt * g.y * g.y;
                a11 = a11 + gxx;
                a12 = a12 + gxy;
                a22 = a22 + gyy;
                b1 = b1 + (gxx * f32(dx) + gxy * f32(dy));
                b2 = b2 + (gxy * f32(dx) + gyy * f32(dy));
            }
        }
        let det = a11 * a22 - a12 * a12;
        let tr = a11 + a22;
        // An edge or flat window constrains q along one direction only.
        if (!(tr > 0.0) || !(det > 1.0e-4 * tr * tr)) {
            q = start;
            status = 0.0;
            break;
        }
        let qn = vec2<f32>(
            f32(cx) + (a22 * b1 - a12 * b2) / det,
            f32(cy) + (a11 * b2 - a12 * b1) / det,
        );
        let moved = qn - start;
        if (!(dot(moved, moved) <= params.max_shift * params.max_shift)) {
            q = start;
            status = 0.0;
            break;
        }
        let step = qn - q;
        q = qn;
        status = 1.0;
        if (dot(step, step) < 1.0e-4) {
            break;
        }
    }
    return RefineCorner(q.x, q.y, score, status);
}

// The selected corners the host wrote into `corners`, refined in place.
@compute @workgroup_size(WORKGROUP_1D)
fn refine(@builtin(global_invocation_id) id: vec3<u32>) {
    let n = id.x;
    if (n >= params.n_corners) {
        return;
    }
    let c = corners[n];
    corners[n] = refined(vec2<f32>(c.x, c.y), c.score);
}
