// The pose check's scores on the GPU (the check of
// the resident loop): the splatted view's weight and colour (resolved by the
// splatter into buffers that never leave the GPU) against the frame's grey
// levels over the same window, reduced to CHECK_SUMS floats. CPU
// reference: `verify::score` in src/tracker/verify.rs (the same rules:
// inner pixels for the ZNCC, contour pixels and the edge search along the
// silhouette's normal for the edge support).
//
// `rows`: one thread per image row writes the row's sums; `sum_rows`:
// one thread per sum adds the rows. The grey levels are summed less `centre` (ZNCC is blind to an
// offset) so that the f32 sums of squares keep the variance.
//
// The sums, in this order: covered pixels, ZNCC pairs n, sum a, sum b,
// sum aa, sum bb, sum ab (a: the view's grey, b: the frame's), contour
// pixels, supported contour pixels, then the texture's pixels (covered,
// with the four pixels `texture_step` away covered) and the sum over them of
// the view grey's squared Laplacian at that step.

// Twin: `CheckParams` in src/tracker/verify_gpu.rs.
struct CheckParams {
    width: u32,
    height: u32,
    // VerifyConfig::edge_search_px.
    search: u32,
    // VerifyConfig::edge_gradient.
    gradient: f32,
    centre: f32,
    // verify::texture_step of the object's projected size.
    texture_step: u32,
    // VerifyConfig::edge_contrast.
    contrast: f32,
    // VerifyConfig::edge_band_px.
    band: u32,
}

@group(0) @binding(0) var<uniform> params: CheckParams;
@group(0) @binding(1) var<storage, read> weight: array<f32>;
@group(0) @binding(2) var<storage, read> colour: array<f32>;
@group(0) @binding(3) var<storage, read> frame: array<f32>;
@group(0) @binding(4) var<storage, read_write> partial: array<f32>;
@group(0) @binding(5) var<storage, read_write> total: array<f32>;

// NaN is tested on the bits: WGSL need not keep NaN through comparisons.
fn is_nan_bits(v: f32) -> bool {
    let b = bitcast<u32>(v);
    return (b & 0x7f800000u) == 0x7f800000u && (b & 0x007fffffu) != 0u;
}

fn covered(x: u32, y: u32) -> bool {
    let w = weight[y * params.width + x];
    return !is_nan_bits(w) && w > 0.0;
}

fn mask(x: u32, y: u32) -> f32 {
    return select(0.0, 1.0, covered(x, y));
}

fn view_grey(i: u32) -> f32 {
    return LUMA_R * colour[3u * i] + LUMA_G * colour[3u * i + 1u] + LUMA_B * colour[3u * i + 2u];
}

fn px(x: u32, y: u32) -> f32 {
    return frame[y * params.width + x];
}

// Sobel / 8 of the frame at (x, y), 1 <= x < width - 1, 1 <= y < height - 1.
fn frame_sobel(x: u32, y: u32) -> vec2<f32> {
    let gx = (px(x + 1u, y - 1u) + 2.0 * px(x + 1u, y) + px(x + 1u, y + 1u))
        - (px(x - 1u, y - 1u) + 2.0 * px(x - 1u, y) + px(x - 1u, y + 1u));
    let gy = (px(x - 1u, y + 1u) + 2.0 * px(x, y + 1u) + px(x + 1u, y + 1u))
        - (px(x - 1u, y - 1u) + 2.0 * px(x, y - 1u) + px(x + 1u, y - 1u));
    return vec2<f32>(gx, gy) / 8.0;
}

fn mask_sobel(x: u32, y: u32) -> vec2<f32> {
    let gx = (mask(x + 1u, y - 1u) + 2.0 * mask(x + 1u, y) + mask(x + 1u, y + 1u))
        - (mask(x - 1u, y - 1u) + 2.0 * mask(x - 1u, y) + mask(x - 1u, y + 1u));
    let gy = (mask(x - 1u, y + 1u) + 2.0 * mask(x, y + 1u) + mask(x + 1u, y + 1u))
        - (mask(x - 1u, y - 1u) + 2.0 * mask(x, y - 1u) + mask(x + 1u, y - 1u));
    return vec2<f32>(gx, gy) / 8.0;
}

