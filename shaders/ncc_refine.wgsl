// NCC matching, the mutual bests' sub-pixel refinement. One module with ncc_score.wgsl,
// ncc_refine.wgsl and ncc_gate.wgsl (composed in that order after the
// prelude and pixel.wgsl; the bindings and the shared structs are in
// ncc_score.wgsl).

// pixel (pinholes included) or the outside voids: (value, 1), else
// (0, -1). Mirrors GreyImage::bilinear.
fn sample_strict(offset: u32, w: u32, h: u32, x: f32, y: f32) -> vec2<f32> {
    return sample_with(offset, w, h, x, y, true);
}

// Mean and norm (of the centred samples) of the strict window at (x, y)
// of image A (`in_b` false) or B; z < 0: void (outside, invalid or flat).
// Sums in sample order, as refine.rs's `window`.
fn window_stats(in_b: bool, x: f32, y: f32) -> vec3<f32> {
    var offset = 0u;
    var w = params.wa;
    var h = params.ha;
    if (in_b) {
        offset = params.offset_b;
        w = params.wb;
        h = params.hb;
    }
    let half = i32(params.refine_half);
    var sum = 0.0;
    var n = 0.0;
    for (var dy = -half; dy <= half; dy++) {
        for (var dx = -half; dx <= half; dx++) {
            let s = sample_strict(offset, w, h, x + f32(dx), y + f32(dy));
            if (s.y < 0.0) {
                return vec3<f32>(0.0, 0.0, -1.0);
            }
            sum = sum + s.x;
            n = n + 1.0;
        }
    }
    let mean = sum / n;
    var ss = 0.0;
    for (var dy = -half; dy <= half; dy++) {
        for (var dx = -half; dx <= half; dx++) {
            let c = sample_strict(offset, w, h, x + f32(dx), y + f32(dy)).x - mean;
            ss = ss + c * c;
        }
    }
    let norm = sqrt(ss);
    if (norm < 1e-6) {
        return vec3<f32>(0.0, 0.0, -1.0);
    }
    return vec3<f32>(mean, norm, 1.0);
}

// The NCC of A's window at `pa` (stats `ta`) with B's at (x, y); < -1.5:
// B's window is void.
fn refine_score(pa: vec2<f32>, ta: vec3<f32>, x: f32, y: f32) -> f32 {
    let tb = window_stats(true, x, y);
    if (tb.z < 0.0) {
        return -3.0;
    }
    let half = i32(params.refine_half);
    var dot = 0.0;
    for (var dy = -half; dy <= half; dy++) {
        for (var dx = -half; dx <= half; dx++) {
            let a = sample_strict(0u, params.wa, params.ha, pa.x + f32(dx), pa.y + f32(dy)).x;
            let b = sample_strict(params.offset_b, params.wb, params.hb, x + f32(dx), y + f32(dy)).x;
            dot = dot + ((a - ta.x) / ta.y) * ((b - tb.x) / tb.y);
        }
    }
    return dot;
}

// refine.rs's parabola_peak.
fn parabola_peak(a: f32, b: f32, c: f32) -> f32 {
    let den = a - 2.0 * b + c;
    if (den >= -1e-9) {
        return 0.0;
    }
    return clamp(0.5 * (a - c) / den, -0.5, 0.5);
}

// Threads of a mutual_refine workgroup (one workgroup per feature of A).
const REFINE_GROUP: u32 = 32u;

var<workgroup> wg_centre: vec2<f32>;
var<workgroup> wg_peak: f32;
// 1 while the refinement holds, 0 once it failed.
var<workgroup> wg_state: u32;

// Feature i of A's row best, whether it is a mutual match of at least
// min_score, and the two points (zero where not).
struct Mutual {
    r: Best,
    mutual: bool,
    pa: vec2<f32>,
    pb: vec2<f32>,
}

fn mutual_of(i: u32) -> Mutual {
    var m = Mutual(Best(NO_INDEX, NO_SCORE), false, vec2<f32>(0.0), vec2<f32>(0.0));
    if (i < params.na) {
        m.r = best[i];
        m.mutual = m.r.index != NO_INDEX && m.r.score >= params.min_score
            && best[params.na + m.r.index].index == i;
    }
    if (m.mutual) {
        m.pa = positions[i];
        m.pb = positions[params.na + m.r.index];
    }
    return m;
}

