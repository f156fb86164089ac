// A camera frame's way in: its 8-bit RGB bytes, uploaded as the
// camera gave them (packed into u32 words, little-endian), become the
// packed grey pixels NCC reads from the resident frame. The grey is the
// host's (GreyImage::from_rgb8) bit for bit: each channel's term is read
// from the same table (luma_terms: LUMA[c] * (v / 255) for c = 0, 1, 2 and
// v = 0..255) and the three are summed in the same order, adds only, each
// correctly rounded.

struct FrameParams {
    width: u32,
    height: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: FrameParams;
@group(0) @binding(1) var<storage, read> luma_terms: array<f32>;
@group(0) @binding(2) var<storage, read> rgb: array<u32>;
@group(0) @binding(3) var<storage, read_write> pixels: array<Pixel>;

fn byte_at(i: u32) -> u32 {
    return (rgb[i / 4u] >> ((i % 4u) * 8u)) & 0xffu;
}

@compute @workgroup_size(WORKGROUP_2D, WORKGROUP_2D)
fn grey_pack(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let i = id.y * params.width + id.x;
    let r = byte_at(3u * i);
    let g = byte_at(3u * i + 1u);
    let b = byte_at(3u * i + 2u);
    let v = luma_terms[r] + luma_terms[256u + g] + luma_terms[512u + b];
    pixels[i] = Pixel(v, PIXEL_VALID);
}

// A window of the resident frame as Harris reads it (its `pixels` input):
// the frame's pixels of the window, row by row, with PIXEL_ALLOWED set
// inside the rectangle where corners may be reported (window
// coordinates, inclusive), as the host packs a crop of the frame with
// that rectangle as its mask.
struct WindowParams {
    frame_width: u32,
    frame_height: u32,
    x0: u32,
    y0: u32,
    width: u32,
    height: u32,
    ax0: u32,
    ay0: u32,
    ax1: u32,
    ay1: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(4) var<storage, read_write> window_out: array<Pixel>;
@group(0) @binding(5) var<uniform> window: WindowParams;

@compute @workgroup_size(WORKGROUP_2D, WORKGROUP_2D)
fn window_pack(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= window.width || id.y >= window.height) {
        return;
    }
    var p = pixels[(window.y0 + id.y) * window.frame_width + window.x0 + id.x];
    if (id.x >= window.ax0 && id.x <= window.ax1 && id.y >= window.ay0 && id.y <= window.ay1) {
        p.flags = p.flags | PIXEL_ALLOWED;
    }
    window_out[id.y * window.width + id.x] = p;
}

// A window of the resident frame's grey levels as the pose check reads
// them (one f32 a pixel): NaN beyond the frame or where a pixel is
// invalid, as the host's crop of the frame gives them.
@group(0) @binding(6) var<storage, read_write> values_out: array<f32>;

@compute @workgroup_size(WORKGROUP_2D, WORKGROUP_2D)
fn window_values(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= window.width || id.y >= window.height) {
        return;
    }
    let x = window.x0 + id.x;
    let y = window.y0 + id.y;
    var v = bitcast<f32>(0x7fc00000u);
    if (x < window.frame_width && y < window.frame_height) {
        let p = pixels[y * window.frame_width + x];
        if ((p.flags & PIXEL_VALID) != 0u) {
            v = p.value;
        }
    }
    values_out[id.y * window.width + id.x] = v;
}
