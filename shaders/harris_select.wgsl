// Harris corners, the selection among the candidates. One module with harris_maps.wgsl,
// harris_select.wgsl, harris_select_small.wgsl and harris_export.wgsl
// (composed in that order after the prelude and pixel.wgsl; the bindings
// and the shared structs are in harris_maps.wgsl).

// ---- The selection of the corners among the candidates, on the GPU ----
// What the host's select_spread_indices, refinement and merge give
// (src/features/harris/mod.rs, the CPU reference), run here so that only
// the final corners come back: select_rank (each candidate's rank within
// its grid cell) -> select_place (its place in the order rank by rank, the
// first max_corners kept) -> select_refine (the kept ones refined, in that
// order) -> merge_order (their place by score, then position) ->
// merge_links (each one's earlier corners closer than the merge radius)
// -> merge_round (MERGE_ROUNDS times: the greedy merge, strongest first,
// a corner too close to a kept one dropped) -> merge_compact_scan (the kept
// ones into `corners`, their count into `counters.selected`). The passes
// run one thread an item, dispatched indirectly (select_sizes). Every
// comparison is exact (scores by their bits, positions in IEEE total
// order, the slot breaking ties as the host's stable sort does), so the
// corners are the host's. At most
// SELECT_MAX candidates: with more, the passes do nothing and the host
// selects (it reads the count); where the rounds leave a corner
// undecided, the host finishes the merge.

@group(0) @binding(9) var<storage, read_write> select_index: array<u32>;
@group(0) @binding(10) var<storage, read_write> select_state: array<atomic<u32>>;
@group(0) @binding(11) var<storage, read_write> ordered: array<RefineCorner>;
// The dispatches' sizes (select_args): over the candidates at 0, over the
// selected at 4.
@group(0) @binding(12) var<storage, read_write> select_args: array<u32>;

const UNDECIDED: u32 = 0u;
const KEPT: u32 = 1u;
const DROPPED: u32 = 2u;

// The candidates the selection runs on: none when there are more than
// params.select_limit (the host then selects).
fn select_count() -> u32 {
    let n = min(atomicLoad(&counters.count), params.capacity);
    return select(0u, n, n <= min(params.select_limit, SELECT_MAX));
}

// The selection's slots: the first max_corners places.
fn slot_count() -> u32 {
    return min(select_count(), params.max_corners);
}

// One thread: the workgroups of the passes over the candidates and over
// the selected, for their indirect dispatches. One thread an item: every
// thread's loops then run at most SELECT_MAX times (lavapipe ends any
// invocation's loops after 65535 iterations in all).
@compute @workgroup_size(1)
fn select_sizes() {
    let groups = (select_count() + WORKGROUP_1D - 1u) / WORKGROUP_1D;
    let slot_groups = (slot_count() + WORKGROUP_1D - 1u) / WORKGROUP_1D;
    select_args[0] = groups;
    select_args[1] = 1u;
    select_args[2] = 1u;
    select_args[4] = slot_groups;
    select_args[5] = 1u;
    select_args[6] = 1u;
    // A workgroup a selected corner (select_refine_group), at most the
    // 65535 a dimension allows (its workgroups stride over the rest).
    select_args[8] = min(slot_count(), 65535u);
    select_args[9] = 1u;
    select_args[10] = 1u;
    // The split counts (select_rank, select_place, merge_order): items by
    // chunks of others.
    select_args[12] = groups;
    select_args[13] = chunks(select_count());
    select_args[14] = 1u;
    select_args[16] = slot_groups;
    select_args[17] = chunks(slot_count());
    select_args[18] = 1u;
}

// Whether candidate a comes before b by score (higher first; responses
// are positive, so their bits order as their values), then y, then x.
fn score_before(a: Candidate, b: Candidate) -> bool {
    let sa = bitcast<u32>(a.score);
    let sb = bitcast<u32>(b.score);
    if (sa != sb) {
        return sa > sb;
    }
    if (a.y != b.y) {
        return a.y < b.y;
    }
    return a.x < b.x;
}

// A candidate's grid cell, packed (x and y below 2^16: images are at most
// 32768 pixels a side); equal for two candidates exactly when
// x / g and y / g both are.
fn cell_of(c: Candidate) -> u32 {
    let g = params.grid_cell;
    return ((c.y / g) << 16u) | (c.x / g);
}

