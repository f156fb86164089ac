//! CPU reference of the Harris detector: every pass of
//! `shaders/harris.wgsl`, operation for operation in `f32`, plus the host
//! steps that both paths share (pixel packing, kernel taps, spread
//! selection, merging of refined duplicates).

use super::FeatureError;
use super::gpu_data::{
    Candidate, INVALID_RESPONSE, MAX_DERIV_RADIUS, MAX_INTEGRATION_RADIUS, PIXEL_ALLOWED,
    PIXEL_VALID, Pixel,
};
use super::harris::{Corner, HarrisConfig};
use super::image::{GreyImage, check_mask};

/// Kernel radius for a Gaussian of standard deviation `sigma`: 3 sigma.
pub(crate) fn radius(sigma: f32) -> usize {
    ((3.0 * sigma).ceil() as usize).max(1)
}

/// Gaussian taps `g` (sum 1) and derivative taps `d` (`sum i d_i = 1`, so a
/// ramp of slope 1 has derivative exactly 1), index `i + r` for offset `i`.
pub(crate) fn gaussian_taps(sigma: f32) -> (Vec<f32>, Vec<f32>) {
    let r = radius(sigma) as i64;
    let s2 = 2.0 * (sigma as f64).powi(2);
    let g: Vec<f64> = (-r..=r).map(|i| (-(i * i) as f64 / s2).exp()).collect();
    let sum: f64 = g.iter().sum();
    let moment: f64 = (-r..=r).zip(&g).map(|(i, g)| (i * i) as f64 * g).sum();
    let taps = g.iter().map(|g| (g / sum) as f32).collect();
    let deriv = (-r..=r)
        .zip(&g)
        .map(|(i, g)| (i as f64 * g / moment) as f32)
        .collect();
    (taps, deriv)
}

impl HarrisConfig {
    /// Checks every parameter; the error names the first bad one.
    pub fn validate(&self) -> Result<(), FeatureError> {
        let bad = |m: String| Err(FeatureError::Config(m));
        let max_d = MAX_DERIV_RADIUS as f32 / 3.0;
        let max_i = MAX_INTEGRATION_RADIUS as f32 / 3.0;
        if !(self.sigma_d > 0.0 && self.sigma_d <= max_d) {
            return bad(format!(
                "sigma_d = {} is not in (0, {max_d:.3}]",
                self.sigma_d
            ));
        }
        if !(self.sigma_i > 0.0 && self.sigma_i <= max_i) {
            return bad(format!(
                "sigma_i = {} is not in (0, {max_i:.3}]",
                self.sigma_i
            ));
        }
        if !(self.k >= 0.0 && self.k < 0.25) {
            return bad(format!("k = {} is not in [0, 0.25)", self.k));
        }
        if !(0.0..=1.0).contains(&self.relative_threshold) {
            return bad(format!(
                "relative_threshold = {} is not in [0, 1]",
                self.relative_threshold
            ));
        }
        if !(self.min_response >= 0.0 && self.min_response.is_finite()) {
            return bad(format!("min_response = {} is not >= 0", self.min_response));
        }
        if self.max_corners == 0 {
            return bad("max_corners is 0".into());
        }
        if self.refine_radius == 0 || self.refine_radius > 15 {
            return bad(format!(
                "refine_radius = {} is not in 1..=15",
                self.refine_radius
            ));
        }
        if self.refine_iterations > 100 {
            return bad(format!(
                "refine_iterations = {} is more than 100",
                self.refine_iterations
            ));
        }
        if !(self.merge_radius >= 0.0 && self.merge_radius.is_finite()) {
            return bad(format!("merge_radius = {} is not >= 0", self.merge_radius));
        }
        Ok(())
    }

    /// The support radius (derivative + integration kernel radii, pixels)
    /// over which a corner's response depends on the image: corners lie at
    /// least this far from the border and from invalid pixels (Chebyshev
    /// distance, before refinement).
    pub fn support_radius(&self) -> usize {
        radius(self.sigma_d) + radius(self.sigma_i)
    }

    /// Gaussian window of the refinement, as `1 / (2 sigma_w^2)`.
    pub(crate) fn refine_inv_2s2(&self) -> f32 {
        let s = 0.75 * self.refine_radius as f32;
        1.0 / (2.0 * s * s)
    }

    pub(crate) fn max_shift(&self) -> f32 {
        self.refine_radius as f32
    }
}

/// The image and mask as the GPU sees them: NaN (invalid) pixels become 0
/// with the valid flag cleared.
pub(crate) fn pack_pixels(img: &GreyImage, mask: Option<&[bool]>) -> Vec<Pixel> {
    img.data
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let valid = v.is_finite();
            let allowed = mask.is_none_or(|m| m[i]);
            Pixel {
                value: if valid { v } else { 0.0 },
                flags: if valid { PIXEL_VALID } else { 0 }
                    | if allowed { PIXEL_ALLOWED } else { 0 },
            }
        })
        .collect()
}

