// NCC matching with a mutual cross-check (Dehais et al. 2010, section 4.2).
// Host code and the CPU reference: src/features/ncc.rs, src/features/ncc_cpu.rs.
// Composed after the prelude and pixel.wgsl (src/shaders.rs): the
// constants (NO_SCORE, NO_INDEX, NCC_TILE, PIXEL_VALID, workgroup sizes)
// and `Pixel` come from there.
//
// vectorize: one thread per feature of A then B; samples the w x w window
//   bilinearly at the feature's sub-pixel position into one row of the
//   (na + nb) x stride descriptor buffer (the paper's n x w^2 layout, rows
//   zero-padded to a multiple of NCC_TILE), zero-mean and unit-norm. The
//   raw samples go to a second block of the same shape (INVALID_SAMPLE
//   where a sample touches an invalid pixel). ok: 0 no match (the window
//   leaves the image, has fewer than min_valid of its samples valid, or is
//   flat), 1 every sample valid, 2 some invalid.
// Pairs of windows with ok 1 score the dot product of their unit rows;
//   pairs where one has holes score the NCC over the samples valid in
//   both (their common set), from the raw rows, when that set holds at
//   least min_valid of the window and is textured in both.
// score_tiled / score_direct: S = A B^T, as a tiled matrix product
//   (NCC_TILE x NCC_TILE tiles in workgroup memory, for GPUs) or one thread per entry reading
//   the rows directly (for CPU adapters such as lavapipe, where workgroup
//   barriers are expensive: 0.55 s against ~0.02 s for 900 x 900; it visits
//   B's features in a host-given spatial order and skips the dot products
//   of pairs that get no score). Same sum in the same order either way.
//   Pairs with an invalid window or beyond the search radius get NO_SCORE.
// bests: one workgroup per row, then per column, reduces to the best
//   score (ties: the lower index), rows and columns in one dispatch; with
//   score_direct, bests_direct scans a row or column per thread. The host
//   keeps mutual bests.
// mutual_refine (the resident path, NccMatcher::match_resident): one
//   workgroup per feature of A keeps its row's best when it is mutual and
//   scores at least min_score, and (refine_on) moves B's point to the
//   sub-pixel NCC peak as features::refine_match does on the host (CPU
//   reference): the best integer shift within max_shift, then two
//   parabola fits, windows of 2 refine_half + 1 sampled strictly (any
//   invalid pixel voids a window). Only these rows come back.

// Twin: NccParams in src/features/gpu_data.rs.
struct NccParams {
    na: u32,
    nb: u32,
    stride: u32,
    window: u32,
    wa: u32,
    ha: u32,
    wb: u32,
    hb: u32,
    offset_b: u32,
    radius2: f32,
    min_std: f32,
    min_valid: f32,
    min_score: f32,
    refine_on: u32,
    refine_half: u32,
    max_shift: u32,
    refine_min: f32,
    shift_bx: f32,
    shift_by: f32,
    // 1: B's features are in their own order (exported, no spatial order
    // uploaded after the window flags).
    b_in_order: u32,
}

// A raw sample that touches an invalid pixel (grey values are in 0..1).
const INVALID_SAMPLE: f32 = -1.0e30;

fn is_valid_sample(v: f32) -> bool {
    return v > -1.0e29;
}

// Twin: Best in src/features/gpu_data.rs.
struct Best {
    index: u32,
    score: f32,
}

// A storage buffer, not a uniform: lavapipe (Mesa 22.3) inlines uniform
// values that steer control flow and recompiles the shader on every dispatch
// (about 0.2 s and 0.25 MB of JIT memory never freed each time).
@group(0) @binding(0) var<storage, read> params: NccParams;
// Image A's pixels, then image B's from offset_b.
@group(0) @binding(1) var<storage, read> pixels: array<Pixel>;
// Feature positions of A, then of B.
@group(0) @binding(2) var<storage, read> positions: array<vec2<f32>>;
// Rows of `stride` floats (a multiple of NCC_TILE), read and written as vec4.
@group(0) @binding(3) var<storage, read_write> desc: array<vec4<f32>>;

