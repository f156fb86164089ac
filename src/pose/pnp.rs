//! A pose from 2-D/3-D correspondences (perspective-n-point), with or without
//! outliers: the first pose of `splattrack init` and the detection of an
//! object by matched points.
//!
//! How it works: candidate poses come from minimal three-point solutions
//! ([`super::p3p`], Grunert's quartic), which covers planar and non-planar
//! point sets alike. [`solve_pnp`] tries many triples, keeps the candidates
//! that best explain all points and polishes them by Levenberg-Marquardt on
//! the reprojection error; [`solve_pnp_ransac`] draws four points at a time
//! (three to solve, the fourth to pick among the up to four solutions),
//! counts the points each pose explains within a pixel threshold, stops when
//! the chance of having missed an all-inlier sample is small, then polishes
//! on the inliers and re-collects them. Pixels are in the image as given:
//! with a distorting camera they are undistorted first, and every residual is
//! measured in the ideal pinhole image.

use super::p3p::p3p;
use crate::geometry::{Intrinsics, Pose};
use crate::rng::Rng;
use nalgebra::{Matrix6, Vector2, Vector3, Vector6};

/// Settings of [`solve_pnp_ransac`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PnpRansacOptions {
    /// The most minimal samples drawn (fewer when the inlier ratio found so
    /// far makes `confidence` reachable sooner).
    pub iterations: usize,
    /// A point is an inlier when it reprojects within this many pixels.
    pub threshold_px: f64,
    /// Wanted probability of having drawn at least one all-inlier sample.
    pub confidence: f64,
    /// Fewer inliers than this (at least 4) is no consensus.
    pub min_inliers: usize,
    /// Seed of the sampling, so runs are reproducible.
    pub seed: u64,
}

impl Default for PnpRansacOptions {
    fn default() -> Self {
        Self {
            iterations: 2000,
            threshold_px: 4.0,
            confidence: 0.999,
            min_inliers: 6,
            seed: 0,
        }
    }
}

/// A pose solved from correspondences.
#[derive(Debug, Clone, PartialEq)]
pub struct PnpSolution {
    /// Object-to-camera pose.
    pub pose: Pose,
    /// Indices of the correspondences the pose was fitted to (all of them
    /// for [`solve_pnp`]), ascending.
    pub inliers: Vec<usize>,
    /// RMS reprojection error over the inliers, pixels.
    pub rms_px: f64,
}

/// Why no pose was solved.
#[derive(thiserror::Error, Debug, Clone, PartialEq)]
pub enum PnpError {
    /// The point and pixel lists differ in length.
    #[error("{points} model points but {pixels} pixels")]
    LengthMismatch {
        /// Number of model points.
        points: usize,
        /// Number of pixels.
        pixels: usize,
    },
    /// Fewer correspondences than the solver needs.
    #[error("{got} correspondences; a pose needs at least {need}")]
    TooFewPoints {
        /// Correspondences given.
        got: usize,
        /// Correspondences needed.
        need: usize,
    },
    /// A coordinate is NaN or infinite.
    #[error("correspondence {index} has a non-finite coordinate")]
    NonFinite {
        /// Index of the first bad correspondence.
        index: usize,
    },
    /// The camera is not valid.
    #[error("camera: {0}")]
    Camera(String),
    /// The correspondences do not fix a pose: coincident or collinear model
    /// points, or pixels (the camera in the plane of the points).
    #[error("{0}: they do not fix a pose")]
    Degenerate(&'static str),
    /// No pose explains the correspondences (e.g. pixels that no rigid
    /// motion of the points can produce).
    #[error("no pose puts the model points on their pixels")]
    NoSolution,
    /// RANSAC found no pose that enough correspondences agree on.
    #[error(
        "no consensus: the best pose explains {best} of {total} correspondences within {threshold_px} px, {need} needed"
    )]
    NoConsensus {
        /// Inliers of the best pose found.
        best: usize,
        /// Correspondences given.
        total: usize,
        /// Inliers needed.
        need: usize,
        /// The inlier threshold, pixels.
        threshold_px: f64,
    },
}

/// Cost of a point behind the camera (squared pixels): far above any
/// reprojection error, so such poses lose every comparison.
const BEHIND: f64 = 1e12;

/// The inputs, checked and reduced to ideal pixels and unit bearings.
struct Problem<'a> {
    points: &'a [Vector3<f64>],
    pixels: Vec<Vector2<f64>>,
    bearings: Vec<Vector3<f64>>,
    cam: Intrinsics,
}