// The O(n^2) passes below (select_rank, select_place, merge_order,
// merge_links) compare each item with every other (or every earlier)
// one. A workgroup walks the others in tiles of WORKGROUP_1D: each thread
// loads one item of the tile into workgroup memory (with its cell or
// rank, computed once a load instead of once a comparison), then every
// thread compares its own with the whole tile. The comparisons and their
// order are the one-thread-an-item loop's, so the counts are the same
// integers; what changes is that a workgroup reads each item from
// global memory once instead of each thread reading all of them (the
// H200's first measurement put these passes at most of a whole-image
// detection, docs/performance.md). The item count comes through
// workgroupUniformLoad so that the tile loops, and their barriers, are
// uniform over the workgroup.
var<workgroup> sel_count: u32;
var<workgroup> sel_tile: array<Candidate, WORKGROUP_1D>;
var<workgroup> sel_key: array<u32, WORKGROUP_1D>;
var<workgroup> mrg_tile: array<RefineCorner, WORKGROUP_1D>;

// `n` as the whole workgroup sees it (thread 0's), uniform for the loops
// whose barriers every thread must pass.
fn uniform_count(lid: u32, n: u32) -> u32 {
    if (lid == 0u) {
        sel_count = n;
    }
    return workgroupUniformLoad(&sel_count);
}

// The tile of candidates from t0 (of n) into sel_tile, each with its cell
// or (`ranks`) its rank from select_index into sel_key, between barriers.
fn load_candidate_tile(lid: u32, t0: u32, n: u32, ranks: bool) {
    workgroupBarrier();
    let j = t0 + lid;
    if (j < n) {
        let o = candidates[j];
        sel_tile[lid] = o;
        if (ranks) {
            sel_key[lid] = select_index[j];
        } else {
            sel_key[lid] = cell_of(o);
        }
    }
    workgroupBarrier();
}

// The tile of selected corners from t0 (of n) into mrg_tile, from
// `corners` or (`merged`) from `ordered`, between barriers.
fn load_corner_tile(lid: u32, t0: u32, n: u32, merged: bool) {
    workgroupBarrier();
    let j = t0 + lid;
    if (j < n) {
        if (merged) {
            mrg_tile[lid] = ordered[j];
        } else {
            mrg_tile[lid] = corners[j];
        }
    }
    workgroupBarrier();
}

// The tiled O(n^2) counts split over the others too (GPUs): a workgroup
// (wid.x) takes WORKGROUP_1D items against one chunk (wid.y) of
// SELECT_CHUNK others, in tiles as above, and adds its count to the item's
// in select_state (zeroed before: select_clear; the counts are integers,
// so the sums are the one-pass counts whatever the order). Then a thread
// an item turns the count into its rank or place (`*_finish`). A
// workgroup comparing its items with every candidate walked thousands of
// them through two barriers a tile: 0.94 ms for a whole 640x480 image's
// selection on the H200 (docs/performance.md).
const SELECT_CHUNK: u32 = 16u * WORKGROUP_1D;

// The chunks of `n` others: the y size of the split dispatches.
fn chunks(n: u32) -> u32 {
    return max((n + SELECT_CHUNK - 1u) / SELECT_CHUNK, 1u);
}

// select_state zeroed over the candidates, for the split counts.
@compute @workgroup_size(WORKGROUP_1D)
fn select_clear(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = select_count();
    for (var i = id.x; i < n; i += groups.x * WORKGROUP_1D) {
        atomicStore(&select_state[i], 0u);
    }
}

// How many of the chunk (wid.y) of candidates come before each item,
// added into select_state: with `places`, in the order by rank (from
// select_index), then by score; else by score within the item's grid
// cell (its rank less one). select_rank and select_place.
fn count_before(lid: u32, wid: vec3<u32>, groups: vec3<u32>, places: bool) {
    let n = uniform_count(lid, select_count());
    let c0 = wid.y * SELECT_CHUNK;
    let c1 = min(c0 + SELECT_CHUNK, n);
    let stride = groups.x * WORKGROUP_1D;
    for (var base = wid.x * WORKGROUP_1D; base < n; base += stride) {
        let i = base + lid;
        var c = Candidate(0u, 0u, 0.0, 0u);
        var key = 0u;
        if (i < n) {
            c = candidates[i];
            key = select(cell_of(c), select_index[i], places);
        }
        var count = 0u;
        for (var t0 = c0; t0 < c1; t0 += WORKGROUP_1D) {
            load_candidate_tile(lid, t0, n, places);
            let m = min(WORKGROUP_1D, c1 - t0);
            for (var k = 0u; k < m; k++) {
                let r = sel_key[k];
                if ((places && r < key) || (r == key && score_before(sel_tile[k], c))) {
                    count++;
                }
            }
        }
        if (i < n && count > 0u) {
            atomicAdd(&select_state[i], count);
        }
    }
}

