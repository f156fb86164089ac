//! Camera and pose maths on the host, in `f64`: the reference that every GPU
//! kernel is tested against.
//!
//! Conventions (DESIGN.md section 2, fixed here once for the whole crate):
//! - A [`Pose`] is the object-to-camera transform `T_co`: `X_c = R X_o + t`.
//! - [`Intrinsics`] are an OpenCV pinhole camera; pixel (0,0) is the *centre*
//!   of the top-left pixel. GPU rasterisers put pixel centres at +0.5; the one
//!   place that converts is [`Intrinsics::to_framebuffer`].
//! - Pose updates are left-multiplied twists in the camera frame:
//!   `E_t = exp(xi^) E_{t-1}`, `xi = (v, w)`, translation first.
//! - The six generators `G_j` are translations along camera x, y, z, then
//!   rotations about camera x, y, z.
//!
//! The motion predictor of generator `j` at a camera-space point `X`
//! (Dehais et al. 2010, eq. 5) is the image velocity of `pi(exp(a G_j) X)` at
//! `a = 0`: `J(X) e_j` for translations and `J(X) (e_j x X)` for rotations.

use nalgebra::{Matrix2x3, Matrix2x6, Matrix3, Matrix4, Vector2, Vector3, Vector6};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Errors of camera files and camera parameters.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    #[error("{path}: cannot read camera file: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: not a valid camera file: {reason}")]
    Parse { path: PathBuf, reason: String },
    #[error("{path}: impossible camera: {reason}")]
    Invalid { path: PathBuf, reason: String },
}

/// Errors of poses that are not rigid transforms.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PoseError {
    #[error("pose has a non-finite value")]
    NonFinite,
    #[error("pose rotation is not a rotation matrix (|R^T R - I| = {0:.2e}, det = {1:.4})")]
    NotRotation(f64, f64),
    #[error("pose matrix bottom row is not (0, 0, 0, 1)")]
    NotRigid,
}

/// Pinhole intrinsics with OpenCV's distortion model (k1, k2, p1, p2, k3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// OpenCV order: k1, k2, p1, p2, k3. All zero for an ideal pinhole.
    pub distortion: [f64; 5],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraJson {
    width: u32,
    height: u32,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    #[serde(default)]
    distortion: Option<Vec<f64>>,
}