impl<'a> Problem<'a> {
    fn new(
        points: &'a [Vector3<f64>],
        pixels: &[Vector2<f64>],
        cam: &Intrinsics,
    ) -> Result<Self, PnpError> {
        if points.len() != pixels.len() {
            return Err(PnpError::LengthMismatch {
                points: points.len(),
                pixels: pixels.len(),
            });
        }
        if points.len() < 4 {
            return Err(PnpError::TooFewPoints {
                got: points.len(),
                need: 4,
            });
        }
        cam.validate().map_err(PnpError::Camera)?;
        if let Some(index) = points.iter().zip(pixels).position(|(p, q)| {
            !(p.iter().all(|v| v.is_finite()) && q.iter().all(|v| v.is_finite()))
        }) {
            return Err(PnpError::NonFinite { index });
        }
        match spread(points) {
            Spread::Coincident => return Err(PnpError::Degenerate("coincident model points")),
            Spread::Collinear => return Err(PnpError::Degenerate("collinear model points")),
            Spread::Fine => {}
        }
        let flat: Vec<Vector3<f64>> = pixels.iter().map(|q| Vector3::new(q.x, q.y, 0.0)).collect();
        match spread(&flat) {
            Spread::Coincident => return Err(PnpError::Degenerate("coincident pixels")),
            Spread::Collinear => return Err(PnpError::Degenerate("collinear pixels")),
            Spread::Fine => {}
        }
        let ideal = cam.undistorted();
        let pixels: Vec<Vector2<f64>> = if cam.has_distortion() {
            pixels.iter().map(|q| cam.undistort_pixel(*q)).collect()
        } else {
            pixels.to_vec()
        };
        let bearings = pixels
            .iter()
            .map(|q| {
                Vector3::new(
                    (q.x - ideal.cx) / ideal.fx,
                    (q.y - ideal.cy) / ideal.fy,
                    1.0,
                )
                .normalize()
            })
            .collect();
        Ok(Self {
            points,
            pixels,
            bearings,
            cam: ideal,
        })
    }

    /// Squared reprojection error of point `i` ([`BEHIND`] behind the camera).
    fn error2(&self, pose: &Pose, i: usize) -> f64 {
        match self.cam.project(&pose.transform_point(&self.points[i])) {
            Some(q) => (q - self.pixels[i]).norm_squared(),
            None => BEHIND,
        }
    }

    fn cost(&self, pose: &Pose, idx: &[usize]) -> f64 {
        idx.iter().map(|&i| self.error2(pose, i)).sum()
    }

    /// The P3P solutions of the triple `t`.
    fn minimal(&self, t: [usize; 3]) -> Vec<Pose> {
        p3p(&t.map(|i| self.points[i]), &t.map(|i| self.bearings[i]))
    }

    /// Levenberg-Marquardt on the reprojection error of `idx`, from `pose`,
    /// with left-multiplied twist updates (the crate's convention).
    fn refine(&self, pose: &Pose, idx: &[usize]) -> Pose {
        let mut pose = *pose;
        let mut cost = self.cost(&pose, idx);
        let mut lambda = 1e-3;
        for _ in 0..100 {
            let mut h = Matrix6::zeros();
            let mut g = Vector6::zeros();
            for &i in idx {
                let xc = pose.transform_point(&self.points[i]);
                let Some(q) = self.cam.project(&xc) else {
                    continue;
                };
                let j = self.cam.motion_predictors(&xc);
                let r = q - self.pixels[i];
                h += j.transpose() * j;
                g += j.transpose() * r;
            }
            let mut improved = false;
            while lambda < 1e12 {
                let mut a = h;
                for k in 0..6 {
                    a[(k, k)] += lambda * h[(k, k)].max(1e-12);
                }
                let Some(step) = a.cholesky().map(|c| c.solve(&(-g))) else {
                    lambda *= 10.0;
                    continue;
                };
                let next = pose.apply_twist(&step);
                let next_cost = self.cost(&next, idx);
                if next_cost < cost {
                    let gain = cost - next_cost;
                    pose = next.orthonormalized();
                    cost = self.cost(&pose, idx);
                    lambda = (lambda * 0.1).max(1e-9);
                    improved = gain > 1e-14 * (1.0 + cost) && step.amax() > 1e-15;
                    break;
                }
                lambda *= 10.0;
            }
            if !improved {
                break;
            }
        }
        pose
    }