@compute @workgroup_size(WORKGROUP_1D)
fn select_rank(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    // Without a grid every rank is 0 (select_rank_finish).
    if (params.grid_cell != 0u) {
        count_before(lid, wid, groups, false);
    }
}

// Each candidate's rank within its grid cell (1: the cell's best), into
// select_index[i]; 0 for all without a grid. select_state zeroed again.
@compute @workgroup_size(WORKGROUP_1D)
fn select_rank_finish(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = select_count();
    for (var i = id.x; i < n; i += groups.x * WORKGROUP_1D) {
        let count = atomicExchange(&select_state[i], 0u);
        select_index[i] = select(0u, 1u + count, params.grid_cell > 0u);
    }
}

@compute @workgroup_size(WORKGROUP_1D)
fn select_place(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    count_before(lid, wid, groups, true);
}

// Each candidate's place in the order by rank, then by score: the first
// max_corners places name their candidate in select_index[SELECT_MAX + p]
// (the ranks below SELECT_MAX are not read again). select_state zeroed
// again, for merge_order.
@compute @workgroup_size(WORKGROUP_1D)
fn select_place_finish(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = select_count();
    for (var i = id.x; i < n; i += groups.x * WORKGROUP_1D) {
        let place = atomicExchange(&select_state[i], 0u);
        if (place < params.max_corners) {
            select_index[SELECT_MAX + place] = i;
        }
    }
}

// The selected candidates, refined (with refinement on) into `corners`
// in their selection order.
@compute @workgroup_size(WORKGROUP_1D)
fn select_refine(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = slot_count();
    let stride = groups.x * WORKGROUP_1D;
    for (var s = id.x; s < n; s += stride) {
        let c = candidates[select_index[SELECT_MAX + s]];
        let start = vec2<f32>(f32(c.x), f32(c.y));
        if (params.refine != 0u) {
            corners[s] = refined(start, c.score);
        } else {
            corners[s] = RefineCorner(start.x, start.y, c.score, 0.0);
        }
    }
}

// select_refine a workgroup a corner (GPUs; refine_radius at most
// REFINE_GROUP_RADIUS): each iteration's per-pixel terms (the gradient's
// load, the weight's exp and products) taken by all the workgroup's
// threads at once into workgroup memory, then summed by one thread in
// `refined`'s order, so the corners are `refined`'s. (One thread a corner,
// as select_refine, measured 0.16 ms a detection of the real cube's frame
// on the H200 and 0.23 ms for a whole 640x480 image: a few workgroups of
// threads each walking windows through dependent loads.)
const REFINE_GROUP_PIXELS: u32 = (2u * REFINE_GROUP_RADIUS + 1u) * (2u * REFINE_GROUP_RADIUS + 1u);
// (gxx, gxy, gyy, the b1 term) and (the b2 term, 1 where the pixel counts).
var<workgroup> rg_terms: array<vec4<f32>, REFINE_GROUP_PIXELS>;
var<workgroup> rg_more: array<vec2<f32>, REFINE_GROUP_PIXELS>;
var<workgroup> rg_q: vec2<f32>;
var<workgroup> rg_status: f32;
var<workgroup> rg_done: u32;

