//! The minimal problem of [`super::pnp`]: the up to four poses that put three
//! model points on three viewing rays (Grunert's elimination), and the rigid
//! fit of point pairs (Kabsch) that turns the rays' depths into a pose.
//!
//! With unit bearings `f_i`, depths `s_i`, and the triangle's sides
//! `a = |X2 - X3|`, `b = |X1 - X3|`, `c = |X1 - X2|`, the law of cosines
//! gives three quadrics in the depths. Writing `s2 = u s1`, `s3 = v s1` and
//! eliminating `s1` leaves two conics in `(u, v)`; their difference is linear
//! in `u`, so `u = N(v) / D(v)` and substituting it back gives a quartic in
//! `v`. Its real positive roots are the candidate solutions.

use crate::geometry::Pose;
use nalgebra::{Matrix3, Vector3};

/// Polynomial coefficients, lowest degree first.
type Poly = Vec<f64>;

fn poly_mul(a: &[f64], b: &[f64]) -> Poly {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

fn poly_add(a: &[f64], b: &[f64], scale_b: f64) -> Poly {
    let mut out = vec![0.0; a.len().max(b.len())];
    for (i, x) in a.iter().enumerate() {
        out[i] += x;
    }
    for (i, y) in b.iter().enumerate() {
        out[i] += scale_b * y;
    }
    out
}

fn poly_eval(p: &[f64], x: f64) -> f64 {
    p.iter().rev().fold(0.0, |acc, c| acc * x + c)
}

/// The real roots of a polynomial (coefficients lowest degree first), by
/// bracketing between the real roots of its derivative and bisecting: slow
/// for high degrees but robust, and exact to rounding for the quartics here.
/// A double root shows as a critical point where the polynomial vanishes.
pub(crate) fn real_roots(p: &[f64]) -> Vec<f64> {
    let scale = p.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    if !(scale.is_finite() && scale > 0.0) {
        return Vec::new();
    }
    let mut deg = p.len() - 1;
    while deg > 0 && p[deg].abs() <= 1e-13 * scale {
        deg -= 1;
    }
    let p = &p[..=deg];
    match deg {
        0 => return Vec::new(),
        1 => return vec![-p[0] / p[1]],
        _ => {}
    }
    let lead = p[deg];
    let bound = 1.0 + p[..deg].iter().fold(0.0f64, |m, c| m.max((c / lead).abs()));
    let deriv: Poly = (1..=deg).map(|i| i as f64 * p[i]).collect();
    let mut knots = vec![-bound];
    let mut crit: Vec<f64> = real_roots(&deriv)
        .into_iter()
        .filter(|x| x.abs() < bound)
        .collect();
    crit.sort_by(f64::total_cmp);
    knots.extend(crit.iter().copied());
    knots.push(bound);
    let mut roots = Vec::new();
    for w in knots.windows(2) {
        let (mut lo, mut hi) = (w[0], w[1]);
        let (flo, fhi) = (poly_eval(p, lo), poly_eval(p, hi));
        if flo == 0.0 {
            roots.push(lo);
            continue;
        }
        if flo.signum() == fhi.signum() {
            continue;
        }
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            let fm = poly_eval(p, mid);
            if fm.signum() == flo.signum() {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        roots.push(0.5 * (lo + hi));
    }
    // Double roots: critical points where the polynomial (nearly) vanishes.
    for &x in &crit {
        let mag: f64 = p
            .iter()
            .enumerate()
            .map(|(i, c)| (c * x.powi(i as i32)).abs())
            .sum();
        if poly_eval(p, x).abs() <= 1e-10 * mag && roots.iter().all(|r| (r - x).abs() > 1e-9) {
            roots.push(x);
        }
    }
    roots
}

/// The rigid transform `(R, t)` minimising `sum |R p_i + t - q_i|^2`
/// (Kabsch, with the reflection removed); exact for three non-collinear
/// pairs that are congruent.
pub(crate) fn rigid_fit(p: &[Vector3<f64>], q: &[Vector3<f64>]) -> Option<Pose> {
    let n = p.len() as f64;
    let pc = p.iter().sum::<Vector3<f64>>() / n;
    let qc = q.iter().sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    for (a, b) in p.iter().zip(q) {
        h += (a - pc) * (b - qc).transpose();
    }
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let v = vt.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    let t = qc - r * pc;
    let pose = Pose {
        rotation: r,
        translation: t,
    };
    pose.validate().ok().map(|_| pose)
}

/// The poses (at most four) that put `x[i]` on the ray of unit bearing
/// `f[i]` in front of the camera. Empty for a degenerate triangle or rays.
pub(crate) fn p3p(x: &[Vector3<f64>; 3], f: &[Vector3<f64>; 3]) -> Vec<Pose> {
    let a2 = (x[1] - x[2]).norm_squared();
    let b2 = (x[0] - x[2]).norm_squared();
    let c2 = (x[0] - x[1]).norm_squared();
    let area2 = (x[1] - x[0]).cross(&(x[2] - x[0])).norm_squared();
    if area2.is_nan() || area2 <= 1e-20 * (a2.max(b2).max(c2)).powi(2) {
        return Vec::new();
    }
    let ca = f[1].dot(&f[2]);
    let cb = f[0].dot(&f[2]);
    let cg = f[0].dot(&f[1]);
    let k = (a2 - c2) / b2;
    // Q(v) = 1 + v^2 - 2 v cos(beta) = |f1 - v f3|^2 (times s1^2 gives b^2).
    let q = [1.0, -2.0 * cb, 1.0];
    // u = N(v) / D(v).
    let num = [-1.0 - k, 2.0 * k * cb, 1.0 - k];
    let den = [-2.0 * cg, 2.0 * ca];
    // u^2 - 2 u cos(gamma) + 1 - (c^2/b^2) Q = 0, times D^2.
    let n2 = poly_mul(&num, &num);
    let nd = poly_mul(&num, &den);
    let d2 = poly_mul(&den, &den);
    let qd2 = poly_mul(&q, &d2);
    let quartic = poly_add(
        &poly_add(&poly_add(&n2, &nd, -2.0 * cg), &d2, 1.0),
        &qd2,
        -c2 / b2,
    );
    let mut out = Vec::new();
    for v in real_roots(&quartic) {
        if v.is_nan() || v <= 0.0 {
            continue;
        }
        let d = poly_eval(&den, v);
        if d.abs() < 1e-12 {
            continue;
        }
        let u = poly_eval(&num, v) / d;
        let qv = poly_eval(&q, v);
        if u.is_nan() || qv.is_nan() || u <= 0.0 || qv <= 0.0 {
            continue;
        }
        let s1 = (b2 / qv).sqrt();
        let cam = [f[0] * s1, f[1] * (u * s1), f[2] * (v * s1)];
        if let Some(pose) = rigid_fit(x, &cam) {
            out.push(pose);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::rotation_exp;

    #[test]
    fn real_roots_of_a_quartic() {
        // (x - 1)(x - 2)(x + 3)(x - 0.5)
        let p = poly_mul(
            &poly_mul(&[-1.0, 1.0], &[-2.0, 1.0]),
            &poly_mul(&[3.0, 1.0], &[-0.5, 1.0]),
        );
        let mut r = real_roots(&p);
        r.sort_by(f64::total_cmp);
        let want = [-3.0, 0.5, 1.0, 2.0];
        assert_eq!(r.len(), 4, "{r:?}");
        for (a, b) in r.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{r:?}");
        }
        // x^2 + 1 has no real roots; (x - 1)^2 (x + 1)^2 has a double root at 1 and -1.
        assert!(real_roots(&[1.0, 0.0, 1.0]).is_empty());
        let dbl = poly_mul(&[1.0, -2.0, 1.0], &[1.0, 2.0, 1.0]);
        let mut r = real_roots(&dbl);
        r.sort_by(f64::total_cmp);
        assert_eq!(r.len(), 2, "{r:?}");
        assert!(
            (r[0] + 1.0).abs() < 1e-6 && (r[1] - 1.0).abs() < 1e-6,
            "{r:?}"
        );
    }

    #[test]
    fn p3p_finds_the_true_pose_among_its_solutions() {
        let r = rotation_exp(&Vector3::new(0.3, -0.5, 0.2));
        let t = Vector3::new(0.05, -0.02, 0.8);
        let x = [
            Vector3::new(0.1, 0.0, 0.02),
            Vector3::new(-0.05, 0.08, 0.0),
            Vector3::new(0.0, -0.07, 0.09),
        ];
        let f = x.map(|p| (r * p + t).normalize());
        let sols = p3p(&x, &f);
        assert!(!sols.is_empty() && sols.len() <= 4);
        let best = sols
            .iter()
            .map(|s| (s.rotation - r).amax() + (s.translation - t).amax())
            .fold(f64::INFINITY, f64::min);
        assert!(best < 1e-9, "{best}");
        // Every solution puts the points on their rays.
        for s in &sols {
            for (p, fi) in x.iter().zip(&f) {
                let c = s.transform_point(p);
                assert!(c.z > 0.0 && (c.normalize() - fi).norm() < 1e-8);
            }
        }
        // A collinear triangle has none.
        let line = [Vector3::zeros(), Vector3::x(), Vector3::x() * 2.0];
        assert!(p3p(&line, &f).is_empty());
    }
}
