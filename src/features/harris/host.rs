//! Harris corners on the host, for CPU adapters: the CPU reference's
//! arithmetic ([`super::cpu`]) with the same operations on every pixel in
//! the same order, so the same bits, but each filter pass loops over a
//! row's pixels tap by tap (loops the compiler vectorises, with the image
//! bounds hoisted out of them) and rows are split over the cores. On
//! lavapipe a compute shader's loads are gathers and its passes cost
//! several times this (docs/performance.md); on a GPU the shader path stays.

use super::cpu::{Maps, corners_of};
use super::{Corner, HarrisConfig, gaussian_taps, pack_pixels, radius};
use crate::features::FeatureError;
use crate::features::gpu_data::{INVALID_RESPONSE, PIXEL_HOLE, PIXEL_VALID, Pixel};
use crate::features::image::{GreyImage, check_mask};

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

/// `v` as `n` zeros (its allocation reused).
fn zeros(v: &mut Vec<f32>, n: usize) {
    v.clear();
    v.resize(n, 0.0);
}

/// Harris corners on the host: [`super::harris_cpu`]'s corners, bit for
/// bit, several times faster (vectorised, on every core). `mask` restricts
/// where corners may be reported; NaN pixels are invalid.
pub fn harris_host(
    img: &GreyImage,
    cfg: &HarrisConfig,
    mask: Option<&[bool]>,
) -> Result<Vec<Corner>, FeatureError> {
    cfg.validate()?;
    check_mask(img, mask)?;
    if img.is_empty() {
        return Ok(Vec::new());
    }
    let mut scratch = Scratch {
        pixels: pack_pixels(img, mask),
        ..Default::default()
    };
    Ok(detect_packed(&mut scratch, img.width, img.height, cfg))
}