// `refined` by the workgroup (every thread calls it, in uniform control
// flow); the result is thread 0's.
fn refined_group(lid: u32, start: vec2<f32>, score: f32) -> RefineCorner {
    workgroupBarrier();
    if (lid == 0u) {
        rg_q = start;
        rg_status = 0.0;
        rg_done = 0u;
    }
    let rw = i32(params.refine_radius);
    let side = u32(2 * rw + 1);
    let w = i32(params.width);
    let h = i32(params.height);
    for (var it = 0u; it < params.refine_iterations; it++) {
        if (workgroupUniformLoad(&rg_done) != 0u) {
            break;
        }
        let q = rg_q;
        let cx = i32(floor(q.x + 0.5));
        let cy = i32(floor(q.y + 0.5));
        for (var k = lid; k < side * side; k += WORKGROUP_1D) {
            let dx = i32(k % side) - rw;
            let dy = i32(k / side) - rw;
            let px = cx + dx;
            let py = cy + dy;
            var t = vec4<f32>(0.0);
            var more = vec2<f32>(0.0);
            if (!(px < 0 || py < 0 || px >= w || py >= h)) {
                let g = grad[u32(py) * u32(w) + u32(px)];
                if (g.z >= 0.5) {
                    let ox = f32(px) - q.x;
                    let oy = f32(py) - q.y;
                    let wt = exp(-(ox * ox + oy * oy) * params.refine_inv_2s2);
                    let gxx = wt * g.x * g.x;
                    let gxy = wt * g.x * g.y;
                    let gyy = wt * g.y * g.y;
                    t = vec4<f32>(gxx, gxy, gyy, gxx * f32(dx) + gxy * f32(dy));
                    more = vec2<f32>(gxy * f32(dx) + gyy * f32(dy), 1.0);
                }
            }
            rg_terms[k] = t;
            rg_more[k] = more;
        }
        workgroupBarrier();
        if (lid == 0u) {
            var a11 = 0.0;
            var a12 = 0.0;
            var a22 = 0.0;
            var b1 = 0.0;
            var b2 = 0.0;
            for (var k = 0u; k < side * side; k++) {
                let more = rg_more[k];
                if (more.y < 0.5) {
                    continue;
                }
                let t = rg_terms[k];
                a11 = a11 + t.x;
                a12 = a12 + t.y;
                a22 = a22 + t.z;
                b1 = b1 + t.w;
                b2 = b2 + more.x;
            }
            let det = a11 * a22 - a12 * a12;
            let tr = a11 + a22;
            let qn = vec2<f32>(
                f32(cx) + (a22 * b1 - a12 * b2) / det,
                f32(cy) + (a11 * b2 - a12 * b1) / det,
            );
            let moved = qn - start;
            if (!(tr > 0.0) || !(det > 1.0e-4 * tr * tr)
                || !(dot(moved, moved) <= params.max_shift * params.max_shift)) {
                rg_q = start;
                rg_status = 0.0;
                rg_done = 1u;
            } else {
                let step = qn - q;
                rg_q = qn;
                rg_status = 1.0;
                if (dot(step, step) < 1.0e-4) {
                    rg_done = 1u;
                }
            }
        }
    }
    workgroupBarrier();
    return RefineCorner(rg_q.x, rg_q.y, score, rg_status);
}

@compute @workgroup_size(WORKGROUP_1D)
fn select_refine_group(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = uniform_count(lid, slot_count());
    for (var s = wid.x; s < n; s += groups.x) {
        let c = candidates[select_index[SELECT_MAX + s]];
        let start = vec2<f32>(f32(c.x), f32(c.y));
        var out = RefineCorner(start.x, start.y, c.score, 0.0);
        if (params.refine != 0u) {
            out = refined_group(lid, start, c.score);
        }
        if (lid == 0u) {
            corners[s] = out;
        }
    }
}

// f32 bits mapped so that unsigned order is IEEE total order (Rust's
// f32::total_cmp).
fn total_key(v: f32) -> u32 {
    let b = bitcast<u32>(v);
    return select(b | 0x80000000u, ~b, (b & 0x80000000u) != 0u);
}

// Whether corner a (slot sa) comes before b (slot sb) in the merge's
// order: score descending, then y, then x, then the selection's order.
fn merge_before(a: RefineCorner, sa: u32, b: RefineCorner, sb: u32) -> bool {
    let ka = total_key(a.score);
    let kb = total_key(b.score);
    if (ka != kb) {
        return ka > kb;
    }
    let ya = total_key(a.y);
    let yb = total_key(b.y);
    if (ya != yb) {
        return ya < yb;
    }
    let xa = total_key(a.x);
    let xb = total_key(b.x);
    if (xa != xb) {
        return xa < xb;
    }
    return sa < sb;
}

