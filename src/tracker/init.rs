//! Automatic initialisation and re-detection: find
//! the object anywhere in a frame without a prior pose.
//!
//! 1. Viewpoints: the keyframes' own poses, each also tilted four ways by
//!    [`InitConfig::keyframe_tilt_deg`], plus [`InitConfig::sphere`]
//!    directions spread over the viewing sphere (a Fibonacci lattice), each
//!    at [`InitConfig::rolls`] turns about the line of sight, all at the
//!    keyframes' median distance (else the distance at which the object
//!    spans a third of the image), the object centred.
//! 2. Templates: each viewpoint splatted with the closest keyframe's
//!    texture at twice the coarse resolution (the object spans about
//!    2 x [`InitConfig::template_px`] pixels), then view and coverage
//!    shrunk by 2 so the object spans about [`InitConfig::template_px`]
//!    pixels (the full-size render the frame is shrunk from would cost
//!    the square of the shrink factor more), from the model thinned to
//!    about [`TEMPLATE_POINTS`] points with radii grown to cover the same
//!    surface (the object is a few dozen pixels wide there; splatting every
//!    point would cost the search most of its time).
//! 3. Search: each template, at three scales, over every position of the
//!    frame shrunk alike ([`best_positions`], pure CPU), scored by the
//!    masked ZNCC of its texture and by how well its silhouette lies on
//!    the frame's edges ([`EdgeMap`]).
//! 4. The best [`InitConfig::candidates`] hits become poses (the template's
//!    pose turned so its centre lies on the hit's line of sight, at the
//!    distance the scale gives; a place refined at most twice), are
//!    refined by the tracker's own KF step (wide search first), else by
//!    the outline where the contour modality is on, and the best to pass
//!    [`super::verify`] (by ZNCC) is the answer; none: not found. On an
//!    object whose views show shading only, a candidate refined by the
//!    outline alone passes [`super::verify::judge_outline_candidate`], and
//!    its start is held for [`InitConfig::confirm_frames`] frames that
//!    must track consistently before it is reported.

use crate::geometry::rotation_exp;
use crate::model::PointModel;
use nalgebra::{Matrix3, Vector3};

/// Points of the model the templates are splatted from.
pub const TEMPLATE_POINTS: usize = 4000;

/// `model` thinned to about `target` points (every n-th), radii grown by
/// the square root of n so the splats still cover the surface; also the
/// indices kept.
pub fn thinned(model: &PointModel, target: usize) -> (PointModel, Vec<usize>) {
    let step = (model.len() / target.max(1)).max(1);
    let idx: Vec<usize> = (0..model.len()).step_by(step).collect();
    let grow = (step as f32).sqrt();
    let thin = PointModel {
        positions: idx.iter().map(|&i| model.positions[i]).collect(),
        normals: idx.iter().map(|&i| model.normals[i]).collect(),
        radii: idx.iter().map(|&i| model.radii[i] * grow).collect(),
        colors: model
            .colors
            .as_ref()
            .map(|c| idx.iter().map(|&i| c[i]).collect()),
        provenance: model.provenance.clone(),
    };
    (thin, idx)
}

/// Settings of the search.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct InitConfig {
    /// Directions over the viewing sphere (besides the keyframes').
    pub sphere: usize,
    /// Turns about the line of sight per direction.
    pub rolls: usize,
    /// Each keyframe's viewpoint is also tried tilted by this angle up,
    /// down, left and right, degrees (0: not).
    pub keyframe_tilt_deg: f64,
    /// Size the object is shrunk to for the search, pixels.
    pub template_px: f64,
    /// Coarse hits refined and verified.
    pub candidates: usize,
    /// KF steps refining each candidate.
    pub refine_steps: usize,
    /// After this many lost frames in a row, and every as many after,
    /// search the whole frame again (0: never).
    pub redetect_after_lost: usize,
    /// The detection by features tried before the templates.
    pub detect: super::detect::config::DetectConfig,
    /// Frames a start found by the outline alone, of an object whose
    /// views show shading only, is held: tracked but
    /// reported `lost` (`confirming`), each turning at most
    /// [`InitConfig::confirm_max_turn_deg`] from the last and passing the
    /// search's check, before the next is reported `tracking`. 0: none.
    pub confirm_frames: usize,
    /// The most a held start may turn from one frame to the next, degrees
    /// (the synthetic Fig. 10 trajectory turns up to 7.5 a frame; the
    /// outline slipping onto clutter turned 16-26).
    pub confirm_max_turn_deg: f64,
}

