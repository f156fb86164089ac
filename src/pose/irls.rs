//! IRLS on the motion-predictor model (see the module [`crate::pose`]).

use nalgebra::{Matrix2x6, Matrix6, SymmetricEigen, Vector2, Vector6};

/// One match seen through the motion predictors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// `L^i`: columns l_1..l_6 (tx, ty, tz, rx, ry, rz) at the match's
    /// position in the reference image, pixels per unit of twist.
    pub predictors: Matrix2x6<f64>,
    /// `d^i = m_t^i - m_{t-1}^i`, pixels.
    pub displacement: Vector2<f64>,
}

/// The robust loss `rho`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Loss {
    /// Plain least squares (no robustness; for comparison).
    LeastSquares,
    /// Huber: quadratic within `k` scales, linear beyond (k = 1.345 gives
    /// 95% efficiency on Gaussian noise).
    Huber {
        /// The threshold, in scales.
        k: f64,
    },
    /// Tukey's biweight: zero weight beyond `c` scales (c = 4.685 gives 95%
    /// efficiency on Gaussian noise).
    Tukey {
        /// The cutoff, in scales.
        c: f64,
    },
}

impl Loss {
    /// Huber with the usual k = 1.345.
    pub const HUBER: Loss = Loss::Huber { k: 1.345 };
    /// Tukey with the usual c = 4.685.
    pub const TUKEY: Loss = Loss::Tukey { c: 4.685 };

    /// IRLS weight of a residual `r` for scale `s`.
    pub fn weight(&self, r: f64, s: f64) -> f64 {
        match *self {
            Loss::LeastSquares => 1.0,
            Loss::Huber { k } => {
                let t = k * s;
                if r <= t { 1.0 } else { t / r }
            }
            Loss::Tukey { c } => {
                let u = r / (c * s);
                if u >= 1.0 {
                    0.0
                } else {
                    let v = 1.0 - u * u;
                    v * v
                }
            }
        }
    }
}

/// Settings of [`irls`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IrlsConfig {
    /// The final loss; Huber iterations always come first (see module docs).
    pub loss: Loss,
    /// Huber iterations before switching to `loss`.
    pub warmup_iterations: usize,
    /// Most IRLS iterations in all (warm-up included).
    pub max_iterations: usize,
    /// Stop when the update of the twist changes less than this (max norm).
    pub tolerance: f64,
    /// Fewer matches than this are refused outright.
    pub min_matches: usize,
    /// Fewer inliers than this after the last iteration: refused.
    pub min_inliers: usize,
    /// Floor of the MAD scale in pixels: with near-perfect matches the
    /// scale would collapse to 0 and every match would become an outlier.
    pub min_scale_px: f64,
    /// Matches within this many scales of the fit count as inliers (Tukey's
    /// cutoff).
    pub inlier_scales: f64,
    /// Largest accepted condition number of the unit-diagonal normal matrix.
    pub max_condition: f64,
}

impl Default for IrlsConfig {
    fn default() -> Self {
        Self {
            loss: Loss::TUKEY,
            warmup_iterations: 3,
            max_iterations: 30,
            tolerance: 1e-10,
            min_matches: 6,
            min_inliers: 6,
            min_scale_px: 0.25,
            inlier_scales: 4.685,
            max_condition: 1e8,
        }
    }
}

/// A pose update and how well it is supported.
#[derive(Debug, Clone, PartialEq)]
pub struct IrlsResult {
    /// The twist `a` = (v, w): apply as `exp(a^) E`.
    pub twist: Vector6<f64>,
    /// Final IRLS weight of each match (0 for rejected ones under Tukey).
    pub weights: Vec<f64>,
    /// Which matches are within `inlier_scales` scales of the fit.
    pub inliers: Vec<bool>,
    /// How many `inliers` are true.
    pub inlier_count: usize,
    /// RMS residual of the inliers, pixels.
    pub residual_rms_px: f64,
    /// Robust scale of the residuals, pixels.
    pub scale_px: f64,
    /// IRLS iterations run.
    pub iterations: usize,
    /// Condition number of the last (unit-diagonal) normal matrix.
    pub condition: f64,
    /// 6x6 covariance of the twist (inverse normal matrix times the
    /// residual variance): a tracker's measure of confidence.
    pub covariance: Matrix6<f64>,
}

