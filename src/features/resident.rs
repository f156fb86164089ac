//! Images that stay on the GPU between the stages of a frame (issue 13):
//! a frame's grey levels uploaded once and read by every NCC matching of
//! the frame (IT, KF) and by the next frame's IT, and a novel view packed
//! by Harris on the GPU ([`super::Harris::resident_view`]), matched
//! without coming back to the host ([`super::NccMatcher::match_resident`]).

use super::FeatureError;
use super::gpu_data::{Pixel, pack_with_holes_into};
use super::image::GreyImage;
use crate::gpu::{GpuContext, GrowBuffer, STORAGE_IN};

/// An image on the GPU: `width x height` packed pixels, row-major (8 bytes
/// each: the grey value and flags, pinholes flagged, as the host's
/// packing for NCC packs them).
#[derive(Clone, Copy)]
pub struct ResidentImage<'a> {
    /// The pixels (at least `width x height` of them).
    pub pixels: &'a wgpu::Buffer,
    /// The image's width, pixels.
    pub width: usize,
    /// The image's height, pixels.
    pub height: usize,
}

impl ResidentImage<'_> {
    /// Checks that `rows` lie in the image and the buffer holds them.
    pub(crate) fn check(&self, rows: &std::ops::Range<usize>) -> Result<(), FeatureError> {
        let px = std::mem::size_of::<Pixel>() as u64;
        let need = (self.width * self.height) as u64 * px;
        if need > self.pixels.size() {
            return Err(FeatureError::ImageSize {
                width: self.width,
                height: self.height,
                len: (self.pixels.size() / px) as usize,
            });
        }
        if rows.end > self.height || rows.start > rows.end {
            return Err(FeatureError::Config(format!(
                "rows {}..{} of an image of {} rows",
                rows.start, rows.end, self.height
            )));
        }
        Ok(())
    }
}

/// A grey image kept on the GPU across calls (a grow-only buffer): the
/// tracker uploads each frame once into one of two and keeps the previous
/// frame's for IT.
pub struct GpuGrey {
    buf: GrowBuffer,
    width: usize,
    height: usize,
    /// The packed pixels on the host, kept between uploads.
    packed: Vec<Pixel>,
}

impl Default for GpuGrey {
    fn default() -> Self {
        Self::new()
    }
}

impl GpuGrey {
    /// An empty image (no buffer yet).
    pub fn new() -> Self {
        Self {
            buf: GrowBuffer::new("resident grey", STORAGE_IN),
            width: 0,
            height: 0,
            packed: Vec::new(),
        }
    }

    /// Uploads `img` (packed as NCC packs a host image: NaN invalid,
    /// pinholes flagged), growing the buffer if needed (on the GPU and on
    /// the host: once grown, an upload allocates nothing).
    pub fn upload(&mut self, ctx: &GpuContext, img: &GreyImage) {
        let px = std::mem::size_of::<Pixel>();
        self.buf.ensure(ctx, (img.data.len().max(1) * px) as u64);
        pack_with_holes_into(img, None, false, &mut self.packed);
        ctx.queue
            .write_buffer(self.buf.get(), 0, bytemuck::cast_slice(&self.packed));
        (self.width, self.height) = (img.width, img.height);
    }

    /// The image as the matcher reads it; `None` before the first upload.
    pub fn image(&self) -> Option<ResidentImage<'_>> {
        (self.width > 0 && self.height > 0).then(|| ResidentImage {
            pixels: self.buf.get(),
            width: self.width,
            height: self.height,
        })
    }
}

/// The largest [`Refinement::window`] the GPU refines.
pub const MAX_REFINE_WINDOW: u32 = 63;

/// The sub-pixel refinement of [`super::NccMatcher::match_resident`]: the
/// arguments of [`super::refine_match`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refinement {
    /// Window side, pixels (an even side uses the odd one below, as
    /// [`super::refine_match`] does).
    pub window: u32,
    /// The integer search, pixels each way.
    pub max_shift: u32,
    /// The least peak score.
    pub min_score: f32,
}

impl Refinement {
    pub(crate) fn validate(&self) -> Result<(), FeatureError> {
        if self.window > MAX_REFINE_WINDOW || self.max_shift > 16 {
            return Err(FeatureError::Config(format!(
                "refinement window {} (at most 63) or shift {} (at most 16)",
                self.window, self.max_shift
            )));
        }
        Ok(())
    }
}

/// A mutual match of [`super::NccMatcher::match_resident`]: feature `a`
/// and `b`, their NCC score, and where `b`'s point lies in its image
/// (pixels): refined when a refinement was asked for (`None` where it
/// failed), else `b`'s position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResidentMatch {
    pub a: usize,
    pub b: usize,
    pub score: f32,
    pub at: Option<[f64; 2]>,
}
