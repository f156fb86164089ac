// A camera frame's way in (issue 13): its 8-bit RGB bytes, uploaded as the
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