fn desc_get(i: u32) -> f32 {
    return desc[i / 4u][i % 4u];
}

fn desc_set(i: u32, v: f32) {
    desc[i / 4u][i % 4u] = v;
}
// The windows' flags (vectorize: A's, then B's), then B's features in
// the host's spatial order (score_direct).
@group(0) @binding(4) var<storage, read_write> ok: array<u32>;
@group(0) @binding(5) var<storage, read_write> scores: array<f32>;
// Best per row of S (na entries), then per column (nb entries).
@group(0) @binding(6) var<storage, read_write> best: array<Best>;

// Twin: MatchOut in src/features/gpu_data.rs.
struct MatchOut {
    b: u32,
    score: f32,
    x: f32,
    y: f32,
    peak: f32,
    refined: u32,
}

// One per feature of A (mutual_refine).
@group(0) @binding(7) var<storage, read_write> matched: array<MatchOut>;

// Bilinear sample (value, 1) at (x, y); (0, 0) if one of the four pixels
// is a pinhole (PIXEL_HOLE) and the others valid; (0, -1) if (x, y) is
// outside the image or one of the four is another invalid pixel (the
// window is then void). Mirrors GreyImage::bilinear.
fn sample(offset: u32, w: u32, h: u32, x: f32, y: f32) -> vec2<f32> {
    return sample_with(offset, w, h, x, y, false);
}

// `sample`, or with `strict` `sample_strict`: a pinhole voids the sample
// as any invalid pixel does.
fn sample_with(offset: u32, w: u32, h: u32, x: f32, y: f32, strict: bool) -> vec2<f32> {
    if (w < 2u || h < 2u || !(x >= 0.0 && y >= 0.0) || x > f32(w - 1u) || y > f32(h - 1u)) {
        return vec2<f32>(0.0, -1.0);
    }
    let x0 = min(u32(floor(x)), w - 2u);
    let y0 = min(u32(floor(y)), h - 2u);
    let fx = x - f32(x0);
    let fy = y - f32(y0);
    let i = offset + y0 * w + x0;
    let p00 = pixels[i];
    let p10 = pixels[i + 1u];
    let p01 = pixels[i + w];
    let p11 = pixels[i + w + 1u];
    if (!(pixel_valid(p00) && pixel_valid(p10) && pixel_valid(p01) && pixel_valid(p11))) {
        let hard = !(pixel_valid(p00) || pixel_hole(p00)) || !(pixel_valid(p10) || pixel_hole(p10))
            || !(pixel_valid(p01) || pixel_hole(p01)) || !(pixel_valid(p11) || pixel_hole(p11));
        return vec2<f32>(0.0, select(0.0, -1.0, hard || strict));
    }
    let top = p00.value + fx * (p10.value - p00.value);
    let bottom = p01.value + fx * (p11.value - p01.value);
    return vec2<f32>(top + fy * (bottom - top), 1.0);
}

// Offset of the raw block of the descriptor buffer.
fn raw_base() -> u32 {
    return (params.na + params.nb) * params.stride;
}

// The smallest number of valid samples a window (or a pair's common set)
// of d samples needs.
fn min_count(d: u32) -> u32 {
    return u32(ceil(params.min_valid * f32(d)));
}

