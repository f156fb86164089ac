//! Normalised images read from a render ([`SplatImage`]).

/// A normalised attribute image read back to the host: row-major
/// `height x width x channels`, NaN in every channel of empty pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct SplatImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Channels per pixel (see [`super::Attribute::channels`]).
    pub channels: usize,
    /// `height * width * channels` values, row-major; NaN where empty.
    pub data: Vec<f32>,
}

impl SplatImage {
    /// The channels of pixel (x, y).
    pub fn pixel(&self, x: u32, y: u32) -> &[f32] {
        let i = (y as usize * self.width as usize + x as usize) * self.channels;
        &self.data[i..i + self.channels]
    }

    /// True where a splat covers the pixel.
    pub fn is_valid(&self, x: u32, y: u32) -> bool {
        !self.pixel(x, y)[0].is_nan()
    }

    /// Number of covered pixels.
    pub fn coverage(&self) -> usize {
        self.data
            .chunks(self.channels)
            .filter(|p| !p[0].is_nan())
            .count()
    }
}