// Where a parabola step's five scores are taken, in its steps: centre,
// left, right, up, down.
const PARABOLA_OFFSETS = array<vec2<f32>, 5>(
    vec2<f32>(0.0, 0.0),
    vec2<f32>(-1.0, 0.0),
    vec2<f32>(1.0, 0.0),
    vec2<f32>(0.0, -1.0),
    vec2<f32>(0.0, 1.0),
);

// A parabola step of `step` pixels from `centre` through the five scores
// (centre, left, right, up, down): the new centre, and z = 0 where a
// window was void (a score below -1.5), 1 else.
fn parabola_step(s: array<f32, 5>, centre: vec2<f32>, step: f32) -> vec3<f32> {
    if (min(min(s[0], s[1]), min(min(s[2], s[3]), s[4])) < -1.5) {
        return vec3<f32>(centre, 0.0);
    }
    return vec3<f32>(
        centre.x + parabola_peak(s[1], s[0], s[2]) * step,
        centre.y + parabola_peak(s[3], s[0], s[4]) * step,
        1.0,
    );
}

// The best integer shift of the first `n` threads' (rl_score, rl_index):
// ties to the first in raster order, as the host's loop.
fn best_shift(n: u32) -> Best {
    var b = Best(NO_INDEX, -1.0e30);
    for (var j = 0u; j < n; j++) {
        let sj = rl_score[j];
        let kj = rl_index[j];
        if (kj != NO_INDEX && (sj > b.score || (sj == b.score && kj < b.index))) {
            b = Best(kj, sj);
        }
    }
    return b;
}

// Feature i of A's row of `matched`: B's point, refined to `centre` (with
// its peak score) where `refined`.
fn match_out(m: Mutual, refined: bool, centre: vec2<f32>, peak: f32) -> MatchOut {
    var out = MatchOut(NO_INDEX, m.r.score, 0.0, 0.0, 0.0, 0u);
    if (m.mutual) {
        out.b = m.r.index;
        out.x = m.pb.x;
        out.y = m.pb.y;
        if (params.refine_on != 0u && refined) {
            out.x = centre.x;
            out.y = centre.y;
            out.peak = peak;
            out.refined = 1u;
        }
    }
    return out;
}

// `mutual_refine` for windows and searches too large for its workgroup
// memory (window over REFINE_LOCAL_WINDOW, or a patch or a grid of shifts
// over theirs): every score sampled from the images.
// One workgroup per feature of A: its row's best when mutual and at least
// min_score; with refine_on, B's point refined (refine.rs's refine_match):
// the (2 max_shift + 1)^2 integer shifts scored by the workgroup's threads
// at once and reduced (ties: the first in raster order, as the host's
// loop), then two parabola steps whose five scores run in parallel.
// Every thread passes every barrier; what a thread computes is steered by
// flags.
@compute @workgroup_size(REFINE_GROUP)
fn mutual_refine_wide(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let i = wid.x;
    let t = lid.x;
    let mm = mutual_of(i);
    let pa = mm.pa;
    let pb = mm.pb;
    var live = mm.mutual && params.refine_on != 0u;
    var ta = vec3<f32>(0.0, 0.0, -1.0);
    if (live) {
        ta = window_stats(false, pa.x, pa.y);
        live = ta.z >= 0.0;
    }
    let m = i32(params.max_shift);
    let side = 2u * params.max_shift + 1u;
    var bs = -1.0e30;
    var bk = NO_INDEX;
    if (live) {
        for (var k = t; k < side * side; k += REFINE_GROUP) {
            let s = refine_score(pa, ta, pb.x + f32(i32(k % side) - m), pb.y + f32(i32(k / side) - m));
            if (s > -1.5 && s > bs) {
                bs = s;
                bk = k;
            }
        }
    }
    rl_score[t] = bs;
    rl_index[t] = bk;
    workgroupBarrier();
    if (t == 0u) {
        let b = best_shift(REFINE_GROUP);
        let s = b.score;
        let k = b.index;
        var state = 0u;
        if (live && k != NO_INDEX) {
            let dx = i32(k % side) - m;
            let dy = i32(k / side) - m;
            if (!(s < params.refine_min || abs(dx) == m || abs(dy) == m)) {
                state = 1u;
                wg_centre = pb + vec2<f32>(f32(dx), f32(dy));
                wg_peak = s;
            }
        }
        wg_state = state;
    }
    workgroupBarrier();
    let offsets = PARABOLA_OFFSETS;
    for (var n = 0u; n < 2u; n++) {
        let step = select(0.5, 1.0, n == 0u);
        let state = wg_state;
        let centre = wg_centre;
        if (state == 1u && t < 5u) {
            let q = centre + offsets[t] * step;
            rl_score[t] = refine_score(pa, ta, q.x, q.y);
        }
        workgroupBarrier();
        if (t == 0u && state == 1u) {
            let sc = array<f32, 5>(rl_score[0], rl_score[1], rl_score[2], rl_score[3], rl_score[4]);
            let next = parabola_step(sc, centre, step);
            if (next.z == 0.0) {
                wg_state = 0u;
            } else {
                wg_centre = next.xy;
                wg_peak = sc[0];
            }
        }
        workgroupBarrier();
    }
    if (t == 0u && i < params.na) {
        matched[i] = match_out(mm, wg_state == 1u, wg_centre, wg_peak);
    }
}

