//! Closing the gaps between splats: each point's radius grown, where its
//! Voronoi cell in its tangent plane is not covered, to cover that cell.

use super::error::{ModelError, memory_path};
use super::pointwise::{PROGRESS_STEP, centred_points, err, par_ranges, threads};
use super::stage::Stage;
use super::types::PointModel;
use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use std::num::NonZeroUsize;
use std::path::Path;

/// Neighbours per point that `close_gaps` looks at: enough that the
/// Voronoi cell of a randomly (Poisson) sampled point is bounded by them
/// (its farthest vertex is rarely beyond half the distance to the 24th
/// neighbour), few enough to stay cheap.
pub const GAP_NEIGHBOURS: usize = 24;

/// A model where fewer than this fraction of the radii leave a gap is taken
/// to cover its surface already (the tracker then keeps its radii): the
/// stratified samplings of `TriangleMesh::sample` grow 3-6% of their radii
/// (along creases and where strata meet, by 0.2-0.6% of the mean radius),
/// the ViSP cube with the tracker's 1 px floor 1.8%, a random sampling with
/// radii of 1.5 spacings 4%, and models with real gaps (radii of one
/// spacing or less on a random sampling) 45-98%. On the real cube even the
/// small changes of the closed radii moved KF+IT by 0.02 degree.
pub const GAP_MODEL_FRACTION: f64 = 0.1;

/// What `close_gaps` changed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GapClosure {
    /// Points whose radius grew.
    pub grown: usize,
    /// Points looked at.
    pub points: usize,
    /// Mean radius before (model units).
    pub mean_before: f64,
    /// Mean radius after (model units).
    pub mean_after: f64,
}

/// A vertex of a clipped cell: its position in the tangent plane and the
/// two constraints that meet there (`BOX` for the bounding square).
#[derive(Clone, Copy)]
struct CellVertex {
    p: [f32; 2],
    a: u32,
    b: u32,
}

const BOX: u32 = u32::MAX;

/// Clips the convex polygon `poly` (edge `k` runs from vertex `k` to
/// `k + 1` and is constraint `poly[k].b`, which is also `poly[k + 1].a`)
/// by the half-plane `n . x <= c`, constraint `id`.
fn clip(poly: &[CellVertex], n: [f32; 2], c: f32, id: u32, out: &mut Vec<CellVertex>) {
    out.clear();
    let m = poly.len();
    let side = |v: &CellVertex| n[0] * v.p[0] + n[1] * v.p[1] - c;
    for k in 0..m {
        let (v, w) = (poly[k], poly[(k + 1) % m]);
        let (sv, sw) = (side(&v), side(&w));
        if sv <= 0.0 {
            out.push(v);
        }
        if (sv <= 0.0) != (sw <= 0.0) {
            let t = sv / (sv - sw);
            let p = [
                v.p[0] + t * (w.p[0] - v.p[0]),
                v.p[1] + t * (w.p[1] - v.p[1]),
            ];
            // The edge v -> w is constraint v.b; leaving the half-plane the
            // new vertex closes it and opens `id`, entering it is the reverse.
            out.push(if sv <= 0.0 {
                CellVertex { p, a: v.b, b: id }
            } else {
                CellVertex { p, a: id, b: v.b }
            });
        }
    }
}

