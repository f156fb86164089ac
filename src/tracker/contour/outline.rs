//! The silhouette of a splatted coverage: its points, their outward
//! normals and sub-pixel edge positions ([`extract_contour`]), moved
//! inward by the splatter's blur ([`inset`]), and the exact normals of
//! limbs ([`limb_normals`]).

use nalgebra::Vector2;

/// Half-width of the window giving a contour point's normal and offset
/// (pixels; the host's [`extract_contour`] and the GPU's outline alike,
/// shared with shaders/outline.wgsl).
pub const OUTLINE_WINDOW: u32 = 5;

/// Least length of a contour point's offset sum over its window: a
/// straight edge through the centre gives 330 (11 x 11); thin parts and
/// corners give less, and their normal is unreliable.
pub const OUTLINE_MIN_GRADIENT: u32 = 120;

/// A point of the splatted silhouette.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContourPoint {
    /// The covered pixel on the silhouette (where the predictors are read).
    pub pixel: [u32; 2],
    /// The sub-pixel edge position, OpenCV pixel coordinates.
    pub position: Vector2<f64>,
    /// The unit image normal, pointing out of the object.
    pub normal: Vector2<f64>,
}

/// Half-width of the window giving a contour point's normal and offset.
const WINDOW: i64 = OUTLINE_WINDOW as i64;

/// The silhouette of a coverage mask (`width x height`, row-major), one
/// point per `spacing x spacing` cell (the first silhouette pixel of the
/// cell in raster order). Pixels beyond the image count as covered, so an
/// object cut by the image border has no contour there (that edge is not
/// the object's).
pub fn extract_contour(
    coverage: &[bool],
    width: usize,
    height: usize,
    spacing: usize,
) -> Vec<ContourPoint> {
    assert_eq!(coverage.len(), width * height, "coverage size");
    let spacing = spacing.max(1);
    let at = |x: i64, y: i64| -> bool {
        if x < 0 || y < 0 || x >= width as i64 || y >= height as i64 {
            true
        } else {
            coverage[y as usize * width + x as usize]
        }
    };
    let (cw, ch) = (width.div_ceil(spacing), height.div_ceil(spacing));
    let mut taken = vec![false; cw * ch];
    let mut out = Vec::new();
    for y in 0..height as i64 {
        for x in 0..width as i64 {
            if !at(x, y) || (at(x - 1, y) && at(x + 1, y) && at(x, y - 1) && at(x, y + 1)) {
                continue;
            }
            let cell = (y as usize / spacing) * cw + x as usize / spacing;
            if taken[cell] {
                continue;
            }
            let (mut gx, mut gy, mut covered) = (0i64, 0i64, 0u32);
            for dy in -WINDOW..=WINDOW {
                for dx in -WINDOW..=WINDOW {
                    if at(x + dx, y + dy) {
                        gx += dx;
                        gy += dy;
                        covered += 1;
                    }
                }
            }
            // |g| < the least (exact in integers): a thin part or a corner,
            // whose normal is unreliable.
            let least = OUTLINE_MIN_GRADIENT as i64;
            if gx * gx + gy * gy < least * least {
                continue;
            }
            taken[cell] = true;
            out.push(contour_point(x as u32, y as u32, gx, gy, covered));
        }
    }
    out
}

/// The contour point of silhouette pixel `(x, y)` whose window
/// ([`extract_contour`]'s, `WINDOW` pixels either side) holds `covered`
/// covered pixels, their offsets from `(x, y)` summing to `(gx, gy)`: the
/// normal is the sums' direction, turned outward, and the covered fraction
/// of the window locates a straight edge along it (its chord at the centre
/// is side / max(|nx|, |ny|)).
pub(crate) fn contour_point(x: u32, y: u32, gx: i64, gy: i64, covered: u32) -> ContourPoint {
    let (gx, gy) = (gx as f64, gy as f64);
    let g = (gx * gx + gy * gy).sqrt();
    let normal = Vector2::new(-gx / g, -gy / g);
    let side = (2 * WINDOW + 1) as f64;
    let offset = (covered as f64 / (side * side) - 0.5) * side * normal.x.abs().max(normal.y.abs());
    ContourPoint {
        pixel: [x, y],
        position: Vector2::new(x as f64, y as f64) + normal * offset,
        normal,
    }
}

/// Moves each point `px` pixels inward along its normal: the splatted
/// coverage extends past the object's outline by about the splatter's
/// low-pass radius (measured 0.65 px on the synthetic `plain` object
/// against its exact rasterised outline, and on the analytic sphere of
/// tests/contour.rs).
pub fn inset(points: &mut [ContourPoint], px: f64) {
    for p in points {
        p.position -= p.normal * px;
    }
}