impl Default for InitConfig {
    fn default() -> Self {
        Self {
            sphere: 16,
            rolls: 4,
            keyframe_tilt_deg: 15.0,
            template_px: 24.0,
            candidates: 6,
            refine_steps: 3,
            redetect_after_lost: 5,
            detect: super::detect::config::DetectConfig::default(),
            confirm_frames: 2,
            confirm_max_turn_deg: 12.0,
        }
    }
}

/// A coarse hit: template `view`, scale, position (top-left, coarse
/// pixels), score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Index of the viewpoint.
    pub view: usize,
    /// Template scale.
    pub scale: f64,
    /// Top-left corner of the scaled template in the coarse frame.
    pub x: usize,
    /// See `x`.
    pub y: usize,
    /// Masked ZNCC.
    pub score: f64,
    /// Top-left corner of the template's crop in the coarse view.
    pub origin: (usize, usize),
}

/// Box-filter shrink by an integer factor.
pub fn shrink(img: &[f32], w: usize, h: usize, f: usize) -> (Vec<f32>, usize, usize) {
    let (cw, ch) = (w / f, h / f);
    let mut out = vec![0.0f32; cw * ch];
    for y in 0..ch {
        for x in 0..cw {
            let mut s = 0.0;
            for dy in 0..f {
                for dx in 0..f {
                    s += img[(y * f + dy) * w + x * f + dx];
                }
            }
            out[y * cw + x] = s / (f * f) as f32;
        }
    }
    (out, cw, ch)
}

/// A masked template: its samples (dx, dy, value), size.
#[derive(Debug, Clone)]
pub struct Template {
    /// Offsets from the top-left and values of the covered samples.
    pub samples: Vec<(usize, usize, f32)>,
    /// Offsets and unit normals of the samples on the silhouette (covered,
    /// with an uncovered 4-neighbour).
    pub edges: Vec<(usize, usize, [f32; 2])>,
    /// Width, coarse pixels.
    pub w: usize,
    /// Height, coarse pixels.
    pub h: usize,
}

