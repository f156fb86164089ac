//! Rigid transforms (SE(3)): the object-to-camera pose, its exponential
//! and logarithm, composition and validation.

use nalgebra::{Matrix3, Matrix4, Vector3, Vector6};

/// Errors of poses that are not rigid transforms.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PoseError {
    /// A rotation or translation entry is NaN or infinite.
    #[error("pose has a non-finite value")]
    NonFinite,
    /// The rotation is not orthonormal with determinant 1 (to 1e-4); holds
    /// the largest entry of `|R^T R - I|` and the determinant.
    #[error("pose rotation is not a rotation matrix (|R^T R - I| = {0:.2e}, det = {1:.4})")]
    NotRotation(f64, f64),
    /// A 4x4 matrix's bottom row is not `(0, 0, 0, 1)`.
    #[error("pose matrix bottom row is not (0, 0, 0, 1)")]
    NotRigid,
}

/// A rigid transform (SE(3)); in this crate, the object-to-camera pose.
/// Serialised as `{"rotation": [[r11, r12, r13], [r21, ...], [r31, ...]],
/// "translation": [tx, ty, tz]}` (rows of R, as in the pose CSV), checked to
/// be rigid when read back.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(into = "PoseRepr", try_from = "PoseRepr")]
pub struct Pose {
    /// Rotation part R (orthonormal, determinant 1).
    pub rotation: Matrix3<f64>,
    /// Translation part t, in the model's length units (usually metres).
    pub translation: Vector3<f64>,
}

/// The serde form of [`Pose`].
#[derive(serde::Serialize, serde::Deserialize)]
struct PoseRepr {
    /// Rows of R.
    rotation: [[f64; 3]; 3],
    translation: [f64; 3],
}

impl From<Pose> for PoseRepr {
    fn from(p: Pose) -> Self {
        let r = &p.rotation;
        Self {
            rotation: [0, 1, 2].map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]),
            translation: [p.translation.x, p.translation.y, p.translation.z],
        }
    }
}

impl TryFrom<PoseRepr> for Pose {
    type Error = PoseError;
    fn try_from(p: PoseRepr) -> Result<Self, PoseError> {
        let [a, b, c] = p.rotation;
        Pose::new(
            Matrix3::from_row_slice(&[a, b, c].concat()),
            Vector3::from(p.translation),
        )
    }
}

impl Default for Pose {
    fn default() -> Self {
        Self::identity()
    }
}

fn skew(w: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0)
}

impl Pose {
    /// The identity transform (no rotation, zero translation).
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// A pose from a rotation matrix and a translation, checked to be rigid.
    pub fn new(rotation: Matrix3<f64>, translation: Vector3<f64>) -> Result<Self, PoseError> {
        let p = Self {
            rotation,
            translation,
        };
        p.validate()?;
        Ok(p)
    }

