//! CPU reference of the Harris detector: every pass of
//! `shaders/harris_*.wgsl`, operation for operation in `f32`. The host steps
//! it shares with the GPU detector are in [`super`].

use super::{Corner, HarrisConfig, gaussian_taps, merge, pack_pixels, radius, select_spread};
use crate::features::FeatureError;
use crate::features::gpu_data::{
    Candidate, INVALID_RESPONSE, PIXEL_ALLOWED, PIXEL_HOLE, PIXEL_VALID, Pixel,
};
use crate::features::image::{GreyImage, check_mask};

#[derive(Default)]
pub(super) struct Maps {
    pub(super) grad: Vec<[f32; 3]>,
    pub(super) response: Vec<f32>,
}

fn maps(pixels: &[Pixel], w: usize, h: usize, cfg: &HarrisConfig) -> Maps {
    let (gd, dd) = gaussian_taps(cfg.sigma_d);
    let (gi, _) = gaussian_taps(cfg.sigma_i);
    let rd = radius(cfg.sigma_d) as i64;
    let ri = radius(cfg.sigma_i) as i64;
    let (wi, hi) = (w as i64, h as i64);
    let n = w * h;

    // deriv_h: (I * g'_x, I * g_x, valid)
    let mut tmp = vec![[0f32; 4]; n];
    for y in 0..hi {
        for x in 0..wi {
            let (mut a, mut b, mut ok) = (0f32, 0f32, 1f32);
            for t in -rd..=rd {
                let xx = x + t;
                if xx < 0 || xx >= wi {
                    ok = -1.0;
                    continue;
                }
                let p = pixels[(y * wi + xx) as usize];
                if p.flags & PIXEL_VALID == 0 {
                    // A pinhole is tolerated, other invalid pixels are not.
                    ok = ok.min(if p.flags & PIXEL_HOLE != 0 { 0.0 } else { -1.0 });
                }
                let k = (t + rd) as usize;
                a += p.value * dd[k];
                b += p.value * gd[k];
            }
            tmp[(y * wi + x) as usize] = [a, b, ok, 0.0];
        }
    }
    // deriv_v: (Ix, Iy, valid)
    let mut grad = vec![[0f32; 3]; n];
    for y in 0..hi {
        for x in 0..wi {
            let (mut ix, mut iy, mut ok) = (0f32, 0f32, 1f32);
            for t in -rd..=rd {
                let yy = y + t;
                if yy < 0 || yy >= hi {
                    ok = -1.0;
                    continue;
                }
                let s = tmp[(yy * wi + x) as usize];
                ok = ok.min(s[2]);
                let k = (t + rd) as usize;
                ix += s[0] * gd[k];
                iy += s[1] * dd[k];
            }
            grad[(y * wi + x) as usize] = [ix, iy, ok];
        }
    }
    // integrate_h: (Sxx, Syy, Sxy, weight of the valid gradients; -1 when
    // the window leaves the image)
    for y in 0..hi {
        for x in 0..wi {
            let (mut sxx, mut syy, mut sxy, mut ws) = (0f32, 0f32, 0f32, 0f32);
            let mut outside = false;
            for t in -ri..=ri {
                let xx = x + t;
                if xx < 0 || xx >= wi {
                    outside = true;
                    continue;
                }
                let g = grad[(y * wi + xx) as usize];
                let v = if g[2] > 0.5 { 1.0 } else { 0.0 };
                outside |= g[2] < -0.5;
                let c = gi[(t + ri) as usize];
                sxx += g[0] * g[0] * v * c;
                syy += g[1] * g[1] * v * c;
                sxy += g[0] * g[1] * v * c;
                ws += v * c;
            }
            tmp[(y * wi + x) as usize] = [sxx, syy, sxy, if outside { -1.0 } else { ws }];
        }
    }
    // integrate_v + response
    let mut response = vec![0f32; n];
    for y in 0..hi {
        for x in 0..wi {
            let (mut sxx, mut syy, mut sxy, mut ws) = (0f32, 0f32, 0f32, 0f32);
            let mut outside = false;
            for t in -ri..=ri {
                let yy = y + t;
                if yy < 0 || yy >= hi {
                    outside = true;
                    continue;
                }
                let s = tmp[(yy * wi + x) as usize];
                outside |= s[3] < 0.0;
                let c = gi[(t + ri) as usize];
                sxx += s[0] * c;
                syy += s[1] * c;
                sxy += s[2] * c;
                ws += s[3] * c;
            }
            let i = (y * wi + x) as usize;
            let ws = if outside { -1.0 } else { ws };
            let valid =
                ws >= cfg.min_valid_weight * (1.0 - 1.0e-5) && pixels[i].flags & PIXEL_VALID != 0;
            response[i] = if !valid {
                INVALID_RESPONSE
            } else {
                // The taps sum to 1: a full window's weight is 1 up to
                // rounding, and keeps the plain sums.
                let scale = if ws < 1.0 - 1.0e-5 { 1.0 / ws } else { 1.0 };
                let (sxx, syy, sxy) = (sxx * scale, syy * scale, sxy * scale);
                let tr = sxx + syy;
                (sxx * syy - sxy * sxy) - cfg.k * (tr * tr)
            };
        }
    }
    Maps { grad, response }
}

/// The Harris response map (row-major; [`INVALID_RESPONSE`] where the
/// support leaves the image or touches an invalid pixel), computed on the
/// CPU exactly as the GPU's `integrate_v` pass writes it.
pub fn harris_response_cpu(img: &GreyImage, cfg: &HarrisConfig) -> Result<Vec<f32>, FeatureError> {
    cfg.validate()?;
    check_mask(img, None)?;
    Ok(maps(&pack_pixels(img, None), img.width, img.height, cfg).response)
}

