//! Patch descriptors of corners for the detector ([`super`]): a grid of
//! grey levels around the corner, sampled on a smoothed image, optionally
//! turned to the corner's dominant gradient orientation, made zero-mean
//! and unit-norm, so that the dot product of two descriptors is their
//! normalised cross-correlation (NCC).
//!
//! Scale is handled on the keyframe side: a keyframe's corners are
//! described at several scales (the grid's spacing and the smoothing grown
//! alike), the frame's at one.

use crate::features::GreyImage;

/// Samples a side of the descriptor's grid.
pub const GRID: usize = 8;

/// Values of a descriptor.
pub const DIM: usize = GRID * GRID;

/// A descriptor: [`DIM`] grey levels, zero-mean and unit-norm.
pub type Descriptor = [f32; DIM];

/// How descriptors are made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DescribeConfig {
    /// Spacing of the grid's samples at scale 1, pixels (the patch spans
    /// `GRID x spacing`).
    pub spacing_px: f32,
    /// Smoothing of the image sampled at scale 1 (Gaussian sigma, pixels),
    /// about half the spacing so the samples do not alias.
    pub sigma_px: f32,
    /// Whether the grid is turned to the corner's dominant gradient
    /// orientation (tolerates in-plane rotation); else it stays upright
    /// (plain NCC of upright patches).
    pub oriented: bool,
    /// Most of the grid's samples that may fall off the image or on
    /// invalid (NaN) pixels; they take the valid samples' mean.
    pub max_invalid: f32,
}

impl Default for DescribeConfig {
    fn default() -> Self {
        Self {
            spacing_px: 3.0,
            sigma_px: 1.5,
            oriented: true,
            max_invalid: 0.25,
        }
    }
}

/// `img` smoothed by a Gaussian of `sigma` pixels, ignoring invalid (NaN)
/// pixels (normalised convolution: the weighted mean of the valid pixels
/// of the support); a pixel stays invalid where it was.
pub fn smoothed(img: &GreyImage, sigma: f32) -> GreyImage {
    let (w, h) = (img.width, img.height);
    // Harris's taps; their scale cancels in the normalised convolution.
    let (taps, _) = crate::features::harris::gaussian_taps(sigma);
    let r = (taps.len() / 2) as isize;
    // (value sum, weight sum) per pixel, horizontally then vertically.
    let mut num = vec![0.0f32; w * h];
    let mut den = vec![0.0f32; w * h];
    for y in 0..h {
        let row = &img.data[y * w..(y + 1) * w];
        for x in 0..w {
            let (mut n, mut d) = (0.0, 0.0);
            for (k, t) in taps.iter().enumerate() {
                let xx = x as isize + k as isize - r;
                if xx < 0 || xx >= w as isize {
                    continue;
                }
                let v = row[xx as usize];
                if v.is_finite() {
                    n += t * v;
                    d += t;
                }
            }
            num[y * w + x] = n;
            den[y * w + x] = d;
        }
    }
    let mut out = vec![f32::NAN; w * h];
    for y in 0..h {
        for x in 0..w {
            if !img.data[y * w + x].is_finite() {
                continue;
            }
            let (mut n, mut d) = (0.0, 0.0);
            for (k, t) in taps.iter().enumerate() {
                let yy = y as isize + k as isize - r;
                if yy < 0 || yy >= h as isize {
                    continue;
                }
                n += t * num[yy as usize * w + x];
                d += t * den[yy as usize * w + x];
            }
            if d > 0.0 {
                out[y * w + x] = n / d;
            }
        }
    }
    GreyImage {
        width: w,
        height: h,
        data: out,
    }
}