/// The best `max_corners` candidates, spread over the image: each is ranked
/// within its `grid_cell`-sized cell, and candidates are taken rank by rank
/// (ties by score, then position). Deterministic whatever the input order.
pub(crate) fn select_spread(mut cands: Vec<Candidate>, cfg: &HarrisConfig) -> Vec<Candidate> {
    let by_score = |a: &Candidate, b: &Candidate| {
        b.score
            .total_cmp(&a.score)
            .then(a.y.cmp(&b.y))
            .then(a.x.cmp(&b.x))
    };
    cands.sort_by(by_score);
    if cfg.grid_cell == 0 {
        cands.truncate(cfg.max_corners);
        return cands;
    }
    let cell = cfg.grid_cell;
    let mut rank_in_cell = std::collections::HashMap::new();
    let mut ranked: Vec<(u32, Candidate)> = cands
        .into_iter()
        .map(|c| {
            let r = rank_in_cell.entry((c.x / cell, c.y / cell)).or_insert(0u32);
            *r += 1;
            (*r, c)
        })
        .collect();
    ranked.sort_by(|(ra, a), (rb, b)| ra.cmp(rb).then(by_score(a, b)));
    ranked.truncate(cfg.max_corners);
    ranked.into_iter().map(|(_, c)| c).collect()
}

/// Greedy merge of refined corners closer than `radius`, strongest first
/// (refinement pulls the split maxima of an X-junction onto one point).
/// The result is sorted by decreasing score.
pub(crate) fn merge(mut corners: Vec<Corner>, radius: f32) -> Vec<Corner> {
    corners.sort_by(|a, b| {
        b.score
            .total_cmp(&a.score)
            .then(a.y.total_cmp(&b.y))
            .then(a.x.total_cmp(&b.x))
    });
    if radius <= 0.0 {
        return corners;
    }
    let r2 = radius * radius;
    let mut kept: Vec<Corner> = Vec::with_capacity(corners.len());
    for c in corners {
        if kept
            .iter()
            .all(|k| (k.x - c.x).powi(2) + (k.y - c.y).powi(2) >= r2)
        {
            kept.push(c);
        }
    }
    kept
}

struct Maps {
    grad: Vec<[f32; 3]>,
    response: Vec<f32>,
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
                    ok = 0.0;
                    continue;
                }
                let p = pixels[(y * wi + xx) as usize];
                if p.flags & PIXEL_VALID == 0 {
                    ok = 0.0;
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
                    ok = 0.0;
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
    // integrate_h: (Sxx, Syy, Sxy, valid)
    for y in 0..hi {
        for x in 0..wi {
            let (mut sxx, mut syy, mut sxy, mut ok) = (0f32, 0f32, 0f32, 1f32);
            for t in -ri..=ri {
                let xx = x + t;
                if xx < 0 || xx >= wi {
                    ok = 0.0;
                    continue;
                }
                let g = grad[(y * wi + xx) as usize];
                ok = ok.min(g[2]);
                let c = gi[(t + ri) as usize];
                sxx += g[0] * g[0] * c;
                syy += g[1] * g[1] * c;
                sxy += g[0] * g[1] * c;
            }
            tmp[(y * wi + x) as usize] = [sxx, syy, sxy, ok];
        }
    }
    // integrate_v + response
    let mut response = vec![0f32; n];
    for y in 0..hi {
        for x in 0..wi {
            let (mut sxx, mut syy, mut sxy, mut ok) = (0f32, 0f32, 0f32, 1f32);
            for t in -ri..=ri {
                let yy = y + t;
                if yy < 0 || yy >= hi {
                    ok = 0.0;
                    continue;
                }
                let s = tmp[(yy * wi + x) as usize];
                ok = ok.min(s[3]);
                let c = gi[(t + ri) as usize];
                sxx += s[0] * c;
                syy += s[1] * c;
                sxy += s[2] * c;
            }
            let tr = sxx + syy;
            response[(y * wi + x) as usize] = if ok < 0.5 {
                INVALID_RESPONSE
            } else {
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
    let selected = select_spread(nms(&pixels, &m.response, w, h, cfg), cfg);
    let corners = selected
        .iter()
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
        .collect();
    Ok(merge(corners, cfg.merge_radius))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn taps_are_normalised() {
        for sigma in [0.7f32, 1.0, 1.5, 2.0] {
            let (g, d) = gaussian_taps(sigma);
            let r = radius(sigma) as i64;
            assert_eq!(g.len(), 2 * r as usize + 1);
            assert!((g.iter().sum::<f32>() - 1.0).abs() < 1e-6);
            let m: f32 = (-r..=r).zip(&d).map(|(i, d)| i as f32 * d).sum();
            assert!((m - 1.0).abs() < 1e-6, "derivative of a unit ramp: {m}");
            assert!(d.iter().sum::<f32>().abs() < 1e-6);
        }
    }

    #[test]
    fn spread_selection_takes_every_cell_first() {
        let cfg = HarrisConfig::default()
            .with_max_corners(3)
            .with_grid_cell(10);
        let c = |x, y, score| Candidate {
            x,
            y,
            score,
            _pad: 0,
        };
        // Three strong corners in one cell, one weak corner in another.
        let got = select_spread(
            vec![c(1, 1, 9.0), c(2, 5, 8.0), c(5, 2, 7.0), c(50, 50, 1.0)],
            &cfg,
        );
        let xs: Vec<u32> = got.iter().map(|c| c.x).collect();
        assert_eq!(xs, vec![1, 50, 2]);
    }

    #[test]
    fn merge_keeps_the_strongest_of_close_corners() {
        let c = |x, y, score| Corner { x, y, score };
        let got = merge(
            vec![c(10.0, 10.0, 1.0), c(10.5, 10.2, 2.0), c(20.0, 10.0, 0.5)],
            1.5,
        );
        assert_eq!(got, vec![c(10.5, 10.2, 2.0), c(20.0, 10.0, 0.5)]);
    }
}
