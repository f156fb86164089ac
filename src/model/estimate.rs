//! Normal and radius estimation from point neighbourhoods.
//!
//! How it works:
//! 1. A k-d tree (kiddo's `ImmutableKdTree`) over the points, centred on their
//!    centroid so that f32 keeps its precision far from the origin. The points
//!    are first reordered in the leaf order of a k-d tree, so that neighbours
//!    in space are neighbours in memory for the queries, the PCA and the
//!    orientation (twice as fast as file order on a million points).
//! 2. Normals: principal component analysis of each point's k nearest
//!    neighbours (Hoppe, DeRose, Duchamp, McDonald & Stuetzle, "Surface
//!    reconstruction from unorganized points", SIGGRAPH 1992): the normal is the
//!    eigenvector of the neighbourhood covariance with the smallest eigenvalue,
//!    found in closed form (Smith, "Eigenvalues of a symmetric 3x3 matrix",
//!    CACM 1961, then a cross product of two rows of `C - lambda I`).
//! 3. Orientation, also after Hoppe et al. 1992: the sign of a PCA normal is
//!    arbitrary, so signs are propagated along a minimum spanning tree of the
//!    symmetrised k-NN graph with edge weights `1 - |n_i . n_j|` (Prim's
//!    algorithm), which crosses smooth regions first and sharp creases last.
//!    Each connected component is seeded at one of its six extreme points
//!    (largest/smallest x, y, z), the one whose normal is most aligned with
//!    that axis; its normal is made to point outward along the axis. When some
//!    normals were loaded from the file, those are fixed and seed the tree
//!    instead.
//! 4. Radii: a disc of radius `d_k` (distance to the k-th neighbour) holds
//!    about k points, so the surface area per point is `pi d_k^2 / k`. The
//!    radius is `radius_factor * d_k / sqrt(k)`, i.e. `radius_factor` times the
//!    radius of a disc of that area: the same law as `c * sqrt(A / (pi N))`
//!    for sampled meshes. With the default factor 2.0 each surface point is
//!    covered by about four discs on average; that closes the surface for
//!    grid-like or stratified samplings (a factor of 1.5 would too) and leaves
//!    about 2% of the surface uncovered for purely random (Poisson) samplings,
//!    where `exp(-factor^2)` of the surface is uncovered.

use super::Stage;
use super::error::ModelError;
use glam::{DVec3, Vec3};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use std::num::NonZeroUsize;
use std::path::Path;

/// Neighbours per point kept in the orientation graph: enough to connect
/// sampled surfaces, few enough to keep the spanning tree cheap.
const GRAPH_K: usize = 8;
/// Coordinates (after centring) beyond this cannot have their squared
/// distances represented in f32.
const MAX_COORDINATE: f32 = 1e15;
const PROGRESS_STEP: usize = 1 << 14;

/// What to estimate.
pub(crate) struct Task<'a> {
    /// `None`: keep the normals. `Some(mask)`: estimate the normals where
    /// `mask` is true (all of them when it is all true); the others are
    /// trusted and anchor the orientation.
    pub normals: Option<&'a [bool]>,
    pub radii: bool,
    pub k: usize,
    pub radius_factor: f32,
}

/// Where the two stages report their progress.
pub(crate) struct Bars<'a> {
    pub neighbours: Stage<'a>,
    pub orient: Stage<'a>,
}

/// The points relative to their centroid, as f32 arrays for the k-d
/// tree (precise near the model even far from the origin); refuses
/// coordinates spanning more than [`MAX_COORDINATE`] (or NaN).
fn centred_points(
    positions: &[Vec3],
    path: &Path,
    what: &'static str,
) -> Result<Vec<[f32; 3]>, ModelError> {
    let centroid = positions
        .iter()
        .fold(DVec3::ZERO, |acc, p| acc + p.as_dvec3())
        / positions.len().max(1) as f64;
    let centre = centroid.as_vec3();
    positions
        .iter()
        .map(|p| {
            let q = *p - centre;
            let extent = q.abs().max_element();
            if extent.is_nan() || extent > MAX_COORDINATE {
                return Err(err(
                    path,
                    what,
                    format!("coordinates span more than {MAX_COORDINATE:e} model units"),
                ));
            }
            Ok(q.to_array())
        })
        .collect()
}

