//! CPU reference of NCC matching: `shaders/ncc_*.wgsl` operation for
//! operation in `f32` (same sampling, same summation order). Windows with
//! a few invalid samples are scored over the samples valid in both windows
//! of a pair (see [`NccConfig::min_valid`]).

use super::config::{Match, NccConfig};
use super::pairs::{mutual, sanitize};
use crate::features::FeatureError;
use crate::features::gpu_data::{Best, NO_INDEX, NO_SCORE, pinholes};
use crate::features::harris::Corner;
use crate::features::image::{GreyImage, check_mask};

/// Features a thread takes at least, where the matching splits over the
/// cores (a thread costs tens of microseconds).
const PER_THREAD: usize = 64;

/// A feature's window as `vectorize` leaves it.
enum Window {
    /// Every sample valid: the zero-mean unit-norm row (w² values, padded
    /// with zeros to `stride`).
    Full(Vec<f32>),
    /// Some samples invalid (`None`), enough valid: the raw samples.
    Partial(Vec<Option<f32>>),
}

/// The smallest number of valid samples of `d` that `min_valid` allows, in
/// f32 as the shader computes it.
fn min_count(min_valid: f32, d: usize) -> usize {
    (min_valid * d as f32).ceil() as usize
}

/// The sample at (x, y): `Some(None)` where it touches a pinhole (and
/// otherwise valid pixels), `None` outside the image or where it touches
/// another invalid pixel (the shader's `sample`).
fn sample(img: &GreyImage, holes: &[bool], x: f32, y: f32) -> Option<Option<f32>> {
    let (w, h) = (img.width, img.height);
    if w < 2 || h < 2 || !(x >= 0.0 && y >= 0.0) || x > (w - 1) as f32 || y > (h - 1) as f32 {
        return None;
    }
    if let Some(v) = img.bilinear(x, y) {
        return Some(Some(v));
    }
    let x0 = (x.floor() as usize).min(w - 2);
    let y0 = (y.floor() as usize).min(h - 2);
    let i = y0 * w + x0;
    let tolerated = [i, i + 1, i + w, i + w + 1]
        .iter()
        .all(|&j| img.data[j].is_finite() || holes[j]);
    tolerated.then_some(None)
}

/// The window of `p`, or `None` if it leaves the image, has fewer valid
/// samples than `cfg.min_valid` allows, or is flat. The `vectorize` kernel.
fn vectorize(
    img: &GreyImage,
    holes: &[bool],
    p: [f32; 2],
    cfg: &NccConfig,
    stride: usize,
) -> Option<Window> {
    let win = cfg.patch;
    let half = (win / 2) as f32;
    let d = (win * win) as usize;
    let mut raw = vec![None; d];
    let (mut sum, mut n) = (0f32, 0usize);
    for k in 0..d as u32 {
        let u = (k % win) as f32 - half;
        let v = (k / win) as f32 - half;
        let s = sample(img, holes, p[0] + u, p[1] + v)?;
        if let Some(s) = s {
            raw[k as usize] = Some(s);
            sum += s;
            n += 1;
        }
    }
    if n < min_count(cfg.min_valid, d) || n == 0 {
        return None;
    }
    let mean = sum / n as f32;
    let mut ss = 0f32;
    for v in raw.iter().flatten() {
        let c = v - mean;
        ss += c * c;
    }
    // Flat windows correlate noise with noise; NaN fails too.
    let textured = (ss / n as f32).sqrt() >= cfg.min_std;
    if !textured {
        return None;
    }
    if n < d {
        return Some(Window::Partial(raw));
    }
    let inv = 1.0 / ss.sqrt();
    let mut row = vec![0f32; stride];
    for (r, v) in row.iter_mut().zip(raw.iter().flatten()) {
        *r = (v - mean) * inv;
    }
    Some(Window::Full(row))
}

/// The raw samples of a window (a full one's are not kept: its unit row is
/// an affine map of them, and NCC is invariant to those).
fn raw_of(w: &Window) -> Option<&[Option<f32>]> {
    match w {
        Window::Partial(r) => Some(r),
        Window::Full(_) => None,
    }
}

/// NCC over the samples valid in both windows: the shader's
/// `partial_score`, in the same order. `None` (no score) when that common
/// set is too small or flat in either window.
fn partial_score(a: &[Option<f32>], b: &[Option<f32>], cfg: &NccConfig) -> Option<f32> {
    let d = a.len();
    let both = || a.iter().zip(b).filter_map(|(x, y)| Some(((*x)?, (*y)?)));
    let (mut n, mut sa, mut sb) = (0usize, 0f32, 0f32);
    for (x, y) in both() {
        n += 1;
        sa += x;
        sb += y;
    }
    if n < min_count(cfg.min_valid, d) || n == 0 {
        return None;
    }
    let (ma, mb) = (sa / n as f32, sb / n as f32);
    let (mut caa, mut cbb, mut cab) = (0f32, 0f32, 0f32);
    for (x, y) in both() {
        let (x, y) = (x - ma, y - mb);
        caa += x * x;
        cbb += y * y;
        cab += x * y;
    }
    let nf = n as f32;
    let textured = (caa / nf).sqrt() >= cfg.min_std && (cbb / nf).sqrt() >= cfg.min_std;
    textured.then(|| cab / (caa * cbb).sqrt())
}

/// Mutual best NCC matches on the CPU: the reference of
/// [`super::NccMatcher::match_features`], sorted by `a`.
pub fn ncc_match_cpu(
    img_a: &GreyImage,
    a: &[Corner],
    img_b: &GreyImage,
    b: &[Corner],
    cfg: &NccConfig,
) -> Result<Vec<Match>, FeatureError> {
    match_in_parts(img_a, a, img_b, b, cfg, PER_THREAD)
}