impl Intrinsics {
    /// An ideal pinhole camera (no distortion).
    pub fn new(width: u32, height: u32, fx: f64, fy: f64, cx: f64, cy: f64) -> Self {
        Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            distortion: [0.0; 5],
        }
    }

    /// Loads `camera.json` (FORMATS.md) or an OpenCV calibration YAML
    /// (`.yaml`/`.yml`, as written by OpenCV's calibration sample).
    pub fn load(path: &Path) -> Result<Self, CameraError> {
        let text = std::fs::read_to_string(path).map_err(|source| CameraError::Io {
            path: path.to_owned(),
            source,
        })?;
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let looks_yaml = text.trim_start().starts_with("%YAML") || text.contains("camera_matrix");
        let cam = if ext == "yaml" || ext == "yml" || (ext != "json" && looks_yaml) {
            Self::parse_opencv_yaml(&text)
        } else {
            Self::parse_json(&text)
        }
        .map_err(|reason| CameraError::Parse {
            path: path.to_owned(),
            reason,
        })?;
        cam.validate().map_err(|reason| CameraError::Invalid {
            path: path.to_owned(),
            reason,
        })?;
        Ok(cam)
    }

    fn parse_json(text: &str) -> Result<Self, String> {
        let j: CameraJson = serde_json::from_str(text).map_err(|e| e.to_string())?;
        let distortion = match j.distortion {
            None => [0.0; 5],
            Some(d) => distortion_from_slice(&d)?,
        };
        Ok(Self {
            width: j.width,
            height: j.height,
            fx: j.fx,
            fy: j.fy,
            cx: j.cx,
            cy: j.cy,
            distortion,
        })
    }

    /// Parses the subset of OpenCV's FileStorage YAML that calibration files
    /// use: scalar `image_width`/`image_height` and `!!opencv-matrix` blocks
    /// with `rows`, `cols`, `dt`, `data: [ ... ]` (which may span lines).
    fn parse_opencv_yaml(text: &str) -> Result<Self, String> {
        let scalar = |key: &str| -> Result<f64, String> {
            for line in text.lines() {
                let l = line.trim();
                if let Some(rest) = l.strip_prefix(key) {
                    if let Some(v) = rest.trim_start().strip_prefix(':') {
                        return v
                            .trim()
                            .parse::<f64>()
                            .map_err(|_| format!("{key} is not a number: {:?}", v.trim()));
                    }
                }
            }
            Err(format!("missing {key}"))
        };
        let matrix = |key: &str| -> Result<Option<Vec<f64>>, String> {
            let Some(start) = text.find(&format!("{key}:")) else {
                return Ok(None);
            };
            let rest = &text[start..];
            let Some(d) = rest.find("data:") else {
                return Err(format!("{key} has no data"));
            };
            let rest = &rest[d + 5..];
            let open = rest.find('[').ok_or(format!("{key}: data is not a [ list ]"))?;
            let close = rest
                .find(']')
                .ok_or(format!("{key}: data list is not closed"))?;
            if close < open {
                return Err(format!("{key}: malformed data list"));
            }
            rest[open + 1..close]
                .split(',')
                .map(|s| s.trim())
                .filter(|s| !s.is_empty())
                .map(|s| {
                    s.parse::<f64>()
                        .map_err(|_| format!("{key}: {s:?} is not a number"))
                })
                .collect::<Result<Vec<_>, _>>()
                .map(Some)
        };
        let w = scalar("image_width")?;
        let h = scalar("image_height")?;
        if !(w >= 1.0 && h >= 1.0 && w.fract() == 0.0 && h.fract() == 0.0 && w < 1e6 && h < 1e6) {
            return Err(format!("image size {w} x {h} is not a positive integer size"));
        }
        let k = matrix("camera_matrix")?.ok_or("missing camera_matrix")?;
        if k.len() != 9 {
            return Err(format!("camera_matrix has {} values, expected 9", k.len()));
        }
        let distortion = match matrix("distortion_coefficients")? {
            None => [0.0; 5],
            Some(d) => distortion_from_slice(&d)?,
        };
        Ok(Self {
            width: w as u32,
            height: h as u32,
            fx: k[0],
            fy: k[4],
            cx: k[2],
            cy: k[5],
            distortion,
        })
    }

    /// Checks that the camera can exist: a positive size, finite positive
    /// focal lengths and finite coefficients.
    pub fn validate(&self) -> Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err(format!("image size {} x {}", self.width, self.height));
        }
        if self.width > 1 << 15 || self.height > 1 << 15 {
            return Err(format!("image size {} x {} is too large", self.width, self.height));
        }
        for (name, v) in [("fx", self.fx), ("fy", self.fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} = {v} (must be finite and > 0)"));
            }
        }
        for (name, v) in [("cx", self.cx), ("cy", self.cy)] {
            if !v.is_finite() {
                return Err(format!("{name} = {v} is not finite"));
            }
        }
        if self.distortion.iter().any(|d| !d.is_finite()) {
            return Err("distortion coefficients are not finite".into());
        }
        Ok(())
    }

    /// True when the camera has non-zero distortion coefficients.
    pub fn has_distortion(&self) -> bool {
        self.distortion.iter().any(|&d| d != 0.0)
    }

    /// The same camera without distortion (what frames look like after
    /// [`Undistorter`]).
    pub fn undistorted(&self) -> Self {
        Self {
            distortion: [0.0; 5],
            ..*self
        }
    }

    /// The camera for an image resampled by `s` (pyramid levels: `s = 0.5`).
    /// With OpenCV's pixel-centre convention a pixel centre `u` maps to
    /// `(u + 0.5) s - 0.5`.
    pub fn scaled(&self, s: f64) -> Self {
        Self {
            width: ((self.width as f64 * s).round() as u32).max(1),
            height: ((self.height as f64 * s).round() as u32).max(1),
            fx: self.fx * s,
            fy: self.fy * s,
            cx: (self.cx + 0.5) * s - 0.5,
            cy: (self.cy + 0.5) * s - 0.5,
            distortion: self.distortion,
        }
    }

    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }

    /// `pi(X) = (fx x/z + cx, fy y/z + cy)` for a camera-space point; `None`
    /// behind (or on) the camera plane.
    pub fn project(&self, x: &Vector3<f64>) -> Option<Vector2<f64>> {
        (x.z > 0.0).then(|| {
            Vector2::new(
                self.fx * x.x / x.z + self.cx,
                self.fy * x.y / x.z + self.cy,
            )
        })
    }

    /// The camera-space point at depth `z` seen at pixel `(u, v)`.
    pub fn unproject(&self, uv: &Vector2<f64>, z: f64) -> Vector3<f64> {
        Vector3::new(
            (uv.x - self.cx) / self.fx * z,
            (uv.y - self.cy) / self.fy * z,
            z,
        )
    }

    /// `J(X) = d pi / d X = [[fx/z, 0, -fx x/z^2], [0, fy/z, -fy y/z^2]]`.
    pub fn projection_jacobian(&self, x: &Vector3<f64>) -> Matrix2x3<f64> {
        let iz = 1.0 / x.z;
        Matrix2x3::new(
            self.fx * iz,
            0.0,
            -self.fx * x.x * iz * iz,
            0.0,
            self.fy * iz,
            -self.fy * x.y * iz * iz,
        )
    }

    /// The motion predictors `l_1..l_6` at camera-space point `X`, as the
    /// columns of a 2x6 matrix (pixels per unit of twist): a small twist `a`
    /// moves the pixel showing `X` by `L a` (Dehais et al. 2010, eq. 5).
    pub fn motion_predictors(&self, x: &Vector3<f64>) -> Matrix2x6<f64> {
        let j = self.projection_jacobian(x);
        let mut l = Matrix2x6::zeros();
        for k in 0..3 {
            l.set_column(k, &j.column(k));
            let e = Vector3::ith(k, 1.0);
            l.set_column(k + 3, &(j * e.cross(x)));
        }
        l
    }

    /// Maps OpenCV pixel coordinates (centre of pixel (0,0) at 0,0) to
    /// framebuffer coordinates (centre at 0.5,0.5) as rasterisers use. The
    /// only place in the crate where the half-pixel convention is crossed.
    pub fn to_framebuffer(uv: Vector2<f64>) -> Vector2<f64> {
        uv.add_scalar(0.5)
    }

    /// Inverse of [`Intrinsics::to_framebuffer`].
    pub fn from_framebuffer(fb: Vector2<f64>) -> Vector2<f64> {
        fb.add_scalar(-0.5)
    }

    /// Applies the distortion model to normalised ideal coordinates.
    pub fn distort_normalized(&self, p: Vector2<f64>) -> Vector2<f64> {
        let [k1, k2, p1, p2, k3] = self.distortion;
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        Vector2::new(
            x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
        )
    }

    /// Inverts [`Intrinsics::distort_normalized`] by fixed-point iteration
    /// (as OpenCV's undistortPoints does); exact for zero distortion.
    pub fn undistort_normalized(&self, d: Vector2<f64>) -> Vector2<f64> {
        let mut p = d;
        for _ in 0..20 {
            let err = self.distort_normalized(p) - d;
            if err.norm() < 1e-12 {
                break;
            }
            p -= err;
        }
        p
    }

    /// Pixel in the distorted (raw) image -> pixel in the ideal pinhole image.
    pub fn undistort_pixel(&self, uv: Vector2<f64>) -> Vector2<f64> {
        let n = Vector2::new((uv.x - self.cx) / self.fx, (uv.y - self.cy) / self.fy);
        let p = self.undistort_normalized(n);
        Vector2::new(p.x * self.fx + self.cx, p.y * self.fy + self.cy)
    }

    /// Pixel in the ideal pinhole image -> pixel in the distorted (raw) image.
    pub fn distort_pixel(&self, uv: Vector2<f64>) -> Vector2<f64> {
        let n = Vector2::new((uv.x - self.cx) / self.fx, (uv.y - self.cy) / self.fy);
        let p = self.distort_normalized(n);
        Vector2::new(p.x * self.fx + self.cx, p.y * self.fy + self.cy)
    }
}