@compute @workgroup_size(WORKGROUP_1D)
fn vectorize(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = id.x;
    if (t >= params.na + params.nb) {
        return;
    }
    var offset = 0u;
    var w = params.wa;
    var h = params.ha;
    if (t >= params.na) {
        offset = params.offset_b;
        w = params.wb;
        h = params.hb;
    }
    let p = positions[t];
    let win = params.window;
    let half = f32(win / 2u);
    let d = win * win;
    let row = t * params.stride;
    let raw = raw_base() + row;
    var inside = true;
    var n = 0u;
    var sum = 0.0;
    for (var k = 0u; k < d; k++) {
        let u = f32(k % win) - half;
        let v = f32(k / win) - half;
        let s = sample(offset, w, h, p.x + u, p.y + v);
        if (s.y < -0.5) {
            inside = false;
            break;
        }
        if (s.y > 0.5) {
            desc_set(raw + k, s.x);
            sum = sum + s.x;
            n = n + 1u;
        } else {
            desc_set(raw + k, INVALID_SAMPLE);
        }
    }
    var state = 0u;
    if (inside && n >= min_count(d) && n > 0u) {
        let mean = sum / f32(n);
        var ss = 0.0;
        for (var k = 0u; k < d; k++) {
            let r = desc_get(raw + k);
            if (is_valid_sample(r)) {
                let c = r - mean;
                ss = ss + c * c;
            }
        }
        // Flat windows correlate noise with noise: no match.
        if (sqrt(ss / f32(n)) >= params.min_std) {
            state = select(2u, 1u, n == d);
        }
        if (state == 1u) {
            let inv = 1.0 / sqrt(ss);
            for (var k = 0u; k < d; k++) {
                desc_set(row + k, (desc_get(raw + k) - mean) * inv);
            }
        }
    }
    if (state != 1u) {
        for (var k = 0u; k < d; k++) {
            desc_set(row + k, 0.0);
        }
    }
    if (!inside) {
        for (var k = 0u; k < d; k++) {
            desc_set(raw + k, INVALID_SAMPLE);
        }
    }
    for (var k = d; k < params.stride; k++) {
        desc_set(row + k, 0.0);
        desc_set(raw + k, INVALID_SAMPLE);
    }
    ok[t] = state;
}

// vectorize a workgroup a window (GPUs, windows of at most
// VECTORIZE_GROUP_WINDOW, from the prelude): the samples taken by all the workgroup's
// threads at once into workgroup memory, the mean and the sum of squares
// by one thread in vectorize's order, then the rows written in parallel:
// vectorize's descriptors bit for bit. (A thread a window walks its
// samples through dependent loads: 0.25 ms for 1800 windows on the H200.)
var<workgroup> vz_value: array<f32, VECTORIZE_GROUP_WINDOW * VECTORIZE_GROUP_WINDOW>;
// 1: valid, 0: a pinhole, -1: outside or another invalid pixel.
var<workgroup> vz_flag: array<f32, VECTORIZE_GROUP_WINDOW * VECTORIZE_GROUP_WINDOW>;
// (mean, 1 / norm, state, inside).
var<workgroup> vz_stats: vec4<f32>;

@compute @workgroup_size(WORKGROUP_1D)
fn vectorize_group(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let win = params.window;
    let half = f32(win / 2u);
    let d = win * win;
    for (var t = wid.x; t < params.na + params.nb; t += groups.x) {
        var offset = 0u;
        var w = params.wa;
        var h = params.ha;
        if (t >= params.na) {
            offset = params.offset_b;
            w = params.wb;
            h = params.hb;
        }
        let p = positions[t];
        for (var k = lid; k < d; k += WORKGROUP_1D) {
            let u = f32(k % win) - half;
            let v = f32(k / win) - half;
            let s = sample(offset, w, h, p.x + u, p.y + v);
            vz_value[k] = s.x;
            vz_flag[k] = s.y;
        }
        workgroupBarrier();
        if (lid == 0u) {
            var inside = true;
            var n = 0u;
            var sum = 0.0;
            for (var k = 0u; k < d; k++) {
                let f = vz_flag[k];
                if (f < -0.5) {
                    inside = false;
                    break;
                }
                if (f > 0.5) {
                    sum = sum + vz_value[k];
                    n = n + 1u;
                }
            }
            var state = 0u;
            var mean = 0.0;
            var inv = 0.0;
            if (inside && n >= min_count(d) && n > 0u) {
                mean = sum / f32(n);
                var ss = 0.0;
                for (var k = 0u; k < d; k++) {
                    if (vz_flag[k] > 0.5) {
                        let c = vz_value[k] - mean;
                        ss = ss + c * c;
                    }
                }
                if (sqrt(ss / f32(n)) >= params.min_std) {
                    state = select(2u, 1u, n == d);
                }
                if (state == 1u) {
                    inv = 1.0 / sqrt(ss);
                }
            }
            vz_stats = vec4<f32>(mean, inv, f32(state), select(0.0, 1.0, inside));
            ok[t] = state;
        }
        workgroupBarrier();
        let st = vz_stats;
        let row = t * params.stride;
        let raw = raw_base() + row;
        for (var k = lid; k < params.stride; k += WORKGROUP_1D) {
            var r = INVALID_SAMPLE;
            var o = 0.0;
            if (k < d && st.w > 0.5 && vz_flag[k] > 0.5) {
                r = vz_value[k];
                if (st.z == 1.0) {
                    o = (r - st.x) * st.y;
                }
            }
            desc_set(raw + k, r);
            desc_set(row + k, o);
        }
        workgroupBarrier();
    }
}

