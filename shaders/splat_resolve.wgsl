// The splatter's normalisation pass (Botsch et al. 2005's deferred
// normalisation; Dehais et al. 2010, eq. 3): divide the accumulated weighted
// attributes by the summed weight. `resolve` writes one attribute of every
// pixel to a packed float buffer (NaN where no splat contributed);
// `gather` samples predictors and depth at a few pixel positions only, so the
// tracker reads back k x GATHER_STRIDE floats instead of whole images.
// CPU references: `SplatImage::from_accumulators` and `cpu::sample_at` in
// src/splat/. The constants (GATHER_STRIDE, workgroup sizes) come from
// the prelude of src/shaders.rs.

// Twin: `ResolveParams` in src/splat/gpu_data.rs.
struct ResolveParams {
    width: u32,
    height: u32,
    // resolve: RESOLVE_COLOR (3 floats), RESOLVE_DEPTH (1), RESOLVE_NORMAL
    // (3), RESOLVE_MOTION (12), RESOLVE_WEIGHT (1, the raw sum),
    // RESOLVE_DEPTH_MOTION (1: the depth of a render without geometry).
    // gather: number of points.
    kind: u32,
    // gather: GATHER_NEAREST (the nearest pixel) or GATHER_BILINEAR
    // (bilinear where all four pixels are covered).
    mode: u32,
    // gather and RESOLVE_DEPTH_MOTION: the render's focal length in x
    // (pixels).
    fx: f32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: ResolveParams;
@group(0) @binding(1) var t0: texture_2d<f32>;
@group(0) @binding(2) var t1: texture_2d<f32>;
@group(0) @binding(3) var t2: texture_2d<f32>;
@group(0) @binding(4) var t3: texture_2d<f32>;
@group(0) @binding(5) var t4: texture_2d<f32>;
@group(0) @binding(6) var<storage, read_write> out: array<f32>;
@group(0) @binding(7) var<storage, read> points: array<vec2<f32>>;

fn nan() -> f32 {
    // A quiet NaN, written where a pixel is empty.
    return bitcast<f32>(0x7fc00000u);
}

@compute @workgroup_size(RESOLVE_WORKGROUP, RESOLVE_WORKGROUP)
fn resolve(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let p = vec2<i32>(id.xy);
    let a = textureLoad(t0, p, 0);
    let w = a.w;
    let pixel = id.y * params.width + id.x;
    switch params.kind {
        case RESOLVE_COLOR: {
            let base = pixel * 3u;
            for (var k = 0u; k < 3u; k++) {
                out[base + k] = select(nan(), a[k] / w, w > 0.0);
            }
        }
        case RESOLVE_DEPTH: {
            out[pixel] = select(nan(), textureLoad(t1, p, 0).x / w, w > 0.0);
        }
        case RESOLVE_DEPTH_MOTION: {
            // gather's depth at every pixel: fx over the normalised du_tx.
            out[pixel] = select(nan(), params.fx / (textureLoad(t2, p, 0).x / w), w > 0.0);
        }
        case RESOLVE_NORMAL: {
            let base = pixel * 3u;
            let n = textureLoad(t1, p, 0).yzw;
            // The weighted mean of unit normals, renormalised.
            let len = length(n);
            for (var k = 0u; k < 3u; k++) {
                out[base + k] = select(nan(), n[k] / len, w > 0.0 && len > 0.0);
            }
        }
        case RESOLVE_MOTION: {
            let base = pixel * 12u;
            let b = textureLoad(t2, p, 0);
            let c = textureLoad(t3, p, 0);
            let d = textureLoad(t4, p, 0);
            for (var k = 0u; k < 4u; k++) {
                out[base + k] = select(nan(), b[k] / w, w > 0.0);
                out[base + 4u + k] = select(nan(), c[k] / w, w > 0.0);
                out[base + 8u + k] = select(nan(), d[k] / w, w > 0.0);
            }
        }
        case RESOLVE_WEIGHT, default: {
            out[pixel] = w;
        }
    }
}

// Normalised predictors of pixel p, or w <= 0 when empty.
struct Sample {
    w: f32,
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
}

fn load(p: vec2<i32>) -> Sample {
    var s: Sample;
    s.w = textureLoad(t0, p, 0).w;
    if s.w <= 0.0 {
        s.w = 0.0;
        return s;
    }
    s.a = textureLoad(t2, p, 0) / s.w;
    s.b = textureLoad(t3, p, 0) / s.w;
    s.c = textureLoad(t4, p, 0) / s.w;
    return s;
}

fn inside(p: vec2<i32>) -> bool {
    return p.x >= 0 && p.y >= 0 && p.x < i32(params.width) && p.y < i32(params.height);
}

// Output per point (GATHER_STRIDE floats): du_tx, dv_tx, ..., du_rz,
// dv_rz (12), depth, valid (1 or 0); predictors and depth are NaN when
// invalid. The depth is the one the translation predictor du_tx = fx / z
// gives (eq. 5): the harmonic mean of the fragments' depths, read from the
// predictors so that a render needs no geometry for it.
@compute @workgroup_size(WORKGROUP_1D)
fn gather(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.kind {
        return;
    }
    let x = points[i];
    var s: Sample;
    s.w = 0.0;
    var done = false;
    if params.mode == GATHER_BILINEAR && all(x == x) {
        let f = floor(x);
        let p0 = vec2<i32>(f);
        let t = x - f;
        if inside(p0) && inside(p0 + vec2<i32>(1, 1)) {
            let s00 = load(p0);
            let s10 = load(p0 + vec2<i32>(1, 0));
            let s01 = load(p0 + vec2<i32>(0, 1));
            let s11 = load(p0 + vec2<i32>(1, 1));
            if s00.w > 0.0 && s10.w > 0.0 && s01.w > 0.0 && s11.w > 0.0 {
                let k00 = (1.0 - t.x) * (1.0 - t.y);
                let k10 = t.x * (1.0 - t.y);
                let k01 = (1.0 - t.x) * t.y;
                let k11 = t.x * t.y;
                s.w = 1.0;
                s.a = k00 * s00.a + k10 * s10.a + k01 * s01.a + k11 * s11.a;
                s.b = k00 * s00.b + k10 * s10.b + k01 * s01.b + k11 * s11.b;
                s.c = k00 * s00.c + k10 * s10.c + k01 * s01.c + k11 * s11.c;
                done = true;
            }
        }
    }
    if !done && all(x == x) {
        let p = vec2<i32>(floor(x + vec2<f32>(0.5, 0.5)));
        if inside(p) {
            s = load(p);
        }
    }
    let base = i * GATHER_STRIDE;
    let valid = s.w > 0.0;
    for (var k = 0u; k < 4u; k++) {
        out[base + k] = select(nan(), s.a[k], valid);
        out[base + 4u + k] = select(nan(), s.b[k], valid);
        out[base + 8u + k] = select(nan(), s.c[k], valid);
    }
    out[base + 12u] = select(nan(), params.fx / s.a.x, valid);
    out[base + 13u] = select(0.0, 1.0, valid);
}