/// Why an update was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error, serde::Serialize, serde::Deserialize)]
pub enum SolveError {
    /// Fewer matches than [`IrlsConfig::min_matches`].
    #[error("too few matches for a pose update: {got} (need at least {need})")]
    TooFewMatches {
        /// Matches given.
        got: usize,
        /// The minimum.
        need: usize,
    },
    /// Fewer inliers than [`IrlsConfig::min_inliers`] after the last
    /// iteration.
    #[error("too few inliers: {got} of {total} matches (need at least {need})")]
    TooFewInliers {
        /// Inliers found.
        got: usize,
        /// Matches given.
        total: usize,
        /// The minimum.
        need: usize,
    },
    /// The normal matrix is rank-deficient or too badly conditioned: the
    /// matches do not constrain every degree of freedom.
    #[error("degenerate configuration: {reason}")]
    Degenerate {
        /// Which motions are unconstrained, or the condition number.
        reason: String,
    },
    /// An observation holds a NaN or an infinity.
    #[error("non-finite input: match {index} has a NaN or infinite value")]
    NonFinite {
        /// The observation's index.
        index: usize,
    },
}

const GENERATOR_NAMES: [&str; 6] = ["tx", "ty", "tz", "rx", "ry", "rz"];

/// Builds `L^T W L` and `L^T W d`.
fn normal_equations(obs: &[Observation], w: &[f64]) -> (Matrix6<f64>, Vector6<f64>) {
    let mut a = Matrix6::zeros();
    let mut b = Vector6::zeros();
    for (o, &wi) in obs.iter().zip(w) {
        if wi == 0.0 {
            continue;
        }
        let lt = o.predictors.transpose();
        a += lt * o.predictors * wi;
        b += lt * o.displacement * wi;
    }
    (a, b)
}

/// Solves `A x = b` after checking rank and conditioning; returns the
/// solution, the condition number and `A^{-1}`.
fn checked_solve(
    a: &Matrix6<f64>,
    b: &Vector6<f64>,
    max_condition: f64,
) -> Result<(Vector6<f64>, f64, Matrix6<f64>), SolveError> {
    let diag = a.diagonal();
    if let Some(j) = (0..6).find(|&j| diag[j].is_nan() || diag[j] <= 0.0) {
        return Err(SolveError::Degenerate {
            reason: format!(
                "no match constrains {} (the weighted matches do not move under it)",
                GENERATOR_NAMES[j]
            ),
        });
    }
    let d = diag.map(|v| 1.0 / v.sqrt());
    let scaled = Matrix6::from_fn(|i, j| a[(i, j)] * d[i] * d[j]);
    let eig = SymmetricEigen::new(scaled);
    let (imin, lmin) = eig
        .eigenvalues
        .iter()
        .copied()
        .enumerate()
        .min_by(|x, y| x.1.total_cmp(&y.1))
        .unwrap_or((0, 0.0));
    let lmax = eig.eigenvalues.max();
    let condition = if lmin > 0.0 {
        lmax / lmin
    } else {
        f64::INFINITY
    };
    if condition.is_nan() || condition > max_condition {
        // Name the motion the matches cannot see: the eigenvector of the
        // smallest eigenvalue, in generator terms.
        let v = eig.eigenvectors.column(imin).component_mul(&d);
        let v = v / v.amax();
        let parts: Vec<String> = (0..6)
            .filter(|&j| v[j].abs() > 0.2)
            .map(|j| format!("{:+.2} {}", v[j], GENERATOR_NAMES[j]))
            .collect();
        return Err(SolveError::Degenerate {
            reason: format!(
                "the matches do not constrain the motion {} (condition number {condition:.1e} > {max_condition:.1e})",
                parts.join(" ")
            ),
        });
    }
    let inv_scaled = eig.eigenvectors
        * Matrix6::from_diagonal(&eig.eigenvalues.map(|l| 1.0 / l))
        * eig.eigenvectors.transpose();
    let inv = Matrix6::from_fn(|i, j| inv_scaled[(i, j)] * d[i] * d[j]);
    Ok((inv * b, condition, inv))
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    *m
}

