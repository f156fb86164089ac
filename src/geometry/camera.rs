//! Pinhole intrinsics with OpenCV's distortion model: projection, its
//! Jacobian, the motion predictors, and frame undistortion. Camera files
//! are read by [`crate::io::camera`].

use nalgebra::{Matrix2x3, Matrix2x6, Matrix3, Vector2, Vector3};

/// Pinhole intrinsics with OpenCV's distortion model (k1, k2, p1, p2, k3).
/// Serialised as the fields below (`distortion`: five numbers), which is
/// also a valid `camera.json`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Intrinsics {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Horizontal focal length in pixels.
    pub fx: f64,
    /// Vertical focal length in pixels.
    pub fy: f64,
    /// Principal point x in pixels (OpenCV convention: centre of pixel (0,0) at 0).
    pub cx: f64,
    /// Principal point y in pixels (OpenCV convention: centre of pixel (0,0) at 0).
    pub cy: f64,
    /// OpenCV order: k1, k2, p1, p2, k3. All zero for an ideal pinhole.
    pub distortion: [f64; 5],
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

    /// Checks that the camera can exist: a positive size, finite positive
    /// focal lengths and finite coefficients.
    pub fn validate(&self) -> Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err(format!("image size {} x {}", self.width, self.height));
        }
        if self.width > 1 << 15 || self.height > 1 << 15 {
            return Err(format!(
                "image size {} x {} is too large",
                self.width, self.height
            ));
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

    /// The 3x3 camera matrix `K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }

    /// `pi(X) = (fx x/z + cx, fy y/z + cy)` for a camera-space point; `None`
    /// behind (or on) the camera plane.
    pub fn project(&self, x: &Vector3<f64>) -> Option<Vector2<f64>> {
        (x.z > 0.0)
            .then(|| Vector2::new(self.fx * x.x / x.z + self.cx, self.fy * x.y / x.z + self.cy))
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

/// Removes lens distortion from frames: a precomputed remap table from each
/// ideal-image pixel to its source position in the raw image, then bilinear
/// sampling. Build once per camera, apply per frame.
pub struct Undistorter {
    width: u32,
    height: u32,
    map: Vec<[f32; 2]>,
}

impl Undistorter {
    /// Builds the remap table for `cam`'s image size and distortion.
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
    // x, y >= 0: truncation is the floor (and inlined, unlike `floor`).
    let (x0, y0) = (x as i64, y as i64);
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let p = |xx: i64, yy: i64| img.get_pixel(xx as u32, yy as u32).0;
    let (a, b, c, d) = (p(x0, y0), p(x1, y0), p(x0, y1), p(x1, y1));
    let mut out = [0u8; 3];
    for k in 0..3 {
        let top = a[k] as f32 * (1.0 - fx) + b[k] as f32 * fx;
        let bot = c[k] as f32 * (1.0 - fx) + d[k] as f32 * fx;
        out[k] = round_to_u8(top * (1.0 - fy) + bot * fy);
    }
    Some(image::Rgb(out))
}

/// `v.round().clamp(0.0, 255.0) as u8` for `v` in about [0, 255] (a convex
/// combination of bytes), without the library call `round` is on x86-64
/// without SSE4.1: the same value (halves away from zero; the fraction
/// `v - trunc(v)` is exact in f32 below 2^23).
fn round_to_u8(v: f32) -> u8 {
    let t = v as i32;
    let r = t + i32::from(v - t as f32 >= 0.5);
    r.clamp(0, 255) as u8
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Pose, look_at};
    use crate::rng::Rng;
    use nalgebra::Vector6;

    fn camera() -> Intrinsics {
        Intrinsics::new(640, 480, 572.4, 573.6, 325.3, 242.0)
    }

    /// Checks `analytic` against the central difference of `f` (a pixel
    /// position as a function of a step along one direction) at 0.
    fn assert_derivative(analytic: Vector2<f64>, f: impl Fn(f64) -> Vector2<f64>, what: &str) {
        let h = 1e-6;
        let fd = (f(h) - f(-h)) / (2.0 * h);
        let rel = (fd - analytic).norm() / (1.0 + analytic.norm());
        assert!(rel < 1e-6, "{what}: fd {fd} vs {analytic}");
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
            for k in 0..3 {
                let f = |h| cam.project(&(x + Vector3::ith(k, h))).unwrap();
                assert_derivative(j.column(k).into(), f, &format!("column {k}"));
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
            for j in 0..6 {
                let f = |h| {
                    cam.project(&Pose::exp(&Vector6::ith(j, h)).transform_point(&x))
                        .unwrap()
                };
                assert_derivative(l.column(j).into(), f, &format!("predictor {j}"));
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
        let raw =
            image::RgbImage::from_fn(64, 48, |x, y| image::Rgb([x as u8 * 3, y as u8 * 5, 0]));
        let und = Undistorter::new(&cam).apply(&raw).unwrap();
        let uv = Vector2::new(10.0, 8.0);
        let src = cam.distort_pixel(uv);
        let px = und.get_pixel(10, 8).0;
        assert!((px[0] as f64 / 3.0 - src.x).abs() < 0.5, "{px:?} vs {src}");
        assert!((px[1] as f64 / 5.0 - src.y).abs() < 0.5, "{px:?} vs {src}");
        assert!(
            Undistorter::new(&cam)
                .apply(&image::RgbImage::new(10, 10))
                .is_err()
        );
    }

    #[test]
    fn serde_roundtrip() {
        let mut cam = camera();
        cam.distortion = [-0.28, 0.09, 0.001, -0.0005, -0.01];
        let text = serde_json::to_string(&cam).unwrap();
        assert_eq!(serde_json::from_str::<Intrinsics>(&text).unwrap(), cam);
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

    #[test]
    fn rounding_to_a_byte_is_the_librarys_round() {
        let reference = |v: f32| v.round().clamp(0.0, 255.0) as u8;
        // Every f32 from -2 to 258 in steps of 2^-10 (the halves and their
        // neighbours included), then the neighbours of each half exactly.
        let mut v = -2.0f32;
        while v <= 258.0 {
            assert_eq!(round_to_u8(v), reference(v), "{v}");
            v += 1.0 / 1024.0;
        }
        for k in -4..=516 {
            let h = k as f32 * 0.5;
            for x in [h, h.next_up(), h.next_down()] {
                assert_eq!(round_to_u8(x), reference(x), "{x}");
            }
        }
        assert_eq!(round_to_u8(f32::NAN), reference(f32::NAN));
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
        let c = cam
            .project(&p.transform_point(&Vector3::new(0.01, 0.02, 0.03)))
            .unwrap();
        assert!((c - Vector2::new(cam.cx, cam.cy)).norm() < 1e-9);
        // Object "up" (+z) appears upwards in the image (smaller v).
        let up = cam
            .project(&p.transform_point(&Vector3::new(0.01, 0.02, 0.13)))
            .unwrap();
        assert!(up.y < c.y);
    }
}