// The NCC of the raw windows of A's feature i and B's feature j over the
// samples valid in both; NO_SCORE when that common set holds fewer than
// min_valid of the window or is flat in either. Two passes (means, then
// centred sums), in sample order, as the CPU reference.
fn partial_score(i: u32, j: u32) -> f32 {
    let d = params.window * params.window;
    let ra = raw_base() + i * params.stride;
    let rb = raw_base() + (params.na + j) * params.stride;
    var n = 0u;
    var sa = 0.0;
    var sb = 0.0;
    for (var k = 0u; k < d; k++) {
        let a = desc_get(ra + k);
        let b = desc_get(rb + k);
        if (is_valid_sample(a) && is_valid_sample(b)) {
            n = n + 1u;
            sa = sa + a;
            sb = sb + b;
        }
    }
    if (n < min_count(d) || n == 0u) {
        return NO_SCORE;
    }
    let ma = sa / f32(n);
    let mb = sb / f32(n);
    var caa = 0.0;
    var cbb = 0.0;
    var cab = 0.0;
    for (var k = 0u; k < d; k++) {
        let a = desc_get(ra + k);
        let b = desc_get(rb + k);
        if (is_valid_sample(a) && is_valid_sample(b)) {
            let x = a - ma;
            let y = b - mb;
            caa = caa + x * x;
            cbb = cbb + y * y;
            cab = cab + x * y;
        }
    }
    let nf = f32(n);
    if (!(sqrt(caa / nf) >= params.min_std && sqrt(cbb / nf) >= params.min_std)) {
        return NO_SCORE;
    }
    return cab / sqrt(caa * cbb);
}

// Rows padded by one: score_tiled reads tile_b down a column across its
// threads (tile_b[lid.x][kk]), which unpadded would fall in one or two
// memory banks.
var<workgroup> tile_a: array<array<f32, NCC_TILE + 1u>, NCC_TILE>;
var<workgroup> tile_b: array<array<f32, NCC_TILE + 1u>, NCC_TILE>;

// The entry (i, j) of S from the dot product `acc`: NO_SCORE for an
// invalid window or a pair beyond the search radius; the NCC over the
// common valid samples where a window has holes.
fn finish_score(i: u32, j: u32, acc: f32) {
    var s = acc;
    if (!pair_live(i, j)) {
        s = NO_SCORE;
    } else if (ok[i] == 2u || ok[params.na + j] == 2u) {
        s = partial_score(i, j);
    }
    scores[i * params.nb + j] = s;
}