impl Template {
    /// The template from a coarse view and coverage (0..1, kept above
    /// 0.75), cropped to the covered box and scaled by `scale` (nearest);
    /// `None` under 12 samples. Also returns the crop's top-left corner.
    pub fn new(
        view: &[f32],
        cover: &[f32],
        w: usize,
        h: usize,
        scale: f64,
    ) -> Option<(Self, (usize, usize))> {
        let on = |x: usize, y: usize| cover[y * w + x] > 0.75;
        let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
        for y in 0..h {
            for x in 0..w {
                if on(x, y) {
                    (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
                }
            }
        }
        if x0 > x1 {
            return None;
        }
        let tw = (((x1 - x0 + 1) as f64) * scale).round().max(1.0) as usize;
        let th = (((y1 - y0 + 1) as f64) * scale).round().max(1.0) as usize;
        // Coverage off the image counts as uncovered.
        let at = |x: isize, y: isize| {
            let inside = x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h;
            if inside && on(x as usize, y as usize) {
                1.0f32
            } else {
                0.0
            }
        };
        let mut samples = Vec::new();
        let mut edges = Vec::new();
        for ty in 0..th {
            for tx in 0..tw {
                let sx = x0 + ((tx as f64 + 0.5) / scale) as usize;
                let sy = y0 + ((ty as f64 + 0.5) / scale) as usize;
                if sx <= x1 && sy <= y1 && on(sx, sy) {
                    samples.push((tx, ty, view[sy * w + sx]));
                    let (x, y) = (sx as isize, sy as isize);
                    let border = [(1, 0), (-1, 0), (0, 1), (0, -1)]
                        .iter()
                        .any(|(dx, dy)| at(x + dx, y + dy) == 0.0);
                    // The outward normal: down the coverage gradient.
                    let n = [at(x - 1, y) - at(x + 1, y), at(x, y - 1) - at(x, y + 1)];
                    let len = n[0].hypot(n[1]);
                    if border && len > 0.0 {
                        edges.push((tx, ty, [n[0] / len, n[1] / len]));
                    }
                }
            }
        }
        (samples.len() >= 12).then_some((
            Self {
                samples,
                edges,
                w: tw,
                h: th,
            },
            (x0, y0),
        ))
    }
}

/// A gradient step (grey levels per coarse pixel) below which a pixel of
/// an [`EdgeMap`] holds no edge.
pub const MIN_EDGE: f32 = 0.01;

/// The weight of the silhouette term in a template's score (the masked
/// ZNCC has the rest).
pub const EDGE_WEIGHT: f64 = 0.5;

/// Where a coarse image has edges: per pixel the unit gradient direction
/// of the strongest gradient in its 3x3 neighbourhood (so that a
/// silhouette a pixel off still meets it), zero where every gradient there
/// is under [`MIN_EDGE`].
#[derive(Debug, Clone)]
pub struct EdgeMap {
    /// Width, pixels.
    pub w: usize,
    /// Height, pixels.
    pub h: usize,
    /// Row-major unit directions, or zero.
    pub dir: Vec<[f32; 2]>,
}

impl EdgeMap {
    /// The edges of `img` (`w` x `h`, row-major), by central differences;
    /// none where `img` is not `w` x `h`.
    pub fn new(img: &[f32], w: usize, h: usize) -> Self {
        let mut grad = vec![[0.0f32; 3]; w * h];
        if img.len() != w * h {
            return Self {
                w,
                h,
                dir: vec![[0.0; 2]; w * h],
            };
        }
        for y in 1..h.saturating_sub(1) {
            for x in 1..w.saturating_sub(1) {
                let gx = 0.5 * (img[y * w + x + 1] - img[y * w + x - 1]);
                let gy = 0.5 * (img[(y + 1) * w + x] - img[(y - 1) * w + x]);
                grad[y * w + x] = [gx, gy, gx.hypot(gy)];
            }
        }
        let mut dir = vec![[0.0f32; 2]; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut best = [0.0f32; 3];
                for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for xx in x.saturating_sub(1)..(x + 2).min(w) {
                        let g = grad[yy * w + xx];
                        if g[2] > best[2] {
                            best = g;
                        }
                    }
                }
                if best[2] >= MIN_EDGE {
                    dir[y * w + x] = [best[0] / best[2], best[1] / best[2]];
                }
            }
        }
        Self { w, h, dir }
    }
}

/// A template's score at each position of a coarse frame `img` (`w` x `h`)
/// where it fits: the masked ZNCC of its texture, blended with
/// [`EDGE_WEIGHT`] of how well its silhouette lies on the frame's edges
/// (the mean of `|n . d|` over the silhouette samples, `n` their normal
/// and `d` the edge direction of `edges` there: a silhouette is an edge
/// whatever the background, of either polarity). The texture alone ranks
/// clutter of the right grey levels above the object turned 20 degrees
/// from every template; the silhouette does not move with the texture.
/// Returns the best `keep` positions, at least `t.w / 2` apart, best
/// first: (x, y, score).
pub fn best_positions(
    t: &Template,
    img: &[f32],
    edges: &EdgeMap,
    w: usize,
    h: usize,
    keep: usize,
) -> Vec<(usize, usize, f64)> {
    if t.w > w || t.h > h || t.samples.is_empty() || edges.dir.len() != w * h {
        return Vec::new();
    }
    let n = t.samples.len() as f64;
    let mean_t = t.samples.iter().map(|s| s.2 as f64).sum::<f64>() / n;
    let var_t: f64 = t
        .samples
        .iter()
        .map(|s| (s.2 as f64 - mean_t).powi(2))
        .sum();
    if var_t < 1e-9 {
        return Vec::new();
    }
    let mut all = Vec::new();
    for y in 0..=h - t.h {
        for x in 0..=w - t.w {
            let (mut si, mut sii, mut sti) = (0.0f64, 0.0, 0.0);
            for &(dx, dy, v) in &t.samples {
                let i = img[(y + dy) * w + x + dx] as f64;
                si += i;
                sii += i * i;
                sti += (v as f64 - mean_t) * i;
            }
            let var_i = sii - si * si / n;
            let zncc = sti / (var_t * var_i).sqrt();
            let edge = if t.edges.is_empty() {
                0.0
            } else {
                t.edges
                    .iter()
                    .map(|&(dx, dy, nv)| {
                        let d = edges.dir[(y + dy) * w + x + dx];
                        (nv[0] * d[0] + nv[1] * d[1]).abs() as f64
                    })
                    .sum::<f64>()
                    / t.edges.len() as f64
            };
            let score = (1.0 - EDGE_WEIGHT) * zncc + EDGE_WEIGHT * edge;
            if var_i > 1e-9 && score.is_finite() {
                all.push((x, y, score));
            }
        }
    }
    all.sort_by(|a, b| b.2.total_cmp(&a.2));
    let sep = (t.w / 2).max(1);
    let mut out: Vec<(usize, usize, f64)> = Vec::new();
    for c in all {
        if out.len() >= keep {
            break;
        }
        if out
            .iter()
            .all(|o| o.0.abs_diff(c.0) >= sep || o.1.abs_diff(c.1) >= sep)
        {
            out.push(c);
        }
    }
    out
}