fn residuals(obs: &[Observation], twist: &Vector6<f64>) -> Vec<f64> {
    obs.iter()
        .map(|o| (o.predictors * twist - o.displacement).norm())
        .collect()
}

/// Robust scale of 2-D residual norms: 1.4826 x their median, floored.
fn robust_scale(r: &[f64], floor: f64) -> f64 {
    let mut v = r.to_vec();
    (1.4826 * median(&mut v)).max(floor)
}

/// Estimates the twist that best explains the matches (module docs).
pub fn irls(obs: &[Observation], cfg: &IrlsConfig) -> Result<IrlsResult, SolveError> {
    irls_grouped(obs, &[], 0.0, cfg)
}

/// Per-row robust scales: row `i` is weighed and judged an inlier against
/// the MAD scale of the rows of its own group `groups[i]` (all rows in one
/// group when `groups` is empty). Modalities with different noise (texture
/// matches, contour distances) then share one solve without either
/// drowning the other.
fn group_scales(r: &[f64], groups: &[u8], floor: f64) -> Vec<f64> {
    if groups.is_empty() {
        return vec![robust_scale(r, floor); r.len()];
    }
    // Each group present is gathered once (in row order; the median does
    // not depend on it): a scan per group present, not per possible group.
    let mut present = [false; 256];
    for &g in groups {
        present[g as usize] = true;
    }
    let mut by_group = [f64::NAN; 256];
    let mut v = Vec::with_capacity(r.len());
    for g in (0..=255u8).filter(|&g| present[g as usize]) {
        v.clear();
        v.extend(
            r.iter()
                .zip(groups)
                .filter(|(_, gi)| **gi == g)
                .map(|(ri, _)| *ri),
        );
        by_group[g as usize] = (1.4826 * median(&mut v)).max(floor);
    }
    groups.iter().map(|&g| by_group[g as usize]).collect()
}