// How many of the chunk's selected corners come before each one in the
// merge's order, added into select_state (split as select_rank; zeroed by
// select_place_finish).
@compute @workgroup_size(WORKGROUP_1D)
fn merge_order(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = uniform_count(lid, slot_count());
    let c0 = wid.y * SELECT_CHUNK;
    let c1 = min(c0 + SELECT_CHUNK, n);
    let stride = groups.x * WORKGROUP_1D;
    for (var base = wid.x * WORKGROUP_1D; base < n; base += stride) {
        let s = base + lid;
        var c = RefineCorner(0.0, 0.0, 0.0, 0.0);
        if (s < n) {
            c = corners[s];
        }
        var count = 0u;
        for (var t0 = c0; t0 < c1; t0 += WORKGROUP_1D) {
            load_corner_tile(lid, t0, n, false);
            let m = min(WORKGROUP_1D, c1 - t0);
            for (var k = 0u; k < m; k++) {
                if (merge_before(mrg_tile[k], t0 + k, c, s)) {
                    count++;
                }
            }
        }
        if (s < n && count > 0u) {
            atomicAdd(&select_state[s], count);
        }
    }
}

// The selected corners in the merge's order, into `ordered`. (merge_links
// then sets select_state over the slots.)
@compute @workgroup_size(WORKGROUP_1D)
fn merge_order_finish(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = slot_count();
    for (var s = id.x; s < n; s += groups.x * WORKGROUP_1D) {
        ordered[atomicLoad(&select_state[s])] = corners[s];
    }
}

// Whether two corners are closer than the merge radius (the host's test,
// negated: kept when the squared distance is at least the radius's).
fn too_close(a: RefineCorner, b: RefineCorner) -> bool {
    let dx = a.x - b.x;
    let dy = a.y - b.y;
    return !(dx * dx + dy * dy >= params.merge_r2);
}

// Each selected corner's earlier corners (in the merge's order) that are
// too close: their count in select_index[s], the first MERGE_LINKS of
// them in select_index[SELECT_MAX + s * MERGE_LINKS + k] (the ranks and
// places are spent by now). Every corner undecided. Tiled as select_rank,
// over the tiles that hold the workgroup's earlier corners.
@compute @workgroup_size(WORKGROUP_1D)
fn merge_links(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = uniform_count(lid, slot_count());
    let stride = groups.x * WORKGROUP_1D;
    for (var base = wid.x * WORKGROUP_1D; base < n; base += stride) {
        let s = base + lid;
        var c = RefineCorner(0.0, 0.0, 0.0, 0.0);
        if (s < n) {
            c = ordered[s];
        }
        var links = 0u;
        // The earlier corners of the workgroup's last one: base + 63.
        let last = min(base + WORKGROUP_1D, n);
        for (var t0 = 0u; t0 < last; t0 += WORKGROUP_1D) {
            load_corner_tile(lid, t0, n, true);
            let m = min(WORKGROUP_1D, n - t0);
            for (var k = 0u; k < m; k++) {
                let t = t0 + k;
                if (t < s && too_close(mrg_tile[k], c)) {
                    if (links < MERGE_LINKS) {
                        select_index[SELECT_MAX + s * MERGE_LINKS + links] = t;
                    }
                    links++;
                }
            }
        }
        if (s < n) {
            select_index[s] = links;
            atomicStore(&select_state[s], UNDECIDED);
        }
    }
}

// The same four passes one thread an item, every thread reading every
// other item from global memory (the first selection): the
// default on CPU adapters, where a workgroup barrier costs more than the
// loads it saves (lavapipe: the tiled passes took 1.4-1.6x as long in the
// real cube's GPU loop, GPU timestamps); `HarrisGpuOptions::tiled_selection`.
// Candidate i's rank within its grid cell (1: the cell's best; 0 for all
// without a grid) into select_index[i], against every other of the n
// read from global memory.
fn rank_direct(i: u32, n: u32) {
    var rank = 0u;
    if (params.grid_cell > 0u) {
        let c = candidates[i];
        rank = 1u;
        for (var j = 0u; j < n; j++) {
            let o = candidates[j];
            if (cell_of(o) == cell_of(c) && score_before(o, c)) {
                rank++;
            }
        }
    }
    select_index[i] = rank;
}