// Whether the pair (i, j) gets a score at all: both windows usable and B's
// feature within the search radius.
fn pair_live(i: u32, j: u32) -> bool {
    let na = params.na;
    var near = true;
    if (params.radius2 >= 0.0) {
        // B's positions in A's pixels: shifted by an integer (exact).
        let dp = positions[na + j] + vec2<f32>(params.shift_bx, params.shift_by) - positions[i];
        near = dp.x * dp.x + dp.y * dp.y <= params.radius2;
    }
    return ok[i] != 0u && ok[na + j] != 0u && near;
}

// B's feature at place q of the host's spatial order (after the na + nb
// window flags in `ok`: B's features by bands of rows, then by x), or of
// their own order (`b_in_order`).
fn b_at(q: u32) -> u32 {
    let k = min(q, params.nb - 1u);
    if (params.b_in_order != 0u) {
        return k;
    }
    return ok[params.na + params.nb + k];
}

// One thread per row of A and four B features, consecutive in the host's
// spatial order: the A row is loaded once for four dot products, and the
// threads of a SIMD group (a CPU adapter's vector lanes) hold nearby B
// features, so that together they skip the dot products of pairs beyond
// the search radius (on lavapipe most pairs are). Scores land at their
// features' own indices.
@compute @workgroup_size(NCC_TILE, NCC_TILE)
fn score_direct(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.y;
    let q0 = id.x * 4u;
    let na = params.na;
    let nb = params.nb;
    if (i >= na || q0 >= nb) {
        return;
    }
    // Places past the end of B repeat the last feature and are not written.
    let js = vec4<u32>(b_at(q0), b_at(q0 + 1u), b_at(q0 + 2u), b_at(q0 + 3u));
    var live = false;
    for (var m = 0u; m < 4u; m++) {
        live = live || (q0 + m < nb && pair_live(i, js[m]));
    }
    if (!live) {
        for (var m = 0u; m < 4u; m++) {
            if (q0 + m < nb) {
                scores[i * nb + js[m]] = NO_SCORE;
            }
        }
        return;
    }
    let s4 = params.stride / 4u;
    let ra = i * s4;
    let rb0 = (na + js[0]) * s4;
    let rb1 = (na + js[1]) * s4;
    let rb2 = (na + js[2]) * s4;
    let rb3 = (na + js[3]) * s4;
    var acc = vec4<f32>(0.0);
    // Four at a time, summed one by one: the order of the CPU reference.
    for (var k = 0u; k < s4; k++) {
        let a = desc[ra + k];
        let b0 = desc[rb0 + k];
        let b1 = desc[rb1 + k];
        let b2 = desc[rb2 + k];
        let b3 = desc[rb3 + k];
        acc = acc + a.x * vec4<f32>(b0.x, b1.x, b2.x, b3.x);
        acc = acc + a.y * vec4<f32>(b0.y, b1.y, b2.y, b3.y);
        acc = acc + a.z * vec4<f32>(b0.z, b1.z, b2.z, b3.z);
        acc = acc + a.w * vec4<f32>(b0.w, b1.w, b2.w, b3.w);
    }
    for (var m = 0u; m < 4u; m++) {
        if (q0 + m < nb) {
            finish_score(i, js[m], acc[m]);
        }
    }
}

@compute @workgroup_size(NCC_TILE, NCC_TILE)
fn score_tiled(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let na = params.na;
    let nb = params.nb;
    let stride = params.stride;
    let i = wid.y * NCC_TILE + lid.y;
    let j = wid.x * NCC_TILE + lid.x;
    // This thread loads row (wid.y*NCC_TILE + lid.y) of A and row
    // (wid.x*NCC_TILE + lid.y) of B, column k0 + lid.x of each.
    let jb = wid.x * NCC_TILE + lid.y;
    var acc = 0.0;
    for (var k0 = 0u; k0 < stride; k0 += NCC_TILE) {
        var va = 0.0;
        if (i < na) {
            va = desc_get(i * stride + k0 + lid.x);
        }
        var vb = 0.0;
        if (jb < nb) {
            vb = desc_get((na + jb) * stride + k0 + lid.x);
        }
        tile_a[lid.y][lid.x] = va;
        tile_b[lid.y][lid.x] = vb;
        workgroupBarrier();
        for (var kk = 0u; kk < NCC_TILE; kk++) {
            acc = acc + tile_a[lid.y][kk] * tile_b[lid.x][kk];
        }
        workgroupBarrier();
    }
    if (i < na && j < nb) {
        finish_score(i, j, acc);
    }
}

