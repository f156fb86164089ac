//! Synthetic test images with known answers: smoothed noise, random
//! polygons, rotated squares and a checkerboard (with their true corners),
//! and a known affine warp. Used by the tests, the benchmarks and the CLI
//! tests; anti-aliased by 4x4 supersampling so that corners are sub-pixel.

use super::image::GreyImage;
use crate::rng::Rng;

/// Supersampling per axis.
const SS: usize = 4;

/// Renders a picture from a function of the continuous position (OpenCV
/// convention: pixel (x, y) covers [x - 0.5, x + 0.5] x [y - 0.5, y + 0.5]),
/// averaging 4x4 samples per pixel.
pub fn render(width: usize, height: usize, f: impl Fn(f32, f32) -> f32) -> GreyImage {
    GreyImage::from_fn(width, height, |x, y| {
        let mut sum = 0.0;
        for j in 0..SS {
            for i in 0..SS {
                let sx = x as f32 - 0.5 + (i as f32 + 0.5) / SS as f32;
                let sy = y as f32 - 0.5 + (j as f32 + 0.5) / SS as f32;
                sum += f(sx, sy);
            }
        }
        sum / (SS * SS) as f32
    })
}

/// A smooth random texture, a sum of 24 plane waves (grey about 0.5 +-
/// 0.5), sampled analytically at any continuous (x, y): shifted copies are
/// exact, for sub-pixel known answers.
pub fn waves(seed: u64) -> impl Fn(f32, f32) -> f32 {
    let mut rng = Rng::new(seed);
    let waves: Vec<(f32, f32, f32, f32)> = (0..24)
        .map(|_| {
            (
                rng.uniform(-0.7, 0.7) as f32,
                rng.uniform(-0.7, 0.7) as f32,
                rng.uniform(0.0, 6.3) as f32,
                rng.uniform(0.02, 0.06) as f32,
            )
        })
        .collect();
    move |x, y| {
        0.5 + waves
            .iter()
            .map(|(kx, ky, ph, a)| a * (kx * x + ky * y + ph).sin())
            .sum::<f32>()
    }
}

/// Uniform noise smoothed by a Gaussian of `sigma` pixels and stretched to
/// 0..1: texture with corners at the scale of `sigma`.
pub fn smooth_noise(width: usize, height: usize, sigma: f32, seed: u64) -> GreyImage {
    let mut rng = Rng::new(seed);
    let mut data: Vec<f32> = (0..width * height).map(|_| rng.next_f64() as f32).collect();
    let r = (3.0 * sigma).ceil() as i64;
    let taps: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
        .collect();
    let norm: f32 = taps.iter().sum();
    let blur = |data: &[f32], horizontal: bool| -> Vec<f32> {
        let mut out = vec![0f32; data.len()];
        for y in 0..height as i64 {
            for x in 0..width as i64 {
                let mut s = 0.0;
                for (k, t) in (-r..=r).zip(&taps) {
                    let (xx, yy) = if horizontal {
                        ((x + k).clamp(0, width as i64 - 1), y)
                    } else {
                        (x, (y + k).clamp(0, height as i64 - 1))
                    };
                    s += data[(yy * width as i64 + xx) as usize] * t;
                }
                out[(y * width as i64 + x) as usize] = s / norm;
            }
        }
        out
    };
    if width > 0 && height > 0 {
        data = blur(&blur(&data, true), false);
    }
    let (lo, hi) = data
        .iter()
        .fold((f32::MAX, f32::MIN), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
    let span = (hi - lo).max(1e-6);
    for v in &mut data {
        *v = (*v - lo) / span;
    }
    GreyImage {
        width,
        height,
        data,
    }
}

/// Whether `p` is inside the convex polygon `poly` (either orientation).
fn inside_convex(poly: &[[f32; 2]], p: [f32; 2]) -> bool {
    let mut sign = 0.0f32;
    for i in 0..poly.len() {
        let a = poly[i];
        let b = poly[(i + 1) % poly.len()];
        let cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        if cross != 0.0 {
            if sign == 0.0 {
                sign = cross.signum();
            } else if cross.signum() != sign {
                return false;
            }
        }
    }
    true
}

/// Random filled convex polygons (triangles to hexagons) of random grey
/// levels, painted over each other on a mid-grey background.
pub fn polygons(width: usize, height: usize, count: usize, seed: u64) -> GreyImage {
    let mut rng = Rng::new(seed);
    let mut shapes: Vec<(Vec<[f32; 2]>, f32)> = Vec::new();
    for _ in 0..count {
        let cx = rng.uniform(0.0, width as f64) as f32;
        let cy = rng.uniform(0.0, height as f64) as f32;
        let r = rng.uniform(4.0, (width.min(height) as f64 / 4.0).max(5.0)) as f32;
        let n = 3 + rng.below(4) as usize;
        let mut angles: Vec<f32> = (0..n)
            .map(|_| rng.uniform(0.0, std::f64::consts::TAU) as f32)
            .collect();
        angles.sort_by(f32::total_cmp);
        let poly = angles
            .iter()
            .map(|a| [cx + r * a.cos(), cy + r * a.sin()])
            .collect();
        shapes.push((poly, rng.uniform(0.0, 1.0) as f32));
    }
    render(width, height, |x, y| {
        shapes
            .iter()
            .rev()
            .find(|(poly, _)| inside_convex(poly, [x, y]))
            .map_or(0.5, |(_, v)| *v)
    })
}

/// A square: centre, half side, rotation (radians).
#[derive(Debug, Clone, Copy)]
pub struct Square {
    /// Centre column in pixels.
    pub cx: f32,
    /// Centre row in pixels.
    pub cy: f32,
    /// Half the side length, in pixels.
    pub half: f32,
    /// Rotation in radians.
    pub angle: f32,
}

impl Square {
    /// The four corners (x, y) in pixels, in order around the square.
    pub fn corners(&self) -> [[f32; 2]; 4] {
        let (s, c) = self.angle.sin_cos();
        [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)].map(|(u, v): (f32, f32)| {
            let (u, v) = (u * self.half, v * self.half);
            [self.cx + c * u - s * v, self.cy + s * u + c * v]
        })
    }
}