/// [`irls`] with each row's robust scale taken over its group only
/// (`groups[i]` for row `i`; empty: one group). A contour residual is one
/// row: give it as an observation whose second predictor row and
/// displacement component are zero. `damping` > 0 adds that fraction of
/// the normal matrix's diagonal to it (Levenberg-Marquardt): motions the
/// rows hardly constrain then stay near zero instead of fitting noise.
///
/// Panics when `groups` is neither empty nor one per observation (a
/// programming error).
pub fn irls_grouped(
    obs: &[Observation],
    groups: &[u8],
    damping: f64,
    cfg: &IrlsConfig,
) -> Result<IrlsResult, SolveError> {
    assert!(
        groups.is_empty() || groups.len() == obs.len(),
        "one group per observation"
    );
    if obs.len() < cfg.min_matches.max(3) {
        return Err(SolveError::TooFewMatches {
            got: obs.len(),
            need: cfg.min_matches.max(3),
        });
    }
    if let Some(index) = obs.iter().position(|o| {
        o.predictors.iter().any(|v| !v.is_finite()) || o.displacement.iter().any(|v| !v.is_finite())
    }) {
        return Err(SolveError::NonFinite { index });
    }
    let mut w = vec![1.0; obs.len()];
    let mut twist = Vector6::zeros();
    let mut condition = 0.0;
    let mut inv = Matrix6::zeros();
    let mut iterations = 0;
    // The first solve is plain least squares: the robust weights need a fit.
    for it in 0..cfg.max_iterations.max(1) {
        let (mut a, b) = normal_equations(obs, &w);
        if damping > 0.0 {
            let d = a.diagonal() * damping;
            a += Matrix6::from_diagonal(&d);
        }
        let (next, cond, ainv) = checked_solve(&a, &b, cfg.max_condition)?;
        condition = cond;
        inv = ainv;
        let step = (next - twist).amax();
        twist = next;
        iterations = it + 1;
        let r = residuals(obs, &twist);
        let s = group_scales(&r, groups, cfg.min_scale_px);
        let loss = if it < cfg.warmup_iterations {
            Loss::HUBER
        } else {
            cfg.loss
        };
        let new_w: Vec<f64> = r
            .iter()
            .zip(&s)
            .map(|(&ri, &si)| loss.weight(ri, si))
            .collect();
        let settled = it >= cfg.warmup_iterations && step < cfg.tolerance;
        w = new_w;
        if settled || matches!(cfg.loss, Loss::LeastSquares) {
            break;
        }
    }
    let r = residuals(obs, &twist);
    let scale = robust_scale(&r, cfg.min_scale_px);
    let scales = group_scales(&r, groups, cfg.min_scale_px);
    let inliers: Vec<bool> = r
        .iter()
        .zip(&scales)
        .map(|(&ri, &si)| ri <= cfg.inlier_scales * si)
        .collect();
    let inlier_count = inliers.iter().filter(|&&i| i).count();
    if inlier_count < cfg.min_inliers {
        return Err(SolveError::TooFewInliers {
            got: inlier_count,
            total: obs.len(),
            need: cfg.min_inliers,
        });
    }
    let sq: f64 = r
        .iter()
        .zip(&inliers)
        .filter(|(_, i)| **i)
        .map(|(ri, _)| ri * ri)
        .sum();
    let residual_rms_px = (sq / inlier_count as f64).sqrt();
    // 2 equations per match, 6 unknowns.
    let dof = (2 * inlier_count).saturating_sub(6).max(1) as f64;
    let covariance = inv * (sq / dof);
    Ok(IrlsResult {
        twist,
        weights: w,
        inliers,
        inlier_count,
        residual_rms_px,
        scale_px: scale,
        iterations,
        condition,
        covariance,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Intrinsics, Pose};
    use crate::rng::Rng;
    use nalgebra::Vector3;

    /// A frame-to-frame motion: a few mm and about a degree per axis.
    const TWIST: Vector6<f64> = Vector6::new(0.002, -0.001, 0.004, 0.01, -0.015, 0.02);

    fn cam() -> Intrinsics {
        Intrinsics::new(640, 480, 600.0, 600.0, 320.0, 240.0)
    }

    /// Matches of points on an object ~0.6 m away moved by `twist`, with
    /// pixel noise and a fraction of gross outliers.
    fn synthetic(
        rng: &mut Rng,
        n: usize,
        twist: &Vector6<f64>,
        noise_px: f64,
        outlier_fraction: f64,
    ) -> (Vec<Observation>, Vec<bool>) {
        let cam = cam();
        let motion = Pose::exp(twist);
        let mut obs = Vec::new();
        let mut is_outlier = Vec::new();
        for _ in 0..n {
            let x = Vector3::new(
                rng.uniform(-0.1, 0.1),
                rng.uniform(-0.08, 0.08),
                0.6 + rng.uniform(-0.05, 0.05),
            );
            let m0 = cam.project(&x).unwrap();
            let mut m1 = cam.project(&motion.transform_point(&x)).unwrap();
            m1 += Vector2::new(rng.normal(), rng.normal()) * noise_px;
            let outlier = rng.next_f64() < outlier_fraction;
            if outlier {
                m1 += Vector2::new(rng.uniform(-40.0, 40.0), rng.uniform(-40.0, 40.0));
            }
            obs.push(Observation {
                predictors: cam.motion_predictors(&x),
                displacement: m1 - m0,
            });
            is_outlier.push(outlier);
        }
        (obs, is_outlier)
    }

    #[test]
    fn recovers_known_twist_with_30_percent_outliers() {
        let mut rng = Rng::new(21);
        for trial in 0..20 {
            // ~1-2 degrees and a few mm: a frame-to-frame motion.
            let twist = Vector6::new(
                rng.uniform(-0.005, 0.005),
                rng.uniform(-0.005, 0.005),
                rng.uniform(-0.01, 0.01),
                rng.uniform(-0.02, 0.02),
                rng.uniform(-0.02, 0.02),
                rng.uniform(-0.03, 0.03),
            );
            let (obs, outlier) = synthetic(&mut rng, 200, &twist, 0.3, 0.3);
            let res = irls(&obs, &IrlsConfig::default()).unwrap();
            // The oracle: least squares on the true inliers only. The robust
            // fit should be as good as knowing which matches are outliers.
            let clean: Vec<Observation> = obs
                .iter()
                .zip(&outlier)
                .filter(|(_, o)| !**o)
                .map(|(ob, _)| *ob)
                .collect();
            let oracle = irls(
                &clean,
                &IrlsConfig {
                    loss: Loss::LeastSquares,
                    warmup_iterations: 0,
                    ..Default::default()
                },
            )
            .unwrap();
            let err = |t: &Vector6<f64>| {
                (
                    (t.fixed_rows::<3>(3) - twist.fixed_rows::<3>(3)).norm(),
                    (t.fixed_rows::<3>(0) - twist.fixed_rows::<3>(0)).norm(),
                )
            };
            let (rot_err, tr_err) = err(&res.twist);
            let (orot, otr) = err(&oracle.twist);
            eprintln!(
                "trial {trial}: robust {rot_err:.2e} rad {tr_err:.2e} m; oracle {orot:.2e} {otr:.2e}"
            );
            // A small object (0.2 m at 0.6 m) couples rotation and
            // translation: 0.3 px of noise leaves ~1e-3 rad of uncertainty.
            assert!(
                rot_err < 3e-3,
                "trial {trial}: rotation error {rot_err} rad"
            );
            assert!(tr_err < 2e-3, "trial {trial}: translation error {tr_err} m");
            assert!(
                rot_err < 1.5 * orot + 2e-4 && tr_err < 1.5 * otr + 1e-4,
                "trial {trial}: robust ({rot_err}, {tr_err}) vs oracle ({orot}, {otr})"
            );
            let flagged_outliers = outlier
                .iter()
                .zip(&res.inliers)
                .filter(|(o, i)| **o && **i)
                .count();
            let n_out = outlier.iter().filter(|&&o| o).count();
            assert!(
                flagged_outliers * 20 <= n_out,
                "trial {trial}: {flagged_outliers} of {n_out} outliers kept as inliers"
            );
            assert!(res.residual_rms_px < 1.0, "{}", res.residual_rms_px);
        }
    }

    /// [`synthetic`] matches moved by [`TWIST`].
    fn moved(seed: u64, n: usize, noise_px: f64, outlier_fraction: f64) -> Vec<Observation> {
        synthetic(&mut Rng::new(seed), n, &TWIST, noise_px, outlier_fraction).0
    }

    #[test]
    fn least_squares_is_ruined_by_the_same_outliers() {
        // The robust loss is what makes the previous test pass.
        let obs = moved(22, 200, 0.3, 0.3);
        let cfg = IrlsConfig {
            loss: Loss::LeastSquares,
            warmup_iterations: 0,
            inlier_scales: f64::INFINITY,
            ..Default::default()
        };
        let ls = irls(&obs, &cfg).unwrap();
        let robust = irls(&obs, &IrlsConfig::default()).unwrap();
        let (e_ls, e_rob) = ((ls.twist - TWIST).norm(), (robust.twist - TWIST).norm());
        assert!(
            e_ls > 3.0 * e_rob,
            "least squares {e_ls:.2e} vs robust {e_rob:.2e}"
        );
    }

    #[test]
    fn huber_also_recovers_the_twist() {
        let obs = moved(23, 300, 0.3, 0.2);
        let cfg = IrlsConfig {
            loss: Loss::HUBER,
            ..Default::default()
        };
        let err = (irls(&obs, &cfg).unwrap().twist - TWIST).norm();
        assert!(err < 3e-3, "{err}");
    }

    #[test]
    fn exact_matches_give_the_exact_linearised_twist() {
        // With displacements generated by the linear model itself, the
        // solution is exact (no first-order approximation involved).
        let cam = cam();
        let mut rng = Rng::new(24);
        let twist = Vector6::new(0.01, -0.02, 0.03, 0.04, -0.05, 0.06);
        let obs: Vec<Observation> = (0..30)
            .map(|_| {
                let x = Vector3::new(
                    rng.uniform(-0.1, 0.1),
                    rng.uniform(-0.1, 0.1),
                    rng.uniform(0.5, 0.7),
                );
                let l = cam.motion_predictors(&x);
                Observation {
                    predictors: l,
                    displacement: l * twist,
                }
            })
            .collect();
        let res = irls(&obs, &IrlsConfig::default()).unwrap();
        assert!((res.twist - twist).amax() < 1e-9);
        assert_eq!(res.inlier_count, 30);
    }

    #[test]
    fn too_few_matches_are_refused() {
        let mut rng = Rng::new(25);
        let (obs, _) = synthetic(&mut rng, 5, &Vector6::zeros(), 0.1, 0.0);
        assert_eq!(
            irls(&obs, &IrlsConfig::default()),
            Err(SolveError::TooFewMatches { got: 5, need: 6 })
        );
        assert!(matches!(
            irls(&[], &IrlsConfig::default()),
            Err(SolveError::TooFewMatches { .. })
        ));
    }

    #[test]
    fn points_on_one_line_are_refused_as_degenerate() {
        // Points on a 3-D line: rotation about that line moves none of them.
        let cam = cam();
        let mut rng = Rng::new(26);
        let p0 = Vector3::new(-0.05, 0.02, 0.6);
        let dir = Vector3::new(1.0, 0.3, 0.2).normalize();
        let obs: Vec<Observation> = (0..50)
            .map(|_| {
                let x = p0 + dir * rng.uniform(0.0, 0.15);
                Observation {
                    predictors: cam.motion_predictors(&x),
                    displacement: Vector2::new(rng.normal(), rng.normal()) * 0.2,
                }
            })
            .collect();
        let err = irls(&obs, &IrlsConfig::default()).unwrap_err();
        assert!(matches!(err, SolveError::Degenerate { .. }), "{err}");
        assert!(err.to_string().contains("do not constrain"), "{err}");
    }

    #[test]
    fn mostly_garbage_is_refused_for_too_few_inliers() {
        let obs = moved(27, 40, 0.2, 0.0);
        let cfg = IrlsConfig {
            min_inliers: 41,
            ..Default::default()
        };
        assert!(matches!(
            irls(&obs, &cfg),
            Err(SolveError::TooFewInliers { .. })
        ));
    }

    #[test]
    fn nan_input_is_refused() {
        let mut rng = Rng::new(28);
        let (mut obs, _) = synthetic(&mut rng, 20, &Vector6::zeros(), 0.1, 0.0);
        obs[7].displacement.x = f64::NAN;
        assert_eq!(
            irls(&obs, &IrlsConfig::default()),
            Err(SolveError::NonFinite { index: 7 })
        );
    }

    #[test]
    fn each_row_is_scaled_by_its_own_groups_median() {
        // Three groups in interleaved rows, one absent value of u8 between
        // them: each row's scale is 1.4826 x the upper median of its group's
        // residuals, floored, whatever the rows' order.
        let mut rng = crate::rng::Rng::new(7);
        let groups: Vec<u8> = (0..301).map(|i| [0u8, 3, 255][i % 3]).collect();
        let r: Vec<f64> = groups
            .iter()
            .map(|&g| rng.uniform(0.0, g as f64 + 1.0))
            .collect();
        let s = group_scales(&r, &groups, 0.05);
        for (i, &g) in groups.iter().enumerate() {
            let mut own: Vec<f64> = (0..r.len())
                .filter(|&j| groups[j] == g)
                .map(|j| r[j])
                .collect();
            own.sort_by(f64::total_cmp);
            let want = (1.4826 * own[own.len() / 2]).max(0.05);
            assert_eq!(s[i].to_bits(), want.to_bits(), "row {i}, group {g}");
        }
        // One group, or none given: the same scale for every row.
        let one = group_scales(&r, &[], 0.05);
        let mut all = r.clone();
        all.sort_by(f64::total_cmp);
        let want = (1.4826 * all[all.len() / 2]).max(0.05);
        assert!(one.iter().all(|x| x.to_bits() == want.to_bits()));
        // Tiny residuals: the floor.
        assert!(
            group_scales(&[1e-9; 4], &[2; 4], 0.05)
                .iter()
                .all(|&x| x == 0.05)
        );
    }

    #[test]
    fn weights_behave() {
        assert_eq!(Loss::TUKEY.weight(0.0, 1.0), 1.0);
        assert_eq!(Loss::TUKEY.weight(5.0, 1.0), 0.0);
        assert!(Loss::TUKEY.weight(2.0, 1.0) > 0.0 && Loss::TUKEY.weight(2.0, 1.0) < 1.0);
        assert_eq!(Loss::HUBER.weight(1.0, 1.0), 1.0);
        assert!((Loss::HUBER.weight(2.69, 1.0) - 0.5).abs() < 1e-9);
    }
}