var<workgroup> red_score: array<f32, WORKGROUP_1D>;
var<workgroup> red_index: array<u32, WORKGROUP_1D>;

fn better(s1: f32, i1: u32, s2: f32, i2: u32) -> bool {
    return s1 > s2 || (s1 == s2 && i1 < i2);
}

// Tree reduction of the WORKGROUP_1D per-thread bests (a power of two);
// the result is in slot 0.
fn reduce(lid: u32) {
    for (var half = WORKGROUP_1D / 2u; half > 0u; half = half / 2u) {
        if (lid < half) {
            let s = red_score[lid + half];
            let i = red_index[lid + half];
            if (better(s, i, red_score[lid], red_index[lid])) {
                red_score[lid] = s;
                red_index[lid] = i;
            }
        }
        workgroupBarrier();
    }
}

// The best of `n` scores `first`, `first + step`, ... (ties: the lower
// position k), reduced over the workgroup into slot 0; `live` false: none.
fn best_of_line(lid: u32, first: u32, step: u32, n: u32, live: bool) {
    var bs = NO_SCORE - 1.0;
    var bi = NO_INDEX;
    if (live) {
        for (var k = lid; k < n; k += WORKGROUP_1D) {
            let s = scores[first + k * step];
            if (better(s, k, bs, bi)) {
                bs = s;
                bi = k;
            }
        }
    }
    red_score[lid] = bs;
    red_index[lid] = bi;
    workgroupBarrier();
    reduce(lid);
}

// Each row's best (feature i of A against every B, into best[i]) and
// each column's (feature j of B against every A, into best[na + j]), a
// workgroup a line: rows first, then columns, in one dispatch (the two
// are independent: one dependent dispatch fewer a matching). The lines
// run x first, then y, so that more than 65535 of them fit a dispatch.
@compute @workgroup_size(WORKGROUP_1D)
fn bests(
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let line = wid.y * groups.x + wid.x;
    let na = params.na;
    let nb = params.nb;
    let row = line < na;
    // Column j where not a row (wrapped, and unused, where a row). One
    // call whatever the line: its barriers in uniform control flow.
    let j = line - na;
    best_of_line(
        lid.x,
        select(j, line * nb, row),
        select(nb, 1u, row),
        select(na, nb, row),
        row || j < nb,
    );
    if (lid.x == 0u && row) {
        best[line] = Best(red_index[0], red_score[0]);
    }
    if (lid.x == 0u && !row && j < nb) {
        best[na + j] = Best(red_index[0], red_score[0]);
    }
}

// The CPU adapters' twin of bests (with score_direct): one
// thread per row / column scans its scores in order, with no workgroup
// barrier (slow on a CPU); the same bests, ties included (`better` orders
// every pair).
fn scan_line(first: u32, step: u32, n: u32) -> Best {
    var bs = NO_SCORE - 1.0;
    var bi = NO_INDEX;
    for (var k = 0u; k < n; k++) {
        let s = scores[first + k * step];
        if (better(s, k, bs, bi)) {
            bs = s;
            bi = k;
        }
    }
    return Best(bi, bs);
}

@compute @workgroup_size(WORKGROUP_1D)
fn bests_direct(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let line = id.y * groups.x * WORKGROUP_1D + id.x;
    let na = params.na;
    let nb = params.nb;
    if (line < na) {
        best[line] = scan_line(line * nb, 1u, nb);
    } else if (line < na + nb) {
        best[line] = scan_line(line - na, nb, na);
    }
}

// A bilinear sample of the image at `offset` (w x h) that any invalid
