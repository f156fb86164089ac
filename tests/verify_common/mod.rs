//! Synthetic scenes for the pose check's edge test, with the check's
//! inputs at a hypothesised 2-D pose: a near-symmetric silhouette (a
//! rounded square, nearly 4-fold symmetric) with or without a texture,
//! over a cluttered or a plain background, with soft (supersampled) edges.

#![allow(dead_code)]

use splattrack::features::GreyImage;
use splattrack::rng::Rng;

/// Where a silhouette sits in the image: its centre (pixels) and its turn
/// (radians).
#[derive(Debug, Clone, Copy)]
pub struct At {
    pub x: f64,
    pub y: f64,
    pub turn: f64,
}

impl At {
    pub fn new(x: f64, y: f64, turn_deg: f64) -> Self {
        Self {
            x,
            y,
            turn: turn_deg.to_radians(),
        }
    }

    /// Shifted by `dx` pixels along x.
    pub fn shifted(self, dx: f64) -> Self {
        Self {
            x: self.x + dx,
            ..self
        }
    }

    /// Turned by `deg` more degrees.
    pub fn turned(self, deg: f64) -> Self {
        Self {
            turn: self.turn + deg.to_radians(),
            ..self
        }
    }

    /// Object coordinates of pixel position (px, py).
    fn local(&self, px: f64, py: f64) -> (f64, f64) {
        let (dx, dy) = (px - self.x, py - self.y);
        let (s, c) = self.turn.sin_cos();
        (c * dx + s * dy, -s * dx + c * dy)
    }
}

/// The silhouette's radius (pixels, before its lobes).
pub const RADIUS: f64 = 40.0;

/// Whether object point (u, v) is inside the silhouette: a near-square
/// (4 lobes of 10%) with a slight 3-lobed bump that breaks the symmetry.
fn inside_local(u: f64, v: f64) -> bool {
    let th = v.atan2(u);
    let r = RADIUS * (1.0 + 0.10 * (4.0 * th).cos() + 0.02 * (3.0 * th).cos());
    u * u + v * v < r * r
}

/// The object's texture at object point (u, v): a grey pattern of 8-18 px
/// wavelengths.
fn texture(u: f64, v: f64) -> f64 {
    0.5 + 0.2 * (0.8 * u).sin() * (0.6 * v).cos() + 0.1 * (0.35 * (u + v)).sin()
}

/// What fills the silhouette in a frame.
#[derive(Debug, Clone, Copy)]
pub enum Fill {
    /// [`texture`].
    Textured,
    /// One grey level.
    Plain(f64),
}

impl Fill {
    fn at(&self, u: f64, v: f64) -> f64 {
        match self {
            Fill::Textured => texture(u, v),
            Fill::Plain(g) => *g,
        }
    }
}

/// The background of a frame.
#[derive(Debug, Clone, Copy)]
pub enum Background {
    /// Blotches, pixel noise of +-0.08 and 60 thin line segments of random
    /// grey levels.
    Clutter,
    /// One grey level with pixel noise uniform in +-`noise`.
    Plain { grey: f64, noise: f64 },
}

/// A frame: `objects` (where, what fills them) over `bg`, the objects'
/// edges anti-aliased over 4x4 subsamples; plain backgrounds' noise is
/// added over the objects too (a camera's).
pub fn frame(w: usize, h: usize, bg: Background, objects: &[(At, Fill)], seed: u64) -> GreyImage {
    let mut rng = Rng::new(seed);
    let mut data: Vec<f64> = match bg {
        Background::Clutter => {
            let waves: Vec<(f64, f64, f64, f64)> = (0..6)
                .map(|_| {
                    (
                        rng.uniform(0.02, 0.15),
                        rng.uniform(0.02, 0.15),
                        rng.uniform(0.0, 6.3),
                        rng.uniform(0.03, 0.08),
                    )
                })
                .collect();
            let mut d: Vec<f64> = (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f64, (i / w) as f64);
                    0.45 + waves
                        .iter()
                        .map(|(a, b, p, amp)| amp * (a * x + b * y + p).sin())
                        .sum::<f64>()
                        + rng.uniform(-0.08, 0.08)
                })
                .collect();
            for _ in 0..60 {
                let (x0, y0) = (rng.uniform(0.0, w as f64), rng.uniform(0.0, h as f64));
                let (len, ang) = (rng.uniform(15.0, 80.0), rng.uniform(0.0, 6.3));
                let grey = rng.uniform(0.0, 1.0);
                let steps = (2.0 * len) as usize;
                for k in 0..=steps {
                    let t = k as f64 / steps as f64 * len;
                    let (x, y) = (x0 + t * ang.cos(), y0 + t * ang.sin());
                    if x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h {
                        d[y as usize * w + x as usize] = grey;
                    }
                }
            }
            d
        }
        Background::Plain { grey, .. } => vec![grey; w * h],
    };
    for (at, fill) in objects {
        let lim = RADIUS * 1.2 + 2.0;
        let x0 = (at.x - lim).floor().max(0.0) as usize;
        let y0 = (at.y - lim).floor().max(0.0) as usize;
        let x1 = ((at.x + lim).ceil() as usize).min(w);
        let y1 = ((at.y + lim).ceil() as usize).min(h);
        for y in y0..y1 {
            for x in x0..x1 {
                let (mut cover, mut value) = (0.0, 0.0);
                for k in 0..16 {
                    let sx = x as f64 + ((k % 4) as f64 + 0.5) / 4.0 - 0.5;
                    let sy = y as f64 + ((k / 4) as f64 + 0.5) / 4.0 - 0.5;
                    let (u, v) = at.local(sx, sy);
                    if inside_local(u, v) {
                        cover += 1.0 / 16.0;
                        value += fill.at(u, v) / 16.0;
                    }
                }
                let i = y * w + x;
                data[i] = data[i] * (1.0 - cover) + value;
            }
        }
    }
    if let Background::Plain { noise, .. } = bg {
        for v in &mut data {
            *v += rng.uniform(-noise, noise);
        }
    }
    GreyImage::new(
        w,
        h,
        data.iter().map(|v| v.clamp(0.0, 1.0) as f32).collect(),
    )
    .unwrap()
}

/// The check's inputs at a hypothesised pose: the covered pixels (pixel
/// centres inside the silhouette) and the view's grey levels (the
/// texture under a gain and an offset; 0 where uncovered).
pub fn view(w: usize, h: usize, at: At) -> (Vec<bool>, Vec<f32>) {
    let mut covered = vec![false; w * h];
    let mut grey = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let (u, v) = at.local(x as f64, y as f64);
            if inside_local(u, v) {
                covered[y * w + x] = true;
                grey[y * w + x] = (0.7 * texture(u, v) + 0.1) as f32;
            }
        }
    }
    (covered, grey)
}