/// Directions on the unit sphere, evenly spread (Fibonacci lattice).
pub fn sphere_directions(n: usize) -> Vec<Vector3<f64>> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            Vector3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect()
}

/// The rotation taking the optical axis (0, 0, 1) to the unit `ray`.
pub(super) fn axis_to(ray: &Vector3<f64>) -> Matrix3<f64> {
    let z = Vector3::z();
    let axis = z.cross(ray);
    let s = axis.norm();
    if s < 1e-12 {
        return Matrix3::identity();
    }
    rotation_exp(&(axis / s * s.atan2(z.dot(ray))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_template_is_found_where_it_was_cut_at_each_scale() {
        let (w, h) = (60, 40);
        let img: Vec<f32> = (0..w * h)
            .map(|i| ((i as u64).wrapping_mul(2_654_435_761) >> 7) % 97)
            .map(|v| v as f32 / 96.0)
            .collect();
        // A 10x8 patch at (23, 17), as a view with its coverage.
        let mut view = vec![0.0; w * h];
        let mut cover = vec![0.0; w * h];
        for y in 17..25 {
            for x in 23..33 {
                view[y * w + x] = 2.0 * img[y * w + x] + 1.0;
                cover[y * w + x] = 1.0;
            }
        }
        let (t, origin) = Template::new(&view, &cover, w, h, 1.0).unwrap();
        assert_eq!((origin, t.w, t.h, t.samples.len()), ((23, 17), 10, 8, 80));
        // Without edges in the frame the score is the ZNCC's share alone.
        let flat = EdgeMap::new(&vec![0.0; w * h], w, h);
        let best = best_positions(&t, &img, &flat, w, h, 3);
        assert_eq!((best[0].0, best[0].1), (23, 17));
        assert!((best[0].2 - (1.0 - EDGE_WEIGHT)).abs() < 1e-9);
        assert!(best[1].2 < 1.0 - EDGE_WEIGHT);
        // A scaled template has the scaled size.
        let (t2, _) = Template::new(&view, &cover, w, h, 1.25).unwrap();
        assert_eq!((t2.w, t2.h), (13, 10));
    }

    #[test]
    fn the_silhouette_finds_an_object_whose_texture_matches_nothing() {
        // A bright 10x8 block at (23, 17) on faint noise; the template has
        // the block's outline and an unrelated texture.
        let (w, h) = (60, 40);
        let noise = |i: usize| (((i as u64).wrapping_mul(2_654_435_761) >> 7) % 97) as f32 / 96.0;
        let inside = |x: usize, y: usize| (23..33).contains(&x) && (17..25).contains(&y);
        let img: Vec<f32> = (0..w * h)
            .map(|i| 0.005 * noise(i) + if inside(i % w, i / w) { 0.5 } else { 0.0 })
            .collect();
        let mut view = vec![0.0; w * h];
        let mut cover = vec![0.0; w * h];
        for y in 5..13 {
            for x in 40..50 {
                view[y * w + x] = noise(7 * (y * w + x) + 3);
                cover[y * w + x] = 1.0;
            }
        }
        let (t, origin) = Template::new(&view, &cover, w, h, 1.0).unwrap();
        assert_eq!((origin, t.w, t.h), ((40, 5), 10, 8));
        // The outline: 2 x 10 + 2 x 6 samples, normals outward.
        assert_eq!(t.edges.len(), 32);
        assert!(t.edges.contains(&(0, 4, [-1.0, 0.0])));
        assert!(t.edges.contains(&(4, 7, [0.0, 1.0])));
        let edges = EdgeMap::new(&img, w, h);
        // Edges on the block's border (spread by a pixel), none far away.
        let d = edges.dir[20 * w + 23];
        assert!(d[0] > 0.999 && d[1].abs() < 0.02, "{d:?}");
        // A wrong size gives no edges, not a panic.
        assert!(
            EdgeMap::new(&img[1..], w, h)
                .dir
                .iter()
                .all(|d| *d == [0.0; 2])
        );
        assert_eq!(edges.dir[20 * w + 10], [0.0, 0.0]);
        let best = best_positions(&t, &img, &edges, w, h, 1);
        // Within the pixel the spread leaves open.
        assert!(
            best[0].0.abs_diff(23) <= 1 && best[0].1.abs_diff(17) <= 1,
            "{best:?}"
        );
        // Every outline sample on an edge of its own direction (the
        // corners' normals are diagonal, the edges there not).
        assert!(best[0].2 > EDGE_WEIGHT * 0.9, "{best:?}");
    }

    #[test]
    fn sphere_directions_are_unit_and_spread() {
        let d = sphere_directions(24);
        assert!(d.iter().all(|v| (v.norm() - 1.0).abs() < 1e-12));
        let mean: Vector3<f64> = d.iter().sum::<Vector3<f64>>() / 24.0;
        assert!(mean.norm() < 0.05, "{mean:?}");
        for ray in &d {
            let r = axis_to(ray);
            assert!((r * Vector3::z() - ray).norm() < 1e-9);
        }
    }

    #[test]
    fn thinning_keeps_every_nth_point_and_grows_radii() {
        let n = 10_000;
        use crate::model::{AttributeSource, Provenance};
        let model = PointModel {
            positions: (0..n)
                .map(|i| glam::Vec3::new(i as f32, 0.0, 1.0))
                .collect(),
            normals: vec![glam::Vec3::Z; n],
            radii: vec![0.5; n],
            colors: Some((0..n).map(|i| [i as f32 / n as f32, 0.0, 0.0]).collect()),
            provenance: Provenance {
                path: None,
                normals: AttributeSource::FromMesh,
                radii: AttributeSource::FromMesh,
                colors: AttributeSource::FromMesh,
                dropped_non_finite: 0,
                normals_reestimated: 0,
            },
        };
        let (thin, idx) = thinned(&model, 2500);
        assert_eq!(idx.len(), 2500);
        assert_eq!(thin.len(), 2500);
        assert_eq!(idx[1], 4);
        assert_eq!(thin.positions[1], model.positions[4]);
        assert_eq!(
            thin.colors.as_ref().unwrap()[1],
            model.colors.as_ref().unwrap()[4]
        );
        // Four times fewer points, each covering four times the area.
        assert!((thin.radii[1] - 1.0).abs() < 1e-6);
        // A small model is kept whole.
        let (same, _) = thinned(&model, 20_000);
        assert_eq!(same.radii, model.radii);
    }

    #[test]
    fn shrink_averages_blocks() {
        let img: Vec<f32> = (0..16).map(|i| i as f32).collect();
        let (s, w, h) = shrink(&img, 4, 4, 2);
        assert_eq!((w, h), (2, 2));
        assert_eq!(s, vec![2.5, 4.5, 10.5, 12.5]);
    }
}