fn distortion_from_slice(d: &[f64]) -> Result<[f64; 5], String> {
    if d.len() > 5 && d[5..].iter().any(|&v| v != 0.0) {
        return Err(format!(
            "{} distortion coefficients with non-zero terms beyond k3 (rational/thin-prism models are not supported)",
            d.len()
        ));
    }
    let mut out = [0.0; 5];
    for (o, v) in out.iter_mut().zip(d) {
        *o = *v;
    }
    Ok(out)
}

/// Removes lens distortion from frames: a precomputed remap table from each
/// ideal-image pixel to its source position in the raw image, then bilinear
/// sampling. Build once per camera, apply per frame.
pub struct Undistorter {
    width: u32,
    height: u32,
    map: Vec<[f32; 2]>,
}

impl Undistorter {
    pub fn new(cam: &Intrinsics) -> Self {
        let (w, h) = (cam.width, cam.height);
        let mut map = Vec::with_capacity((w * h) as usize);
        for v in 0..h {
            for u in 0..w {
                let src = cam.distort_pixel(Vector2::new(u as f64, v as f64));
                map.push([src.x as f32, src.y as f32]);
            }
        }
        Self {
            width: w,
            height: h,
            map,
        }
    }

    /// Undistorts an RGB image of the camera's size; pixels whose source lies
    /// outside the raw image become black.
    pub fn apply(&self, img: &image::RgbImage) -> Result<image::RgbImage, String> {
        if img.width() != self.width || img.height() != self.height {
            return Err(format!(
                "image is {}x{}, camera is {}x{}",
                img.width(),
                img.height(),
                self.width,
                self.height
            ));
        }
        let mut out = image::RgbImage::new(self.width, self.height);
        for (i, px) in out.pixels_mut().enumerate() {
            let [sx, sy] = self.map[i];
            *px = sample_bilinear_rgb(img, sx, sy).unwrap_or(image::Rgb([0, 0, 0]));
        }
        Ok(out)
    }
}