// ---- mutual_refine: the refinement from workgroup memory ----
// The same matches and refined points as mutual_refine_wide (and the
// host's refine_match, the CPU reference), with the samples each score
// needs taken once by all the workgroup's threads into workgroup memory
// instead of by one thread sampling the images three times a score (the
// H200 measured mutual_refine_wide at 0.5 ms of the real cube's frame, a
// few hundred workgroups each waiting on thousands of dependent global
// loads: docs/performance.md). Every window's sums still run in
// sample order on one thread, so the scores are the same floats:
//   - A's window at pa, sampled in parallel, then its mean and norm (one
//     thread), then normalised in parallel ((a - mean) / norm, as before);
//   - the integer shifts: where every pb + m (|m| <= half + max_shift) is
//     exact in f32 (refine.rs's shifts_exact; tested here conservatively),
//     B's samples at pb + (k, l) form one patch whose windows are the
//     shifted windows bit for bit (refine.rs cuts them so), sampled in
//     parallel; elsewhere each thread samples its shifts' windows itself;
//   - the first parabola step's five scores are integer shifts inside the
//     search: from the patch's scores where there is one (as refine.rs);
//     the second's (and the first's without a patch) five windows are
//     sampled in parallel, then scored by five threads.
// Invalid samples are stored as INVALID_SAMPLE (WGSL need not keep NaN).
const REFINE_LOCAL_GROUP: u32 = 64u;
// Largest window (REFINE_LOCAL_WINDOW, from the prelude: wider ones run
// mutual_refine_wide), patch (samples) and grid of integer shifts held
// here (with the window at 21: 4 * (441 + 2205 + 81) bytes of workgroup
// memory with the rest, under the 16 KiB every WebGPU adapter has); a
// larger patch or grid: each thread samples its shifts' windows itself.
const REFINE_LOCAL_SAMPLES: u32 = REFINE_LOCAL_WINDOW * REFINE_LOCAL_WINDOW;
const REFINE_LOCAL_PATCH: u32 = 1024u;
const REFINE_LOCAL_GRID: u32 = 81u;

var<workgroup> rl_tpl: array<f32, REFINE_LOCAL_SAMPLES>;
// B's patch, or the five windows of a parabola step.
var<workgroup> rl_buf: array<f32, 5u * REFINE_LOCAL_SAMPLES>;
var<workgroup> rl_grid: array<f32, REFINE_LOCAL_GRID>;
var<workgroup> rl_score: array<f32, REFINE_LOCAL_GROUP>;
var<workgroup> rl_index: array<u32, REFINE_LOCAL_GROUP>;
// A's mean and norm; z < 0: void.
var<workgroup> rl_ta: vec3<f32>;
var<workgroup> rl_centre: vec2<f32>;
var<workgroup> rl_peak: f32;
// 1 while the refinement holds, 0 once it failed.
var<workgroup> rl_state: u32;

// Whether p + m is exact in f32 for every integer |m| <= r: p a multiple
// of the unit in the last place of |p| + r (every p + m is then a
// multiple of a unit at least its own, in range). |p| + r rounds up to the
// next binade at worst, which only makes the test stricter.
fn shifts_exact(p: f32, r: u32) -> bool {
    let big = abs(p) + f32(r);
    let e = (bitcast<u32>(big) >> 23u) & 0xffu;
    if (e < 24u || e >= 254u) {
        return false;
    }
    let ulp = bitcast<f32>((e - 23u) << 23u);
    return fract(p / ulp) == 0.0;
}