/// Grows the radii that leave gaps between splats, never shrinking one
/// (Voronoi coverage in each point's tangent plane):
///
/// 1. the point's `k` nearest neighbours (those on the same sheet: normals
///    less than 120 degrees apart) are projected onto its tangent plane;
/// 2. its Voronoi cell among them is clipped out of a square, keeping for
///    each vertex the two bisectors that meet there (vertices on the square
///    are where the neighbourhood does not surround the point, e.g. the rim
///    of an open scan: they are ignored);
/// 3. the cells tile the surface, and the farthest point of a cell from its
///    centre is one of its vertices. Where a vertex of the cell, or a point
///    along one of its edges, is inside no disc of the point or its
///    neighbours (with equal radii the vertices are the deepest points of
///    the gaps), the point's radius grows to its farthest vertex, so that
///    its disc covers its whole cell. A vertex beyond the farthest
///    neighbour (a gap wider than the neighbourhood) counts at that
///    distance: growth is capped there.
///
/// A model whose discs already cover its surface comes out unchanged; one
/// sampled at random with small radii grows only around its gaps, by as
/// much as each gap needs (unlike a global factor, which blurs every splat).
/// Coverage is tested against the radii as given, so the result does not
/// depend on the order of the points.
pub(crate) fn close_gaps(
    positions: &[Vec3],
    normals: &[Vec3],
    radii: &mut [f32],
    k: usize,
    path: &Path,
    bar: &Stage<'_>,
) -> Result<GapClosure, ModelError> {
    close_gaps_on(positions, normals, radii, k, path, bar, threads())
}

/// [`close_gaps`] on `threads` threads (the result does not depend on it).
pub(super) fn close_gaps_on(
    positions: &[Vec3],
    normals: &[Vec3],
    radii: &mut [f32],
    k: usize,
    path: &Path,
    bar: &Stage<'_>,
    threads: usize,
) -> Result<GapClosure, ModelError> {
    let n = positions.len();
    let mean = |r: &[f32]| r.iter().map(|&v| v as f64).sum::<f64>() / r.len().max(1) as f64;
    let mean_before = mean(radii);
    let unchanged = GapClosure {
        grown: 0,
        points: n,
        mean_before,
        mean_after: mean_before,
    };
    if n < 3 {
        return Ok(unchanged);
    }
    if normals.len() != n || radii.len() != n {
        return Err(err(
            path,
            "radii",
            format!(
                "{n} points but {} normals and {} radii",
                normals.len(),
                radii.len()
            ),
        ));
    }
    if n > u32::MAX as usize {
        return Err(err(path, "radii", format!("{n} points is too many")));
    }
    let k = k.clamp(2, n - 1);
    let pts = centred_points(positions, path, "radii")?;
    let tree = ImmutableKdTree::<f32, 3>::new_from_slice(&pts)
        .map_err(|e| err(path, "radii", format!("k-d tree: {e}")))?;
    let qty = NonZeroUsize::new(k + 1).unwrap_or(NonZeroUsize::MIN);
    let radii_in: &[f32] = radii;
    // Per range of points: those whose radius grows, and to what.
    let chunks = par_ranges(n, threads, bar, |range, report| {
        let mut scratch = tree.create_scratch::<SquaredEuclidean<f32>>();
        let (mut poly, mut next): (Vec<CellVertex>, Vec<CellVertex>) = (Vec::new(), Vec::new());
        let mut near: Vec<([f32; 2], f32)> = Vec::with_capacity(k);
        let mut grown_radii: Vec<(usize, f32)> = Vec::new();
        for i in range {
            let point = &pts[i];
            let found = tree
                .query(point)
                .nearest_n::<SquaredEuclidean<f32>>(qty)
                .with_scratch(&mut scratch)
                .execute();
            let ni = normals[i];
            let (u, v) = ni.any_orthonormal_pair();
            let pi = Vec3::from_array(*point);
            near.clear();
            let mut reach = 0f32;
            for r in &found {
                let j = r.item as usize;
                if j == i || r.distance <= 0.0 || normals[j].dot(ni) < -0.5 {
                    continue;
                }
                // Unfolded into the tangent plane: the projected direction at the
                // 3-D distance. On a plane this is the projection; across a
                // crease it lays the other face out beyond the crease instead of
                // squeezing it onto the crease line (which would pretend that
                // its discs cover this face up to the crease).
                let d = Vec3::from_array(pts[j]) - pi;
                let (x, y) = (d.dot(u), d.dot(v));
                let flat = (x * x + y * y).sqrt();
                if flat <= 1e-3 * d.length() {
                    continue;
                }
                let s = d.length() / flat;
                near.push(([x * s, y * s], radii_in[j]));
                reach = reach.max(r.distance.sqrt());
            }
            if near.len() < 3 || reach <= 0.0 {
                continue;
            }
            let l = 2.0 * reach;
            poly.clear();
            for (x, y) in [(-l, -l), (l, -l), (l, l), (-l, l)] {
                poly.push(CellVertex {
                    p: [x, y],
                    a: BOX,
                    b: BOX,
                });
            }
            for (j, (q, _)) in near.iter().enumerate() {
                let c = 0.5 * (q[0] * q[0] + q[1] * q[1]);
                clip(&poly, *q, c, j as u32, &mut next);
                std::mem::swap(&mut poly, &mut next);
                if poly.is_empty() {
                    break;
                }
            }
            // Vertices, and points along the edges between two of them (with
            // unequal radii a gap can open mid-edge between covered vertices).
            let ri = radii_in[i];
            let uncovered = |p: [f32; 2]| {
                p[0] * p[0] + p[1] * p[1] > ri * ri
                    && !near.iter().any(|(q, rj)| {
                        let (dx, dy) = (p[0] - q[0], p[1] - q[1]);
                        dx * dx + dy * dy <= rj * rj
                    })
            };
            let m = poly.len();
            let (mut farthest, mut gap) = (0f32, false);
            for (e, vx) in poly.iter().enumerate() {
                if vx.a == BOX || vx.b == BOX {
                    continue;
                }
                let dist = (vx.p[0] * vx.p[0] + vx.p[1] * vx.p[1]).sqrt();
                farthest = farthest.max(dist.min(reach));
                gap = gap || uncovered(vx.p);
                let w = poly[(e + 1) % m];
                if w.a == BOX || w.b == BOX {
                    continue;
                }
                for t in [0.25f32, 0.5, 0.75] {
                    let p = [
                        vx.p[0] + t * (w.p[0] - vx.p[0]),
                        vx.p[1] + t * (w.p[1] - vx.p[1]),
                    ];
                    gap = gap || uncovered(p);
                }
            }
            // A gap in the cell: the point's disc grows to cover the whole cell
            // (its farthest vertex), which closes it whatever the neighbours do.
            let need = if gap { farthest } else { ri };
            if need > ri {
                grown_radii.push((i, need));
            }
            if i % PROGRESS_STEP == PROGRESS_STEP - 1 {
                report(PROGRESS_STEP);
            }
        }
        grown_radii
    });
    let grown_radii: Vec<(usize, f32)> = chunks.into_iter().flatten().collect();
    bar.finish();
    for &(i, r) in &grown_radii {
        radii[i] = r;
    }
    Ok(GapClosure {
        grown: grown_radii.len(),
        points: n,
        mean_before,
        mean_after: mean(radii),
    })
}

