// Self-test kernel: y[i] = a * x[i] + y[i]. Used by `splattrack info` and the
// GPU context tests to prove upload, dispatch and readback end to end.

// Twin: `SelftestParams` in src/gpu/selftest.rs.
struct SelftestParams {
    a: f32,
    n: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: SelftestParams;
@group(0) @binding(1) var<storage, read> x: array<f32>;
@group(0) @binding(2) var<storage, read_write> y: array<f32>;

@compute @workgroup_size(WORKGROUP_1D)
fn saxpy(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.n) {
        return;
    }
    y[i] = fma(params.a, x[i], y[i]);
}
