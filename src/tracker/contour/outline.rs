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

/// Most pixels of a contour point's window that may disagree with the
/// straight edge its position and normal describe ([`straight_edges`]).
pub const OUTLINE_MAX_MISMATCH: u32 = 7;

/// Keeps the points whose window is one straight edge: the half-plane
/// through the point's sub-pixel position, across its normal, predicts the
/// coverage of all but [`OUTLINE_MAX_MISMATCH`] pixels of the window
/// (`covered(x, y)`: the coverage, in the points' pixel coordinates,
/// covered beyond the image as in [`extract_contour`]). Near a corner the
/// window holds two edges and its covered fraction places the point up to
/// 2 px inside the outline (on the box's corners, measured against the
/// exact outline); such points pull the fit towards a larger outline, so
/// the object towards the camera. Call it before [`inset`].
pub fn straight_edges(points: &mut Vec<ContourPoint>, covered: impl Fn(i64, i64) -> bool) {
    points.retain(|p| straight_edge(p, &covered));
}

/// Whether `p`'s window is one straight edge ([`straight_edges`]).
pub fn straight_edge(p: &ContourPoint, covered: impl Fn(i64, i64) -> bool) -> bool {
    let (x, y) = (p.pixel[0] as i64, p.pixel[1] as i64);
    let mut mismatch = 0;
    for dy in -WINDOW..=WINDOW {
        for dx in -WINDOW..=WINDOW {
            let q = Vector2::new((x + dx) as f64, (y + dy) as f64);
            let inside = (q - p.position).dot(&p.normal) <= 0.0;
            if inside != covered(x + dx, y + dy) {
                mismatch += 1;
            }
        }
    }
    mismatch <= OUTLINE_MAX_MISMATCH
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

/// Moves each point inward by its own amount (`px[i]` pixels for point
/// `i`): [`inset`] point by point.
pub fn inset_each(points: &mut [ContourPoint], px: &[f64]) {
    assert_eq!(points.len(), px.len(), "one inset a point");
    for (p, px) in points.iter_mut().zip(px) {
        p.position -= p.normal * *px;
    }
}

/// How far the splatted coverage reaches past a crease (a face that ends
/// at the outline, facing the camera there), pixels, for splats of radius
/// `radius_px` pixels there, points as dense as `sampling_px` says (the
/// radius of their density, [`super::ModelNormals::sampling_radius`], in
/// pixels) and the splatter's low-pass radius `lowpass_px`. Each splat
/// covers its disc and the low-pass disc round its centre. Dense points:
/// the low-pass discs reach past the edge, less what the outermost
/// centres' places inside it and the dips between their discs take, which
/// grows as the square of their spacing (`lowpass - CREASE_DIP s^2 /
/// lowpass`). Large splats: their discs reach past the edge by a share of
/// their radius (`CREASE_DISC r`). Fitted to the untextured box sampled
/// with 12k to 800k points at 0.55 m (0.3 to 2.5 px), the tracker's splat
/// radii raised to 1 px, so that the contour tracks it without a bias
/// along the viewing ray (docs/contour.md, "Depth"). A limb (the surface
/// folding away at the outline, its splats seen edge-on and crowding
/// there) takes nearly the whole low-pass radius instead
/// ([`ContourConfig::inset_px`](super::ContourConfig::inset_px)).
pub fn crease_inset(radius_px: f64, sampling_px: f64, lowpass_px: f64) -> f64 {
    let s = sampling_px.max(0.0);
    (lowpass_px - CREASE_DIP * s * s / lowpass_px.max(1e-6)).max(CREASE_DISC * radius_px.max(0.0))
}

/// What the gaps between the outermost splats of a crease take off the
/// low-pass radius, per squared sampling radius over the low-pass radius
/// ([`crease_inset`]).
const CREASE_DIP: f64 = 0.17;

/// How far a large splat's coverage reaches past a crease, in splat radii
/// ([`crease_inset`]).
const CREASE_DISC: f64 = 0.38;

/// Least `|N . ray|` (the unit surface normal against the unit viewing
/// ray) of a point that takes [`crease_inset`]: every point that is no
/// limb. Higher cut-offs leave more of a box's crease points with the
/// limb's inset and its depth bias back (0.7: 0.42% of the untextured
/// box's diameter against 0.19%, its points 0.126 px inside the exact
/// outline against 0.067 px); on the real dragon, whose detailed outline
/// has limbs with leaning mean normals, any cut-off from 0.3 to 0.7 moved
/// its figures within their noise only (docs/contour.md).
pub const CREASE_FACING: f64 = 0.3;

/// Each point's inset, pixels: `limb_px` on limbs (and where `creases`
/// says nothing), [`crease_inset`] on creases, for splats of radius
/// `radius` and points of sampling radius `sampling` (model units) at the
/// point's camera depth `depths[i]` seen with focal length `fx` pixels.
pub fn insets(
    creases: &[bool],
    depths: &[f32],
    (radius, sampling): (f64, f64),
    fx: f64,
    limb_px: f64,
    lowpass_px: f64,
) -> Vec<f64> {
    depths
        .iter()
        .enumerate()
        .map(|(i, &z)| {
            if creases.get(i).copied().unwrap_or(false) && z > 0.0 {
                let px = fx / z as f64;
                crease_inset(radius * px, sampling * px, lowpass_px)
            } else {
                limb_px
            }
        })
        .collect()
}

/// Replaces the coverage-gradient normal of each point on an occluding
/// contour (a limb: the splatted surface normal `N` there is nearly
/// perpendicular to the viewing ray) by the exact one: the surface's
/// tangent plane there contains the ray, so it projects onto the contour's
/// tangent line, whose image normal is `(N_x / f_x, N_y / f_y)`. Crease
/// outlines (a box's edges, where `N` faces the camera) keep theirs.
/// `normals`: the splatted normals (3 channels, NaN where empty). Returns,
/// per point, whether it lies on a crease.
pub fn limb_normals(
    cam: &crate::geometry::Intrinsics,
    normals: &crate::splat::SplatImage,
    points: &mut [ContourPoint],
) -> Vec<bool> {
    limb_normals_with(cam, points, false, |p| {
        let nv = normals.pixel(p.pixel[0], p.pixel[1]);
        Some(nalgebra::Vector3::new(
            nv[0] as f64,
            nv[1] as f64,
            nv[2] as f64,
        ))
    })
}

/// [`limb_normals`] with the camera-space surface normal at each point
/// given by `normal_at` (`None`: keep the point's normal). `perpendicular`:
/// a limb's normal is taken perpendicular to the ray (the part along the
/// ray removed), as it is by definition: a mean of the normals around the
/// limb ([`super::ModelNormals`]) leans towards the camera, which would tilt the
/// image normal towards or away from the principal point. Returns, per
/// point, whether it takes the crease inset (`|N . ray|` over
/// `CREASE_FACING`; `false` where `N` is unknown). Points with
/// `|N . ray|` over 0.3 keep their coverage normal either way.
pub fn limb_normals_with(
    cam: &crate::geometry::Intrinsics,
    points: &mut [ContourPoint],
    perpendicular: bool,
    mut normal_at: impl FnMut(&ContourPoint) -> Option<nalgebra::Vector3<f64>>,
) -> Vec<bool> {
    let mut creases = vec![false; points.len()];
    for (p, crease) in points.iter_mut().zip(&mut creases) {
        let Some(n3) = normal_at(p) else {
            continue;
        };
        if !n3.iter().all(|v| v.is_finite()) || n3.norm() < 0.5 {
            continue;
        }
        let ray = cam
            .unproject(&Vector2::new(p.pixel[0] as f64, p.pixel[1] as f64), 1.0)
            .normalize();
        let facing = n3.normalize().dot(&ray).abs();
        if facing > 0.3 {
            *crease = facing > CREASE_FACING;
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
    creases
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

    /// An edge: its unit outward normal `n` and offset `o` (`n . x = o`).
    type Edge = (Vector2<f64>, f64);

    /// A square of side 60 turned by `turn` radians about (64, 50) +
    /// `shift` in a 128x100 mask, and its four edges as (unit outward
    /// normal, offset: the edge is `n . x = offset`).
    fn square(turn: f64, shift: (f64, f64)) -> (Vec<bool>, usize, usize, Vec<Edge>) {
        let (w, h) = (128, 100);
        let c = Vector2::new(64.0 + shift.0, 50.0 + shift.1);
        let edges: Vec<Edge> = (0..4)
            .map(|k| {
                let a = turn + k as f64 * std::f64::consts::FRAC_PI_2;
                let n = Vector2::new(a.cos(), a.sin());
                (n, n.dot(&c) + 30.0)
            })
            .collect();
        let m = (0..w * h)
            .map(|i| {
                let q = Vector2::new((i % w) as f64, (i / w) as f64);
                edges.iter().all(|(n, o)| n.dot(&q) <= *o)
            })
            .collect();
        (m, w, h, edges)
    }

    /// Squares turned by 0 to 45 degrees at three sub-pixel places, a
    /// point per 2x2 cell: before, the points near the corners lie up
    /// to 2 px inside and pull the mean 0.17 px inside; kept, the points lie
    /// on the edges (mean -0.01 px; at most 0.45 px off, the quantisation
    /// of an axis-aligned edge's pixel centres), and 84% are kept.
    #[test]
    fn corner_points_are_dropped_and_the_rest_lie_on_the_edges() {
        let (mut before, mut after) = (Vec::new(), Vec::new());
        for turn in [0.0, 0.1, 0.35, 0.62, 0.785] {
            for shift in [(0.13, 0.71), (0.52, 0.37), (0.91, 0.05)] {
                let (m, w, h, edges) = square(turn, shift);
                // Signed: positive where the point lies inside its edge.
                let off = |p: &ContourPoint| {
                    edges
                        .iter()
                        .map(|(n, o)| o - n.dot(&p.position))
                        .min_by(|a, b| a.abs().total_cmp(&b.abs()))
                        .expect("four edges")
                };
                let mut pts = extract_contour(&m, w, h, 2);
                before.extend(pts.iter().map(off));
                straight_edges(&mut pts, |x, y| {
                    x < 0
                        || y < 0
                        || x >= w as i64
                        || y >= h as i64
                        || m[y as usize * w + x as usize]
                });
                after.extend(pts.iter().map(off));
            }
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let worst = |v: &[f64]| v.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        assert!(
            mean(&before) > 0.1 && worst(&before) > 1.5,
            "no corner error to remove: mean {:.3}, worst {:.3}",
            mean(&before),
            worst(&before)
        );
        assert!(mean(&after).abs() < 0.04, "mean {:.3} px", mean(&after));
        assert!(worst(&after) < 0.5, "a point {:.3} px off", worst(&after));
        assert!(
            after.len() * 10 >= before.len() * 8,
            "{} of {} points kept",
            after.len(),
            before.len()
        );
    }

    #[test]
    fn a_gently_curved_outline_keeps_its_points() {
        let (m, w, h, _, _) = disc();
        let mut pts = extract_contour(&m, w, h, 2);
        let all = pts.len();
        straight_edges(&mut pts, |x, y| {
            x < 0 || y < 0 || x >= w as i64 || y >= h as i64 || m[y as usize * w + x as usize]
        });
        assert!(pts.len() * 10 >= all * 9, "{} of {all} kept", pts.len());
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