    /// From the 12 numbers of a pose CSV row: R row-major, then t.
    pub fn from_row_major(v: &[f64; 12]) -> Result<Self, PoseError> {
        let r = Matrix3::new(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]);
        Self::new(r, Vector3::new(v[9], v[10], v[11]))
    }

    /// R row-major, then t (the pose CSV's column order).
    pub fn to_row_major(&self) -> [f64; 12] {
        let r = &self.rotation;
        let t = &self.translation;
        [
            r[(0, 0)],
            r[(0, 1)],
            r[(0, 2)],
            r[(1, 0)],
            r[(1, 1)],
            r[(1, 2)],
            r[(2, 0)],
            r[(2, 1)],
            r[(2, 2)],
            t.x,
            t.y,
            t.z,
        ]
    }

    /// From a homogeneous 4x4 matrix `[R t; 0 0 0 1]`, checked to be rigid.
    pub fn from_matrix4(m: &Matrix4<f64>) -> Result<Self, PoseError> {
        let bottom = m.fixed_view::<1, 4>(3, 0);
        if (bottom - nalgebra::RowVector4::new(0.0, 0.0, 0.0, 1.0)).amax() > 1e-9 {
            return Err(PoseError::NotRigid);
        }
        Self::new(
            m.fixed_view::<3, 3>(0, 0).into_owned(),
            m.fixed_view::<3, 1>(0, 3).into_owned(),
        )
    }

    /// The homogeneous 4x4 matrix `[R t; 0 0 0 1]`.
    pub fn to_matrix4(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rotation);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }

    /// Rejects non-finite values and matrices that are not rotations (to
    /// 1e-4, loose enough for poses written with 6 decimals).
    pub fn validate(&self) -> Result<(), PoseError> {
        if self
            .rotation
            .iter()
            .chain(self.translation.iter())
            .any(|v| !v.is_finite())
        {
            return Err(PoseError::NonFinite);
        }
        let ortho = (self.rotation.transpose() * self.rotation - Matrix3::identity()).amax();
        let det = self.rotation.determinant();
        if ortho > 1e-4 || (det - 1.0).abs() > 1e-4 {
            return Err(PoseError::NotRotation(ortho, det));
        }
        Ok(())
    }

    /// Re-orthonormalises the rotation (polar decomposition via SVD), to
    /// remove the drift of many composed updates or rounded file values.
    pub fn orthonormalized(&self) -> Self {
        let svd = self.rotation.svd(true, true);
        let (u, vt) = (svd.u.unwrap_or_default(), svd.v_t.unwrap_or_default());
        let mut r = u * vt;
        if r.determinant() < 0.0 {
            let mut u2 = u;
            u2.column_mut(2).neg_mut();
            r = u2 * vt;
        }
        Self {
            rotation: r,
            translation: self.translation,
        }
    }

    /// `self * other`: first `other`, then `self`.
    pub fn compose(&self, other: &Pose) -> Pose {
        Pose {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }

    /// The inverse transform: `(R^T, -R^T t)`.
    pub fn inverse(&self) -> Pose {
        let rt = self.rotation.transpose();
        Pose {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// Maps a point: `R x + t`.
    pub fn transform_point(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * x + self.translation
    }

    /// The SE(3) exponential of a twist `xi = (v, w)` (translation first).
    pub fn exp(xi: &Vector6<f64>) -> Pose {
        let v = xi.fixed_rows::<3>(0).into_owned();
        let w = xi.fixed_rows::<3>(3).into_owned();
        let theta2 = w.norm_squared();
        let theta = theta2.sqrt();
        let wx = skew(&w);
        let wx2 = wx * wx;
        // Taylor expansions below 1e-4 rad keep full precision.
        let (a, b, c) = if theta < 1e-4 {
            (
                1.0 - theta2 / 6.0,
                0.5 - theta2 / 24.0,
                1.0 / 6.0 - theta2 / 120.0,
            )
        } else {
            (
                theta.sin() / theta,
                (1.0 - theta.cos()) / theta2,
                (theta - theta.sin()) / (theta2 * theta),
            )
        };
        let r = Matrix3::identity() + wx * a + wx2 * b;
        let vmat = Matrix3::identity() + wx * b + wx2 * c;
        Pose {
            rotation: r,
            translation: vmat * v,
        }
    }

    /// The twist whose exponential is this pose (inverse of [`Pose::exp`] for
    /// rotation angles below pi).
    pub fn log(&self) -> Vector6<f64> {
        let w = rotation_log(&self.rotation);
        let theta2 = w.norm_squared();
        let theta = theta2.sqrt();
        let wx = skew(&w);
        // V^{-1} = I - wx/2 + (1/theta^2)(1 - (theta sin)/(2(1-cos))) wx^2
        let coef = if theta < 1e-4 {
            1.0 / 12.0 + theta2 / 720.0
        } else {
            (1.0 - theta * theta.sin() / (2.0 * (1.0 - theta.cos()))) / theta2
        };
        let vinv = Matrix3::identity() - wx * 0.5 + wx * wx * coef;
        let v = vinv * self.translation;
        Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z)
    }

    /// `exp(xi^) * self`: the update of the conventions (docs/design.md).
    pub fn apply_twist(&self, xi: &Vector6<f64>) -> Pose {
        Pose::exp(xi).compose(self)
    }

    /// Angle (degrees) of `R_gt^T R`, the rotation error against `gt`.
    pub fn rotation_error_deg(&self, gt: &Pose) -> f64 {
        let r = gt.rotation.transpose() * self.rotation;
        let c = ((r.trace() - 1.0) * 0.5).clamp(-1.0, 1.0);
        c.acos().to_degrees()
    }

    /// Distance between the translations, in model units.
    pub fn translation_error(&self, gt: &Pose) -> f64 {
        (self.translation - gt.translation).norm()
    }
}

/// The rotation vector (axis * angle) of a rotation matrix, robust near 0
/// and near pi.
pub fn rotation_log(r: &Matrix3<f64>) -> Vector3<f64> {
    let c = ((r.trace() - 1.0) * 0.5).clamp(-1.0, 1.0);
    let theta = c.acos();
    let vee = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    );
    if theta < 1e-4 {
        // sin(theta)/theta ~ 1 - theta^2/6
        return vee * (0.5 * (1.0 + theta * theta / 6.0));
    }
    if std::f64::consts::PI - theta > 1e-4 {
        return vee * (theta / (2.0 * theta.sin()));
    }
    // Near pi: R ~ 2 a a^T - I; take the axis from the largest diagonal.
    let b = (r + Matrix3::identity()) * 0.5;
    let k = (0..3)
        .max_by(|&i, &j| b[(i, i)].total_cmp(&b[(j, j)]))
        .unwrap_or(0);
    let mut a = b.column(k).into_owned() / b[(k, k)].max(1e-300).sqrt();
    a.normalize_mut();
    // Fix the sign with the (small) antisymmetric part.
    if a.dot(&vee) < 0.0 {
        a = -a;
    }
    a * theta
}

/// The rotation matrix of a rotation vector (Rodrigues).
pub fn rotation_exp(w: &Vector3<f64>) -> Matrix3<f64> {
    Pose::exp(&Vector6::new(0.0, 0.0, 0.0, w.x, w.y, w.z)).rotation
}

