// NCC matching, the gate of A's features by a gather. One module with ncc_score.wgsl,
// ncc_refine.wgsl and ncc_gate.wgsl (composed in that order after the
// prelude and pixel.wgsl; the bindings and the shared structs are in
// ncc_score.wgsl).

// The gate (NccMatcher::match_resident_exported_b): A's features whose
// sample in a gather at them is empty (its validity, the last of its
// GATHER_STRIDE floats, 0: off the object) are moved far outside any
// image before the matching, so that they match nothing, as where the
// host leaves them out. One thread a feature of A.
@group(0) @binding(20) var<storage, read> gate_samples: array<f32>;
@group(0) @binding(22) var<storage, read_write> gate_positions: array<vec2<f32>>;

// NccMatcher's sanitize: a position far outside any image.
const GATE_FAR: f32 = -1.0e9;

@compute @workgroup_size(WORKGROUP_1D)
fn gate(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.na) {
        return;
    }
    if (!(gate_samples[i * GATHER_STRIDE + GATHER_STRIDE - 1u] > 0.5)) {
        gate_positions[i] = vec2<f32>(GATE_FAR, GATE_FAR);
    }
}