/// Threads for the per-point loops: the machine's cores, at most 16.
fn threads() -> usize {
    crate::par::cores().min(16)
}

/// Runs `work` over `0..n` cut into `threads` contiguous ranges, one thread
/// each, and returns the ranges' results in order: the same, point for
/// point, as one range on one thread. `work` reports the points it
/// finishes through its second argument; the calling thread passes each
/// report on to `bar` as it comes.
fn par_ranges<T: Send>(
    n: usize,
    threads: usize,
    bar: &Stage<'_>,
    work: impl Fn(std::ops::Range<usize>, &dyn Fn(usize)) -> T + Sync,
) -> Vec<T> {
    let threads = threads.clamp(1, n.max(1));
    if threads == 1 {
        return vec![work(0..n, &|units| bar.advance(units as u64))];
    }
    let step = n.div_ceil(threads);
    let (tx, rx) = std::sync::mpsc::channel::<usize>();
    let ranges: Vec<_> = (0..threads)
        .map(|t| (t * step).min(n)..((t + 1) * step).min(n))
        .collect();
    std::thread::scope(|scope| {
        // A range whose thread cannot be started (the system out of
        // threads) is worked on here afterwards.
        let handles: Vec<_> = ranges
            .iter()
            .map(|range| {
                let (work, tx, range) = (&work, tx.clone(), range.clone());
                std::thread::Builder::new()
                    .name("splattrack-estimate".into())
                    .spawn_scoped(scope, move || {
                        work(range, &|units| {
                            let _ = tx.send(units);
                        })
                    })
                    .ok()
            })
            .collect();
        drop(tx);
        // Ends when every started worker has ended (and dropped its sender).
        for units in rx {
            bar.advance(units as u64);
        }
        handles
            .into_iter()
            .zip(ranges)
            .map(|(h, range)| match h {
                Some(h) => match h.join() {
                    Ok(v) => v,
                    Err(panic) => std::panic::resume_unwind(panic),
                },
                None => work(range, &|units| bar.advance(units as u64)),
            })
            .collect()
    })
}

fn err(path: &Path, what: &'static str, reason: impl Into<String>) -> ModelError {
    ModelError::Estimation {
        path: path.to_path_buf(),
        what,
        reason: reason.into(),
    }
}

/// Fills `normals` (length n) and `radii` (length n) as `task` says, on
/// every core ([`threads`]).
pub(crate) fn estimate(
    positions: &[Vec3],
    normals: &mut [Vec3],
    radii: &mut [f32],
    task: &Task,
    path: &Path,
    bars: &Bars<'_>,
) -> Result<(), ModelError> {
    estimate_on(positions, normals, radii, task, path, bars, threads())
}