/// Replaces the coverage-gradient normal of each point on an occluding
/// contour (a limb: the splatted surface normal `N` there is nearly
/// perpendicular to the viewing ray) by the exact one: the surface's
/// tangent plane there contains the ray, so it projects onto the contour's
/// tangent line, whose image normal is `(N_x / f_x, N_y / f_y)`. Crease
/// outlines (a box's edges, where `N` faces the camera) keep theirs.
/// `normals`: the splatted normals (3 channels, NaN where empty).
pub fn limb_normals(
    cam: &crate::geometry::Intrinsics,
    normals: &crate::splat::SplatImage,
    points: &mut [ContourPoint],
) {
    limb_normals_with(cam, points, false, |p| {
        let nv = normals.pixel(p.pixel[0], p.pixel[1]);
        Some(nalgebra::Vector3::new(
            nv[0] as f64,
            nv[1] as f64,
            nv[2] as f64,
        ))
    });
}

/// [`limb_normals`] with the camera-space surface normal at each point
/// given by `normal_at` (`None`: keep the point's normal). `perpendicular`:
/// a limb's normal is taken perpendicular to the ray (the part along the
/// ray removed), as it is by definition: a mean of the normals around the
/// limb ([`super::ModelNormals`]) leans towards the camera, which would tilt the
/// image normal towards or away from the principal point.
pub fn limb_normals_with(
    cam: &crate::geometry::Intrinsics,
    points: &mut [ContourPoint],
    perpendicular: bool,
    mut normal_at: impl FnMut(&ContourPoint) -> Option<nalgebra::Vector3<f64>>,
) {
    for p in points {
        let Some(n3) = normal_at(p) else {
            continue;
        };
        if !n3.iter().all(|v| v.is_finite()) || n3.norm() < 0.5 {
            continue;
        }
        let ray = cam
            .unproject(&Vector2::new(p.pixel[0] as f64, p.pixel[1] as f64), 1.0)
            .normalize();
        if n3.normalize().dot(&ray).abs() > 0.3 {
            continue;
        }
        let n3 = if perpendicular {
            n3 - ray * n3.dot(&ray)
        } else {
            n3
        };
        let img = Vector2::new(n3.x / cam.fx, n3.y / cam.fy);
        if img.norm() < 1e-12 {
            continue;
        }
        let img = img.normalize();
        // Only a refinement: a normal far from the outline's is a sign of
        // a mixed pixel, keep the coverage's then.
        if img.dot(&p.normal) > 0.9 {
            p.normal = img;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A disc of radius 40 centred at (60.3, 50.7) in a 128x100 mask.
    fn disc() -> (Vec<bool>, usize, usize, Vector2<f64>, f64) {
        let (w, h) = (128, 100);
        let c = Vector2::new(60.3, 50.7);
        let r = 40.0;
        let m = (0..w * h)
            .map(|i| (Vector2::new((i % w) as f64, (i / w) as f64) - c).norm() <= r)
            .collect();
        (m, w, h, c, r)
    }

    #[test]
    fn contour_of_a_disc_lies_on_its_circle_with_radial_normals() {
        let (m, w, h, c, r) = disc();
        let pts = extract_contour(&m, w, h, 6);
        assert!(pts.len() > 30, "{} points", pts.len());
        let mut err = 0.0f64;
        let mut worst_angle = 0.0f64;
        for p in &pts {
            let radial = (p.position - c).normalize();
            worst_angle = worst_angle.max(radial.dot(&p.normal).clamp(-1.0, 1.0).acos());
            err += ((p.position - c).norm() - r).abs();
        }
        err /= pts.len() as f64;
        assert!(err < 0.3, "mean distance to the circle {err:.3} px");
        assert!(worst_angle < 0.2, "normal off by {worst_angle:.3} rad");
    }

    #[test]
    fn the_image_border_is_not_a_contour() {
        let (w, h) = (40, 40);
        // The object covers the left half, cut by the image's left border.
        let m: Vec<bool> = (0..w * h).map(|i| i % w < 20).collect();
        let pts = extract_contour(&m, w, h, 1);
        assert!(!pts.is_empty());
        assert!(pts.iter().all(|p| p.pixel[0] == 19), "{pts:?}");
        // Away from the corners, the normal is +x and the edge lies half-way
        // between the last covered pixel and the first empty one.
        let inner: Vec<_> = pts
            .iter()
            .filter(|p| p.pixel[1] > 5 && p.pixel[1] < 34)
            .collect();
        assert!(!inner.is_empty());
        assert!(
            inner
                .iter()
                .all(|p| (p.normal - Vector2::new(1.0, 0.0)).norm() < 1e-9)
        );
        assert!(inner.iter().all(|p| (p.position.x - 19.5).abs() < 1e-9));
    }
}
