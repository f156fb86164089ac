//! Harris corners on the host, for CPU adapters: the CPU reference's
//! arithmetic ([`super::cpu`]) with the same operations on every pixel in
//! the same order, so the same bits, but each filter pass sums four or
//! eight pixels at a time in vectors kept in registers over its taps (the
//! pixels whose horizontal taps leave the image take the reference's
//! per-pixel path) and rows are split over the cores. On
//! lavapipe a compute shader's loads are gathers and its passes cost
//! several times this (docs/performance.md); on a GPU the shader path stays.

use super::cpu::{Maps, corners_of};
use super::{Corner, HarrisConfig, gaussian_taps, pack_pixels, radius};
use crate::features::FeatureError;
use crate::features::gpu_data::{INVALID_RESPONSE, PIXEL_HOLE, PIXEL_VALID, Pixel};
use crate::features::image::{GreyImage, check_mask};
use glam::{BVec4A, Vec4};

/// The host detector's images, kept between detections by [`super::Harris`]
/// in host mode (grow-only: a detection of a size seen before allocates
/// nothing and touches no fresh pages).
#[derive(Default)]
pub(super) struct Scratch {
    pub(super) pixels: Vec<Pixel>,
    value: Vec<f32>,
    code: Vec<f32>,
    ha: Vec<f32>,
    hb: Vec<f32>,
    hok: Vec<f32>,
    gx: Vec<f32>,
    gy: Vec<f32>,
    gok: Vec<f32>,
    sxx: Vec<f32>,
    syy: Vec<f32>,
    sxy: Vec<f32>,
    sw: Vec<f32>,
    maps: Maps,
}

/// Harris corners on the host: [`super::harris_cpu`]'s corners, bit for
/// bit, several times faster (vectorised, on every core). `mask` restricts
/// where corners may be reported; NaN pixels are invalid.
pub fn harris_host(
    img: &GreyImage,
    cfg: &HarrisConfig,
    mask: Option<&[bool]>,
) -> Result<Vec<Corner>, FeatureError> {
    HostHarris::new(cfg.clone())?.detect(img, mask)
}

/// [`harris_host`] with its images kept from one detection to the next
/// (the CPU device's detector, which runs a few a frame: fresh images of
/// a window's size cost page faults on every call).
pub(crate) struct HostHarris {
    config: HarrisConfig,
    scratch: Scratch,
}

impl HostHarris {
    /// A detector for `config`, checked.
    pub(crate) fn new(config: HarrisConfig) -> Result<Self, FeatureError> {
        config.validate()?;
        Ok(Self {
            config,
            scratch: Scratch::default(),
        })
    }

    /// [`harris_host`] of `img` within `mask`.
    pub(crate) fn detect(
        &mut self,
        img: &GreyImage,
        mask: Option<&[bool]>,
    ) -> Result<Vec<Corner>, FeatureError> {
        check_mask(img, mask)?;
        if img.is_empty() {
            return Ok(Vec::new());
        }
        let pixels = &mut self.scratch.pixels;
        crate::features::gpu_data::pack_with_holes_into(img, mask, true, pixels);
        Ok(detect_packed(
            &mut self.scratch,
            img.width,
            img.height,
            &self.config,
        ))
    }

    /// The corners of a rendered view's grey levels with its pinholes
    /// packed as holes, every pixel allowed: what
    /// [`super::Harris::detect_resolved`] detects on the host, for the CPU
    /// device, whose views are on the host.
    pub(crate) fn detect_view(&mut self, grey: &GreyImage) -> Vec<Corner> {
        if grey.is_empty() {
            return Vec::new();
        }
        let pixels = &mut self.scratch.pixels;
        crate::features::gpu_data::pack_with_holes_into(grey, None, true, pixels);
        detect_packed(&mut self.scratch, grey.width, grey.height, &self.config)
    }
}

/// The corners of the packed pixels in `scratch.pixels` (`w x h`, as
/// [`pack_pixels`] makes them).
pub(super) fn detect_packed(
    scratch: &mut Scratch,
    w: usize,
    h: usize,
    cfg: &HarrisConfig,
) -> Vec<Corner> {
    maps(scratch, w, h, cfg);
    corners_of(&scratch.pixels[..w * h], &scratch.maps, w, h, cfg)
}

