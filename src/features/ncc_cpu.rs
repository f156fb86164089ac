//! CPU reference of NCC matching: `shaders/ncc.wgsl` operation for
//! operation in `f32` (same sampling, same summation order).

use super::FeatureError;
use super::gpu_data::{Best, NO_INDEX, NO_SCORE};
use super::harris::Corner;
use super::image::{GreyImage, check_mask};
use super::ncc::{Match, NccConfig, mutual, sanitize};

/// The zero-mean unit-norm window of `p` (w² values, padded with zeros to
/// `stride`), or `None` if it leaves the image, touches an invalid pixel,
/// or is flat. The `vectorize` kernel.
fn vectorize(img: &GreyImage, p: [f32; 2], cfg: &NccConfig, stride: usize) -> Option<Vec<f32>> {
    let win = cfg.window;
    let half = (win / 2) as f32;
    let d = (win * win) as usize;
    let mut row = vec![0f32; stride];
    let mut sum = 0f32;
    for k in 0..d as u32 {
        let u = (k % win) as f32 - half;
        let v = (k / win) as f32 - half;
        let s = img.bilinear(p[0] + u, p[1] + v)?;
        row[k as usize] = s;
        sum += s;
    }
    let mean = sum / d as f32;
    let mut ss = 0f32;
    for v in &row[..d] {
        let c = v - mean;
        ss += c * c;
    }
    // Flat windows correlate noise with noise; NaN fails too.
    let textured = (ss / d as f32).sqrt() >= cfg.min_std;
    if !textured {
        return None;
    }
    let inv = 1.0 / ss.sqrt();
    for v in &mut row[..d] {
        *v = (*v - mean) * inv;
    }
    Some(row)
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
    cfg.validate()?;
    check_mask(img_a, None)?;
    check_mask(img_b, None)?;
    if a.is_empty() || b.is_empty() {
        return Ok(Vec::new());
    }
    let stride = cfg.stride() as usize;
    let pa: Vec<[f32; 2]> = a.iter().map(sanitize).collect();
    let pb: Vec<[f32; 2]> = b.iter().map(sanitize).collect();
    let da: Vec<Option<Vec<f32>>> = pa
        .iter()
        .map(|p| vectorize(img_a, *p, cfg, stride))
        .collect();
    let db: Vec<Option<Vec<f32>>> = pb
        .iter()
        .map(|p| vectorize(img_b, *p, cfg, stride))
        .collect();
    let radius2 = cfg.search_radius.map(|r| r * r);
    let none = Best {
        index: NO_INDEX,
        score: NO_SCORE - 1.0,
    };
    let mut rows = vec![none; a.len()];
    let mut cols = vec![none; b.len()];
    // Rows and columns scanned in increasing index with a strict `>`: ties
    // go to the lower index, as in the GPU reduction.
    for (i, (ra, pi)) in da.iter().zip(&pa).enumerate() {
        for (j, (rb, pj)) in db.iter().zip(&pb).enumerate() {
            let s = match (ra, rb) {
                (Some(ra), Some(rb)) => {
                    let (dx, dy) = (pj[0] - pi[0], pj[1] - pi[1]);
                    if radius2.is_some_and(|r2| dx * dx + dy * dy > r2) {
                        NO_SCORE
                    } else {
                        let mut acc = 0f32;
                        for (x, y) in ra.iter().zip(rb) {
                            acc += x * y;
                        }
                        acc
                    }
                }
                _ => NO_SCORE,
            };
            if s > rows[i].score {
                rows[i] = Best {
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
    Ok(mutual(&rows, &cols, cfg.min_score))
}