impl PointModel {
    /// Grows the radii that leave gaps between splats, and only those,
    /// never shrinking one: each point's radius becomes large enough to
    /// cover the farthest vertex of its Voronoi cell (in its tangent plane,
    /// among its [`GAP_NEIGHBOURS`] nearest neighbours) that no disc of the
    /// point or its neighbours covers. A model whose discs already cover its
    /// surface comes out unchanged. The method is in the `gaps` module.
    /// Models of fewer than 3 points are left as they are.
    pub fn close_gaps(&mut self) -> Result<GapClosure, ModelError> {
        let mut radii = std::mem::take(&mut self.radii);
        let closed = self.close_gaps_of(&mut radii);
        self.radii = radii;
        closed
    }

    /// [`PointModel::close_gaps`] applied to `radii` (one a point, in
    /// place of the model's own) instead of the model's radii, which stay
    /// as they are: for a model shared read-only.
    pub fn close_gaps_of(&self, radii: &mut [f32]) -> Result<GapClosure, ModelError> {
        let path = self.provenance.path.clone().unwrap_or_else(memory_path);
        if radii.len() != self.positions.len() {
            return Err(ModelError::Invalid {
                path,
                reason: format!("{} radii for {} points", radii.len(), self.positions.len()),
            });
        }
        close_gaps(
            &self.positions,
            &self.normals,
            radii,
            GAP_NEIGHBOURS,
            &path,
            &Stage::silent(),
        )
    }
}