/// The Harris response map on the host ([`super::harris_response_cpu`]'s,
/// bit for bit).
pub fn harris_response_host(img: &GreyImage, cfg: &HarrisConfig) -> Result<Vec<f32>, FeatureError> {
    cfg.validate()?;
    check_mask(img, None)?;
    let mut scratch = Scratch {
        pixels: pack_pixels(img, None),
        ..Default::default()
    };
    maps(&mut scratch, img.width, img.height, cfg);
    Ok(scratch.maps.response)
}

/// Runs `f(first_row, rows, outputs)` on bands of rows of the `K` row-major
/// `w`-wide images `outs`, one band per core (`f` gets each output's rows
/// of its band).
fn par_rows<const K: usize, F>(h: usize, w: usize, outs: [&mut [f32]; K], f: F)
where
    F: Fn(usize, usize, [&mut [f32]; K]) + Sync,
{
    let threads = crate::par::cores().min(8).min(h.div_ceil(16).max(1));
    let per = h.div_ceil(threads);
    let mut rest = outs;
    std::thread::scope(|scope| {
        let mut y0 = 0;
        while y0 < h {
            let rows = per.min(h - y0);
            let band: [&mut [f32]; K] = std::array::from_fn(|i| {
                let (mine, tail) = std::mem::take(&mut rest[i]).split_at_mut(rows * w);
                rest[i] = tail;
                mine
            });
            let f = &f;
            if y0 + rows < h {
                scope.spawn(move || f(y0, rows, band));
            } else {
                f(y0, rows, band);
            }
            y0 += rows;
        }
    });
}

/// `v` resized to `n` values, its old ones kept (every pass writes all
/// of its output, so nothing needs clearing).
fn sized(v: &mut Vec<f32>, n: usize) {
    v.resize(n, 0.0);
}

/// Pixels a horizontal pass sums at once, in two four-lane vectors kept in
/// registers across the taps (each lane's sum in the reference's order,
/// so the same bits).
const STEP: usize = 8;

/// The columns of a `w`-pixel row whose `2 r + 1` taps are all inside it:
/// the first and one past the last (the columns before and after take
/// the per-pixel path).
fn interior(w: usize, r: usize) -> (usize, usize) {
    let lo = r.min(w);
    (lo, w.saturating_sub(r).max(lo))
}

/// Four values of `s` from `at`.
#[inline(always)]
fn load(s: &[f32], at: usize) -> Vec4 {
    Vec4::from_slice(&s[at..at + 4])
}

/// `STEP` lanes into `out`.
#[inline(always)]
fn store(v: &[Vec4; 2], out: &mut [f32]) {
    v[0].write_to_slice(&mut out[..4]);
    v[1].write_to_slice(&mut out[4..STEP]);
}

/// deriv_h over one row: `(I * g'_x, I * g_x, valid)` of the row's grey
/// levels `value` and validity codes `code`.
fn deriv_h_row(
    (value, code): (&[f32], &[f32]),
    (dd, gd): (&[f32], &[f32]),
    (a, b, ok): (&mut [f32], &mut [f32], &mut [f32]),
) {
    let w = value.len();
    let r = dd.len() / 2;
    let one = |x: usize| {
        let (mut sa, mut sb, mut so) = (0f32, 0f32, 1f32);
        for k in 0..dd.len() {
            let Some(xx) = (x + k).checked_sub(r).filter(|&xx| xx < w) else {
                so = -1.0;
                continue;
            };
            so = so.min(code[xx]);
            sa += value[xx] * dd[k];
            sb += value[xx] * gd[k];
        }
        (sa, sb, so)
    };
    let (lo, hi) = interior(w, r);
    let mut x = 0;
    while x < w {
        if x >= lo && x + STEP <= hi {
            let (mut sa, mut sb, mut so) = ([Vec4::ZERO; 2], [Vec4::ZERO; 2], [Vec4::ONE; 2]);
            for k in 0..dd.len() {
                let at = x + k - r;
                let (d, g) = (Vec4::splat(dd[k]), Vec4::splat(gd[k]));
                for j in 0..2 {
                    let (v, c) = (load(value, at + 4 * j), load(code, at + 4 * j));
                    // The codes are never NaN: the vector min is f32::min.
                    so[j] = so[j].min(c);
                    sa[j] += v * d;
                    sb[j] += v * g;
                }
            }
            store(&sa, &mut a[x..x + STEP]);
            store(&sb, &mut b[x..x + STEP]);
            store(&so, &mut ok[x..x + STEP]);
            x += STEP;
        } else {
            (a[x], b[x], ok[x]) = one(x);
            x += 1;
        }
    }
}

