//! How well the model's shape at a pose explains the frame's shading,
//! whatever the light.
//!
//! An object of shading only has little for the check to compare: its
//! outline, and a novel view textured by keyframes that were lit
//! otherwise than the frame (their ZNCC against the frame falls from
//! 0.99 to 0.45 over a turn at right poses). A near-symmetric object can
//! then slip about its axis with its outline on the frame's edges. The
//! shading itself still tells: under a distant light (and ambient light)
//! a matte surface's brightness is a smooth function of its normal, which
//! nine spherical-harmonic terms of the normal (orders 0 to 2) capture
//! closely, clamped shadows included. At the right pose the render's
//! normals explain the frame's grey levels up to noise; at a pose turned
//! about the object's axis the normals land on the wrong pixels where the
//! shape is not symmetric, and the residual rises.
//!
//! [`shading_rms`] fits the nine terms by least squares over the view's
//! inner pixels and returns the RMS of what is left. Its absolute level
//! depends on the object (texture, gloss and noise add to it), so the
//! tracker compares it with the track's own recent frames
//! (`VerifyConfig::shading_drop`, `tracker/steady.rs`).

use crate::features::GreyImage;
use nalgebra::{SMatrix, SVector};

/// The basis's terms: 1, the normal's three components and five of
/// second order.
const TERMS: usize = 9;

/// Fewest pixels a fit is made over.
const MIN_SHADING_PIXELS: usize = 100;

/// The nine basis terms of unit normal `n` (camera frame).
fn basis(n: [f64; 3]) -> [f64; TERMS] {
    let [x, y, z] = n;
    [
        1.0,
        x,
        y,
        z,
        x * y,
        x * z,
        y * z,
        x * x - y * y,
        3.0 * z * z - 1.0,
    ]
}

/// The RMS (grey levels 0..1) of the frame's brightness left after the
/// best fit of the nine terms of the render's normals, over the inner
/// pixels of the view (with a normal, as are their four neighbours; every
/// other one, in a checkerboard): `frame` one grey level a pixel,
/// `normals` three floats a pixel of the same image (camera frame; NaN
/// where empty, as the splatter's reads give them). `None` under
/// [`MIN_SHADING_PIXELS`] such pixels with a finite frame value.
pub(crate) fn shading_rms(frame: &GreyImage, normals: &[f32]) -> Option<f64> {
    let (w, h) = (frame.width, frame.height);
    debug_assert_eq!(normals.len(), 3 * w * h);
    let covered = |i: usize| !normals[3 * i].is_nan();
    let mut sums = Sums::default();
    for y in 1..h.saturating_sub(1) {
        // Every other pixel, in a checkerboard: nine terms need far fewer
        // than an object's pixels, and the sums cost half as much.
        for x in (1 + (y + 1) % 2..w.saturating_sub(1)).step_by(2) {
            let i = y * w + x;
            let inner =
                covered(i) && covered(i - 1) && covered(i + 1) && covered(i - w) && covered(i + w);
            if !inner {
                continue;
            }
            let n = [0, 1, 2].map(|k| normals[3 * i + k] as f64);
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let b = frame.data[i] as f64;
            // Zero normals and frame values outside the image (NaN) fail
            // these.
            if len > 1e-6 && b.is_finite() {
                sums.add(&basis(n.map(|c| c / len)), b);
            }
        }
    }
    sums.rms()
}

/// The sums of the normal equations of the fit, upper triangle only, in
/// one pass (no pixel is kept).
struct Sums {
    n: f64,
    /// Upper triangle of the sum of `v vᵀ`, row by row.
    vv: [f64; TERMS * (TERMS + 1) / 2],
    vb: [f64; TERMS],
    bb: f64,
}

impl Default for Sums {
    fn default() -> Self {
        Self {
            n: 0.0,
            vv: [0.0; TERMS * (TERMS + 1) / 2],
            vb: [0.0; TERMS],
            bb: 0.0,
        }
    }
}

