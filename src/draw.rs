//! Drawing on RGB images, for every picture the tool writes: primitives
//! (lines, circles, crosses, rectangles, 8x8 bitmap text), tracking
//! overlays, and pictures of corners and matches.

use crate::features::{Corner, Match};
use image::{Rgb, RgbImage};

/// An RGB colour, one byte per channel.
pub type Colour = [u8; 3];

/// Pure white.
pub const WHITE: Colour = [255, 255, 255];
/// Pure black.
pub const BLACK: Colour = [0, 0, 0];
/// Mid grey, for axes and secondary marks.
pub const GREY: Colour = [150, 150, 150];
/// Light grey, for grid lines and backgrounds.
pub const LIGHT_GREY: Colour = [225, 225, 225];

/// A palette of distinguishable colours for series (Okabe-Ito).
pub const PALETTE: [Colour; 7] = [
    [0, 114, 178],
    [213, 94, 0],
    [0, 158, 115],
    [204, 121, 167],
    [230, 159, 0],
    [86, 180, 233],
    [120, 120, 120],
];

/// Sets pixel (x, y) if inside the image, blending with `alpha` in 0..1.
pub fn blend(img: &mut RgbImage, x: i64, y: i64, c: Colour, alpha: f32) {
    if x < 0 || y < 0 || x >= img.width() as i64 || y >= img.height() as i64 {
        return;
    }
    let p = img.get_pixel_mut(x as u32, y as u32);
    for (v, ck) in p.0.iter_mut().zip(c) {
        *v = (*v as f32 * (1.0 - alpha) + ck as f32 * alpha).round() as u8;
    }
}

/// Sets pixel (x, y) to `c` if inside the image; does nothing otherwise.
pub fn put(img: &mut RgbImage, x: i64, y: i64, c: Colour) {
    if x >= 0 && y >= 0 && x < img.width() as i64 && y < img.height() as i64 {
        img.put_pixel(x as u32, y as u32, Rgb(c));
    }
}

/// A line of `width` pixels between two points (pixel-centre coordinates).
pub fn line(img: &mut RgbImage, x0: f64, y0: f64, x1: f64, y1: f64, c: Colour, width: f64) {
    if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) {
        return;
    }
    let len = ((x1 - x0).powi(2) + (y1 - y0).powi(2)).sqrt();
    let steps = (len * 2.0).ceil().clamp(1.0, 1e5) as usize;
    let r = (width * 0.5).max(0.5);
    let ri = r.ceil() as i64;
    for s in 0..=steps {
        let t = s as f64 / steps as f64;
        let (x, y) = (x0 + (x1 - x0) * t, y0 + (y1 - y0) * t);
        for dy in -ri..=ri {
            for dx in -ri..=ri {
                if ((dx * dx + dy * dy) as f64) <= r * r {
                    put(img, x.round() as i64 + dx, y.round() as i64 + dy, c);
                }
            }
        }
    }
}

/// A circle outline of radius `r` around (x, y).
pub fn circle(img: &mut RgbImage, x: f64, y: f64, r: f64, c: Colour) {
    let n = (r * 8.0).ceil().max(8.0) as usize;
    for k in 0..n {
        let a = k as f64 / n as f64 * std::f64::consts::TAU;
        put(
            img,
            (x + r * a.cos()).round() as i64,
            (y + r * a.sin()).round() as i64,
            c,
        );
    }
}

/// A "+" of half-size `r` at (x, y).
pub fn cross(img: &mut RgbImage, x: f64, y: f64, r: f64, c: Colour) {
    line(img, x - r, y, x + r, y, c, 1.0);
    line(img, x, y - r, x, y + r, c, 1.0);
}

/// A filled rectangle.
pub fn fill_rect(img: &mut RgbImage, x0: i64, y0: i64, x1: i64, y1: i64, c: Colour) {
    for y in y0.min(y1)..=y0.max(y1) {
        for x in x0.min(x1)..=x0.max(x1) {
            put(img, x, y, c);
        }
    }
}

/// Width in pixels of `text` at `scale`.
pub fn text_width(text: &str, scale: u32) -> i64 {
    (text.chars().count() as i64) * 8 * scale as i64
}