    fn inliers(&self, pose: &Pose, threshold_px: f64) -> Vec<usize> {
        let t2 = threshold_px * threshold_px;
        (0..self.points.len())
            .filter(|&i| self.error2(pose, i) <= t2)
            .collect()
    }

    fn solution(&self, pose: Pose, inliers: Vec<usize>) -> PnpSolution {
        let rms_px = (self.cost(&pose, &inliers) / inliers.len().max(1) as f64).sqrt();
        PnpSolution {
            pose,
            inliers,
            rms_px,
        }
    }
}

/// How a point set spreads.
enum Spread {
    Coincident,
    Collinear,
    Fine,
}

/// Coincident and collinear point sets: the spread along the second
/// principal axis must be a fair fraction (1e-4) of the first.
fn spread(points: &[Vector3<f64>]) -> Spread {
    let n = points.len() as f64;
    let c = points.iter().sum::<Vector3<f64>>() / n;
    let cov = points
        .iter()
        .map(|p| (p - c) * (p - c).transpose())
        .sum::<nalgebra::Matrix3<f64>>();
    let mut ev: Vec<f64> = cov.symmetric_eigenvalues().iter().copied().collect();
    ev.sort_by(|a, b| b.total_cmp(a));
    if ev[0].is_nan() || ev[0] <= 0.0 {
        Spread::Coincident
    } else if ev[1] < 1e-8 * ev[0] {
        Spread::Collinear
    } else {
        Spread::Fine
    }
}

/// Squared area of the triangle of three model points, relative to its
/// longest side to the fourth power (0 for collinear points).
fn triangle_quality(p: &[Vector3<f64>], t: [usize; 3]) -> f64 {
    let (a, b, c) = (p[t[0]], p[t[1]], p[t[2]]);
    let area2 = (b - a).cross(&(c - a)).norm_squared();
    let side2 = (b - a)
        .norm_squared()
        .max((c - a).norm_squared())
        .max((c - b).norm_squared());
    if side2 > 0.0 {
        area2 / (side2 * side2)
    } else {
        0.0
    }
}

/// The pose that puts every model point `points[i]` on its pixel
/// `pixels[i]`, in the least-squares sense: at least 4 correspondences,
/// planar or not, none an outlier. Candidates from three-point solutions of
/// many triples are polished by Levenberg-Marquardt on all points; the one
/// with the least reprojection error wins.
pub fn solve_pnp(
    points: &[Vector3<f64>],
    pixels: &[Vector2<f64>],
    cam: &Intrinsics,
) -> Result<PnpSolution, PnpError> {
    let pb = Problem::new(points, pixels, cam)?;
    let n = points.len();
    let all: Vec<usize> = (0..n).collect();
    // Every triple for small sets; a fixed pseudo-random choice otherwise.
    const MAX_TRIPLES: usize = 120;
    let mut triples = Vec::new();
    if n * (n - 1) * (n - 2) / 6 <= MAX_TRIPLES {
        for i in 0..n {
            for j in i + 1..n {
                for k in j + 1..n {
                    triples.push([i, j, k]);
                }
            }
        }
    } else {
        let mut rng = Rng::new(0x9e3779b9);
        while triples.len() < MAX_TRIPLES {
            let t = [0, 1, 2].map(|_| rng.below(n as u64) as usize);
            if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                triples.push(t);
            }
        }
    }
    let mut candidates: Vec<(f64, Pose)> = Vec::new();
    for t in triples {
        if triangle_quality(points, t) < 1e-6 {
            continue;
        }
        for pose in pb.minimal(t) {
            candidates.push((pb.cost(&pose, &all), pose));
        }
    }
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best: Option<(f64, Pose)> = None;
    let mut tried: Vec<Pose> = Vec::new();
    for (_, pose) in candidates {
        if tried.len() >= 6 {
            break;
        }
        // Skip near-duplicates of candidates already polished.
        if tried
            .iter()
            .any(|p| (p.rotation - pose.rotation).amax() < 1e-3)
        {
            continue;
        }
        tried.push(pose);
        let refined = pb.refine(&pose, &all);
        let cost = pb.cost(&refined, &all);
        if best.as_ref().is_none_or(|b| cost < b.0) {
            best = Some((cost, refined));
        }
    }
    match best {
        Some((cost, pose)) if cost < BEHIND => Ok(pb.solution(pose, all)),
        _ => Err(PnpError::NoSolution),
    }
}