/// [`estimate`] on `threads` threads (the result does not depend on it).
fn estimate_on(
    positions: &[Vec3],
    normals: &mut [Vec3],
    radii: &mut [f32],
    task: &Task,
    path: &Path,
    bars: &Bars<'_>,
    threads: usize,
) -> Result<(), ModelError> {
    let n = positions.len();
    let what = if task.normals.is_some() {
        "normals"
    } else {
        "radii"
    };
    if task.normals.is_none() && !task.radii {
        return Ok(());
    }
    if n < 3 {
        return Err(err(
            path,
            what,
            format!("{n} points; at least 3 are needed"),
        ));
    }
    if n > u32::MAX as usize {
        return Err(err(path, what, format!("{n} points is too many")));
    }
    let k = task.k.clamp(2, n - 1);
    if task.radii && !(task.radius_factor.is_finite() && task.radius_factor > 0.0) {
        return Err(err(
            path,
            "radii",
            format!(
                "the radius factor is {}; it must be > 0",
                task.radius_factor
            ),
        ));
    }

    let pts = centred_points(positions, path, what)?;
    // Work in the leaf order of a first tree: neighbours in space are then
    // neighbours in memory, for the queries, the PCA and the orientation
    // alike (about twice as fast on a million points as file order).
    let build = |pts: &[[f32; 3]]| {
        ImmutableKdTree::<f32, 3>::new_from_slice(pts)
            .map_err(|e| err(path, what, format!("k-d tree: {e}")))
    };
    let order: Vec<u32> = build(&pts)?.iter().map(|(item, _)| item).collect();
    if order.len() != n {
        return Err(err(path, what, "the k-d tree lost points"));
    }
    let pts: Vec<[f32; 3]> = order.iter().map(|&i| pts[i as usize]).collect();
    let tree = build(&pts)?;
    let mut sorted_normals: Vec<Vec3> = Vec::new();
    let mut sorted_mask: Vec<bool> = Vec::new();
    if let Some(mask) = task.normals {
        sorted_normals = order.iter().map(|&i| normals[i as usize]).collect();
        sorted_mask = order.iter().map(|&i| mask[i as usize]).collect();
    }

    let orient_too = task.normals.is_some();
    let kg = GRAPH_K.min(k);
    let qty = NonZeroUsize::new(k + 1).unwrap_or(NonZeroUsize::MIN);
    // Per range of points: its graph rows, normals and radii.
    let chunks = par_ranges(n, threads, &bars.neighbours, |range, report| {
        let mut scratch = tree.create_scratch::<SquaredEuclidean<f32>>();
        let mut nbrs: Vec<u32> = Vec::with_capacity(k + 1);
        let m = range.len();
        let mut graph: Vec<u32> = if orient_too {
            vec![0; m * kg]
        } else {
            Vec::new()
        };
        let mut normals: Vec<Vec3> = Vec::new();
        let mut radii: Vec<f32> = Vec::new();
        for i in range {
            let point = &pts[i];
            let item = i as u32;
            let found = tree
                .query(point)
                .nearest_n::<SquaredEuclidean<f32>>(qty)
                .with_scratch(&mut scratch)
                .execute();
            // The point itself is among the results unless more than k
            // points share its position; either way keep k others.
            nbrs.clear();
            let mut last_dist2 = 0.0f32;
            let mut skipped_self = false;
            for r in &found {
                if !skipped_self && r.item == item {
                    skipped_self = true;
                    continue;
                }
                if nbrs.len() < k {
                    nbrs.push(r.item);
                    last_dist2 = r.distance;
                }
            }
            if orient_too {
                // Coincident points say nothing about orientation and would
                // use up the row (a cloud of duplicated points would fall
                // apart into tiny components), so the graph links distinct
                // positions only; unused slots point to the point itself and
                // are never followed.
                let at = normals.len();
                let row = &mut graph[at * kg..(at + 1) * kg];
                row.fill(item);
                let distinct = found
                    .iter()
                    .filter(|r| r.item != item && r.distance > 0.0)
                    .map(|r| r.item);
                for (slot, j) in row.iter_mut().zip(distinct) {
                    *slot = j;
                }
                normals.push(if sorted_mask[i] {
                    pca_normal(&pts, i, &nbrs)
                } else {
                    sorted_normals[i]
                });
            }
            if task.radii {
                radii.push(task.radius_factor * last_dist2.max(0.0).sqrt() / (k as f32).sqrt());
            }
            if i % PROGRESS_STEP == PROGRESS_STEP - 1 {
                report(PROGRESS_STEP);
            }
        }
        (graph, normals, radii)
    });
    let mut graph: Vec<u32> = Vec::with_capacity(if orient_too { n * kg } else { 0 });
    let mut estimated_normals: Vec<Vec3> = Vec::with_capacity(if orient_too { n } else { 0 });
    let mut sorted_radii: Vec<f32> = Vec::with_capacity(if task.radii { n } else { 0 });
    for (g, nm, r) in chunks {
        graph.extend(g);
        estimated_normals.extend(nm);
        sorted_radii.extend(r);
    }
    if orient_too {
        sorted_normals = estimated_normals;
    }
    bars.neighbours.finish();

    if orient_too {
        orient(
            &pts,
            &mut sorted_normals,
            &sorted_mask,
            &graph,
            kg,
            &bars.orient,
        );
        for (s, &i) in order.iter().enumerate() {
            normals[i as usize] = sorted_normals[s];
        }
    }
    if task.radii {
        for (s, &i) in order.iter().enumerate() {
            radii[i as usize] = sorted_radii[s];
        }
        fix_radii(radii).ok_or_else(|| {
            err(
                path,
                "radii",
                format!("no point has {k} neighbours at a positive distance (the points coincide)"),
            )
        })?;
    }
    Ok(())
}

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
    /// Mean radius before and after (model units).
    pub mean_before: f64,
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
fn close_gaps_on(
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

/// Replaces radii that came out zero (more than k coincident points) by the
/// median of the others. `None` when no radius is positive.
fn fix_radii(radii: &mut [f32]) -> Option<()> {
    let bad = |r: f32| !(r.is_finite() && r > 0.0);
    if !radii.iter().any(|&r| bad(r)) {
        return Some(());
    }
    let mut good: Vec<f32> = radii.iter().copied().filter(|&r| !bad(r)).collect();
    if good.is_empty() {
        return None;
    }
    let mid = good.len() / 2;
    let (_, &mut median, _) = good.select_nth_unstable_by(mid, f32::total_cmp);
    for r in radii.iter_mut().filter(|r| bad(**r)) {
        *r = median;
    }
    Some(())
}

/// The PCA normal of point `i` and its neighbours; never zero-length.
fn pca_normal(pts: &[[f32; 3]], i: usize, nbrs: &[u32]) -> Vec3 {
    let at = |j: usize| DVec3::from_array(pts[j].map(f64::from));
    let m = (nbrs.len() + 1) as f64;
    let mean = nbrs.iter().fold(at(i), |acc, &j| acc + at(j as usize)) / m;
    let mut c = [0.0f64; 6]; // xx xy xz yy yz zz
    for d in std::iter::once(i)
        .chain(nbrs.iter().map(|&j| j as usize))
        .map(|j| at(j) - mean)
    {
        c[0] += d.x * d.x;
        c[1] += d.x * d.y;
        c[2] += d.x * d.z;
        c[3] += d.y * d.y;
        c[4] += d.y * d.z;
        c[5] += d.z * d.z;
    }
    let n = smallest_eigenvector([[c[0], c[1], c[2]], [c[1], c[3], c[4]], [c[2], c[4], c[5]]]);
    // Coincident neighbours leave the direction undefined: any unit vector
    // will do, orientation then picks its sign.
    n.unwrap_or(DVec3::Z).as_vec3()
}

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

/// Hoppe et al. 1992 orientation: flips normals so that they agree along a
/// minimum spanning tree of the k-NN graph (weights `1 - |n_i . n_j|`).
fn orient(
    pts: &[[f32; 3]],
    normals: &mut [Vec3],
    estimated: &[bool],
    graph: &[u32],
    kg: usize,
    bar: &Stage,
) {
    let n = pts.len();
    // Reverse edges, so that the graph is symmetric: j may be i's neighbour
    // without i being j's.
    let mut rev_start = vec![0usize; n + 1];
    for &j in graph {
        rev_start[j as usize + 1] += 1;
    }
    for i in 0..n {
        rev_start[i + 1] += rev_start[i];
    }
    let mut fill = rev_start.clone();
    let mut rev = vec![0u32; graph.len()];
    for (e, &j) in graph.iter().enumerate() {
        let slot = &mut fill[j as usize];
        rev[*slot] = (e / kg) as u32;
        *slot += 1;
    }
    drop(fill);
    let neighbours = |i: usize| {
        graph[i * kg..(i + 1) * kg]
            .iter()
            .chain(&rev[rev_start[i]..rev_start[i + 1]])
            .map(|&j| j as usize)
    };

    const UNSEEN: u8 = 0;
    const QUEUED: u8 = 1;
    const DONE: u8 = 2;
    let mut state: Vec<u8> = estimated
        .iter()
        .map(|&e| if e { UNSEEN } else { DONE })
        .collect();
    let mut queue = BucketQueue::new();
    let push_edges = |i: usize, state: &[u8], normals: &[Vec3], queue: &mut BucketQueue| {
        for j in neighbours(i) {
            if state[j] != DONE {
                queue.push(normals[i].dot(normals[j]), j as u32, i as u32);
            }
        }
    };
    let mut done = 0usize;
    let mut grow = |queue: &mut BucketQueue, state: &mut [u8], normals: &mut [Vec3]| {
        while let Some((to, from)) = queue.pop() {
            let (to, from) = (to as usize, from as usize);
            if state[to] == DONE {
                continue;
            }
            if normals[to].dot(normals[from]) < 0.0 {
                normals[to] = -normals[to];
            }
            state[to] = DONE;
            push_edges(to, state, normals, queue);
            done += 1;
            if done.is_multiple_of(PROGRESS_STEP) {
                bar.advance(PROGRESS_STEP as u64);
            }
        }
    };

    // Trusted normals first: they orient everything connected to them.
    for i in 0..n {
        if state[i] == DONE {
            push_edges(i, &state, normals, &mut queue);
        }
    }
    grow(&mut queue, &mut state, normals);

    // What remains are components without a trusted normal: seed each.
    let mut members: Vec<usize> = Vec::new();
    let mut stack: Vec<usize> = Vec::new();
    for start in 0..n {
        if state[start] != UNSEEN {
            continue;
        }
        members.clear();
        stack.push(start);
        state[start] = QUEUED;
        while let Some(i) = stack.pop() {
            members.push(i);
            for j in neighbours(i) {
                if state[j] == UNSEEN {
                    state[j] = QUEUED;
                    stack.push(j);
                }
            }
        }
        let seed = choose_seed(pts, normals, &members);
        state[seed] = DONE;
        push_edges(seed, &state, normals, &mut queue);
        grow(&mut queue, &mut state, normals);
    }
    bar.finish();
}

/// Buckets for the edge weights of the orientation tree. Prim's algorithm
/// only needs the cheapest edge next, and an exact order among nearly equal
/// weights does not matter, so weights are quantised: the bucket is linear in
/// `sqrt(1 - |cos|)`, about the angle between the normals (0.35 degree per
/// bucket near parallel). Pushes are O(1) and pops scan up from the lowest
/// non-empty bucket; on smooth surfaces nearly every edge lands in the first
/// few buckets. Several times faster than a binary heap here.
struct BucketQueue {
    buckets: Vec<Vec<(u32, u32)>>,
    lowest: usize,
    len: usize,
}

impl BucketQueue {
    const BUCKETS: usize = 256;

    fn new() -> Self {
        Self {
            buckets: vec![Vec::new(); Self::BUCKETS],
            lowest: Self::BUCKETS,
            len: 0,
        }
    }

    /// Queues the edge `from -> to` whose normals have cosine `cos`.
    #[inline]
    fn push(&mut self, cos: f32, to: u32, from: u32) {
        let w = (1.0 - cos.abs()).max(0.0).sqrt();
        // NaN and values >= 1 both land in the last bucket.
        let b = ((w * Self::BUCKETS as f32) as usize).min(Self::BUCKETS - 1);
        self.buckets[b].push((to, from));
        self.lowest = self.lowest.min(b);
        self.len += 1;
    }

    /// The queued edge of (about) the lowest weight, as `(to, from)`.
    #[inline]
    fn pop(&mut self) -> Option<(u32, u32)> {
        if self.len == 0 {
            self.lowest = Self::BUCKETS;
            return None;
        }
        while self.buckets[self.lowest].is_empty() {
            self.lowest += 1;
        }
        self.len -= 1;
        self.buckets[self.lowest].pop()
    }
}

/// Among the six extreme points of a component, the one whose normal is most
/// aligned with its axis; that normal is flipped to point outward along it.
fn choose_seed(pts: &[[f32; 3]], normals: &mut [Vec3], members: &[usize]) -> usize {
    let mut best = (members[0], 0usize, false, -1.0f32); // point, axis, negative side, score
    for axis in 0..3 {
        for negative in [false, true] {
            let key = |i: &usize| {
                let v = pts[*i][axis];
                if negative { -v } else { v }
            };
            let Some(&i) = members.iter().max_by(|a, b| key(a).total_cmp(&key(b))) else {
                continue;
            };
            let score = normals[i][axis].abs();
            if score > best.3 {
                best = (i, axis, negative, score);
            }
        }
    }
    let (i, axis, negative, _) = best;
    let outward = if negative { -1.0 } else { 1.0 };
    if normals[i][axis] * outward < 0.0 {
        normals[i] = -normals[i];
    }
    i
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

    #[test]
    fn results_do_not_depend_on_the_threads() {
        // A noisy sphere of 40k points (more than two progress steps per
        // thread at 5 threads), random radii, some normals trusted.
        let mut rng = Rng::new(11);
        let n = 40_000;
        let positions: Vec<Vec3> = (0..n)
            .map(|_| {
                let v = Vec3::new(
                    rng.next_f64() as f32 - 0.5,
                    rng.next_f64() as f32 - 0.5,
                    rng.next_f64() as f32 - 0.5,
                );
                v.normalize_or(Vec3::Z) * (1.0 + 0.01 * rng.next_f64() as f32)
            })
            .collect();
        let mask: Vec<bool> = (0..n).map(|i| i % 7 != 0).collect();
        let task = Task {
            normals: Some(&mask),
            radii: true,
            k: 12,
            radius_factor: 0.6,
        };
        let run = |threads: usize| {
            let mut normals: Vec<Vec3> = positions.clone();
            let mut radii = vec![0.0f32; n];
            let bars = Bars {
                neighbours: Stage::silent(),
                orient: Stage::silent(),
            };
            let path = Path::new("sphere.ply");
            estimate_on(
                &positions,
                &mut normals,
                &mut radii,
                &task,
                path,
                &bars,
                threads,
            )
            .unwrap();
            let before = radii.clone();
            let closed = close_gaps_on(
                &positions,
                &normals,
                &mut radii,
                GAP_NEIGHBOURS,
                path,
                &Stage::silent(),
                threads,
            )
            .unwrap();
            (normals, before, radii, closed.grown)
        };
        let one = run(1);
        let five = run(5);
        // Radii of 0.6 spacings leave gaps: some grow.
        assert!(one.3 > 1000, "{} grown", one.3);
        assert!(one.0 == five.0, "normals differ");
        assert!(one.1 == five.1, "estimated radii differ");
        assert!(one.2 == five.2, "closed radii differ");
        assert_eq!(one.3, five.3);
    }

    #[test]
    fn radii_fix_uses_median() {
        let mut r = [0.0, 1.0, 2.0, 3.0, f32::NAN];
        fix_radii(&mut r).expect("some positive");
        assert_eq!(r, [2.0, 1.0, 2.0, 3.0, 2.0]);
        assert!(fix_radii(&mut [0.0, 0.0]).is_none());
    }
}