/// integrate_h over one row: `(Sxx, Syy, Sxy, weight of the valid
/// gradients)` of the row's gradients, the weight -1 where the window
/// leaves the row or meets an invalid gradient support.
fn integrate_h_row(
    (gx, gy, gok): (&[f32], &[f32], &[f32]),
    gi: &[f32],
    (sxx, syy, sxy, sw): (&mut [f32], &mut [f32], &mut [f32], &mut [f32]),
) {
    let w = gx.len();
    let r = gi.len() / 2;
    let one = |x: usize| {
        let (mut xx, mut yy, mut xy, mut ws) = (0f32, 0f32, 0f32, 0f32);
        let mut outside = false;
        for (k, &c) in gi.iter().enumerate() {
            let Some(t) = (x + k).checked_sub(r).filter(|&t| t < w) else {
                outside = true;
                continue;
            };
            let (g0, g1, g2) = (gx[t], gy[t], gok[t]);
            let v = if g2 > 0.5 { 1.0 } else { 0.0 };
            outside |= g2 < -0.5;
            xx += g0 * g0 * v * c;
            yy += g1 * g1 * v * c;
            xy += g0 * g1 * v * c;
            ws += v * c;
        }
        (xx, yy, xy, if outside { -1.0 } else { ws })
    };
    let (lo, hi) = interior(w, r);
    let mut x = 0;
    while x < w {
        if x >= lo && x + STEP <= hi {
            let mut acc = [[Vec4::ZERO; 2]; 4];
            let mut out = [BVec4A::FALSE; 2];
            for (k, &c) in gi.iter().enumerate() {
                let t = x + k - r;
                let c = Vec4::splat(c);
                for j in 0..2 {
                    let at = t + 4 * j;
                    let (g0, g1, g2) = (load(gx, at), load(gy, at), load(gok, at));
                    let v = Vec4::select(g2.cmpgt(Vec4::splat(0.5)), Vec4::ONE, Vec4::ZERO);
                    out[j] |= g2.cmplt(Vec4::splat(-0.5));
                    acc[0][j] += g0 * g0 * v * c;
                    acc[1][j] += g1 * g1 * v * c;
                    acc[2][j] += g0 * g1 * v * c;
                    acc[3][j] += v * c;
                }
            }
            for j in 0..2 {
                acc[3][j] = Vec4::select(out[j], Vec4::splat(-1.0), acc[3][j]);
            }
            store(&acc[0], &mut sxx[x..x + STEP]);
            store(&acc[1], &mut syy[x..x + STEP]);
            store(&acc[2], &mut sxy[x..x + STEP]);
            store(&acc[3], &mut sw[x..x + STEP]);
            x += STEP;
        } else {
            (sxx[x], syy[x], sxy[x], sw[x]) = one(x);
            x += 1;
        }
    }
}

/// The rows of a vertical pass at output row `y` into `out` (its
/// allocation reused from row to row): each tap's source row (its first
/// pixel), `None` where it leaves the `h`-row image.
fn tap_rows(out: &mut Vec<Option<usize>>, y: usize, r: usize, taps: usize, w: usize, h: usize) {
    out.clear();
    out.extend((0..taps).map(|k| (y + k).checked_sub(r).filter(|&yy| yy < h).map(|yy| yy * w)));
}

/// deriv_v over one row: `(Ix, Iy, valid)` from deriv_h's rows (`rows`,
/// the `2 rd + 1` around it).
fn deriv_v_row(
    rows: &[Option<usize>],
    (ha, hb, hok): (&[f32], &[f32], &[f32]),
    (gd, dd): (&[f32], &[f32]),
    (ix, iy, ok): (&mut [f32], &mut [f32], &mut [f32]),
) {
    let w = ix.len();
    let any_outside = rows.iter().any(Option::is_none);
    let mut x = 0;
    while x + 4 <= w {
        let (mut sx, mut sy, mut so) = (Vec4::ZERO, Vec4::ZERO, Vec4::ONE);
        for (k, row) in rows.iter().enumerate() {
            let Some(at) = row else {
                continue;
            };
            let i = at + x;
            so = so.min(load(hok, i));
            sx += load(ha, i) * Vec4::splat(gd[k]);
            sy += load(hb, i) * Vec4::splat(dd[k]);
        }
        if any_outside {
            so = Vec4::splat(-1.0);
        }
        sx.write_to_slice(&mut ix[x..]);
        sy.write_to_slice(&mut iy[x..]);
        so.write_to_slice(&mut ok[x..]);
        x += 4;
    }
    for x in x..w {
        let (mut sx, mut sy, mut so) = (0f32, 0f32, 1f32);
        for (k, row) in rows.iter().enumerate() {
            let Some(at) = row else {
                so = -1.0;
                continue;
            };
            let i = at + x;
            so = so.min(hok[i]);
            sx += ha[i] * gd[k];
            sy += hb[i] * dd[k];
        }
        (ix[x], iy[x], ok[x]) = (sx, sy, so);
    }
}

