// The grey pixel of the feature kernels (harris_*.wgsl, ncc_*.wgsl,
// frame.wgsl), composed after the prelude (src/features/gpu_data.rs
// declares the part and its constants: PIXEL_VALID, PIXEL_ALLOWED,
// PIXEL_HOLE). Checked against its Rust twin by the tests of
// src/shaders.rs.

// A grey pixel of the feature kernels (twin: `Pixel` in
// src/features/gpu_data.rs); `flags` holds PIXEL_VALID and PIXEL_ALLOWED.
struct Pixel {
    value: f32,
    flags: u32,
}

// The value is finite and usable.
fn pixel_valid(p: Pixel) -> bool {
    return (p.flags & PIXEL_VALID) != 0u;
}

// An invalid pixel that is a pinhole (tolerated by Harris and NCC).
fn pixel_hole(p: Pixel) -> bool {
    return (p.flags & PIXEL_HOLE) != 0u;
}

// A corner may be reported here (inside the mask).
fn pixel_allowed(p: Pixel) -> bool {
    return (p.flags & PIXEL_ALLOWED) != 0u;
}
