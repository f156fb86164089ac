// Harris corners, the export of the selected corners. One module with harris_maps.wgsl,
// harris_select.wgsl, harris_select_small.wgsl and harris_export.wgsl
// (composed in that order after the prelude and pixel.wgsl; the bindings
// and the shared structs are in harris_maps.wgsl).

// ---------------------------------------------------------------------------
// The export (Harris::export_corners): the corners a detection selected
// here, handed to the next stages without a readback, as one side of an
// NCC matching (NccMatcher::match_resident_exported) and the points of a
// gather. One thread a slot of `n` (the most corners a detection keeps):
// slot i < kept gets corner i, the others a point far outside any image
// (a void window, an empty sample). `kept` is 0 where the corners are not
// final here (more candidates than the GPU selects among, or a merge left
// to the host): the host then matches the corners it finishes itself.
// The points are the corners' positions in the window (the detection's
// pixels). NCC's positions are those moved by the origin (into the
// matched image's pixels, one rounding as the host's), far away where
// outside the clip rectangle (as the host leaves features outside its
// crop out), with the band's first row taken off (a second rounding, as
// the host's), from slot `first` on.

// Twin: ExportParams in src/features/gpu_data.rs.
struct ExportParams {
    origin_x: f32,
    origin_y: f32,
    // The first row of the band in NCC's pixel buffer.
    band_y0: f32,
    n: u32,
    first: u32,
    clip: u32,
    pad0: u32,
    pad1: u32,
    clip_x0: f32,
    clip_y0: f32,
    clip_x1: f32,
    clip_y1: f32,
}

@group(0) @binding(13) var<uniform> export_params: ExportParams;
@group(0) @binding(14) var<storage, read_write> export_positions: array<vec2<f32>>;
@group(0) @binding(15) var<storage, read_write> export_points: array<vec2<f32>>;

// NccMatcher's sanitize: a position far outside any image.
const FAR_AWAY: f32 = -1.0e9;

@compute @workgroup_size(WORKGROUP_1D)
fn export_corners(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    let e = export_params;
    if (i >= e.n) {
        return;
    }
    var kept = 0u;
    if (atomicLoad(&counters.undecided) == 0u) {
        kept = min(atomicLoad(&counters.selected), slot_count());
    }
    var pos = vec2<f32>(FAR_AWAY, FAR_AWAY);
    var pt = pos;
    if (i < kept) {
        let c = corners[i];
        pt = vec2<f32>(c.x, c.y);
        let x = c.x + e.origin_x;
        let y = c.y + e.origin_y;
        let inside = x >= e.clip_x0 && y >= e.clip_y0 && x < e.clip_x1 && y < e.clip_y1;
        if (e.clip == 0u || inside) {
            pos = vec2<f32>(x, y - e.band_y0);
        }
    }
    export_positions[e.first + i] = pos;
    export_points[i] = pt;
}