/// integrate_v over one row, then the response: the structure tensor's
/// window sums from integrate_h's rows (`rows`, the `2 ri + 1` around it),
/// normalised by the valid weight, and `det - k tr^2` where the pixel and
/// its window are valid (`INVALID_RESPONSE` elsewhere).
fn response_row(
    rows: &[Option<usize>],
    (sxx, syy, sxy, sw): (&[f32], &[f32], &[f32], &[f32]),
    gi: &[f32],
    pixels: &[Pixel],
    (k, min_weight): (f32, f32),
    resp: &mut [f32],
) {
    let w = resp.len();
    let any_outside = rows.iter().any(Option::is_none);
    let response = |x: usize, [xx, yy, xy, ws]: [f32; 4], outside: bool| {
        let ws = if outside { -1.0 } else { ws };
        let valid = ws >= min_weight * (1.0 - 1.0e-5) && pixels[x].flags & PIXEL_VALID != 0;
        if !valid {
            INVALID_RESPONSE
        } else {
            let scale = if ws < 1.0 - 1.0e-5 { 1.0 / ws } else { 1.0 };
            let (sxx, syy, sxy) = (xx * scale, yy * scale, xy * scale);
            let tr = sxx + syy;
            (sxx * syy - sxy * sxy) - k * (tr * tr)
        }
    };
    let mut x = 0;
    while x + 4 <= w {
        let mut acc = [Vec4::ZERO; 4];
        let mut out = BVec4A::splat(any_outside);
        for (t, row) in rows.iter().enumerate() {
            let Some(at) = row else {
                continue;
            };
            let (i, c) = (at + x, Vec4::splat(gi[t]));
            let s3 = load(sw, i);
            out |= s3.cmplt(Vec4::ZERO);
            acc[0] += load(sxx, i) * c;
            acc[1] += load(syy, i) * c;
            acc[2] += load(sxy, i) * c;
            acc[3] += s3 * c;
        }
        // The response in four lanes, each with the scalar's operations.
        let ws = Vec4::select(out, Vec4::splat(-1.0), acc[3]);
        let px = &pixels[x..x + 4];
        let ok = |l: usize| px[l].flags & PIXEL_VALID != 0;
        let valid = ws.cmpge(Vec4::splat(min_weight * (1.0 - 1.0e-5)))
            & BVec4A::new(ok(0), ok(1), ok(2), ok(3));
        let scale = Vec4::select(
            ws.cmplt(Vec4::splat(1.0 - 1.0e-5)),
            Vec4::ONE / ws,
            Vec4::ONE,
        );
        let (sxx, syy, sxy) = (acc[0] * scale, acc[1] * scale, acc[2] * scale);
        let tr = sxx + syy;
        let r = (sxx * syy - sxy * sxy) - Vec4::splat(k) * (tr * tr);
        Vec4::select(valid, r, Vec4::splat(INVALID_RESPONSE)).write_to_slice(&mut resp[x..]);
        x += 4;
    }
    for (x, out) in resp.iter_mut().enumerate().skip(x) {
        let mut v = [0f32; 4];
        let mut outside = false;
        for (t, row) in rows.iter().enumerate() {
            let Some(at) = row else {
                outside = true;
                continue;
            };
            let (i, c) = (at + x, gi[t]);
            outside |= sw[i] < 0.0;
            v[0] += sxx[i] * c;
            v[1] += syy[i] * c;
            v[2] += sxy[i] * c;
            v[3] += sw[i] * c;
        }
        *out = response(x, v, outside);
    }
}