impl Sums {
    fn add(&mut self, v: &[f64; TERMS], b: f64) {
        self.n += 1.0;
        let mut k = 0;
        for r in 0..TERMS {
            for c in r..TERMS {
                self.vv[k] += v[r] * v[c];
                k += 1;
            }
            self.vb[r] += v[r] * b;
        }
        self.bb += b * b;
    }

    /// The RMS residual of the least-squares fit ([`shading_rms`]);
    /// `None` under [`MIN_SHADING_PIXELS`] samples.
    fn rms(&self) -> Option<f64> {
        if self.n < MIN_SHADING_PIXELS as f64 {
            return None;
        }
        let n = self.n;
        // Centred on the mean brightness (the constant term's share), so
        // that the remainder's sums do not cancel.
        let mean = self.vb[0] / n;
        let mut ata = SMatrix::<f64, TERMS, TERMS>::zeros();
        let mut k = 0;
        for r in 0..TERMS {
            for c in r..TERMS {
                ata[(r, c)] = self.vv[k];
                ata[(c, r)] = self.vv[k];
                k += 1;
            }
        }
        // Σ v (b - mean), and Σ (b - mean)².
        let sv = ata.column(0).into_owned();
        let atb = SVector::<f64, TERMS>::from(self.vb) - sv * mean;
        let sst = self.bb - n * mean * mean;
        // A view of one flat face has a single normal: the terms are then
        // collinear, and a small ridge keeps the solve defined.
        let ridge = 1e-9 * n;
        for k in 0..TERMS {
            ata[(k, k)] += ridge;
        }
        let c = ata.cholesky()?.solve(&atb);
        // The residual's sum of squares: Σ(b - mean)² - 2 cᵀ atb + cᵀ A c,
        // with A c = atb up to the ridge.
        let sse = sst - 2.0 * c.dot(&atb) + c.dot(&(ata * c)) - ridge * c.norm_squared();
        Some((sse.max(0.0) / n).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// A sphere of radius `r` px at the centre of a `w` x `w` image with a
    /// flat facet cut into it off centre (orthographic): its coverage and
    /// camera-frame normals, the whole turned about the view axis by
    /// `turn` radians (its outline, a circle, does not change).
    fn faceted(w: usize, r: f64, turn: f64) -> (Vec<bool>, Vec<f32>) {
        let mut covered = vec![false; w * w];
        let mut normals = vec![f32::NAN; 3 * w * w];
        let c = w as f64 / 2.0;
        let (s, co) = turn.sin_cos();
        for y in 0..w {
            for x in 0..w {
                // The point in the shape's own frame (turned back).
                let (px, py) = ((x as f64 - c) / r, (y as f64 - c) / r);
                let (dx, dy) = (co * px + s * py, -s * px + co * py);
                let d2 = dx * dx + dy * dy;
                if d2 >= 1.0 {
                    continue;
                }
                let on_facet = (dx - 0.45).powi(2) + dy * dy < 0.3 * 0.3;
                let n = if on_facet {
                    [0.5, 0.0, -0.866]
                } else {
                    [dx, dy, -(1.0 - d2).sqrt()]
                };
                // Back to the image's frame.
                let n = [co * n[0] - s * n[1], s * n[0] + co * n[1], n[2]];
                covered[y * w + x] = true;
                for k in 0..3 {
                    normals[3 * (y * w + x) + k] = n[k] as f32;
                }
            }
        }
        (covered, normals)
    }

    /// [`faceted`] unturned, matte under a distant light and ambient, with
    /// a printed spot the normals do not know (`spot`) and noise of
    /// `sigma` grey levels.
    fn lit(w: usize, r: f64, sigma: f64, spot: bool) -> GreyImage {
        let (covered, normals) = faceted(w, r, 0.0);
        let l = [0.5f64, -0.4, -0.768];
        let mut rng = Rng::new(7);
        let c = w as f64 / 2.0;
        GreyImage::from_fn(w, w, |x, y| {
            let i = y * w + x;
            if !covered[i] {
                return 0.2;
            }
            let n = [0, 1, 2].map(|k| normals[3 * i + k] as f64);
            let lambert = (n[0] * l[0] + n[1] * l[1] + n[2] * l[2]).max(0.0);
            let (dx, dy) = ((x as f64 - c) / r, (y as f64 - c) / r);
            let bump = if spot && (dx + 0.4).abs() < 0.25 && dy.abs() < 0.25 {
                0.2
            } else {
                0.0
            };
            (0.1 + 0.6 * lambert + bump + sigma * rng.normal()) as f32
        })
    }

    #[test]
    fn a_lit_matte_shape_leaves_its_noise_and_a_wrong_pose_more() {
        let (w, r) = (96, 40.0);
        let (_, normals) = faceted(w, r, 0.0);
        // Without noise what is left is the clamped shadow's edge, which
        // nine terms smooth: measured 0.016, under 3% of the light's gain
        // (0.6).
        let clean = shading_rms(&lit(w, r, 0.0, false), &normals).unwrap();
        assert!(clean < 0.018, "{clean}");
        // With noise of 0.01 the two add in quadrature (0.019).
        let frame = lit(w, r, 0.01, false);
        let right = shading_rms(&frame, &normals).unwrap();
        assert!(right < 0.021, "{right}");
        // The same outline turned about the view axis by 34 degrees (a
        // symmetric outline slipped): the facet's normals land where the
        // frame shows the sphere's, and the reverse. Measured 0.032.
        let (_, turned) = faceted(w, r, 0.6);
        let wrong = shading_rms(&frame, &turned).unwrap();
        assert!(wrong > 1.5 * right, "{wrong} vs {right}");
        // A spot the shape does not explain stays in the residual.
        let spotted = shading_rms(&lit(w, r, 0.01, true), &normals).unwrap();
        assert!(spotted > 2.0 * right, "{spotted} vs {right}");
    }

    #[test]
    fn the_fit_takes_any_light_and_gain() {
        // Brightness a + b.n for any a, b (and second-order terms) is
        // explained exactly.
        let (w, r) = (64, 25.0);
        let (covered, normals) = faceted(w, r, 0.0);
        let frame = GreyImage::from_fn(w, w, |x, y| {
            let i = y * w + x;
            let n = [0, 1, 2].map(|k| normals[3 * i + k]);
            if covered[i] {
                0.3 + 0.2 * n[0] - 0.1 * n[2] + 0.15 * n[0] * n[1]
            } else {
                0.0
            }
        });
        let rms = shading_rms(&frame, &normals).unwrap();
        assert!(rms < 1e-5, "{rms}");
    }

    #[test]
    fn one_flat_face_is_its_spread_and_too_few_pixels_none() {
        // One normal everywhere: the terms are collinear; the fit is the
        // mean, the RMS the frame's spread about it.
        let w = 32;
        let normals: Vec<f32> = (0..w * w).flat_map(|_| [0.0f32, 0.0, -1.0]).collect();
        let frame = GreyImage::from_fn(w, w, |x, _| if x % 2 == 0 { 0.4 } else { 0.6 });
        let rms = shading_rms(&frame, &normals).unwrap();
        assert!((rms - 0.1).abs() < 1e-6, "{rms}");
        // Under MIN_SHADING_PIXELS inner pixels (9 x 9 covered: 7 x 7
        // inner): no fit.
        let mut small = vec![f32::NAN; 3 * w * w];
        for y in 0..9 {
            for x in 0..9 {
                small[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&[0.0, 0.0, -1.0]);
            }
        }
        assert_eq!(shading_rms(&frame, &small), None);
        // Empty normals (NaN) are left out.
        let nan = vec![f32::NAN; 3 * w * w];
        assert_eq!(shading_rms(&frame, &nan), None);
    }
}