// The frame's gradient along the unit normal n at `s` whole pixels along
// it from (x, y), rounded to the nearest pixel; negative where outside
// the image (the sample `verify::edge_support` leaves out).
fn along(x: u32, y: u32, n: vec2<f32>, s: i32) -> f32 {
    // Rounding half away from zero, as Rust's f64::round, for the values
    // that can pass the bounds below.
    let q = floor(vec2<f32>(f32(x), f32(y)) + f32(s) * n + 0.5);
    if q.x < 1.0 || q.y < 1.0 || q.x >= f32(params.width) - 1.0
        || q.y >= f32(params.height) - 1.0 {
        return -1.0;
    }
    let g = frame_sobel(u32(q.x), u32(q.y));
    return abs(g.x * n.x + g.y * n.y);
}

// The mean gradient along n from search + 2 to band pixels on the side
// `sign`, negative where no sample is in the image.
fn side_level(x: u32, y: u32, n: vec2<f32>, sign: i32) -> f32 {
    var count = 0.0;
    var sum = 0.0;
    for (var s = i32(params.search) + 2; s <= i32(params.band); s++) {
        let g = along(x, y, n, sign * s);
        if g >= 0.0 {
            count += 1.0;
            sum += g;
        }
    }
    return select(-1.0, sum / max(count, 1.0), count > 0.0);
}

// Whether a contour pixel (x, y) with unit normal n is on a frame edge (the
// rule of `verify::edge_hit`): the peak within `search` pixels at least
// `gradient` and `contrast` times the quieter side's level beyond.
fn supported(x: u32, y: u32, n: vec2<f32>) -> bool {
    let r = i32(params.search);
    var peak = 0.0;
    for (var s = -r; s <= r; s++) {
        peak = max(peak, along(x, y, n, s));
    }
    if peak < params.gradient {
        return false;
    }
    let a = side_level(x, y, n, -1);
    let b = side_level(x, y, n, 1);
    var level = 0.0;
    if a >= 0.0 && b >= 0.0 {
        level = min(a, b);
    } else {
        level = max(max(a, b), 0.0);
    }
    return peak >= params.contrast * level;
}

// A pixel's share of the sums (CHECK_SUMS of them, in the order above).
struct Sums {
    covered_px: f32,
    n: f32,
    sa: f32,
    sb: f32,
    saa: f32,
    sbb: f32,
    sab: f32,
    contour: f32,
    hits: f32,
    texture_px: f32,
    lap2: f32,
}