/// A pose that looks at `target` from `eye` (object coordinates), with image
/// "up" as close as possible to `up`: convenient for synthetic views.
/// Camera axes are OpenCV's (x right, y down, z forward).
pub fn look_at(eye: &Vector3<f64>, target: &Vector3<f64>, up: &Vector3<f64>) -> Pose {
    let z = (target - eye).normalize();
    let mut x = z.cross(up);
    if x.norm() < 1e-9 {
        x = z.cross(&Vector3::new(1.0, 0.0, 0.0));
        if x.norm() < 1e-9 {
            x = z.cross(&Vector3::new(0.0, 1.0, 0.0));
        }
    }
    let x = x.normalize();
    let y = z.cross(&x);
    // Rows of R are the camera axes in object coordinates.
    let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    Pose {
        rotation: r,
        translation: -(r * eye),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn random_pose(rng: &mut Rng, max_angle: f64) -> Pose {
        let axis = rng.unit_vector();
        let angle = rng.uniform(0.0, max_angle);
        let t = Vector3::new(
            rng.uniform(-0.3, 0.3),
            rng.uniform(-0.3, 0.3),
            rng.uniform(0.3, 1.5),
        );
        Pose::new(rotation_exp(&(axis * angle)), t).unwrap()
    }

    #[test]
    fn exp_log_roundtrip_on_random_poses() {
        let mut rng = Rng::new(1);
        for i in 0..2000 {
            // Cover tiny angles, ordinary ones and angles close to pi.
            let max = match i % 3 {
                0 => 1e-6,
                1 => 3.0,
                _ => std::f64::consts::PI - 1e-6,
            };
            let p = random_pose(&mut rng, max);
            let q = Pose::exp(&p.log());
            assert!(
                (q.to_matrix4() - p.to_matrix4()).amax() < 1e-9,
                "exp(log T) != T for {p:?} -> {q:?}"
            );
        }
    }

    #[test]
    fn log_exp_roundtrip_on_random_twists() {
        let mut rng = Rng::new(2);
        for _ in 0..1000 {
            let xi = Vector6::from_fn(|_, _| rng.uniform(-1.0, 1.0));
            let back = Pose::exp(&xi).log();
            assert!((back - xi).amax() < 1e-9, "{xi} -> {back}");
        }
    }

    #[test]
    fn compose_inverse_is_identity() {
        let mut rng = Rng::new(3);
        for _ in 0..100 {
            let p = random_pose(&mut rng, 3.0);
            let i = p.compose(&p.inverse());
            assert!((i.to_matrix4() - Matrix4::identity()).amax() < 1e-12);
            let x = Vector3::new(rng.uniform(-1.0, 1.0), 0.2, 0.7);
            let back = p.inverse().transform_point(&p.transform_point(&x));
            assert!((back - x).norm() < 1e-12);
        }
    }

    #[test]
    fn exp_matches_generator_derivative() {
        // d/da exp(a G_j) X at a = 0 is e_j (translations) or e_j x X (rotations).
        let x = Vector3::new(0.1, -0.2, 0.9);
        let h = 1e-6;
        for j in 0..6 {
            let xi = Vector6::ith(j, h);
            let d = (Pose::exp(&xi).transform_point(&x) - Pose::exp(&-xi).transform_point(&x))
                / (2.0 * h);
            let e = Vector3::ith(j % 3, 1.0);
            let want = if j < 3 { e } else { e.cross(&x) };
            assert!((d - want).norm() < 1e-8, "generator {j}: {d} vs {want}");
        }
    }

    #[test]
    fn serde_roundtrip_is_readable_and_checked() {
        let mut rng = Rng::new(7);
        let p = random_pose(&mut rng, 2.0);
        let text = serde_json::to_string(&p).unwrap();
        let back: Pose = serde_json::from_str(&text).unwrap();
        // serde_json reads floats to within an ulp (exactly only with its
        // `float_roundtrip` feature).
        let close = |a: f64, b: f64| (a - b).abs() < 1e-15 * b.abs().max(1.0);
        assert!(
            (back.to_matrix4() - p.to_matrix4()).amax() < 1e-15,
            "{text}"
        );
        let r = p.to_row_major();
        let rows: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert!(
            close(rows["rotation"][1][2].as_f64().unwrap(), r[5]),
            "{text}"
        );
        assert!(
            close(rows["translation"][2].as_f64().unwrap(), r[11]),
            "{text}"
        );
        let bad = r#"{"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, -1]], "translation": [0, 0, 1]}"#;
        let e = serde_json::from_str::<Pose>(bad).unwrap_err().to_string();
        assert!(e.contains("not a rotation"), "{e}");
    }

    #[test]
    fn rejects_non_rotations() {
        let bad = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0);
        assert!(matches!(
            Pose::new(bad, Vector3::zeros()),
            Err(PoseError::NotRotation(..))
        ));
        let nan = Vector3::new(f64::NAN, 0.0, 0.0);
        assert_eq!(
            Pose::new(Matrix3::identity(), nan),
            Err(PoseError::NonFinite)
        );
    }
}
