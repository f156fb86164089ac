// The contour's silhouette points on the GPU (no image readback
// in the loop): from the splatted depth of the contour's window (NaN where
// empty, as the splatter resolves it), the points `extract_contour` in
// src/tracker/contour/outline.rs finds, its CPU reference. A few integers a point
// come back (its pixel, the covered pixels' offset sums over its window,
// their count, the depth there), and the window's coverage as bits, for
// learning the colours; the host turns the sums into the normal and the
// sub-pixel edge position with the reference's own f64 arithmetic.
//
// Passes: `candidates` (one thread per pixel) finds the silhouette pixels
// whose window gives a reliable normal and keeps, per spacing x spacing
// cell, the first of them in raster order (an atomic max of its inverted
// index: 0 is none); `points` (one thread per cell) writes the kept
// pixel's point, in no particular order (the host sorts them by index);
// `coverage` (one thread per 32 pixels) packs the coverage into bits.
// The cells and the count are cleared by the host's encoder before.

// Twin: `OutlineParams` in src/tracker/outline_gpu.rs.
struct OutlineParams {
    width: u32,
    height: u32,
    spacing: u32,
    cells_x: u32,
    cells: u32,
    // Points the `points` buffer holds.
    capacity: u32,
    // u32 words of coverage bits.
    words: u32,
    pad: u32,
}

// Twin: `OutlinePoint` in src/tracker/outline_gpu.rs.
struct OutlinePoint {
    x: u32,
    y: u32,
    // The sums of the covered pixels' offsets over the window, and their
    // count.
    gx: i32,
    gy: i32,
    covered: u32,
    depth: f32,
}

@group(0) @binding(0) var<uniform> params: OutlineParams;
@group(0) @binding(1) var<storage, read> depth: array<f32>;
@group(0) @binding(2) var<storage, read_write> first: array<atomic<u32>>;
// [0]: the points found (more than `capacity` when some did not fit).
@group(0) @binding(3) var<storage, read_write> count: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read_write> points: array<OutlinePoint>;
@group(0) @binding(5) var<storage, read_write> bits: array<u32>;

// Whether the pixel holds a splat: a finite depth (a bit test, so that no
// compiler can fold a NaN comparison away). Pixels beyond the window
// count as covered, as in the reference: an object the window (the image)
// cuts has no contour there.
fn covered(x: i32, y: i32) -> bool {
    if (x < 0 || y < 0 || x >= i32(params.width) || y >= i32(params.height)) {
        return true;
    }
    let b = bitcast<u32>(depth[u32(y) * params.width + u32(x)]);
    return (b & 0x7f800000u) != 0x7f800000u;
}

// The covered pixels' offset sums (x, y) and count over the
// (2 OUTLINE_WINDOW + 1)^2 window around (x, y).
fn window_sums(x: i32, y: i32) -> vec3<i32> {
    var s = vec3<i32>(0, 0, 0);
    let r = i32(OUTLINE_WINDOW);
    for (var dy = -r; dy <= r; dy++) {
        for (var dx = -r; dx <= r; dx++) {
            if (covered(x + dx, y + dy)) {
                s += vec3<i32>(dx, dy, 1);
            }
        }
    }
    return s;
}

@compute @workgroup_size(WORKGROUP_2D, WORKGROUP_2D)
fn candidates(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let x = i32(id.x);
    let y = i32(id.y);
    if (!covered(x, y)
        || (covered(x - 1, y) && covered(x + 1, y) && covered(x, y - 1) && covered(x, y + 1))) {
        return;
    }
    let s = window_sums(x, y);
    // |g| < OUTLINE_MIN_GRADIENT (exact in integers): a thin part or a
    // corner, whose normal is unreliable.
    if (s.x * s.x + s.y * s.y < i32(OUTLINE_MIN_GRADIENT * OUTLINE_MIN_GRADIENT)) {
        return;
    }
    let cell = (id.y / params.spacing) * params.cells_x + id.x / params.spacing;
    atomicMax(&first[cell], 0xffffffffu - (id.y * params.width + id.x));
}

@compute @workgroup_size(WORKGROUP_1D)
fn points_of_cells(@builtin(global_invocation_id) id: vec3<u32>) {
    let cell = id.x;
    if (cell >= params.cells) {
        return;
    }
    let f = atomicLoad(&first[cell]);
    if (f == 0u) {
        return;
    }
    let i = 0xffffffffu - f;
    let x = i % params.width;
    let y = i / params.width;
    let s = window_sums(i32(x), i32(y));
    let slot = atomicAdd(&count[0], 1u);
    if (slot < params.capacity) {
        points[slot] = OutlinePoint(x, y, s.x, s.y, u32(s.z), depth[i]);
    }
}

@compute @workgroup_size(WORKGROUP_1D)
fn coverage(@builtin(global_invocation_id) id: vec3<u32>) {
    let word = id.x;
    if (word >= params.words) {
        return;
    }
    let n = params.width * params.height;
    var b = 0u;
    for (var k = 0u; k < 32u; k++) {
        let i = word * 32u + k;
        if (i < n && covered(i32(i % params.width), i32(i / params.width))) {
            b |= 1u << k;
        }
    }
    bits[word] = b;
}
