//! Matching a frame's descriptors against one keyframe's ([`super`]): the
//! score of a pair is the dot product of their descriptors (their NCC);
//! a keyframe corner described at several scales scores its best scale.
//! A pair is kept when each is the other's best (mutual), the score is
//! high enough, and the frame descriptor's best corner is clearly better
//! than its second best (the ratio test, on the descriptors' distances
//! `sqrt(2 - 2 score)`): repeated texture gives no match rather than a
//! wrong one.

use super::features::Descriptor;

/// How matches are kept.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchConfig {
    /// Lowest score (NCC) of a match.
    pub min_score: f32,
    /// Largest ratio of the best to the second best distance.
    pub ratio: f32,
}

impl Default for MatchConfig {
    fn default() -> Self {
        Self {
            min_score: 0.6,
            ratio: 0.85,
        }
    }
}

/// A kept match: the frame descriptor's index, the keyframe corner, the
/// score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DescMatch {
    /// Index into the frame's descriptors.
    pub frame: usize,
    /// The keyframe corner (owner of the keyframe descriptor).
    pub corner: usize,
    /// The score (NCC).
    pub score: f32,
}

/// A row's best corner and score, its second best (another corner's)
/// score.
#[derive(Debug, Clone, Copy)]
struct RowBest {
    corner: usize,
    best: f32,
    second: f32,
}

fn dot(a: &Descriptor, b: &Descriptor) -> f32 {
    // Eight accumulators: the compiler vectorises the sum.
    let mut acc = [0.0f32; 8];
    for (ca, cb) in a.chunks_exact(8).zip(b.chunks_exact(8)) {
        for k in 0..8 {
            acc[k] += ca[k] * cb[k];
        }
    }
    acc.iter().sum()
}

