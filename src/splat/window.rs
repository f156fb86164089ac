//! Windows of the image: where the object projects, so that the tracker
//! splats, reads, detects and matches there instead of over the whole
//! image ("only what is needed, only where it is needed").
//!
//! How it works: a [`Window`] is a pixel rectangle inside the image. A
//! render into it uses the camera shifted by the window's origin
//! ([`Window::camera`]: the principal point moves by `-origin`, nothing
//! else changes), into targets of the window's size: pixel `(x, y)` of the
//! window is pixel `(x0 + x, y0 + y)` of the full render, up to the f32
//! rounding of `u - (cx - x0)` against `(u + x0) - cx` (tests/splat_window.rs
//! checks it against the full render and the CPU reference). Depth and the
//! motion predictors depend on the camera-space point only, so they are
//! the same. [`Window::of_box`] bounds the projection of a model's
//! bounding box grown by its largest splat, so the window holds every
//! covered pixel of the full render.

use crate::geometry::{Intrinsics, Pose};
use nalgebra::Vector3;

/// A pixel rectangle of an image: columns `x0 .. x0 + width`, rows
/// `y0 .. y0 + height`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    /// First column, in pixels of the full image.
    pub x0: u32,
    /// First row, in pixels of the full image.
    pub y0: u32,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Window {
    /// The whole image of `cam`.
    pub fn full(cam: &Intrinsics) -> Self {
        Self {
            x0: 0,
            y0: 0,
            width: cam.width,
            height: cam.height,
        }
    }

    /// Whether this is the whole image of `cam`.
    pub fn is_full(&self, cam: &Intrinsics) -> bool {
        *self == Self::full(cam)
    }

    /// The camera whose image is this window of `cam`'s image.
    pub fn camera(&self, cam: &Intrinsics) -> Intrinsics {
        Intrinsics {
            width: self.width,
            height: self.height,
            cx: cam.cx - self.x0 as f64,
            cy: cam.cy - self.y0 as f64,
            ..*cam
        }
    }

    /// The origin as a pixel offset (subtract it to go from image to
    /// window coordinates).
    pub fn origin(&self) -> [f32; 2] {
        [self.x0 as f32, self.y0 as f32]
    }

    /// Number of pixels.
    pub fn area(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The window holding the pixel rectangle `[x0, x1] x [y0, y1]` (image
    /// coordinates, any real values) grown by `margin` pixels, with its
    /// origin rounded down to a multiple of `align` and its size up to one
    /// (so that grids anchored at the image origin, such as the Harris
    /// selection cells, fall on the same pixels, and few distinct sizes
    /// occur), clipped to the `width x height` image. `None` when nothing
    /// of the rectangle is in the image.
    pub fn around(
        rect: [f64; 4],
        margin: f64,
        align: u32,
        width: u32,
        height: u32,
    ) -> Option<Self> {
        let [x0, y0, x1, y1] = rect;
        if !(x0 <= x1 && y0 <= y1) || width == 0 || height == 0 {
            return None;
        }
        let (x0, y0) = ((x0 - margin).floor(), (y0 - margin).floor());
        let (x1, y1) = ((x1 + margin).ceil(), (y1 + margin).ceil());
        if x1 < 0.0 || y1 < 0.0 || x0 > (width - 1) as f64 || y0 > (height - 1) as f64 {
            return None;
        }
        let a = align.max(1);
        let clip = |v: f64, n: u32| v.clamp(0.0, (n - 1) as f64) as u32;
        let (x0, y0) = (clip(x0, width) / a * a, clip(y0, height) / a * a);
        let (x1, y1) = (clip(x1, width), clip(y1, height));
        let w = (x1 - x0 + 1).div_ceil(a) * a;
        let h = (y1 - y0 + 1).div_ceil(a) * a;
        Some(Self {
            x0,
            y0,
            width: w.min(width - x0),
            height: h.min(height - y0),
        })
    }

    /// The window holding the projection of the box `[lo, hi]` (object
    /// coordinates) at `pose`, grown by `margin` pixels and aligned as in
    /// [`Window::around`]. The whole image when a corner of the box is not
    /// in front of the camera (the projection is then unbounded); `None`
    /// when the box projects wholly outside the image.
    pub fn of_box(
        cam: &Intrinsics,
        pose: &Pose,
        lo: &Vector3<f64>,
        hi: &Vector3<f64>,
        margin: f64,
        align: u32,
    ) -> Option<Self> {
        let mut rect = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for p in box_corners(lo, hi) {
            let c = pose.transform_point(&p);
            if c.z.is_nan() || c.z <= 1e-9 * (1.0 + c.norm()) {
                return Some(Self::full(cam));
            }
            let (u, v) = (cam.fx * c.x / c.z + cam.cx, cam.fy * c.y / c.z + cam.cy);
            rect = [
                rect[0].min(u),
                rect[1].min(v),
                rect[2].max(u),
                rect[3].max(v),
            ];
        }
        if !rect.iter().all(|v| v.is_finite()) {
            return Some(Self::full(cam));
        }
        Self::around(rect, margin, align, cam.width, cam.height)
    }

    /// Rows `y0..y0+height`, columns `x0..x0+width` of a row-major image of
    /// `stride` pixels per row with `channels` values per pixel.
    pub fn crop<T: Copy>(&self, data: &[T], stride: usize, channels: usize) -> Vec<T> {
        let (x0, w) = (self.x0 as usize * channels, self.width as usize * channels);
        let mut out = Vec::with_capacity(self.area() * channels);
        for y in self.y0 as usize..(self.y0 + self.height) as usize {
            let row = y * stride * channels;
            out.extend_from_slice(&data[row + x0..row + x0 + w]);
        }
        out
    }

    /// The smallest window holding both.
    pub fn union(&self, other: &Window) -> Window {
        let x0 = self.x0.min(other.x0);
        let y0 = self.y0.min(other.y0);
        let x1 = (self.x0 + self.width).max(other.x0 + other.width);
        let y1 = (self.y0 + self.height).max(other.y0 + other.height);
        Window {
            x0,
            y0,
            width: x1 - x0,
            height: y1 - y0,
        }
    }
}

/// The eight corners of the box `[lo, hi]`.
pub(crate) fn box_corners(lo: &Vector3<f64>, hi: &Vector3<f64>) -> [Vector3<f64>; 8] {
    std::array::from_fn(|i| {
        Vector3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn around_aligns_grows_and_clips() {
        let w = Window::around([100.2, 50.0, 140.0, 70.9], 8.0, 32, 640, 480).unwrap();
        // 92..148 x 42..79, origin down to 64/32, size up to 96 x 64.
        assert_eq!(
            w,
            Window {
                x0: 64,
                y0: 32,
                width: 96,
                height: 64
            }
        );
        // Clipped at the far border: the size stops at the image.
        let w = Window::around([600.0, 440.0, 700.0, 500.0], 0.0, 32, 640, 480).unwrap();
        assert_eq!((w.x0, w.y0, w.width, w.height), (576, 416, 64, 64));
        let w = Window::around([600.0, 0.0, 700.0, 10.0], 0.0, 32, 630, 470).unwrap();
        assert_eq!((w.x0, w.width), (576, 54));
        // Wholly outside, or empty.
        assert_eq!(
            Window::around([-50.0, 0.0, -10.0, 5.0], 4.0, 32, 640, 480),
            None
        );
        assert_eq!(
            Window::around([5.0, 0.0, 1.0, 5.0], 4.0, 32, 640, 480),
            None
        );
        assert_eq!(
            Window::around([f64::NAN, 0.0, 1.0, 5.0], 4.0, 32, 640, 480),
            None
        );
    }

    #[test]
    fn camera_shifts_the_principal_point_only() {
        let cam = Intrinsics::new(640, 480, 500.0, 510.0, 320.5, 240.25);
        let w = Window {
            x0: 64,
            y0: 32,
            width: 96,
            height: 64,
        };
        let c = w.camera(&cam);
        assert_eq!((c.width, c.height, c.fx, c.fy), (96, 64, 500.0, 510.0));
        let x = Vector3::new(0.01, -0.02, 0.5);
        let a = cam.project(&x).unwrap();
        // The same point lands 64, 32 pixels further up-left (it may leave
        // the window's image, so compare the formula).
        let u = c.fx * x.x / x.z + c.cx;
        let v = c.fy * x.y / x.z + c.cy;
        assert!(
            (a.x - 64.0 - u).abs() < 1e-9 && (a.y - 32.0 - v).abs() < 1e-9,
            "{a:?}"
        );
    }

    #[test]
    fn box_window_holds_every_projected_point() {
        let cam = Intrinsics::new(640, 480, 600.0, 600.0, 320.0, 240.0);
        let (lo, hi) = (
            Vector3::new(-0.05, -0.04, -0.03),
            Vector3::new(0.05, 0.04, 0.03),
        );
        let mut rng = crate::rng::Rng::new(7);
        for _ in 0..50 {
            let r = crate::geometry::rotation_exp(&(rng.unit_vector() * rng.uniform(0.0, 3.0)));
            let t = Vector3::new(rng.uniform(-0.2, 0.2), rng.uniform(-0.15, 0.15), 0.4);
            let pose = Pose::new(r, t).unwrap();
            let Some(w) = Window::of_box(&cam, &pose, &lo, &hi, 2.0, 32) else {
                continue;
            };
            for _ in 0..200 {
                let p = Vector3::new(
                    rng.uniform(lo.x, hi.x),
                    rng.uniform(lo.y, hi.y),
                    rng.uniform(lo.z, hi.z),
                );
                if let Some(uv) = cam.project(&pose.transform_point(&p)) {
                    if uv.x >= 0.0 && uv.y >= 0.0 && uv.x <= 639.0 && uv.y <= 479.0 {
                        assert!(uv.x >= w.x0 as f64, "{uv:?} left of {w:?}");
                        assert!(uv.x <= (w.x0 + w.width - 1) as f64, "{uv:?} right of {w:?}");
                        assert!(uv.y >= w.y0 as f64, "{uv:?} above {w:?}");
                        assert!(uv.y <= (w.y0 + w.height - 1) as f64, "{uv:?} below {w:?}");
                    }
                }
            }
        }
        // Behind the camera: the whole image.
        let behind =
            Pose::new(nalgebra::Matrix3::identity(), Vector3::new(0.0, 0.0, 0.01)).unwrap();
        assert_eq!(
            Window::of_box(&cam, &behind, &lo, &hi, 2.0, 32),
            Some(Window::full(&cam))
        );
    }

    #[test]
    fn crop_takes_the_window_rows() {
        let data: Vec<u32> = (0..6 * 4 * 2).collect();
        let w = Window {
            x0: 1,
            y0: 2,
            width: 3,
            height: 2,
        };
        // 6 x 4 image, 2 channels: row 2 starts at 24, row 3 at 36.
        assert_eq!(
            w.crop(&data, 6, 2),
            vec![26, 27, 28, 29, 30, 31, 38, 39, 40, 41, 42, 43]
        );
    }
}