/// The dominant gradient orientation (radians, image axes: x right, y
/// down) around `(x, y)` within `radius` pixels: the peak of a 36-bin
/// histogram of gradient directions weighted by magnitude and a Gaussian
/// of the distance, smoothed, interpolated between bins. `None` where the
/// region holds no gradient.
pub fn orientation(img: &GreyImage, x: f32, y: f32, radius: f32) -> Option<f32> {
    const BINS: usize = 36;
    let (w, h) = (img.width as isize, img.height as isize);
    let r = radius.ceil() as isize;
    let (cx, cy) = (x.round() as isize, y.round() as isize);
    let s2 = 2.0 * (radius / 2.0).powi(2);
    let mut hist = [0.0f32; BINS];
    let at = |xx: isize, yy: isize| img.data[(yy * w + xx) as usize];
    for yy in (cy - r).max(1)..=(cy + r).min(h - 2) {
        for xx in (cx - r).max(1)..=(cx + r).min(w - 2) {
            let (dx, dy) = (xx as f32 - x, yy as f32 - y);
            let d2 = dx * dx + dy * dy;
            if d2 > radius * radius {
                continue;
            }
            let gx = at(xx + 1, yy) - at(xx - 1, yy);
            let gy = at(xx, yy + 1) - at(xx, yy - 1);
            let m = gx.hypot(gy);
            if !m.is_finite() || m == 0.0 {
                continue;
            }
            let a = gy.atan2(gx).rem_euclid(std::f32::consts::TAU);
            let b = ((a / std::f32::consts::TAU * BINS as f32) as usize).min(BINS - 1);
            hist[b] += m * (-d2 / s2).exp();
        }
    }
    for _ in 0..2 {
        let prev = hist;
        for (i, v) in hist.iter_mut().enumerate() {
            *v = 0.25 * prev[(i + BINS - 1) % BINS] + 0.5 * prev[i] + 0.25 * prev[(i + 1) % BINS];
        }
    }
    let (i, &peak) = hist.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    if peak <= 0.0 {
        return None;
    }
    let (l, r) = (hist[(i + BINS - 1) % BINS], hist[(i + 1) % BINS]);
    let den = l - 2.0 * peak + r;
    let off = if den.abs() > 1e-12 {
        0.5 * (l - r) / den
    } else {
        0.0
    };
    Some((i as f32 + 0.5 + off) / BINS as f32 * std::f32::consts::TAU)
}

/// The descriptor of the corner at `(x, y)` on `img` (smoothed for
/// `scale`): the grid spaced `scale x spacing_px`, turned by `angle`
/// radians; `None` where too many samples are invalid or the patch is
/// flat.
pub fn describe(
    img: &GreyImage,
    x: f32,
    y: f32,
    scale: f32,
    angle: f32,
    cfg: &DescribeConfig,
) -> Option<Descriptor> {
    let step = cfg.spacing_px * scale;
    let (s, c) = angle.sin_cos();
    let mut out = [0.0f32; DIM];
    let mut valid = [false; DIM];
    let (mut sum, mut n) = (0.0f32, 0usize);
    let half = (GRID as f32 - 1.0) / 2.0;
    for j in 0..GRID {
        for i in 0..GRID {
            let (u, v) = ((i as f32 - half) * step, (j as f32 - half) * step);
            let (px, py) = (x + c * u - s * v, y + s * u + c * v);
            if let Some(g) = img.bilinear(px, py) {
                out[j * GRID + i] = g;
                valid[j * GRID + i] = true;
                sum += g;
                n += 1;
            }
        }
    }
    if n == 0 || ((DIM - n) as f32) > cfg.max_invalid * DIM as f32 {
        return None;
    }
    let mean = sum / n as f32;
    let mut norm = 0.0f32;
    for (o, ok) in out.iter_mut().zip(valid) {
        *o = if ok { *o - mean } else { 0.0 };
        norm += *o * *o;
    }
    let norm = norm.sqrt();
    // Flat: under about a grey level of contrast per sample.
    if norm < 1e-3 * (n as f32).sqrt() {
        return None;
    }
    for o in &mut out {
        *o /= norm;
    }
    Some(out)
}