/// Bilinear sample at OpenCV pixel coordinates; `None` outside the image.
pub fn sample_bilinear_rgb(img: &image::RgbImage, x: f32, y: f32) -> Option<image::Rgb<u8>> {
    let (w, h) = (img.width() as i64, img.height() as i64);
    if !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f32 && y <= (h - 1) as f32) {
        return None;
    }
    let (x0, y0) = (x.floor() as i64, y.floor() as i64);
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let p = |xx: i64, yy: i64| img.get_pixel(xx as u32, yy as u32).0;
    let (a, b, c, d) = (p(x0, y0), p(x1, y0), p(x0, y1), p(x1, y1));
    let mut out = [0u8; 3];
    for k in 0..3 {
        let top = a[k] as f32 * (1.0 - fx) + b[k] as f32 * fx;
        let bot = c[k] as f32 * (1.0 - fx) + d[k] as f32 * fx;
        out[k] = (top * (1.0 - fy) + bot * fy).round().clamp(0.0, 255.0) as u8;
    }
    Some(image::Rgb(out))
}

/// A rigid transform (SE(3)); in this crate, the object-to-camera pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub rotation: Matrix3<f64>,
    pub translation: Vector3<f64>,
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

    pub fn to_matrix4(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rotation);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }

    /// Rejects non-finite values and matrices that are not rotations (to
    /// 1e-4, loose enough for poses written with 6 decimals).
    pub fn validate(&self) -> Result<(), PoseError> {
        if self.rotation.iter().chain(self.translation.iter()).any(|v| !v.is_finite()) {
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

    pub fn inverse(&self) -> Pose {
        let rt = self.rotation.transpose();
        Pose {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

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

    /// `exp(xi^) * self`: the update of DESIGN.md section 2.
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

    fn camera() -> Intrinsics {
        Intrinsics::new(640, 480, 572.4, 573.6, 325.3, 242.0)
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
    fn jacobian_matches_finite_differences() {
        let cam = camera();
        let mut rng = Rng::new(4);
        for _ in 0..200 {
            let x = Vector3::new(
                rng.uniform(-0.5, 0.5),
                rng.uniform(-0.5, 0.5),
                rng.uniform(0.2, 3.0),
            );
            let j = cam.projection_jacobian(&x);
            let h = 1e-6;
            for k in 0..3 {
                let dx = Vector3::ith(k, h);
                let fd = (cam.project(&(x + dx)).unwrap() - cam.project(&(x - dx)).unwrap())
                    / (2.0 * h);
                let rel = (fd - j.column(k)).norm() / (1.0 + j.column(k).norm());
                assert!(rel < 1e-6, "column {k}: fd {fd} vs J {}", j.column(k));
            }
        }
    }

    #[test]
    fn predictors_match_finite_motion_of_projection() {
        let cam = camera();
        let mut rng = Rng::new(5);
        for _ in 0..200 {
            let x = Vector3::new(
                rng.uniform(-0.4, 0.4),
                rng.uniform(-0.3, 0.3),
                rng.uniform(0.3, 2.0),
            );
            let l = cam.motion_predictors(&x);
            let h = 1e-6;
            for j in 0..6 {
                let xi = Vector6::ith(j, h);
                let fd = (cam.project(&Pose::exp(&xi).transform_point(&x)).unwrap()
                    - cam.project(&Pose::exp(&-xi).transform_point(&x)).unwrap())
                    / (2.0 * h);
                let rel = (fd - l.column(j)).norm() / (1.0 + l.column(j).norm());
                assert!(rel < 1e-6, "predictor {j}: fd {fd} vs l {}", l.column(j));
            }
        }
    }

    #[test]
    fn small_twist_moves_pixel_by_l_a() {
        // First-order check of the linear model the solver relies on.
        let cam = camera();
        let x = Vector3::new(0.05, -0.03, 0.6);
        let a = Vector6::new(0.001, -0.002, 0.003, 0.002, -0.001, 0.003);
        let moved = cam.project(&Pose::exp(&a).transform_point(&x)).unwrap();
        let predicted = cam.project(&x).unwrap() + cam.motion_predictors(&x) * a;
        assert!((moved - predicted).norm() < 0.02, "{moved} vs {predicted}");
    }

    #[test]
    fn distortion_roundtrip() {
        let mut cam = camera();
        cam.distortion = [-0.28, 0.09, 0.001, -0.0005, -0.01];
        let mut rng = Rng::new(6);
        for _ in 0..500 {
            let uv = Vector2::new(rng.uniform(0.0, 639.0), rng.uniform(0.0, 479.0));
            let back = cam.distort_pixel(cam.undistort_pixel(uv));
            assert!((back - uv).norm() < 1e-6, "{uv} -> {back}");
        }
    }

    #[test]
    fn undistorter_moves_pixels_where_the_model_says() {
        let mut cam = Intrinsics::new(64, 48, 60.0, 60.0, 31.5, 23.5);
        cam.distortion = [-0.2, 0.05, 0.0, 0.0, 0.0];
        // A raw image whose red channel encodes x and green encodes y.
        let raw = image::RgbImage::from_fn(64, 48, |x, y| image::Rgb([x as u8 * 3, y as u8 * 5, 0]));
        let und = Undistorter::new(&cam).apply(&raw).unwrap();
        let uv = Vector2::new(10.0, 8.0);
        let src = cam.distort_pixel(uv);
        let px = und.get_pixel(10, 8).0;
        assert!((px[0] as f64 / 3.0 - src.x).abs() < 0.5, "{px:?} vs {src}");
        assert!((px[1] as f64 / 5.0 - src.y).abs() < 0.5, "{px:?} vs {src}");
        assert!(Undistorter::new(&cam).apply(&image::RgbImage::new(10, 10)).is_err());
    }

    #[test]
    fn look_at_centres_target() {
        let cam = camera();
        let p = look_at(
            &Vector3::new(0.3, -0.4, 0.5),
            &Vector3::new(0.01, 0.02, 0.03),
            &Vector3::new(0.0, 0.0, 1.0),
        );
        p.validate().unwrap();
        let c = cam.project(&p.transform_point(&Vector3::new(0.01, 0.02, 0.03))).unwrap();
        assert!((c - Vector2::new(cam.cx, cam.cy)).norm() < 1e-9);
        // Object "up" (+z) appears upwards in the image (smaller v).
        let up = cam.project(&p.transform_point(&Vector3::new(0.01, 0.02, 0.13))).unwrap();
        assert!(up.y < c.y);
    }

    #[test]
    fn rejects_non_rotations() {
        let bad = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0);
        assert!(matches!(Pose::new(bad, Vector3::zeros()), Err(PoseError::NotRotation(..))));
        let nan = Vector3::new(f64::NAN, 0.0, 0.0);
        assert_eq!(Pose::new(Matrix3::identity(), nan), Err(PoseError::NonFinite));
    }

    #[test]
    fn scaled_camera_keeps_pixel_centres() {
        let cam = camera();
        let half = cam.scaled(0.5);
        let x = Vector3::new(0.1, 0.05, 0.8);
        let p = cam.project(&x).unwrap();
        let q = half.project(&x).unwrap();
        assert!(((p.add_scalar(0.5)) * 0.5 - q.add_scalar(0.5)).norm() < 1e-12);
    }
}
