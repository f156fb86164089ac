//! The grey float image that feature detection and matching work on.

use super::FeatureError;

/// Rec. 601 luma weights, the usual grey conversion of 8-bit video.
pub const LUMA: [f32; 3] = [0.299, 0.587, 0.114];

/// [`LUMA`] for WGSL (shaders/harris_maps.wgsl, shaders/verify.wgsl).
pub(crate) const LUMA_CONSTANTS: crate::shaders::Constants = &[
    ("LUMA_R", crate::shaders::WgslValue::F32(LUMA[0])),
    ("LUMA_G", crate::shaders::WgslValue::F32(LUMA[1])),
    ("LUMA_B", crate::shaders::WgslValue::F32(LUMA[2])),
];

/// `LUMA[c] * (v as f32 / 255.0)` for every channel `c` and byte `v`
/// ([`GreyImage::from_rgb8`]).
pub(crate) static LUMA_TERMS: std::sync::LazyLock<[[f32; 256]; 3]> =
    std::sync::LazyLock::new(|| {
        std::array::from_fn(|c| std::array::from_fn(|v| LUMA[c] * (v as f32 / 255.0)))
    });

/// A grey image, row-major, values in 0..1 (any finite range works: the
/// Harris threshold is relative and NCC is invariant to gain and offset).
/// NaN marks an invalid pixel, e.g. an empty pixel of a rendered novel view:
/// no corner's support and no matching window may touch one.
#[derive(Debug, Clone, PartialEq)]
pub struct GreyImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height` grey values, row-major; NaN marks an invalid pixel.
    pub data: Vec<f32>,
}

impl GreyImage {
    /// An image from row-major data; errors if the length is not
    /// `width * height`.
    pub fn new(width: usize, height: usize, data: Vec<f32>) -> Result<Self, FeatureError> {
        if width.checked_mul(height) != Some(data.len()) {
            return Err(FeatureError::ImageSize {
                width,
                height,
                len: data.len(),
            });
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// A constant image.
    pub fn filled(width: usize, height: usize, value: f32) -> Self {
        Self {
            width,
            height,
            data: vec![value; width * height],
        }
    }

    /// An image whose pixel (x, y) is `f(x, y)`.
    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> f32) -> Self {
        let mut data = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Self {
            width,
            height,
            data,
        }
    }

    /// Grey (Rec. 601 luma) of any decoded image, scaled to 0..1. Alpha is
    /// ignored.
    pub fn from_dynamic(img: &image::DynamicImage) -> Self {
        let rgb = img.to_rgb32f();
        let (w, h) = rgb.dimensions();
        let data = rgb
            .pixels()
            .map(|p| LUMA[0] * p[0] + LUMA[1] * p[1] + LUMA[2] * p[2])
            .collect();
        Self {
            width: w as usize,
            height: h as usize,
            data,
        }
    }

    /// Grey (Rec. 601 luma) of an 8-bit RGB image, scaled to 0..1: the CPU
    /// twin of the GPU's `grey` pass ([`super::Harris::detect_rgb8`]).
    pub fn from_rgb8(img: &image::RgbImage) -> Self {
        let (w, h) = img.dimensions();
        // Each channel's term tabulated (`LUMA[c] * (v / 255)`, the same
        // rounding), summed in the same order: the same grey bit for bit,
        // without a division a channel (3x faster at 640x480).
        let t = &*LUMA_TERMS;
        let data = img
            .as_raw()
            .chunks_exact(3)
            .map(|p| t[0][p[0] as usize] + t[1][p[1] as usize] + t[2][p[2] as usize])
            .collect();
        Self {
            width: w as usize,
            height: h as usize,
            data,
        }
    }

    /// Grey of interleaved RGB floats (e.g. a rendered colour `.npy`, 0..1);
    /// a pixel with any NaN channel becomes NaN (invalid).
    pub fn from_rgb_f32(width: usize, height: usize, rgb: &[f32]) -> Result<Self, FeatureError> {
        if width.checked_mul(height).and_then(|n| n.checked_mul(3)) != Some(rgb.len()) {
            return Err(FeatureError::ImageSize {
                width,
                height,
                len: rgb.len() / 3,
            });
        }
        let data = rgb
            .chunks_exact(3)
            .map(|p| LUMA[0] * p[0] + LUMA[1] * p[1] + LUMA[2] * p[2])
            .collect();
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// The value at (x, y); panics out of bounds.
    pub fn get(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Whether the image has no pixels.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// An 8-bit grey picture (invalid pixels black), for visualisation.
    pub fn to_luma8(&self) -> image::GrayImage {
        let px = self
            .data
            .iter()
            .map(|v| {
                if v.is_finite() {
                    (v.clamp(0.0, 1.0) * 255.0).round() as u8
                } else {
                    0
                }
            })
            .collect();
        image::GrayImage::from_raw(self.width as u32, self.height as u32, px)
            .unwrap_or_else(|| image::GrayImage::new(0, 0))
    }

    /// Bilinear sample at sub-pixel `(x, y)` (OpenCV convention), or `None`
    /// if any of the four pixels involved is outside the image or invalid.
    /// This is the sampling rule of the NCC windows.
    pub fn bilinear(&self, x: f32, y: f32) -> Option<f32> {
        let (w, h) = (self.width as i64, self.height as i64);
        if w < 2 || h < 2 || !(x >= 0.0 && y >= 0.0) {
            return None;
        }
        if x > (w - 1) as f32 || y > (h - 1) as f32 {
            return None;
        }
        // Clamp so that x0 + 1 stays inside: a sample on the last column
        // then has fx = 1 rather than needing a column beyond the image.
        let x0 = (x.floor() as i64).min(w - 2);
        let y0 = (y.floor() as i64).min(h - 2);
        let fx = x - x0 as f32;
        let fy = y - y0 as f32;
        let i = (y0 * w + x0) as usize;
        let w = w as usize;
        let (p00, p10, p01, p11) = (
            self.data[i],
            self.data[i + 1],
            self.data[i + w],
            self.data[i + w + 1],
        );
        if !(p00.is_finite() && p10.is_finite() && p01.is_finite() && p11.is_finite()) {
            return None;
        }
        Some(bilerp(p00, p10, p01, p11, fx, fy))
    }
}

/// Bilinear interpolation written once, in the order the NCC shader uses.
pub(crate) fn bilerp(p00: f32, p10: f32, p01: f32, p11: f32, fx: f32, fy: f32) -> f32 {
    let top = p00 + fx * (p10 - p00);
    let bottom = p01 + fx * (p11 - p01);
    top + fy * (bottom - top)
}

/// Checks an optional mask against an image's size.
pub(crate) fn check_mask(img: &GreyImage, mask: Option<&[bool]>) -> Result<(), FeatureError> {
    if img.width.checked_mul(img.height) != Some(img.data.len()) {
        return Err(FeatureError::ImageSize {
            width: img.width,
            height: img.height,
            len: img.data.len(),
        });
    }
    match mask {
        Some(m) if m.len() != img.data.len() => Err(FeatureError::MaskSize {
            expected: img.data.len(),
            got: m.len(),
        }),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_interpolates_and_refuses_outside_or_invalid() {
        #[rustfmt::skip]
        let img = GreyImage::new(3, 2, vec![
            0.0, 1.0, 2.0,
            3.0, 4.0, f32::NAN,
        ]).unwrap();
        assert_eq!(img.bilinear(0.5, 0.5), Some(2.0));
        assert_eq!(img.bilinear(0.0, 0.0), Some(0.0));
        assert_eq!(img.bilinear(1.0, 1.0), None, "touches the NaN pixel");
        assert_eq!(img.bilinear(-0.1, 0.0), None);
        assert_eq!(img.bilinear(0.0, 1.01), None);
        assert_eq!(img.bilinear(f32::NAN, 0.0), None);
        assert!(GreyImage::filled(1, 1, 0.5).bilinear(0.0, 0.0).is_none());
    }

    #[test]
    fn grey_of_8_bit_rgb_is_the_luma_formula_bit_for_bit() {
        // The tabulated terms against the formula: every byte of each
        // channel with the others at 0, 128 and 255, and 200,000 random
        // pixels.
        let formula = |p: [u8; 3]| {
            let [r, g, b] = p.map(|v| v as f32 / 255.0);
            LUMA[0] * r + LUMA[1] * g + LUMA[2] * b
        };
        let mut pixels: Vec<[u8; 3]> = Vec::new();
        for v in 0..=255u8 {
            for o in [0u8, 128, 255] {
                pixels.extend([[v, o, o], [o, v, o], [o, o, v]]);
            }
        }
        let mut rng = crate::rng::Rng::new(5);
        pixels.extend((0..200_000).map(|_| [0; 3].map(|_: u8| rng.uniform(0.0, 256.0) as u8)));
        let img = image::RgbImage::from_raw(
            pixels.len() as u32,
            1,
            pixels.iter().flatten().copied().collect(),
        )
        .unwrap();
        let grey = GreyImage::from_rgb8(&img);
        for (p, g) in pixels.iter().zip(&grey.data) {
            assert_eq!(g.to_bits(), formula(*p).to_bits(), "{p:?}");
        }
    }

    #[test]
    fn sizes_are_checked() {
        assert!(GreyImage::new(3, 2, vec![0.0; 5]).is_err());
        assert!(GreyImage::new(0, 0, vec![]).is_ok());
        assert!(GreyImage::from_rgb_f32(2, 1, &[0.0; 5]).is_err());
        let g = GreyImage::from_rgb_f32(2, 1, &[1.0, 1.0, 1.0, f32::NAN, 0.0, 0.0]).unwrap();
        assert!((g.data[0] - 1.0).abs() < 1e-6 && g.data[1].is_nan());
        let img = GreyImage::filled(2, 2, 0.0);
        assert!(check_mask(&img, Some(&[true; 3])).is_err());
        assert!(check_mask(&img, Some(&[true; 4])).is_ok());
    }
}