fn nms(
    pixels: &[Pixel],
    response: &[f32],
    w: usize,
    h: usize,
    cfg: &HarrisConfig,
) -> Vec<Candidate> {
    let max_r = response
        .iter()
        .zip(pixels)
        .filter(|(r, p)| **r > 0.0 && p.flags & PIXEL_ALLOWED != 0)
        .map(|(r, _)| *r)
        .fold(0f32, f32::max);
    let threshold = (cfg.relative_threshold * max_r).max(cfg.min_response);
    let (wi, hi) = (w as i64, h as i64);
    let mut out = Vec::new();
    for y in 0..hi {
        'px: for x in 0..wi {
            let i = (y * wi + x) as usize;
            let r = response[i];
            if r <= INVALID_RESPONSE || pixels[i].flags & PIXEL_ALLOWED == 0 {
                continue;
            }
            if !(r > 0.0 && r >= threshold) {
                continue;
            }
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (xx, yy) = (x + dx, y + dy);
                    if (dx == 0 && dy == 0) || xx < 0 || yy < 0 || xx >= wi || yy >= hi {
                        continue;
                    }
                    let j = (yy * wi + xx) as usize;
                    let rn = response[j];
                    if rn > r || (rn == r && j < i) {
                        continue 'px;
                    }
                }
            }
            out.push(Candidate {
                x: x as u32,
                y: y as u32,
                score: r,
                _pad: 0,
            });
        }
    }
    out
}

/// The `refine` kernel on the CPU.
fn refine(
    grad: &[[f32; 3]],
    w: usize,
    h: usize,
    start: (f32, f32),
    cfg: &HarrisConfig,
) -> (f32, f32) {
    let rw = cfg.refine_radius as i64;
    let inv_2s2 = cfg.refine_inv_2s2();
    let max_shift = cfg.max_shift();
    let (wi, hi) = (w as i64, h as i64);
    let mut q = start;
    for _ in 0..cfg.refine_iterations {
        let cx = (q.0 + 0.5).floor() as i64;
        let cy = (q.1 + 0.5).floor() as i64;
        let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0f32, 0f32, 0f32, 0f32, 0f32);
        for dy in -rw..=rw {
            for dx in -rw..=rw {
                let (px, py) = (cx + dx, cy + dy);
                if px < 0 || py < 0 || px >= wi || py >= hi {
                    continue;
                }
                let g = grad[(py * wi + px) as usize];
                if g[2] < 0.5 {
                    continue;
                }
                let ox = px as f32 - q.0;
                let oy = py as f32 - q.1;
                let wt = (-(ox * ox + oy * oy) * inv_2s2).exp();
                let gxx = wt * g[0] * g[0];
                let gxy = wt * g[0] * g[1];
                let gyy = wt * g[1] * g[1];
                a11 += gxx;
                a12 += gxy;
                a22 += gyy;
                b1 += gxx * dx as f32 + gxy * dy as f32;
                b2 += gxy * dx as f32 + gyy * dy as f32;
            }
        }
        let det = a11 * a22 - a12 * a12;
        let tr = a11 + a22;
        // Written so that NaN fails the test, as in the shader.
        let well_posed = tr > 0.0 && det > 1.0e-4 * tr * tr;
        if !well_posed {
            return start;
        }
        let qn = (
            cx as f32 + (a22 * b1 - a12 * b2) / det,
            cy as f32 + (a11 * b2 - a12 * b1) / det,
        );
        let moved = (qn.0 - start.0, qn.1 - start.1);
        let near_start = moved.0 * moved.0 + moved.1 * moved.1 <= max_shift * max_shift;
        if !near_start {
            return start;
        }
        let step = (qn.0 - q.0, qn.1 - q.1);
        q = qn;
        if step.0 * step.0 + step.1 * step.1 < 1.0e-4 {
            break;
        }
    }
    q
}

/// Harris corners on the CPU: the reference of [`super::Harris::detect`],
/// the same maths in the same order. `mask` (row-major, one flag per pixel)
/// restricts where corners may be reported; NaN pixels are invalid.
pub fn harris_cpu(
    img: &GreyImage,
    cfg: &HarrisConfig,
    mask: Option<&[bool]>,
) -> Result<Vec<Corner>, FeatureError> {
    cfg.validate()?;
    check_mask(img, mask)?;
    if img.is_empty() {
        return Ok(Vec::new());
    }
    let (w, h) = (img.width, img.height);
    let pixels = pack_pixels(img, mask);
    let m = maps(&pixels, w, h, cfg);
    Ok(corners_of(&pixels, &m, w, h, cfg))
}

/// The corners of `pixels` (`w x h`) from their maps `m`: NMS, the spread
/// selection, the refinement and the merging of duplicates (shared with
/// the host detector, `super::host`).
pub(super) fn corners_of(
    pixels: &[Pixel],
    m: &Maps,
    w: usize,
    h: usize,
    cfg: &HarrisConfig,
) -> Vec<Corner> {
    let selected = select_spread(nms(pixels, &m.response, w, h, cfg), cfg);
    // Each corner is refined on its own: the corners split over the cores
    // give the one pass's.
    let corners = crate::par::flat_map_split(&selected, 64, |part| {
        part.iter()
            .map(|c| {
                let start = (c.x as f32, c.y as f32);
                let (x, y) = if cfg.refine {
                    refine(&m.grad, w, h, start, cfg)
                } else {
                    start
                };
                Corner {
                    x,
                    y,
                    score: c.score,
                }
            })
            .collect()
    });
    merge(corners, cfg.merge_radius)
}