// A strict sample as a float: its value, or INVALID_SAMPLE.
fn strict_value(offset: u32, w: u32, h: u32, x: f32, y: f32) -> f32 {
    let s = sample_strict(offset, w, h, x, y);
    return select(INVALID_SAMPLE, s.x, s.y >= 0.0);
}

// The score of B's window whose samples are `rl_buf[first + j * row + i]`
// (i, j < side, side^2 samples) against the normalised template: -3 when
// a sample is invalid or the window flat. refine_score's arithmetic in its
// order (window_stats: sum, mean, squares, norm; then the dot).
fn local_score(first: u32, row: u32, side: u32) -> f32 {
    var sum = 0.0;
    var n = 0.0;
    for (var j = 0u; j < side; j++) {
        for (var i = 0u; i < side; i++) {
            let v = rl_buf[first + j * row + i];
            if (!is_valid_sample(v)) {
                return -3.0;
            }
            sum = sum + v;
            n = n + 1.0;
        }
    }
    let mean = sum / n;
    var ss = 0.0;
    for (var j = 0u; j < side; j++) {
        for (var i = 0u; i < side; i++) {
            let c = rl_buf[first + j * row + i] - mean;
            ss = ss + c * c;
        }
    }
    let norm = sqrt(ss);
    if (norm < 1e-6) {
        return -3.0;
    }
    var dot = 0.0;
    for (var j = 0u; j < side; j++) {
        for (var i = 0u; i < side; i++) {
            let b = rl_buf[first + j * row + i];
            dot = dot + rl_tpl[j * side + i] * ((b - mean) / norm);
        }
    }
    return dot;
}

// refine_score with the template from rl_tpl (B sampled from the image).
fn sampled_score(x: f32, y: f32) -> f32 {
    let tb = window_stats(true, x, y);
    if (tb.z < 0.0) {
        return -3.0;
    }
    let half = i32(params.refine_half);
    let side = 2u * params.refine_half + 1u;
    var dot = 0.0;
    var k = 0u;
    for (var dy = -half; dy <= half; dy++) {
        for (var dx = -half; dx <= half; dx++) {
            let b = sample_strict(params.offset_b, params.wb, params.hb, x + f32(dx), y + f32(dy)).x;
            dot = dot + rl_tpl[k] * ((b - tb.x) / tb.y);
            k++;
        }
    }
    return dot;
}