/// The matches of `frame` descriptors with the keyframe's (`kf`, each with
/// the corner it describes, `owners`, one corner's descriptors adjacent),
/// over `corners` keyframe corners.
pub fn match_descriptors(
    frame: &[Descriptor],
    kf: &[Descriptor],
    owners: &[usize],
    corners: usize,
    cfg: &MatchConfig,
) -> Vec<DescMatch> {
    if frame.is_empty() || kf.is_empty() || kf.len() != owners.len() {
        return Vec::new();
    }
    let rows: Vec<usize> = (0..frame.len()).collect();
    // Per part of the rows: each row's best, and each corner's best row
    // within the part.
    let parts = crate::par::flat_map_chunks(&rows, 128, |part| {
        let mut col = vec![(f32::NEG_INFINITY, usize::MAX); corners];
        let mut best = Vec::with_capacity(part.len());
        for &r in part {
            let mut rb = RowBest {
                corner: usize::MAX,
                best: f32::NEG_INFINITY,
                second: f32::NEG_INFINITY,
            };
            // The best over the current corner's scales.
            let (mut cur, mut cur_score) = (usize::MAX, f32::NEG_INFINITY);
            let mut close = |c: usize, s: f32, rb: &mut RowBest| {
                if c == usize::MAX {
                    return;
                }
                if s > col[c].0 {
                    col[c] = (s, r);
                }
                if s > rb.best {
                    rb.second = rb.best;
                    rb.best = s;
                    rb.corner = c;
                } else if s > rb.second {
                    rb.second = s;
                }
            };
            for (d, &o) in kf.iter().zip(owners) {
                if o != cur {
                    close(cur, cur_score, &mut rb);
                    (cur, cur_score) = (o, f32::NEG_INFINITY);
                }
                cur_score = cur_score.max(dot(&frame[r], d));
            }
            close(cur, cur_score, &mut rb);
            best.push(rb);
        }
        vec![(best, col)]
    });
    let mut rows_best = Vec::with_capacity(frame.len());
    let mut col = vec![(f32::NEG_INFINITY, usize::MAX); corners];
    for (b, c) in parts {
        rows_best.extend(b);
        for (m, v) in col.iter_mut().zip(c) {
            if v.0 > m.0 {
                *m = v;
            }
        }
    }
    let dist = |s: f32| (2.0 - 2.0 * s).max(0.0).sqrt();
    rows_best
        .iter()
        .enumerate()
        .filter(|(_, b)| b.corner != usize::MAX && b.best >= cfg.min_score)
        .filter(|(_, b)| dist(b.best) <= cfg.ratio * dist(b.second))
        .filter(|(r, b)| col[b.corner].1 == *r)
        .map(|(r, b)| DescMatch {
            frame: r,
            corner: b.corner,
            score: b.best,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::features::{DIM, DescribeConfig, describe_all, smoothed};
    use super::*;
    use crate::features::GreyImage;
    use crate::features::patterns::smooth_noise;
    use crate::rng::Rng;

    /// Random zero-mean unit-norm descriptors.
    fn random(rng: &mut Rng, n: usize) -> Vec<Descriptor> {
        (0..n)
            .map(|_| {
                let mut d = [0.0f32; DIM];
                for v in &mut d {
                    *v = rng.uniform(-1.0, 1.0) as f32;
                }
                normalised(d)
            })
            .collect()
    }

    /// `d` made zero-mean and unit-norm, as descriptors are.
    fn normalised(d: Descriptor) -> Descriptor {
        let m = d.iter().sum::<f32>() / DIM as f32;
        let n = d.iter().map(|v| (v - m) * (v - m)).sum::<f32>().sqrt();
        d.map(|v| (v - m) / n)
    }

    #[test]
    fn mutual_best_and_the_ratio_test_keep_the_true_pairs_only() {
        let mut rng = Rng::new(5);
        let mut kf = random(&mut rng, 300);
        // Corner 200 repeats corner 50 (repeated texture): neither may
        // match, whatever the frame.
        kf[200] = kf[50];
        kf[200][0] += 0.01;
        kf[200] = normalised(kf[200]);
        // The frame: noisy copies of the first 100, in reverse, then 400
        // unrelated descriptors, then an exact copy of corner 7 (which
        // takes corner 7 from its noisy copy: mutual best).
        let mut frame: Vec<Descriptor> = (0..100)
            .rev()
            .map(|i| {
                let mut d = kf[i];
                for v in &mut d {
                    *v += rng.uniform(-0.03, 0.03) as f32;
                }
                normalised(d)
            })
            .collect();
        frame.extend(random(&mut rng, 400));
        frame.push(kf[7]);
        let owners: Vec<usize> = (0..300).collect();
        let m = match_descriptors(&frame, &kf, &owners, 300, &MatchConfig::default());
        assert!(m.len() >= 95, "{} matches", m.len());
        for x in &m {
            assert!(x.frame < 100 || x.frame == 500, "{x:?}");
            if x.frame < 100 {
                assert_eq!(x.corner, 99 - x.frame);
            }
        }
        assert!(!m.iter().any(|x| x.frame == 92));
        assert!(m.iter().any(|x| x.frame == 500 && x.corner == 7));
        assert!(!m.iter().any(|x| x.corner == 50 || x.corner == 200));
    }

    /// `img` shifted by (dx, dy) and turned by `angle` about its centre.
    fn moved(img: &GreyImage, dx: f32, dy: f32, angle: f32) -> GreyImage {
        let (cx, cy) = (img.width as f32 / 2.0, img.height as f32 / 2.0);
        let (s, c) = angle.sin_cos();
        GreyImage::from_fn(img.width, img.height, |x, y| {
            let (u, v) = (x as f32 - dx - cx, y as f32 - dy - cy);
            img.bilinear(cx + c * u + s * v, cy - s * u + c * v)
                .unwrap_or(f32::NAN)
        })
    }

    #[test]
    fn matching_finds_a_known_shift_and_rotation_of_a_textured_image() {
        let img = smooth_noise(200, 200, 2.5, 3);
        let (dx, dy, angle) = (9.0f32, -6.0f32, 35f32.to_radians());
        let other = moved(&img, dx, dy, angle);
        let cfg = DescribeConfig::default();
        // Corners: a grid of points (their own detection is Harris's job).
        let pts: Vec<[f32; 2]> = (0..12)
            .flat_map(|j| (0..12).map(move |i| [40.0 + 10.0 * i as f32, 40.0 + 10.0 * j as f32]))
            .collect();
        let (cx, cy) = (100.0f32, 100.0f32);
        let (s, c) = angle.sin_cos();
        let map = |p: [f32; 2]| {
            let (u, v) = (p[0] - cx, p[1] - cy);
            [cx + c * u - s * v + dx, cy + s * u + c * v + dy]
        };
        let moved_pts: Vec<[f32; 2]> = pts.iter().map(|p| map(*p)).collect();
        let a = smoothed(&img, cfg.sigma_px);
        let b = smoothed(&other, cfg.sigma_px);
        let da = describe_all(&a, &pts, 1.0, &cfg);
        let db = describe_all(&b, &moved_pts, 1.0, &cfg);
        let kf: Vec<Descriptor> = da.iter().map(|x| x.1).collect();
        let owners: Vec<usize> = da.iter().map(|x| x.0).collect();
        let fr: Vec<Descriptor> = db.iter().map(|x| x.1).collect();
        let m = match_descriptors(&fr, &kf, &owners, pts.len(), &MatchConfig::default());
        let right = m.iter().filter(|x| db[x.frame].0 == x.corner).count();
        assert!(right >= pts.len() / 2, "{right} of {} right", m.len());
        assert!(right * 20 >= m.len() * 19, "{right} of {} right", m.len());
    }
}
