//! The unit eigenvector of a symmetric 3x3 matrix's smallest eigenvalue,
//! in closed form (Smith, "Eigenvalues of a symmetric 3x3 matrix", CACM
//! 1961, then a cross product of two rows of `C - lambda I`): the normal of
//! a neighbourhood's covariance.

use glam::DVec3;

/// Unit eigenvector of the smallest eigenvalue of the symmetric matrix `a`;
/// `None` when `a` is zero or not finite.
pub(crate) fn smallest_eigenvector(a: [[f64; 3]; 3]) -> Option<DVec3> {
    let scale = a.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    let a = a.map(|r| r.map(|v| v / scale));
    let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    let q = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
    let lambda = if off == 0.0 {
        a[0][0].min(a[1][1]).min(a[2][2])
    } else {
        let d = [a[0][0] - q, a[1][1] - q, a[2][2] - q];
        let p = ((d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + 2.0 * off) / 6.0).sqrt();
        let b = |r: usize, c: usize| (a[r][c] - if r == c { q } else { 0.0 }) / p;
        let det = b(0, 0) * (b(1, 1) * b(2, 2) - b(1, 2) * b(2, 1))
            - b(0, 1) * (b(1, 0) * b(2, 2) - b(1, 2) * b(2, 0))
            + b(0, 2) * (b(1, 0) * b(2, 1) - b(1, 1) * b(2, 0));
        let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
        q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos()
    };
    let rows = [
        DVec3::new(a[0][0] - lambda, a[0][1], a[0][2]),
        DVec3::new(a[1][0], a[1][1] - lambda, a[1][2]),
        DVec3::new(a[2][0], a[2][1], a[2][2] - lambda),
    ];
    // The eigenvector is orthogonal to every row of A - lambda I: the largest
    // cross product of two rows is the best-conditioned estimate.
    let best = [
        rows[0].cross(rows[1]),
        rows[0].cross(rows[2]),
        rows[1].cross(rows[2]),
    ]
    .into_iter()
    .max_by(|u, v| u.length_squared().total_cmp(&v.length_squared()))?;
    if best.length_squared() > 1e-20 {
        return Some(best.normalize());
    }
    // Rank <= 1: the smallest eigenvalue is repeated (a line-like or round
    // neighbourhood) and any vector orthogonal to the remaining row is valid.
    let row = rows
        .into_iter()
        .max_by(|u, v| u.length_squared().total_cmp(&v.length_squared()))?;
    if row.length_squared() > 1e-20 {
        Some(row.any_orthonormal_vector())
    } else {
        Some(DVec3::Z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    #[test]
    fn eigenvector_matches_nalgebra() {
        let mut rng = Rng::new(3);
        for _ in 0..500 {
            let mut m = [[0.0f64; 3]; 3];
            for (r, c) in [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)] {
                let v = rng.next_f64() * 2.0 - 1.0;
                m[r][c] = v;
                m[c][r] = v;
            }
            let na = nalgebra::Matrix3::from_fn(|r, c| m[r][c]);
            let eig = na.symmetric_eigen();
            let (imin, _) = eig
                .eigenvalues
                .iter()
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(b.1))
                .expect("3 eigenvalues");
            let mut sorted: Vec<f64> = eig.eigenvalues.iter().copied().collect();
            sorted.sort_by(f64::total_cmp);
            if sorted[1] - sorted[0] < 1e-3 {
                continue; // direction ill-defined
            }
            let want = eig.eigenvectors.column(imin);
            let got = smallest_eigenvector(m).expect("non-zero matrix");
            let dot = got.x * want[0] + got.y * want[1] + got.z * want[2];
            assert!(dot.abs() > 1.0 - 1e-6, "{m:?}: {got:?} vs {want:?}");
        }
    }

    #[test]
    fn eigenvector_degenerate_cases() {
        assert!(smallest_eigenvector([[0.0; 3]; 3]).is_none());
        assert!(smallest_eigenvector([[f64::NAN; 3]; 3]).is_none());
        let d = smallest_eigenvector([[3.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]])
            .expect("diagonal");
        assert!((d.y.abs() - 1.0).abs() < 1e-12);
        // A line along x: any unit vector orthogonal to x.
        let l = smallest_eigenvector([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
            .expect("line");
        assert!(l.x.abs() < 1e-12 && (l.length() - 1.0).abs() < 1e-12);
        // Isotropic: any unit vector.
        let s = smallest_eigenvector([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
            .expect("sphere");
        assert!((s.length() - 1.0).abs() < 1e-12);
        // Nearly flat, tilted plane z = 0.5 x.
        let mut rng = Rng::new(9);
        let pts: Vec<DVec3> = (0..50)
            .map(|_| {
                let (x, y) = (rng.next_f64(), rng.next_f64());
                DVec3::new(x, y, 0.5 * x + 1e-9 * rng.next_f64())
            })
            .collect();
        let mean = pts.iter().copied().sum::<DVec3>() / 50.0;
        let mut c = [[0.0; 3]; 3];
        for p in &pts {
            let d = (*p - mean).to_array();
            for r in 0..3 {
                for s in 0..3 {
                    c[r][s] += d[r] * d[s];
                }
            }
        }
        let n = smallest_eigenvector(c).expect("plane");
        let want = DVec3::new(-0.5, 0.0, 1.0).normalize();
        assert!(n.dot(want).abs() > 1.0 - 1e-9, "{n:?}");
    }
}