// One workgroup per feature of A (see above). Every thread passes every
// barrier (the loops' bounds come from params); what a thread computes is
// steered by flags.
@compute @workgroup_size(REFINE_LOCAL_GROUP)
fn mutual_refine(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let i = wid.x;
    let t = lid.x;
    let mm = mutual_of(i);
    let pa = mm.pa;
    let pb = mm.pb;
    let live = mm.mutual && params.refine_on != 0u;
    let half = params.refine_half;
    let win = 2u * half + 1u;
    let d = win * win;
    let m = params.max_shift;
    let side = 2u * m + 1u;
    let reach = half + m;
    let ps = 2u * reach + 1u;
    // A's window.
    for (var k = t; k < d; k += REFINE_LOCAL_GROUP) {
        if (live) {
            let dx = f32(i32(k % win) - i32(half));
            let dy = f32(i32(k / win) - i32(half));
            rl_tpl[k] = strict_value(0u, params.wa, params.ha, pa.x + dx, pa.y + dy);
        }
    }
    workgroupBarrier();
    if (t == 0u) {
        var ta = vec3<f32>(0.0, 0.0, -1.0);
        if (live) {
            var sum = 0.0;
            var n = 0.0;
            var valid = true;
            for (var k = 0u; k < d; k++) {
                let v = rl_tpl[k];
                if (!is_valid_sample(v)) {
                    valid = false;
                    break;
                }
                sum = sum + v;
                n = n + 1.0;
            }
            if (valid) {
                let mean = sum / n;
                var ss = 0.0;
                for (var k = 0u; k < d; k++) {
                    let c = rl_tpl[k] - mean;
                    ss = ss + c * c;
                }
                let norm = sqrt(ss);
                if (norm >= 1e-6) {
                    ta = vec3<f32>(mean, norm, 1.0);
                }
            }
        }
        rl_ta = ta;
    }
    workgroupBarrier();
    let ta = rl_ta;
    let on = live && ta.z >= 0.0;
    for (var k = t; k < d; k += REFINE_LOCAL_GROUP) {
        if (on) {
            rl_tpl[k] = (rl_tpl[k] - ta.x) / ta.y;
        }
    }
    // B's patch where the shifts are exact.
    let cut = on && ps * ps <= REFINE_LOCAL_PATCH && side * side <= REFINE_LOCAL_GRID
        && shifts_exact(pb.x, reach) && shifts_exact(pb.y, reach);
    for (var k = t; k < ps * ps; k += REFINE_LOCAL_GROUP) {
        if (cut) {
            let dx = f32(i32(k % ps) - i32(reach));
            let dy = f32(i32(k / ps) - i32(reach));
            rl_buf[k] = strict_value(params.offset_b, params.wb, params.hb, pb.x + dx, pb.y + dy);
        }
    }
    workgroupBarrier();
    // The integer shifts, the best of each thread's (ties: the first in
    // raster order), their scores kept with a patch.
    var bs = -1.0e30;
    var bk = NO_INDEX;
    for (var k = t; k < side * side; k += REFINE_LOCAL_GROUP) {
        if (on) {
            let sx = k % side;
            let sy = k / side;
            var s = -3.0;
            if (cut) {
                s = local_score(sy * ps + sx, ps, win);
                rl_grid[k] = s;
            } else {
                s = sampled_score(pb.x + f32(i32(sx) - i32(m)), pb.y + f32(i32(sy) - i32(m)));
            }
            if (s > -1.5 && s > bs) {
                bs = s;
                bk = k;
            }
        }
    }
    rl_score[t] = bs;
    rl_index[t] = bk;
    workgroupBarrier();
    if (t == 0u) {
        let b = best_shift(REFINE_LOCAL_GROUP);
        let s = b.score;
        let k = b.index;
        var state = 0u;
        if (on && k != NO_INDEX) {
            let dx = i32(k % side) - i32(m);
            let dy = i32(k / side) - i32(m);
            if (!(s < params.refine_min || abs(dx) == i32(m) || abs(dy) == i32(m))) {
                state = 1u;
                rl_centre = pb + vec2<f32>(f32(dx), f32(dy));
                rl_peak = s;
                // The first step's five scores from the grid.
                if (cut) {
                    let g = u32(dy + i32(m)) * side + u32(dx + i32(m));
                    let sc = array<f32, 5>(
                        rl_grid[g],
                        rl_grid[g - 1u],
                        rl_grid[g + 1u],
                        rl_grid[g - side],
                        rl_grid[g + side],
                    );
                    let next = parabola_step(sc, rl_centre, 1.0);
                    if (next.z == 0.0) {
                        state = 0u;
                    } else {
                        rl_centre = next.xy;
                        rl_peak = sc[0];
                    }
                }
            }
        }
        rl_state = state;
    }
    workgroupBarrier();
    let offsets = PARABOLA_OFFSETS;
    for (var n = 0u; n < 2u; n++) {
        let step = select(0.5, 1.0, n == 0u);
        // With a patch, the first step is done.
        let state = rl_state;
        let centre = rl_centre;
        let run = state == 1u && !(n == 0u && cut);
        for (var k = t; k < 5u * d; k += REFINE_LOCAL_GROUP) {
            if (run) {
                let w = k / d;
                let e = k % d;
                let q = centre + offsets[w] * step;
                let dx = f32(i32(e % win) - i32(half));
                let dy = f32(i32(e / win) - i32(half));
                rl_buf[k] = strict_value(params.offset_b, params.wb, params.hb, q.x + dx, q.y + dy);
            }
        }
        workgroupBarrier();
        if (run && t < 5u) {
            rl_score[t] = local_score(t * d, win, win);
        }
        workgroupBarrier();
        if (t == 0u && run) {
            let sc = array<f32, 5>(rl_score[0], rl_score[1], rl_score[2], rl_score[3], rl_score[4]);
            let next = parabola_step(sc, centre, step);
            if (next.z == 0.0) {
                rl_state = 0u;
            } else {
                rl_centre = next.xy;
                rl_peak = sc[0];
            }
        }
        workgroupBarrier();
    }
    if (t == 0u && i < params.na) {
        matched[i] = match_out(mm, rl_state == 1u, rl_centre, rl_peak);
    }
}
