// Harris corners, the selection in one workgroup. One module with harris_maps.wgsl,
// harris_select.wgsl, harris_select_small.wgsl and harris_export.wgsl
// (composed in that order after the prelude and pixel.wgsl; the bindings
// and the shared structs are in harris_maps.wgsl).

// ---- The selection in one workgroup (GPUs, few candidates) ----
// select_rank, select_place and (behind the refinement) the merge's
// passes as one dispatch each of one workgroup, their phases parted by
// barriers instead of dispatches: the frame loop's detections have a few
// hundred candidates, where the split passes' fourteen dependent
// dispatches a detection cost more in the GPU's gaps between them than
// in work. Each phase is the one-thread-an-item passes' (`*_direct`,
// the CPU adapters' kernels), so the corners are the same; the merge's
// rounds run until every corner is decided (none is left to the host).
// The host picks these from the last detections' counts
// (`HarrisGpuOptions::small_selection`) and then caps params.select_limit at
// SMALL_CAP (1024): a busier detection is selected on the host, as beyond
// the limit (one workgroup's loops over thousands would be slow, and
// would pass lavapipe's 65535 iterations an invocation).
const SMALL_GROUP: u32 = 256u;
var<workgroup> small_undecided: atomic<u32>;
var<workgroup> small_more: u32;
var<workgroup> small_scan: array<u32, SMALL_GROUP>;

@compute @workgroup_size(SMALL_GROUP)
fn select_small(@builtin(local_invocation_index) lid: u32) {
    let n = select_count();
    for (var i = lid; i < n; i += SMALL_GROUP) {
        rank_direct(i, n);
    }
    storageBarrier();
    workgroupBarrier();
    for (var i = lid; i < n; i += SMALL_GROUP) {
        place_direct(i, n);
    }
}

@compute @workgroup_size(SMALL_GROUP)
fn merge_small(@builtin(local_invocation_index) lid: u32) {
    let n = slot_count();
    for (var s = lid; s < n; s += SMALL_GROUP) {
        order_direct(s, n);
    }
    storageBarrier();
    workgroupBarrier();
    for (var s = lid; s < n; s += SMALL_GROUP) {
        links_direct(s);
    }
    // Rounds until none is undecided: each decides at least the earliest
    // undecided corner, so at most n.
    loop {
        if (lid == 0u) {
            atomicStore(&small_undecided, 0u);
        }
        storageBarrier();
        workgroupBarrier();
        var mine = 0u;
        for (var s = lid; s < n; s += SMALL_GROUP) {
            if (decide_one(s)) {
                mine++;
            }
        }
        if (mine > 0u) {
            atomicAdd(&small_undecided, mine);
        }
        workgroupBarrier();
        if (lid == 0u) {
            small_more = atomicLoad(&small_undecided);
        }
        if (workgroupUniformLoad(&small_more) == 0u) {
            break;
        }
    }
    storageBarrier();
    workgroupBarrier();
    compact_scan(lid);
}

// The kept corners, in the merge's order, into `corners` and their count
// into counters.selected (the undecided counted into counters.undecided),
// by one workgroup: a prefix sum instead of each kept corner counting
// every earlier slot (n atomic loads a kept corner, one thread each).
// Each
// thread takes a run of consecutive slots, counts its kept ones, and
// writes them after the kept ones of the runs before (an inclusive scan
// of the counts across the workgroup): the same places, so the same
// `corners`. Every thread calls it, in uniform control flow.
fn compact_scan(lid: u32) {
    let n = slot_count();
    let per = (n + SMALL_GROUP - 1u) / SMALL_GROUP;
    let s0 = min(lid * per, n);
    let s1 = min(s0 + per, n);
    var kept = 0u;
    var undecided = 0u;
    for (var s = s0; s < s1; s++) {
        let state = atomicLoad(&select_state[s]);
        kept += u32(state == KEPT);
        undecided += u32(state == UNDECIDED);
    }
    small_scan[lid] = kept;
    workgroupBarrier();
    for (var off = 1u; off < SMALL_GROUP; off *= 2u) {
        var v = small_scan[lid];
        if (lid >= off) {
            v += small_scan[lid - off];
        }
        workgroupBarrier();
        small_scan[lid] = v;
        workgroupBarrier();
    }
    var place = small_scan[lid] - kept;
    for (var s = s0; s < s1; s++) {
        if (atomicLoad(&select_state[s]) == KEPT) {
            corners[place] = ordered[s];
            place++;
        }
    }
    if (lid == SMALL_GROUP - 1u) {
        atomicAdd(&counters.selected, small_scan[lid]);
    }
    if (undecided > 0u) {
        atomicAdd(&counters.undecided, undecided);
    }
}

// compact_scan as a pass of its own (the split and the one-thread-an-item
// merges'; on lavapipe no slower than the per-corner counts).
@compute @workgroup_size(SMALL_GROUP)
fn merge_compact_scan(@builtin(local_invocation_index) lid: u32) {
    compact_scan(lid);
}