/// The reference's maps (`cpu::maps`) of `s.pixels` into `s.maps`, pass
/// by pass, with the same sums in the same order for every pixel.
fn maps(s: &mut Scratch, w: usize, h: usize, cfg: &HarrisConfig) {
    let (gd, dd) = gaussian_taps(cfg.sigma_d);
    let (gi, _) = gaussian_taps(cfg.sigma_i);
    let rd = radius(cfg.sigma_d);
    let ri = radius(cfg.sigma_i);
    let n = w * h;
    let Scratch {
        pixels,
        value,
        code,
        ha,
        hb,
        hok,
        gx,
        gy,
        gok,
        sxx,
        syy,
        sxy,
        sw,
        maps,
    } = s;
    let pixels = &pixels[..n];
    value.clear();
    value.extend(pixels.iter().map(|p| p.value));
    // What an invalid pixel does to a derivative's validity: a pinhole
    // makes it 0, another invalid pixel -1 (a valid one leaves it: 1).
    code.clear();
    code.extend(pixels.iter().map(|p| {
        if p.flags & PIXEL_VALID != 0 {
            1.0
        } else if p.flags & PIXEL_HOLE != 0 {
            0.0
        } else {
            -1.0
        }
    }));
    let (value, code) = (&value[..], &code[..]);
    for v in [
        &mut *ha,
        &mut *hb,
        &mut *hok,
        &mut *gx,
        &mut *gy,
        &mut *gok,
        &mut *sxx,
        &mut *syy,
        &mut *sxy,
        &mut *sw,
        &mut maps.response,
    ] {
        sized(v, n);
    }
    let (dd, gd, gi) = (&dd[..], &gd[..], &gi[..]);
    par_rows(
        h,
        w,
        [&mut ha[..], &mut hb[..], &mut hok[..]],
        |y0, rows, [a, b, ok]| {
            for r in 0..rows {
                let (src, row) = ((y0 + r) * w, r * w..(r + 1) * w);
                deriv_h_row(
                    (&value[src..src + w], &code[src..src + w]),
                    (dd, gd),
                    (&mut a[row.clone()], &mut b[row.clone()], &mut ok[row]),
                );
            }
        },
    );
    let (ha, hb, hok) = (&ha[..], &hb[..], &hok[..]);
    par_rows(
        h,
        w,
        [&mut gx[..], &mut gy[..], &mut gok[..]],
        |y0, rows, [ix, iy, ok]| {
            let mut taps = Vec::new();
            for r in 0..rows {
                tap_rows(&mut taps, y0 + r, rd, gd.len(), w, h);
                let row = r * w..(r + 1) * w;
                deriv_v_row(
                    &taps,
                    (ha, hb, hok),
                    (gd, dd),
                    (&mut ix[row.clone()], &mut iy[row.clone()], &mut ok[row]),
                );
            }
        },
    );
    let (gx, gy, gok) = (&gx[..], &gy[..], &gok[..]);
    par_rows(
        h,
        w,
        [&mut sxx[..], &mut syy[..], &mut sxy[..], &mut sw[..]],
        |y0, rows, [xx, yy, xy, ws]| {
            for r in 0..rows {
                let (src, row) = ((y0 + r) * w, r * w..(r + 1) * w);
                integrate_h_row(
                    (&gx[src..src + w], &gy[src..src + w], &gok[src..src + w]),
                    gi,
                    (
                        &mut xx[row.clone()],
                        &mut yy[row.clone()],
                        &mut xy[row.clone()],
                        &mut ws[row],
                    ),
                );
            }
        },
    );
    let (sxx, syy, sxy, sw) = (&sxx[..], &syy[..], &sxy[..], &sw[..]);
    let kw = (cfg.k, cfg.min_valid_weight);
    par_rows(h, w, [&mut maps.response[..]], |y0, rows, [resp]| {
        let mut taps = Vec::new();
        for r in 0..rows {
            let y = y0 + r;
            tap_rows(&mut taps, y, ri, gi.len(), w, h);
            response_row(
                &taps,
                (sxx, syy, sxy, sw),
                gi,
                &pixels[y * w..(y + 1) * w],
                kw,
                &mut resp[r * w..(r + 1) * w],
            );
        }
    });
    maps.grad.clear();
    maps.grad
        .extend(gx.iter().zip(gy).zip(gok).map(|((x, y), ok)| [*x, *y, *ok]));
}