/// The pose that most correspondences agree on, when some are wrong
/// (RANSAC on minimal four-point samples, then Levenberg-Marquardt on the
/// inliers, re-collected until they settle). The sample count adapts to the
/// inlier ratio found so far, up to `opts.iterations`.
pub fn solve_pnp_ransac(
    points: &[Vector3<f64>],
    pixels: &[Vector2<f64>],
    cam: &Intrinsics,
    opts: &PnpRansacOptions,
) -> Result<PnpSolution, PnpError> {
    let pb = Problem::new(points, pixels, cam)?;
    let n = points.len();
    let need = opts.min_inliers.max(4);
    let thr = if opts.threshold_px.is_finite() && opts.threshold_px > 0.0 {
        opts.threshold_px
    } else {
        PnpRansacOptions::default().threshold_px
    };
    let thr2 = thr * thr;
    let confidence = opts.confidence.clamp(0.0, 1.0 - 1e-12);
    let mut rng = Rng::new(opts.seed);
    let mut best: Option<(usize, f64, Pose)> = None;
    let mut needed = opts.iterations.max(1);
    let mut drawn = 0;
    while drawn < needed {
        drawn += 1;
        let mut s = [0usize; 4];
        let mut k = 0;
        while k < 4 {
            let c = rng.below(n as u64) as usize;
            if !s[..k].contains(&c) {
                s[k] = c;
                k += 1;
            }
        }
        if triangle_quality(points, [s[0], s[1], s[2]]) < 1e-8 {
            continue;
        }
        let Some((e4, pose)) = pb
            .minimal([s[0], s[1], s[2]])
            .into_iter()
            .map(|p| (pb.error2(&p, s[3]), p))
            .min_by(|a, b| a.0.total_cmp(&b.0))
        else {
            continue;
        };
        if e4 > thr2 {
            continue;
        }
        // MSAC score: inliers count their error, outliers the threshold.
        let (mut count, mut score) = (0, 0.0);
        for i in 0..n {
            let e = pb.error2(&pose, i);
            if e <= thr2 {
                count += 1;
                score += e;
            } else {
                score += thr2;
            }
        }
        if best
            .as_ref()
            .is_none_or(|b| count > b.0 || (count == b.0 && score < b.1))
        {
            best = Some((count, score, pose));
            let w = count as f64 / n as f64;
            let miss = 1.0 - w.powi(4);
            if miss <= 0.0 {
                needed = drawn;
            } else {
                let k = ((1.0 - confidence).ln() / miss.ln()).ceil();
                if k.is_finite() && k >= 0.0 {
                    needed = needed.min(k as usize);
                }
            }
        }
    }
    let Some((count, _, mut pose)) = best else {
        return Err(PnpError::NoConsensus {
            best: 0,
            total: n,
            need,
            threshold_px: thr,
        });
    };
    if count < need {
        return Err(PnpError::NoConsensus {
            best: count,
            total: n,
            need,
            threshold_px: thr,
        });
    }
    let mut inliers = pb.inliers(&pose, thr);
    for _ in 0..5 {
        pose = pb.refine(&pose, &inliers);
        let next = pb.inliers(&pose, thr);
        if next == inliers {
            break;
        }
        if next.len() < 4 {
            break;
        }
        inliers = next;
    }
    if inliers.len() < need {
        return Err(PnpError::NoConsensus {
            best: inliers.len(),
            total: n,
            need,
            threshold_px: thr,
        });
    }
    Ok(pb.solution(pose, inliers))
}

/// The reprojection error (pixels, in the ideal pinhole image as
/// [`solve_pnp`] measures it) of each correspondence at `pose`; infinite for
/// a point behind the camera.
pub fn reprojection_errors(
    pose: &Pose,
    points: &[Vector3<f64>],
    pixels: &[Vector2<f64>],
    cam: &Intrinsics,
) -> Vec<f64> {
    let ideal = cam.undistorted();
    points
        .iter()
        .zip(pixels)
        .map(|(p, q)| {
            let q = if cam.has_distortion() {
                cam.undistort_pixel(*q)
            } else {
                *q
            };
            let xc = pose.transform_point(p);
            match ideal.project(&xc) {
                Some(r) => (r - q).norm(),
                None => f64::INFINITY,
            }
        })
        .collect()
}

#[cfg(test)]
#[path = "pnp_tests.rs"]
mod tests;