/// [`ncc_match_cpu`], split over the cores where there are at least
/// `per_thread` features.
fn match_in_parts(
    img_a: &GreyImage,
    a: &[Corner],
    img_b: &GreyImage,
    b: &[Corner],
    cfg: &NccConfig,
    per_thread: usize,
) -> Result<Vec<Match>, FeatureError> {
    cfg.validate()?;
    check_mask(img_a, None)?;
    check_mask(img_b, None)?;
    if a.is_empty() || b.is_empty() {
        return Ok(Vec::new());
    }
    let stride = cfg.stride() as usize;
    let pa: Vec<[f32; 2]> = a.iter().map(sanitize).collect();
    let pb: Vec<[f32; 2]> = b.iter().map(sanitize).collect();
    // Windows with holes keep their raw samples; full windows that meet
    // one are re-sampled raw (the shader keeps every window's raw samples).
    let raw_full = |img: &GreyImage, p: [f32; 2]| -> Vec<Option<f32>> {
        let win = cfg.patch;
        let half = (win / 2) as f32;
        (0..win * win)
            .map(|k| {
                img.bilinear(
                    p[0] + (k % win) as f32 - half,
                    p[1] + (k / win) as f32 - half,
                )
            })
            .collect()
    };
    let (holes_a, holes_b) = (pinholes(img_a), pinholes(img_b));
    // The windows and the rows of the score matrix split over the cores:
    // each value is the one-pass value, whatever the split.
    let windows = |img: &GreyImage, holes: &[bool], p: &[[f32; 2]]| {
        crate::par::flat_map_split(p, per_thread, |part| {
            part.iter()
                .map(|p| vectorize(img, holes, *p, cfg, stride))
                .collect()
        })
    };
    let da: Vec<Option<Window>> = windows(img_a, &holes_a, &pa);
    let db: Vec<Option<Window>> = windows(img_b, &holes_b, &pb);
    let radius2 = cfg.search_radius.map(|r| r * r);
    let none = Best {
        index: NO_INDEX,
        score: NO_SCORE - 1.0,
    };
    // One part's rows `is`: their best columns, and each column's best
    // among them. Rows and columns are scanned in increasing index with a
    // strict `>`: ties go to the lower index, as in the GPU reduction.
    let scan = |is: &[usize]| {
        let mut rows = vec![none; is.len()];
        let mut cols = vec![none; b.len()];
        for (row, &i) in rows.iter_mut().zip(is) {
            let (ra, pi) = (&da[i], &pa[i]);
            for (j, (rb, pj)) in db.iter().zip(&pb).enumerate() {
                let (dx, dy) = (pj[0] - pi[0], pj[1] - pi[1]);
                let near = radius2.is_none_or(|r2| dx * dx + dy * dy <= r2);
                let s = match (ra, rb) {
                    (Some(Window::Full(ra)), Some(Window::Full(rb))) if near => {
                        let mut acc = 0f32;
                        for (x, y) in ra.iter().zip(rb) {
                            acc += x * y;
                        }
                        acc
                    }
                    (Some(wa), Some(wb)) if near => {
                        let ra = raw_of(wa).map_or_else(|| raw_full(img_a, *pi), <[_]>::to_vec);
                        let rb = raw_of(wb).map_or_else(|| raw_full(img_b, *pj), <[_]>::to_vec);
                        partial_score(&ra, &rb, cfg).unwrap_or(NO_SCORE)
                    }
                    _ => NO_SCORE,
                };
                if s > row.score {
                    *row = Best {
                        index: j as u32,
                        score: s,
                    };
                }
                if s > cols[j].score {
                    cols[j] = Best {
                        index: i as u32,
                        score: s,
                    };
                }
            }
        }
        vec![(rows, cols)]
    };
    let is: Vec<usize> = (0..a.len()).collect();
    let mut rows = Vec::with_capacity(a.len());
    let mut cols = vec![none; b.len()];
    // The parts in order of their rows: a later part's column wins only
    // with a higher score, as in one pass.
    for (part_rows, part_cols) in crate::par::flat_map_split(&is, per_thread, scan) {
        rows.extend(part_rows);
        for (c, p) in cols.iter_mut().zip(part_cols) {
            if p.score > c.score {
                *c = p;
            }
        }
    }
    Ok(mutual(&rows, &cols, cfg.min_score))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::patterns;

    /// Split over the cores, the matching is the one pass's, ties
    /// included: a checkerboard's corners all look alike, so most rows
    /// and columns have several equal best scores.
    #[test]
    fn parts_give_the_one_pass_matches_ties_included() {
        let (img, xs) = patterns::checkerboard(200, 160, [4.0, 4.0], 8.0, 0.0, 23, 19);
        let corners = |dx: f32| -> Vec<Corner> {
            xs.iter()
                .map(|p| Corner {
                    x: p[0] + dx,
                    y: p[1],
                    score: 1.0,
                })
                .collect()
        };
        let (a, b) = (corners(0.0), corners(0.25));
        assert!(a.len() > 300);
        for radius in [None, Some(20.0)] {
            let cfg = NccConfig {
                search_radius: radius,
                ..NccConfig::default()
            };
            let one = match_in_parts(&img, &a, &img, &b, &cfg, usize::MAX).unwrap();
            let split = match_in_parts(&img, &a, &img, &b, &cfg, 1).unwrap();
            assert_eq!(one, split, "radius {radius:?}");
            assert!(!one.is_empty());
        }
    }
}
