// The live view's blit: the composed picture (an RGBA8 texture) drawn into
// a window's surface, scaled to fit and letterboxed, by bilinear
// interpolation written out with textureLoad (no sampler: the CPU
// reference, `present_cpu` in src/view/present.rs, does the same f32
// arithmetic, so the two agree to the rounding of the output).

// Twin: `PresentParams` in src/view/present.rs.
struct PresentParams {
    // The picture's rectangle in the target, pixels: x0, y0, x1, y1.
    rect: vec4<f32>,
    // The colour around it (RGBA, 0-1).
    background: vec4<f32>,
    // The picture's size, pixels.
    size: vec2<u32>,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: PresentParams;
@group(0) @binding(1) var picture: texture_2d<f32>;

// One triangle that covers the whole target.
@vertex
fn vs_present(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let x = f32(i32(i & 1u) * 4 - 1);
    let y = f32(i32(i >> 1u) * 4 - 1);
    return vec4<f32>(x, y, 0.0, 1.0);
}

fn texel(x: i32, y: i32) -> vec4<f32> {
    let hi = vec2<i32>(params.size) - vec2<i32>(1, 1);
    return textureLoad(picture, clamp(vec2<i32>(x, y), vec2<i32>(0, 0), hi), 0);
}

@fragment
fn fs_present(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
    // p.xy is the target pixel's centre (x + 0.5, y + 0.5).
    let r = params.rect;
    if (p.x < r.x || p.y < r.y || p.x >= r.z || p.y >= r.w) {
        return params.background;
    }
    let size = vec2<f32>(params.size);
    // The picture's continuous coordinates, pixel centres at integers.
    let u = (p.x - r.x) * size.x / (r.z - r.x) - 0.5;
    let v = (p.y - r.y) * size.y / (r.w - r.y) - 0.5;
    let x0 = floor(u);
    let y0 = floor(v);
    let fx = u - x0;
    let fy = v - y0;
    let ix = i32(x0);
    let iy = i32(y0);
    let top = mix(texel(ix, iy), texel(ix + 1, iy), fx);
    let bottom = mix(texel(ix, iy + 1), texel(ix + 1, iy + 1), fx);
    return mix(top, bottom, fy);
}