/// Descriptors of `points` on `img` smoothed for `scale` (as
/// [`smoothed`] with `scale x sigma_px`, done by the caller): for each
/// point that has one, its index and descriptor.
pub fn describe_all(
    img: &GreyImage,
    points: &[[f32; 2]],
    scale: f32,
    cfg: &DescribeConfig,
) -> Vec<(usize, Descriptor)> {
    crate::par::flat_map_chunks(
        &points.iter().enumerate().collect::<Vec<_>>(),
        256,
        |part| {
            part.iter()
                .filter_map(|&(i, p)| {
                    let angle = if cfg.oriented {
                        orientation(img, p[0], p[1], 4.0 * cfg.spacing_px * scale)?
                    } else {
                        0.0
                    };
                    describe(img, p[0], p[1], scale, angle, cfg).map(|d| (i, d))
                })
                .collect()
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::patterns::smooth_noise;

    fn dot(a: &Descriptor, b: &Descriptor) -> f32 {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }

    /// `img` turned by `angle` about `(cx, cy)` (bilinear).
    fn turned(img: &GreyImage, angle: f32, cx: f32, cy: f32) -> GreyImage {
        let (s, c) = angle.sin_cos();
        GreyImage::from_fn(img.width, img.height, |x, y| {
            let (dx, dy) = (x as f32 - cx, y as f32 - cy);
            // The source of (x, y): turned back.
            let (sx, sy) = (cx + c * dx + s * dy, cy - s * dx + c * dy);
            img.bilinear(sx, sy).unwrap_or(0.5)
        })
    }

    #[test]
    fn a_descriptor_is_zero_mean_unit_norm_and_flat_patches_have_none() {
        let img = smooth_noise(96, 96, 2.0, 7);
        let cfg = DescribeConfig::default();
        let d = describe(&img, 48.0, 48.0, 1.0, 0.3, &cfg).unwrap();
        let mean: f32 = d.iter().sum::<f32>() / DIM as f32;
        assert!(mean.abs() < 1e-5 && (dot(&d, &d) - 1.0).abs() < 1e-4);
        assert!(describe(&GreyImage::filled(96, 96, 0.4), 48.0, 48.0, 1.0, 0.0, &cfg).is_none());
        // Off the image: too many samples invalid.
        assert!(describe(&img, 2.0, 2.0, 1.0, 0.0, &cfg).is_none());
    }

    #[test]
    fn oriented_descriptors_survive_an_in_plane_turn_upright_ones_do_not() {
        let img = smoothed(&smooth_noise(128, 128, 2.5, 11), 1.5);
        let angle = 50f32.to_radians();
        let other = smoothed(&turned(&img, angle, 64.0, 64.0), 1.5);
        // Orientation follows the turn.
        let a = orientation(&img, 64.0, 64.0, 12.0).unwrap();
        let b = orientation(&other, 64.0, 64.0, 12.0).unwrap();
        let diff = (b - a - angle).rem_euclid(std::f32::consts::TAU);
        let diff = diff.min(std::f32::consts::TAU - diff);
        assert!(diff < 5f32.to_radians(), "{} deg", diff.to_degrees());
        let oriented = DescribeConfig::default();
        let upright = DescribeConfig {
            oriented: false,
            ..oriented
        };
        let at = [[64.0f32, 64.0]];
        let score = |cfg: &DescribeConfig| {
            let d0 = describe_all(&img, &at, 1.0, cfg)[0].1;
            let d1 = describe_all(&other, &at, 1.0, cfg)[0].1;
            dot(&d0, &d1)
        };
        let (so, su) = (score(&oriented), score(&upright));
        assert!(so > 0.9 && su < 0.6, "oriented {so}, upright {su}");
    }

    #[test]
    fn smoothing_ignores_invalid_pixels_and_keeps_them_invalid() {
        let mut img = GreyImage::filled(20, 10, 0.5);
        for y in 0..10 {
            for x in 10..20 {
                img.data[y * 20 + x] = f32::NAN;
            }
        }
        let s = smoothed(&img, 1.5);
        assert!((s.get(9, 5) - 0.5).abs() < 1e-6);
        assert!(s.get(10, 5).is_nan());
    }
}
