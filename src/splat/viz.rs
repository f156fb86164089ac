//! Pictures of splatted attribute images (for `splattrack render` and the
//! docs, docs/guide.md): colour as 8-bit sRGB, depth through a colour map, normals as
//! RGB, and the motion predictors as a motion-field picture in the spirit of
//! the paper's Figs. 4c and 5: six panels, one per generator (top row:
//! translations x, y, z; bottom row: rotations about x, y, z), each a
//! colour-wheel encoding of the image motion (hue: direction, brightness:
//! speed relative to that generator's 99th-percentile speed). Empty pixels
//! are transparent (colour) or black (the others).

use super::SplatImage;
use image::{Rgb, RgbImage, Rgba, RgbaImage};

fn srgb(linear: f32) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// Colour (3 channels, linear RGB) as RGBA, empty pixels transparent.
pub fn color_picture(img: &SplatImage) -> RgbaImage {
    RgbaImage::from_fn(img.width, img.height, |x, y| {
        let p = img.pixel(x, y);
        if p[0].is_nan() {
            Rgba([0, 0, 0, 0])
        } else {
            Rgba([srgb(p[0]), srgb(p[1]), srgb(p[2]), 255])
        }
    })
}

/// A perceptually ordered map from dark blue (0) through green to yellow (1).
fn colormap(t: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] = [
        [0.19, 0.07, 0.23],
        [0.17, 0.45, 0.85],
        [0.10, 0.80, 0.55],
        [0.75, 0.85, 0.20],
        [0.98, 0.95, 0.55],
    ];
    let t = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f32;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let f = t - i as f32;
    std::array::from_fn(|k| ((STOPS[i][k] * (1.0 - f) + STOPS[i + 1][k] * f) * 255.0).round() as u8)
}

/// Depth (1 channel) through the colour map, near bright, far dark,
/// normalised to the covered pixels' range.
pub fn depth_picture(img: &SplatImage) -> RgbImage {
    let (lo, hi) = img
        .data
        .iter()
        .filter(|v| !v.is_nan())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let range = (hi - lo).max(1e-12);
    RgbImage::from_fn(img.width, img.height, |x, y| {
        let z = img.pixel(x, y)[0];
        if z.is_nan() {
            Rgb([0, 0, 0])
        } else {
            Rgb(colormap(1.0 - (z - lo) / range))
        }
    })
}

/// Normals (3 channels) as RGB = (n + 1) / 2.
pub fn normal_picture(img: &SplatImage) -> RgbImage {
    RgbImage::from_fn(img.width, img.height, |x, y| {
        let n = img.pixel(x, y);
        if n[0].is_nan() {
            Rgb([0, 0, 0])
        } else {
            Rgb(std::array::from_fn(|k| {
                (((n[k] + 1.0) * 0.5).clamp(0.0, 1.0) * 255.0).round() as u8
            }))
        }
    })
}

fn hsv(h: f32, s: f32, v: f32) -> [u8; 3] {
    let h = h.rem_euclid(1.0) * 6.0;
    let i = h.floor();
    let f = h - i;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    let rgb = match i as u32 {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    };
    rgb.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)
}

/// The motion predictors (12 channels) as six half-resolution colour-wheel
/// panels, 3 x 2, separated by 2-pixel grey lines.
pub fn motion_picture(img: &SplatImage) -> RgbImage {
    let (pw, ph) = (img.width.div_ceil(2), img.height.div_ceil(2));
    let gap = 2;
    let mut out = RgbImage::from_pixel(3 * pw + 2 * gap, 2 * ph + gap, Rgb([64, 64, 64]));
    for j in 0..6 {
        let mut speeds: Vec<f32> = img
            .data
            .chunks(12)
            .filter(|p| !p[0].is_nan())
            .map(|p| p[2 * j].hypot(p[2 * j + 1]))
            .collect();
        speeds.sort_by(f32::total_cmp);
        let scale = speeds
            .get((speeds.len() as f32 * 0.99) as usize)
            .or(speeds.last())
            .copied()
            .unwrap_or(1.0)
            .max(1e-12);
        let (ox, oy) = ((j as u32 % 3) * (pw + gap), (j as u32 / 3) * (ph + gap));
        for y in 0..ph {
            for x in 0..pw {
                let p = img.pixel((2 * x).min(img.width - 1), (2 * y).min(img.height - 1));
                let c = if p[0].is_nan() {
                    [0, 0, 0]
                } else {
                    let (du, dv) = (p[2 * j], p[2 * j + 1]);
                    let hue = dv.atan2(du) / std::f32::consts::TAU;
                    let mag = (du.hypot(dv) / scale).min(1.0);
                    hsv(hue, 0.85, 0.25 + 0.75 * mag)
                };
                out.put_pixel(ox + x, oy + y, Rgb(c));
            }
        }
    }
    out
}