@compute @workgroup_size(WORKGROUP_1D)
fn select_rank_direct(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = select_count();
    let stride = groups.x * WORKGROUP_1D;
    for (var i = id.x; i < n; i += stride) {
        rank_direct(i, n);
    }
}

// Candidate i's place in the order by rank, then by score; the first
// max_corners places name their candidate in select_index[SELECT_MAX + p].
fn place_direct(i: u32, n: u32) {
    let c = candidates[i];
    let rank = select_index[i];
    var place = 0u;
    for (var j = 0u; j < n; j++) {
        let r = select_index[j];
        if (r < rank || (r == rank && score_before(candidates[j], c))) {
            place++;
        }
    }
    if (place < params.max_corners) {
        select_index[SELECT_MAX + place] = i;
    }
}

@compute @workgroup_size(WORKGROUP_1D)
fn select_place_direct(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = select_count();
    let stride = groups.x * WORKGROUP_1D;
    for (var i = id.x; i < n; i += stride) {
        place_direct(i, n);
    }
}

// Selected corner s into `ordered` at its place in the merge's order.
fn order_direct(s: u32, n: u32) {
    let c = corners[s];
    var place = 0u;
    for (var t = 0u; t < n; t++) {
        if (merge_before(corners[t], t, c, s)) {
            place++;
        }
    }
    ordered[place] = c;
}

@compute @workgroup_size(WORKGROUP_1D)
fn merge_order_direct(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = slot_count();
    let stride = groups.x * WORKGROUP_1D;
    for (var s = id.x; s < n; s += stride) {
        order_direct(s, n);
    }
}

// Corner s's earlier close corners (in the merge's order): their count
// in select_index[s], the first MERGE_LINKS of them after SELECT_MAX (as
// merge_links); s undecided.
fn links_direct(s: u32) {
    let c = ordered[s];
    var links = 0u;
    for (var t = 0u; t < s; t++) {
        if (too_close(ordered[t], c)) {
            if (links < MERGE_LINKS) {
                select_index[SELECT_MAX + s * MERGE_LINKS + links] = t;
            }
            links++;
        }
    }
    select_index[s] = links;
    atomicStore(&select_state[s], UNDECIDED);
}

@compute @workgroup_size(WORKGROUP_1D)
fn merge_links_direct(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = slot_count();
    let stride = groups.x * WORKGROUP_1D;
    for (var s = id.x; s < n; s += stride) {
        links_direct(s);
    }
}

// The decision on corner s from its earlier close corners' decisions:
// dropped when one is kept, kept when all are dropped, else undecided.
fn decide(s: u32) -> u32 {
    let links = select_index[s];
    var state = KEPT;
    if (links <= MERGE_LINKS) {
        for (var k = 0u; k < links; k++) {
            let st = atomicLoad(&select_state[select_index[SELECT_MAX + s * MERGE_LINKS + k]]);
            if (st == KEPT) {
                return DROPPED;
            }
            if (st == UNDECIDED) {
                state = UNDECIDED;
            }
        }
        return state;
    }
    let c = ordered[s];
    for (var t = 0u; t < s; t++) {
        if (!too_close(ordered[t], c)) {
            continue;
        }
        let st = atomicLoad(&select_state[t]);
        if (st == KEPT) {
            return DROPPED;
        }
        if (st == UNDECIDED) {
            state = UNDECIDED;
        }
    }
    return state;
}

// One round of the greedy merge (a corner is kept when no kept corner
// before it is too close), every undecided corner at once: a decision is
// final whenever it is taken, so decisions seen during the round only
// speed it. A round decides at least the earliest undecided corner; the
// host records MERGE_ROUNDS of them, which decide every corner unless
// close corners chain further (the host then finishes the merge).
@compute @workgroup_size(WORKGROUP_1D)
fn merge_round(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let n = slot_count();
    let stride = groups.x * WORKGROUP_1D;
    for (var s = id.x; s < n; s += stride) {
        decide_one(s);
    }
}

// Corner s decided where it can be; whether it is still undecided.
fn decide_one(s: u32) -> bool {
    if (atomicLoad(&select_state[s]) != UNDECIDED) {
        return false;
    }
    let state = decide(s);
    if (state != UNDECIDED) {
        atomicStore(&select_state[s], state);
    }
    return state == UNDECIDED;
}
