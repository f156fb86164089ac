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

use super::eigen::smallest_eigenvector;
use super::error::{ModelError, memory_path};
use super::orient::orient;
use super::pointwise::{PROGRESS_STEP, centred_points, err, par_ranges, threads};
use super::stage::Stage;
use super::types::{AttributeSource, LoadOptions, PointModel};
use glam::{DVec3, Vec3};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use std::num::NonZeroUsize;
use std::path::Path;

/// Neighbours per point kept in the orientation graph: enough to connect
/// sampled surfaces, few enough to keep the spanning tree cheap.
const GRAPH_K: usize = 8;

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

impl PointModel {
    /// Re-estimates every normal from the point neighbourhoods (PCA, oriented
    /// after Hoppe et al. 1992).
    pub fn estimate_normals(&mut self, opts: &LoadOptions) -> Result<(), ModelError> {
        let n = self.len();
        let mask = vec![true; n];
        let task = Task {
            normals: Some(&mask),
            radii: false,
            k: opts.k_neighbours,
            radius_factor: opts.radius_factor,
        };
        let bars = Bars {
            neighbours: Stage::new(opts.progress.as_ref(), "neighbours", n),
            orient: Stage::new(opts.progress.as_ref(), "orienting", n),
        };
        let path = self.provenance.path.clone().unwrap_or_else(memory_path);
        self.normals.resize(n, Vec3::Z);
        estimate(
            &self.positions,
            &mut self.normals,
            &mut [],
            &task,
            &path,
            &bars,
        )?;
        self.provenance.normals = AttributeSource::Estimated;
        self.provenance.normals_reestimated = 0;
        Ok(())
    }

    /// Re-estimates every radius from the local point spacing.
    pub fn estimate_radii(&mut self, opts: &LoadOptions) -> Result<(), ModelError> {
        let n = self.len();
        let task = Task {
            normals: None,
            radii: true,
            k: opts.k_neighbours,
            radius_factor: opts.radius_factor,
        };
        let bars = Bars {
            neighbours: Stage::new(opts.progress.as_ref(), "neighbours", n),
            orient: Stage::silent(),
        };
        let path = self.provenance.path.clone().unwrap_or_else(memory_path);
        self.radii.resize(n, 0.0);
        estimate(
            &self.positions,
            &mut [],
            &mut self.radii,
            &task,
            &path,
            &bars,
        )?;
        self.provenance.radii = AttributeSource::Estimated;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::GAP_NEIGHBOURS;
    use crate::model::gaps::close_gaps_on;
    use crate::rng::Rng;

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