/// ASCII text with its top-left corner at (x, y), each glyph 8x8 pixels
/// times `scale`. Non-ASCII characters show as '?'.
pub fn text(img: &mut RgbImage, x: i64, y: i64, s: &str, c: Colour, scale: u32) {
    let scale = scale.max(1) as i64;
    for (i, ch) in s.chars().enumerate() {
        let code = if ch.is_ascii() {
            ch as usize
        } else {
            '?' as usize
        };
        let glyph = font8x8::legacy::BASIC_LEGACY[code];
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) != 0 {
                    let (px, py) = (x + (i as i64 * 8 + col) * scale, y + row as i64 * scale);
                    fill_rect(img, px, py, px + scale - 1, py + scale - 1, c);
                }
            }
        }
    }
}

/// Text on a filled background box, for labels over busy images.
pub fn label(img: &mut RgbImage, x: i64, y: i64, s: &str, fg: Colour, bg: Colour, scale: u32) {
    let w = text_width(s, scale);
    fill_rect(img, x - 2, y - 2, x + w + 1, y + 8 * scale as i64 + 1, bg);
    text(img, x, y, s, fg, scale);
}

/// A saturated colour of hue `t` in [0, 1).
pub fn hue(t: f32) -> Colour {
    let h = t * 6.0;
    let x = (1.0 - (h % 2.0 - 1.0).abs()) * 255.0;
    let (r, g, b) = match h as u32 {
        0 => (255.0, x, 0.0),
        1 => (x, 255.0, 0.0),
        2 => (0.0, 255.0, x),
        3 => (0.0, x, 255.0),
        4 => (x, 0.0, 255.0),
        _ => (255.0, 0.0, x),
    };
    [r as u8, g as u8, b as u8]
}

/// The `k`-th of a sequence of well-separated saturated colours.
pub fn distinct(k: usize) -> Colour {
    hue((k as f32 * 0.618_034).fract())
}

/// `frame` with the outline of `mask` (one flag per pixel, row-major: the
/// object's silhouette) drawn in `colour`, the inside lightly tinted, and
/// `text` as a label in the top-left corner.
pub fn silhouette_overlay(frame: &RgbImage, mask: &[bool], colour: Colour, text: &str) -> RgbImage {
    let mut img = frame.clone();
    silhouette(&mut img, mask, colour);
    label(&mut img, 6, 6, text, WHITE, BLACK, 1);
    img
}

/// Draws the outline of `mask` (one flag per pixel of `img`, row-major:
/// the object's silhouette) in `colour`, 2 pixels wide, and tints its
/// inside: a mask pixel with a 4-neighbour outside the mask (or the image)
/// is a border pixel, drawn with its right and lower neighbours.
pub fn silhouette(img: &mut RgbImage, mask: &[bool], colour: Colour) {
    let (w, h) = (img.width() as usize, img.height() as usize);
    if mask.len() != w * h {
        return;
    }
    for y in 0..h {
        for x in 0..w {
            if !mask[y * w + x] {
                continue;
            }
            let edge = [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)]
                .iter()
                .any(|(dx, dy)| {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    nx < 0
                        || ny < 0
                        || nx >= w as i64
                        || ny >= h as i64
                        || !mask[ny as usize * w + nx as usize]
                });
            if edge {
                for (dx, dy) in [(0, 0), (1, 0), (0, 1)] {
                    put(img, x as i64 + dx, y as i64 + dy, colour);
                }
            } else {
                blend(img, x as i64, y as i64, colour, SILHOUETTE_TINT);
            }
        }
    }
}

/// How strongly [`silhouette`] tints the inside of the outline (0..1).
pub const SILHOUETTE_TINT: f32 = 0.18;

/// `img` with a green cross on each corner.
pub fn corners_picture(img: &RgbImage, corners: &[Corner]) -> RgbImage {
    let mut pic = img.clone();
    for c in corners {
        cross(&mut pic, c.x as f64, c.y as f64, 3.0, [0, 255, 0]);
    }
    pic
}

