//! A frame as the tracker's steps see it ([`Frame`]).

use crate::features::{Corner, GreyImage};

/// A frame as the steps see it (the one being tracked, and the previous
/// one for IT): its bytes, kept (the next frame's frozen check compares
/// them), its corners, and its grey levels, made from the bytes when a
/// host path first asks for them ([`Frame::grey`]). The resident loop
/// never does: the GPU makes its own grey image from the uploaded bytes
/// ([`crate::features::resident::FrameIntake`]).
pub(super) struct Frame {
    pub(super) rgb: image::RgbImage,
    pub(super) grey: std::sync::OnceLock<GreyImage>,
    pub(super) corners: Vec<Corner>,
}

impl Frame {
    /// Frame `rgb`, its corners to come.
    pub(super) fn new(rgb: image::RgbImage) -> Self {
        Self {
            rgb,
            grey: std::sync::OnceLock::new(),
            corners: Vec::new(),
        }
    }

    /// The frame's grey levels ([`GreyImage::from_rgb8`]), made at the
    /// first call.
    pub(super) fn grey(&self) -> &GreyImage {
        self.grey.get_or_init(|| GreyImage::from_rgb8(&self.rgb))
    }

    /// The whole frame as a window.
    pub(super) fn whole(&self) -> crate::splat::Window {
        crate::splat::Window {
            x0: 0,
            y0: 0,
            width: self.rgb.width(),
            height: self.rgb.height(),
        }
    }
}