/// The corners of a rendered view's grey levels with its pinholes packed
/// as holes, every pixel allowed: what [`super::Harris::detect_resolved`]
/// detects on the host, for the CPU device, whose views are on the host.
pub(crate) fn harris_host_view(grey: &GreyImage, cfg: &HarrisConfig) -> Vec<Corner> {
    if grey.is_empty() {
        return Vec::new();
    }
    let mut scratch = Scratch::default();
    crate::features::gpu_data::pack_with_holes_into(grey, None, true, &mut scratch.pixels);
    detect_packed(&mut scratch, grey.width, grey.height, cfg)
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

/// The offsets `x` of a `w`-pixel row whose neighbour `x + t` is inside it.
fn inside(w: usize, t: isize) -> std::ops::Range<usize> {
    let lo = (-t).max(0) as usize;
    let hi = (w as isize - t).clamp(0, w as isize) as usize;
    lo.min(hi)..hi
}

/// The reference's maps (`cpu::maps`) of `s.pixels` into `s.maps`, pass
/// by pass, with the same sums in the same order for every pixel.
fn maps(s: &mut Scratch, w: usize, h: usize, cfg: &HarrisConfig) {
    let (gd, dd) = gaussian_taps(cfg.sigma_d);
    let (gi, _) = gaussian_taps(cfg.sigma_i);
    let rd = radius(cfg.sigma_d) as isize;
    let ri = radius(cfg.sigma_i) as isize;
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
    for v in [&mut *ha, &mut *hb, &mut *hok, &mut *gx, &mut *gy, &mut *gok] {
        zeros(v, n);
    }
    for v in [
        &mut *sxx,
        &mut *syy,
        &mut *sxy,
        &mut *sw,
        &mut maps.response,
    ] {
        zeros(v, n);
    }

    // deriv_h: (I * g'_x, I * g_x, valid)
    par_rows(
        h,
        w,
        [&mut ha[..], &mut hb[..], &mut hok[..]],
        |y0, rows, [a, b, ok]| {
            ok.fill(1.0);
            for r in 0..rows {
                let src = (y0 + r) * w;
                let row = r * w..(r + 1) * w;
                let (a, b, ok) = (&mut a[row.clone()], &mut b[row.clone()], &mut ok[row]);
                for t in -rd..=rd {
                    let k = (t + rd) as usize;
                    let (d, g) = (dd[k], gd[k]);
                    let xs = inside(w, t);
                    ok[..xs.start].fill(-1.0);
                    ok[xs.end..].fill(-1.0);
                    if xs.is_empty() {
                        continue;
                    }
                    let from = (src as isize + xs.start as isize + t) as usize;
                    let v = &value[from..from + xs.len()];
                    let c = &code[from..from + xs.len()];
                    for ((((a, b), ok), v), c) in a[xs.clone()]
                        .iter_mut()
                        .zip(&mut b[xs.clone()])
                        .zip(&mut ok[xs.clone()])
                        .zip(v)
                        .zip(c)
                    {
                        *ok = ok.min(*c);
                        *a += v * d;
                        *b += v * g;
                    }
                }
            }
        },
    );
    // deriv_v: (Ix, Iy, valid)
    let (ha, hb, hok) = (&ha[..], &hb[..], &hok[..]);
    par_rows(
        h,
        w,
        [&mut gx[..], &mut gy[..], &mut gok[..]],
        |y0, rows, [ix, iy, ok]| {
            ok.fill(1.0);
            for r in 0..rows {
                let y = (y0 + r) as isize;
                let row = r * w..(r + 1) * w;
                let (ix, iy, ok) = (&mut ix[row.clone()], &mut iy[row.clone()], &mut ok[row]);
                for t in -rd..=rd {
                    let yy = y + t;
                    if yy < 0 || yy >= h as isize {
                        ok.fill(-1.0);
                        continue;
                    }
                    let k = (t + rd) as usize;
                    let (g, d) = (gd[k], dd[k]);
                    let src = yy as usize * w..(yy as usize + 1) * w;
                    for (((((ix, iy), ok), sa), sb), sok) in ix
                        .iter_mut()
                        .zip(iy.iter_mut())
                        .zip(ok.iter_mut())
                        .zip(&ha[src.clone()])
                        .zip(&hb[src.clone()])
                        .zip(&hok[src.clone()])
                    {
                        *ok = ok.min(*sok);
                        *ix += sa * g;
                        *iy += sb * d;
                    }
                }
            }
        },
    );
    // integrate_h: (Sxx, Syy, Sxy, weight of the valid gradients; -1 when
    // the window leaves the image)
    let (gx, gy, gok) = (&gx[..], &gy[..], &gok[..]);
    par_rows(
        h,
        w,
        [&mut sxx[..], &mut syy[..], &mut sxy[..], &mut sw[..]],
        |y0, rows, [sxx, syy, sxy, sw]| {
            // 1 where the window left the image or met an invalid gradient
            // support (the reference's `outside`).
            let mut outside = vec![0f32; w];
            for r in 0..rows {
                let src = (y0 + r) * w;
                let row = r * w..(r + 1) * w;
                let (sxx, syy, sxy, sw) = (
                    &mut sxx[row.clone()],
                    &mut syy[row.clone()],
                    &mut sxy[row.clone()],
                    &mut sw[row],
                );
                outside.fill(0.0);
                for t in -ri..=ri {
                    let c = gi[(t + ri) as usize];
                    let xs = inside(w, t);
                    outside[..xs.start].fill(1.0);
                    outside[xs.end..].fill(1.0);
                    if xs.is_empty() {
                        continue;
                    }
                    let from = (src as isize + xs.start as isize + t) as usize;
                    let to = from + xs.len();
                    for (((((((xx, yy), xy), ws), out), g0), g1), g2) in sxx[xs.clone()]
                        .iter_mut()
                        .zip(&mut syy[xs.clone()])
                        .zip(&mut sxy[xs.clone()])
                        .zip(&mut sw[xs.clone()])
                        .zip(&mut outside[xs.clone()])
                        .zip(&gx[from..to])
                        .zip(&gy[from..to])
                        .zip(&gok[from..to])
                    {
                        let v = if *g2 > 0.5 { 1.0 } else { 0.0 };
                        if *g2 < -0.5 {
                            *out = 1.0;
                        }
                        *xx += g0 * g0 * v * c;
                        *yy += g1 * g1 * v * c;
                        *xy += g0 * g1 * v * c;
                        *ws += v * c;
                    }
                }
                for (ws, out) in sw.iter_mut().zip(&outside) {
                    if *out != 0.0 {
                        *ws = -1.0;
                    }
                }
            }
        },
    );
    // integrate_v + response
    let (sxx, syy, sxy, sw) = (&sxx[..], &syy[..], &sxy[..], &sw[..]);
    let (k, min_weight) = (cfg.k, cfg.min_valid_weight);
    par_rows(h, w, [&mut maps.response[..]], |y0, rows, [resp]| {
        let (mut axx, mut ayy, mut axy, mut aw) =
            (vec![0f32; w], vec![0f32; w], vec![0f32; w], vec![0f32; w]);
        let mut outside = vec![0f32; w];
        for r in 0..rows {
            let y = (y0 + r) as isize;
            for v in [&mut axx, &mut ayy, &mut axy, &mut aw, &mut outside] {
                v.fill(0.0);
            }
            for t in -ri..=ri {
                let yy = y + t;
                if yy < 0 || yy >= h as isize {
                    outside.fill(1.0);
                    continue;
                }
                let c = gi[(t + ri) as usize];
                let src = yy as usize * w..(yy as usize + 1) * w;
                for (((((((xx, yy), xy), ws), out), s0), s1), (s2, s3)) in axx
                    .iter_mut()
                    .zip(ayy.iter_mut())
                    .zip(axy.iter_mut())
                    .zip(aw.iter_mut())
                    .zip(outside.iter_mut())
                    .zip(&sxx[src.clone()])
                    .zip(&syy[src.clone()])
                    .zip(sxy[src.clone()].iter().zip(&sw[src.clone()]))
                {
                    if *s3 < 0.0 {
                        *out = 1.0;
                    }
                    *xx += s0 * c;
                    *yy += s1 * c;
                    *xy += s2 * c;
                    *ws += s3 * c;
                }
            }
            let at = (y0 + r) * w;
            for x in 0..w {
                let ws = if outside[x] != 0.0 { -1.0 } else { aw[x] };
                let valid =
                    ws >= min_weight * (1.0 - 1.0e-5) && pixels[at + x].flags & PIXEL_VALID != 0;
                resp[r * w + x] = if !valid {
                    INVALID_RESPONSE
                } else {
                    let scale = if ws < 1.0 - 1.0e-5 { 1.0 / ws } else { 1.0 };
                    let (sxx, syy, sxy) = (axx[x] * scale, ayy[x] * scale, axy[x] * scale);
                    let tr = sxx + syy;
                    (sxx * syy - sxy * sxy) - k * (tr * tr)
                };
            }
        }
    });
    maps.grad.clear();
    maps.grad
        .extend(gx.iter().zip(gy).zip(gok).map(|((x, y), ok)| [*x, *y, *ok]));
}