/// A and B side by side (B to the right), a line from each matched corner
/// of A to its match in B, unmatched corners as small grey crosses.
pub fn matches_side_by_side(
    a: &RgbImage,
    b: &RgbImage,
    ca: &[Corner],
    cb: &[Corner],
    matches: &[Match],
) -> RgbImage {
    let (wa, ha) = a.dimensions();
    let (wb, hb) = b.dimensions();
    let mut pic = RgbImage::from_pixel(wa + wb, ha.max(hb), Rgb(BLACK));
    image::imageops::replace(&mut pic, a, 0, 0);
    image::imageops::replace(&mut pic, b, wa as i64, 0);
    let dx = wa as f64;
    for c in ca {
        cross(&mut pic, c.x as f64, c.y as f64, 2.0, GREY);
    }
    for c in cb {
        cross(&mut pic, c.x as f64 + dx, c.y as f64, 2.0, GREY);
    }
    for (k, m) in matches.iter().enumerate() {
        let col = distinct(k);
        let (p, q) = (ca[m.a], cb[m.b]);
        let (px, py, qx, qy) = (p.x as f64, p.y as f64, q.x as f64 + dx, q.y as f64);
        line(&mut pic, px, py, qx, qy, col, 1.0);
        cross(&mut pic, px, py, 3.0, col);
        cross(&mut pic, qx, qy, 3.0, col);
    }
    pic
}

/// B, dimmed, with an arrow per match from the corner's position in A to
/// its match in B (the image motion), coloured by direction.
pub fn match_arrows(b: &RgbImage, ca: &[Corner], cb: &[Corner], matches: &[Match]) -> RgbImage {
    let mut pic = b.clone();
    for p in pic.pixels_mut() {
        p.0 = p.0.map(|v| (v as f32 * 0.55) as u8);
    }
    for m in matches {
        let (p, q) = (ca[m.a], cb[m.b]);
        let angle = (q.y - p.y).atan2(q.x - p.x);
        let col = hue((angle / std::f32::consts::TAU).rem_euclid(1.0));
        let (px, py, qx, qy) = (p.x as f64, p.y as f64, q.x as f64, q.y as f64);
        line(&mut pic, px, py, qx, qy, col, 1.0);
        cross(&mut pic, qx, qy, 2.0, col);
    }
    pic
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_and_lines_touch_the_right_pixels() {
        let mut img = RgbImage::new(40, 20);
        text(&mut img, 0, 0, "1", WHITE, 1);
        // '1' has ink in its 8x8 cell and none outside it.
        let ink = |x0: u32, x1: u32| {
            (x0..x1)
                .flat_map(|x| (0..20).map(move |y| (x, y)))
                .filter(|&(x, y)| img.get_pixel(x, y).0 != [0, 0, 0])
                .count()
        };
        assert!(ink(0, 8) > 5);
        assert_eq!(ink(8, 40), 0);
        let mut img = RgbImage::new(20, 20);
        line(&mut img, 2.0, 10.0, 17.0, 10.0, WHITE, 1.0);
        assert_eq!(img.get_pixel(9, 10).0, WHITE);
        assert_eq!(img.get_pixel(9, 5).0, BLACK);
        // Off-image and non-finite coordinates are ignored, not panics.
        line(&mut img, -50.0, -50.0, f64::NAN, 3.0, WHITE, 3.0);
        circle(&mut img, 100.0, 100.0, 5.0, WHITE);
    }

    #[test]
    fn silhouette_overlay_outlines_and_tints_the_mask() {
        let frame = RgbImage::from_pixel(40, 30, Rgb([100, 100, 100]));
        // A 10x10 square at (20..30, 10..20).
        let mask: Vec<bool> = (0..30 * 40)
            .map(|i| (20..30).contains(&(i % 40)) && (10..20).contains(&(i / 40)))
            .collect();
        let img = silhouette_overlay(&frame, &mask, [0, 255, 0], "");
        assert_eq!(img.get_pixel(20, 15).0, [0, 255, 0]); // outline
        let inside = img.get_pixel(25, 15).0;
        assert!(inside[1] > 100 && inside[0] < 100, "{inside:?}"); // tinted
        assert_eq!(img.get_pixel(35, 25).0, [100, 100, 100]); // untouched
        assert_eq!(hue(0.0), [255, 0, 0]);
        assert_ne!(distinct(0), distinct(1));
    }
}