/// White rotated squares on black (`fg` on `bg`); returns the image and the
/// true corners.
pub fn squares(
    width: usize,
    height: usize,
    squares: &[Square],
    bg: f32,
    fg: f32,
) -> (GreyImage, Vec<[f32; 2]>) {
    let polys: Vec<[[f32; 2]; 4]> = squares.iter().map(Square::corners).collect();
    let img = render(width, height, |x, y| {
        if polys.iter().any(|p| inside_convex(p, [x, y])) {
            fg
        } else {
            bg
        }
    });
    (img, polys.concat())
}

/// A checkerboard of `nx x ny` cells of `cell` pixels, rotated by `angle`
/// about its top-left corner `origin`, on mid-grey; returns the image and
/// its inner corners (the X-junctions).
pub fn checkerboard(
    width: usize,
    height: usize,
    origin: [f32; 2],
    cell: f32,
    angle: f32,
    nx: usize,
    ny: usize,
) -> (GreyImage, Vec<[f32; 2]>) {
    let (s, c) = angle.sin_cos();
    let img = render(width, height, |x, y| {
        let (dx, dy) = (x - origin[0], y - origin[1]);
        // Board coordinates: rotate back.
        let u = (c * dx + s * dy) / cell;
        let v = (-s * dx + c * dy) / cell;
        if u < 0.0 || v < 0.0 || u >= nx as f32 || v >= ny as f32 {
            0.5
        } else if (u.floor() as i64 + v.floor() as i64) % 2 == 0 {
            0.9
        } else {
            0.1
        }
    });
    let mut inner = Vec::new();
    for j in 1..ny {
        for i in 1..nx {
            let (u, v) = (i as f32 * cell, j as f32 * cell);
            inner.push([origin[0] + c * u - s * v, origin[1] + s * u + c * v]);
        }
    }
    (img, inner)
}

/// A 2-D similarity-plus-intensity change: `B(T(p)) = gain * A(p) + bias`
/// with `T(p) = R(angle) (p - centre) + centre + shift`.
#[derive(Debug, Clone, Copy)]
pub struct Warp {
    /// Translation added after the rotation, in pixels.
    pub shift: [f32; 2],
    /// Rotation about `centre`, in radians.
    pub angle: f32,
    /// Centre of the rotation (x, y), in pixels.
    pub centre: [f32; 2],
    /// Multiplier of the intensities.
    pub gain: f32,
    /// Offset added to the intensities.
    pub bias: f32,
}

impl Warp {
    /// Where the point `p` of A lands in B.
    pub fn apply(&self, p: [f32; 2]) -> [f32; 2] {
        let (s, c) = self.angle.sin_cos();
        let (dx, dy) = (p[0] - self.centre[0], p[1] - self.centre[1]);
        [
            c * dx - s * dy + self.centre[0] + self.shift[0],
            s * dx + c * dy + self.centre[1] + self.shift[1],
        ]
    }

    /// B, sampled bilinearly from A through the inverse warp (NaN where the
    /// inverse falls outside A).
    pub fn image(&self, a: &GreyImage) -> GreyImage {
        let (s, c) = self.angle.sin_cos();
        GreyImage::from_fn(a.width, a.height, |x, y| {
            let (dx, dy) = (
                x as f32 - self.centre[0] - self.shift[0],
                y as f32 - self.centre[1] - self.shift[1],
            );
            let px = c * dx + s * dy + self.centre[0];
            let py = -s * dx + c * dy + self.centre[1];
            a.bilinear(px, py)
                .map_or(f32::NAN, |v| self.gain * v + self.bias)
        })
    }
}