fn no_sums() -> Sums {
    return Sums(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
}

fn plus(a: Sums, b: Sums) -> Sums {
    return Sums(
        a.covered_px + b.covered_px,
        a.n + b.n,
        a.sa + b.sa,
        a.sb + b.sb,
        a.saa + b.saa,
        a.sbb + b.sbb,
        a.sab + b.sab,
        a.contour + b.contour,
        a.hits + b.hits,
        a.texture_px + b.texture_px,
        a.lap2 + b.lap2,
    );
}

// Adds pixel (x, y)'s share into `s` (`verify::score`'s rules).
fn add_pixel(x: u32, y: u32, s: ptr<function, Sums>) {
    let w = params.width;
    let h = params.height;
    let d = max(params.texture_step, 1u);
    if !covered(x, y) {
        return;
    }
    (*s).covered_px += 1.0;
    if x == 0u || y == 0u || x + 1u >= w || y + 1u >= h {
        return;
    }
    let four = covered(x - 1u, y) && covered(x + 1u, y) && covered(x, y - 1u)
        && covered(x, y + 1u);
    if four {
        let i = y * w + x;
        let a = view_grey(i) - params.centre;
        let b = frame[i] - params.centre;
        (*s).n += 1.0;
        (*s).sa += a;
        (*s).sb += b;
        (*s).saa += a * a;
        (*s).sbb += b * b;
        (*s).sab += a * b;
        if x >= d && y >= d && x + d < w && y + d < h && covered(x - d, y)
            && covered(x + d, y) && covered(x, y - d) && covered(x, y + d) {
            let lap = 4.0 * view_grey(i) - (view_grey(i - d) + view_grey(i + d)
                + view_grey(i - d * w) + view_grey(i + d * w));
            (*s).texture_px += 1.0;
            (*s).lap2 += lap * lap;
        }
        return;
    }
    let m = mask_sobel(x, y);
    let norm = length(m);
    if norm < 1e-9 {
        return;
    }
    (*s).contour += 1.0;
    (*s).hits += select(0.0, 1.0, supported(x, y, m / norm));
}

fn write_partial(o: u32, s: Sums) {
    partial[o] = s.covered_px;
    partial[o + 1u] = s.n;
    partial[o + 2u] = s.sa;
    partial[o + 3u] = s.sb;
    partial[o + 4u] = s.saa;
    partial[o + 5u] = s.sbb;
    partial[o + 6u] = s.sab;
    partial[o + 7u] = s.contour;
    partial[o + 8u] = s.hits;
    partial[o + 9u] = s.texture_px;
    partial[o + 10u] = s.lap2;
}

// One thread per row: scalar sums and no barrier (barriers and arrays
// indexed at run time are slow on CPU adapters). The CPU adapters'
// kernel: on the H200 a thread a row took 0.27 ms of the real cube's
// frame (a few hundred threads each walking a whole row), see rows_tiled.
@compute @workgroup_size(CHECK_WORKGROUP)
fn rows(@builtin(global_invocation_id) id: vec3<u32>) {
    let y = id.x;
    if y >= params.height {
        return;
    }
    var s = no_sums();
    for (var x = 0u; x < params.width; x++) {
        add_pixel(x, y, &s);
    }
    write_partial(y * CHECK_SUMS, s);
}

// One thread per sum, over the rows.
@compute @workgroup_size(CHECK_SUMS)
fn sum_rows(@builtin(local_invocation_index) k: u32) {
    var s = 0.0;
    for (var y = 0u; y < params.height; y++) {
        s += partial[y * CHECK_SUMS + k];
    }
    total[k] = s;
}

// The GPUs' twins of rows and sum_rows: a workgroup a row, its threads
// taking every CHECK_WORKGROUP-th pixel (neighbours load neighbours),
// their sums added pairwise in workgroup memory; then a workgroup a sum,
// likewise over the rows. Another order of the f32 additions than the
// one-thread-a-row passes (both within the test's tolerance of the CPU
// reference, which sums in f64); the counts are exact in both.
var<workgroup> wg_sums: array<Sums, CHECK_WORKGROUP>;
var<workgroup> wg_one: array<f32, CHECK_WORKGROUP>;

@compute @workgroup_size(CHECK_WORKGROUP)
fn rows_tiled(@builtin(local_invocation_index) t: u32, @builtin(workgroup_id) wid: vec3<u32>) {
    let y = wid.x;
    var s = no_sums();
    if y < params.height {
        for (var x = t; x < params.width; x += CHECK_WORKGROUP) {
            add_pixel(x, y, &s);
        }
    }
    wg_sums[t] = s;
    workgroupBarrier();
    for (var half = CHECK_WORKGROUP / 2u; half > 0u; half /= 2u) {
        if t < half {
            wg_sums[t] = plus(wg_sums[t], wg_sums[t + half]);
        }
        workgroupBarrier();
    }
    if t == 0u && y < params.height {
        write_partial(y * CHECK_SUMS, wg_sums[0]);
    }
}

@compute @workgroup_size(CHECK_WORKGROUP)
fn sum_rows_tiled(@builtin(local_invocation_index) t: u32, @builtin(workgroup_id) wid: vec3<u32>) {
    let k = wid.x;
    var s = 0.0;
    for (var y = t; y < params.height; y += CHECK_WORKGROUP) {
        s += partial[y * CHECK_SUMS + k];
    }
    wg_one[t] = s;
    workgroupBarrier();
    for (var half = CHECK_WORKGROUP / 2u; half > 0u; half /= 2u) {
        if t < half {
            wg_one[t] = wg_one[t] + wg_one[t + half];
        }
        workgroupBarrier();
    }
    if t == 0u {
        total[k] = wg_one[0];
    }
}
