//! The model's normals near a point, for the limbs of depth-only renders.

/// The model's normals near a point, for the limb normals of a depth-only
/// render (which splats no normals): the points in a uniform grid of
/// cells of twice the median splat radius, and at a query the
/// kernel-weighted mean normal (`exp(-2 (d / r)^2)`, as the splatter
/// weights a splat `d` away from its centre) of the points facing the
/// camera within twice their radius, as the splatted normal averages the
/// visible splats covering the pixel.
#[derive(Debug, Clone)]
pub struct ModelNormals {
    cell: f32,
    lo: glam::Vec3,
    dims: [usize; 3],
    /// Points of cell `c`: `points[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    /// The model's points that can count (a positive radius), in cell
    /// order and, within a cell, in the model's: a query reads its cells'
    /// points from one place instead of three arrays at random.
    points: Vec<GridPoint>,
    /// Per cell, the largest radius of its points (0 when empty): a cell
    /// farther than twice that from a query holds no point near it.
    reach: Vec<f32>,
}

/// A model point as [`ModelNormals`] keeps it.
#[derive(Debug, Clone, Copy)]
struct GridPoint {
    position: glam::Vec3,
    normal: glam::Vec3,
    radius: f32,
}

impl ModelNormals {
    /// The grid of `model`'s points (`None` for an empty model, or one
    /// without a positive radius).
    pub fn new(model: &crate::model::PointModel) -> Option<Self> {
        if model.positions.is_empty() {
            return None;
        }
        let mut radii: Vec<f32> = model.radii.iter().copied().filter(|r| *r > 0.0).collect();
        if radii.is_empty() {
            return None;
        }
        let mid = radii.len() / 2;
        let median = *radii.select_nth_unstable_by(mid, f32::total_cmp).1;
        let (mut lo, mut hi) = (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN));
        for p in &model.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        // At most about 2^24 cells: a model of a few far-apart points
        // gets larger cells, not a huge grid.
        let extent = (hi - lo).max_element().max(1e-9);
        let cell = (2.0 * median).max(extent / 256.0);
        let dims = [0, 1, 2].map(|k| ((hi[k] - lo[k]) / cell) as usize + 1);
        let n = dims[0] * dims[1] * dims[2];
        let index = |p: &glam::Vec3| {
            let c = ((*p - lo) / cell).as_uvec3();
            let c = [0, 1, 2].map(|k| (c[k] as usize).min(dims[k] - 1));
            (c[2] * dims[1] + c[1]) * dims[0] + c[0]
        };
        // Points with a NaN or non-positive radius never count
        // (`normal_at`): left out.
        let counted = |i: usize| model.radii[i] > 0.0;
        let mut start = vec![0u32; n + 1];
        let mut reach = vec![0f32; n];
        for (i, p) in model.positions.iter().enumerate() {
            if counted(i) {
                let c = index(p);
                start[c + 1] += 1;
                reach[c] = reach[c].max(model.radii[i]);
            }
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let empty = GridPoint {
            position: glam::Vec3::ZERO,
            normal: glam::Vec3::ZERO,
            radius: 0.0,
        };
        let mut points = vec![empty; start[n] as usize];
        for (i, p) in model.positions.iter().enumerate() {
            if counted(i) {
                let c = index(p);
                points[fill[c] as usize] = GridPoint {
                    position: *p,
                    normal: model.normals[i],
                    radius: model.radii[i],
                };
                fill[c] += 1;
            }
        }
        Some(Self {
            cell,
            lo,
            dims,
            start,
            points,
            reach,
        })
    }

    /// The weighted mean normal (object frame, not normalised) at the
    /// object-frame point `x` of the points whose normal faces `eye` (the
    /// camera centre, object frame); `None` when no point is near. The
    /// sums run over the points of the 27 cells around `x` in a fixed
    /// order, skipping the cells too far to hold a point within twice its
    /// radius (which would add nothing).
    pub fn normal_at(&self, x: glam::Vec3, eye: glam::Vec3) -> Option<glam::Vec3> {
        let mut sum = glam::Vec3::ZERO;
        let mut wsum = 0.0f32;
        for (k, q) in self.cells_around(x) {
            if self.beyond_reach(k, q, x) {
                continue;
            }
            for g in self.cell(k) {
                let (p, n, r) = (g.position, g.normal, g.radius);
                if n.dot(eye - p) <= 0.0 {
                    continue;
                }
                let d2 = (x - p).length_squared() / (r * r);
                if d2 > 4.0 {
                    continue;
                }
                let w = (-2.0 * d2).exp();
                sum += n * w;
                wsum += w;
            }
        }
        (wsum > 0.0).then_some(sum)
    }

    /// The radius a point of the model's density is given by the radius
    /// law of mesh sampling and of the radius estimate
    /// (`2 sqrt(A / (pi N))`, `A / N` the area a point), from the
    /// distance `d` to the 8th nearest point as `2 d / sqrt(8)`: the median
    /// over about 2000 points, taken evenly through the grid (`None`
    /// without 9 points near each other). Unlike the splat radii, which
    /// may have been raised to a pixel floor or to close gaps, it measures
    /// how far apart the points lie.
    pub fn sampling_radius(&self) -> Option<f32> {
        const K: usize = 8;
        let step = (self.points.len() / 2000).max(1);
        let mut found: Vec<f32> = Vec::new();
        let mut near: Vec<f32> = Vec::new();
        for g in self.points.iter().step_by(step) {
            let x = g.position;
            near.clear();
            for (k, _) in self.cells_around(x) {
                for p in self.cell(k) {
                    let d2 = (p.position - x).length_squared();
                    if d2 > 0.0 {
                        near.push(d2);
                    }
                }
            }
            if near.len() >= K {
                let d2 = *near.select_nth_unstable_by(K - 1, f32::total_cmp).1;
                found.push(2.0 * d2.sqrt() / (K as f32).sqrt());
            }
        }
        if found.is_empty() {
            return None;
        }
        let mid = found.len() / 2;
        Some(*found.select_nth_unstable_by(mid, f32::total_cmp).1)
    }

    /// The cells of the 27 around `x`'s that lie in the grid, in a fixed
    /// order (z outermost, x innermost): each one's index and coordinates.
    fn cells_around(&self, x: glam::Vec3) -> impl Iterator<Item = (usize, [usize; 3])> + '_ {
        let c = ((x - self.lo) / self.cell).floor();
        (-1..=1)
            .flat_map(|dz| (-1..=1).flat_map(move |dy| (-1..=1).map(move |dx| (dx, dy, dz))))
            .filter_map(move |(dx, dy, dz)| {
                let q = c + glam::Vec3::new(dx as f32, dy as f32, dz as f32);
                if q.min_element() < 0.0 {
                    return None;
                }
                let q = [q.x as usize, q.y as usize, q.z as usize];
                if (0..3).any(|k| q[k] >= self.dims[k]) {
                    return None;
                }
                Some(((q[2] * self.dims[1] + q[1]) * self.dims[0] + q[0], q))
            })
    }

    /// The points of cell `k`.
    fn cell(&self, k: usize) -> &[GridPoint] {
        &self.points[self.start[k] as usize..self.start[k + 1] as usize]
    }

    /// Whether cell `k` (at `q`) lies farther from `x` than twice its
    /// largest radius, with a margin: well beyond f32 rounding in the
    /// cell's bounds (the points on the grid's far faces are clamped into
    /// its last cells) and in `normal_at`'s test, so no point that would
    /// count is skipped.
    fn beyond_reach(&self, k: usize, q: [usize; 3], x: glam::Vec3) -> bool {
        let slack = 1e-3 * self.cell;
        let mut d2 = 0.0f32;
        for a in 0..3 {
            let lo = self.lo[a] + q[a] as f32 * self.cell - slack;
            let hi = self.lo[a] + (q[a] + 1) as f32 * self.cell + slack;
            let d = (lo - x[a]).max(x[a] - hi).max(0.0);
            d2 += d * d;
        }
        let reach = 2.0 * self.reach[k] * 1.001;
        d2 > reach * reach
    }
}

/// The splat radius and the sampling radius (model units) that set a
/// crease's inset ([`super::insets`]): the median of the model's positive
/// radii, and `grid`'s [`ModelNormals::sampling_radius`] (the splat
/// radius where there is no grid or too few points).
pub fn crease_radii(model: &crate::model::PointModel, grid: Option<&ModelNormals>) -> (f64, f64) {
    let mut r: Vec<f32> = model.radii.iter().copied().filter(|r| *r > 0.0).collect();
    let radius = if r.is_empty() {
        0.0
    } else {
        let mid = r.len() / 2;
        *r.select_nth_unstable_by(mid, f32::total_cmp).1 as f64
    };
    let sampling = grid
        .and_then(|g| g.sampling_radius())
        .map_or(radius, |s| s as f64);
    (radius, sampling)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`ModelNormals::normal_at`] as first written: every point of the
    /// 27 cells, read from the model's arrays.
    fn normal_at_reference(
        model: &crate::model::PointModel,
        grid: &ModelNormals,
        x: glam::Vec3,
        eye: glam::Vec3,
    ) -> Option<glam::Vec3> {
        let c = ((x - grid.lo) / grid.cell).floor();
        let (mut sum, mut wsum) = (glam::Vec3::ZERO, 0.0f32);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let q = c + glam::Vec3::new(dx as f32, dy as f32, dz as f32);
                    if q.min_element() < 0.0 {
                        continue;
                    }
                    let q = [q.x as usize, q.y as usize, q.z as usize];
                    if (0..3).any(|k| q[k] >= grid.dims[k]) {
                        continue;
                    }
                    let cell = [0, 1, 2].map(|k| q[k] as u32);
                    for (i, p) in model.positions.iter().enumerate() {
                        let at = ((*p - grid.lo) / grid.cell).as_uvec3();
                        let at = [0, 1, 2].map(|k| at[k].min(grid.dims[k] as u32 - 1));
                        if at != cell {
                            continue;
                        }
                        let (n, r) = (model.normals[i], model.radii[i]);
                        if n.dot(eye - *p) <= 0.0 || r.is_nan() || r <= 0.0 {
                            continue;
                        }
                        let d2 = (x - *p).length_squared() / (r * r);
                        if d2 > 4.0 {
                            continue;
                        }
                        let w = (-2.0 * d2).exp();
                        sum += n * w;
                        wsum += w;
                    }
                }
            }
        }
        (wsum > 0.0).then_some(sum)
    }

    #[test]
    fn model_normals_are_every_near_points_sum_bit_for_bit() {
        // normal_at reads its points packed in cell order and skips the
        // cells beyond their points' reach: the sums must be those over
        // every point of the 27 cells, in the model's order, exactly.
        // Radii from a tenth to four times the median (and some NaN, zero,
        // negative), queries on the surface, off it by up to a few radii
        // and across the grid's faces, eyes all round.
        let c = glam::Vec3::new(0.3, -0.1, 0.2);
        let mut model = crate::model::shapes::sphere(c, 0.5, 3_000, 1.2);
        let mut rng = crate::rng::Rng::new(23);
        for (i, r) in model.radii.iter_mut().enumerate() {
            *r = match i % 50 {
                0 => f32::NAN,
                1 => 0.0,
                2 => -0.01,
                _ => *r * rng.uniform(0.1, 4.0) as f32,
            };
        }
        let grid = ModelNormals::new(&model).unwrap();
        let median = 0.5 * grid.cell;
        let (mut some, mut none) = (0, 0);
        for _ in 0..600 {
            let u = rng.unit_vector();
            let u = glam::Vec3::new(u.x as f32, u.y as f32, u.z as f32);
            let off = rng.uniform(-4.0, 4.0) as f32 * median;
            let x = c + u * (0.5 + off);
            let e = rng.unit_vector();
            let eye = c + glam::Vec3::new(e.x as f32, e.y as f32, e.z as f32) * 3.0;
            let got = grid.normal_at(x, eye);
            let want = normal_at_reference(&model, &grid, x, eye);
            let bits = |v: Option<glam::Vec3>| v.map(|v| v.to_array().map(f32::to_bits));
            assert_eq!(bits(got), bits(want), "x {x}, eye {eye}");
            if got.is_some() {
                some += 1;
            } else {
                none += 1;
            }
        }
        assert!(some > 200 && none > 50, "{some} found, {none} not");
    }

    #[test]
    fn model_normals_are_the_sphere_radial_ones_and_only_facing_points_count() {
        let c = glam::Vec3::new(0.3, -0.1, 0.2);
        let model = crate::model::shapes::sphere(c, 0.5, 20_000, 1.2);
        let grid = ModelNormals::new(&model).unwrap();
        let mut rng = crate::rng::Rng::new(5);
        let mut worst = 0.0f32;
        for _ in 0..200 {
            let u = rng.unit_vector();
            let u = glam::Vec3::new(u.x as f32, u.y as f32, u.z as f32);
            // On the surface, or a radius's worth off it (a pushed-back
            // depth), seen from outside along any direction not behind it.
            let x = c + u * (0.5 + rng.uniform(-0.005, 0.005) as f32);
            let eye = c + u * 3.0;
            let n = grid.normal_at(x, eye).unwrap().normalize();
            worst = worst.max(n.angle_between(u));
            // Seen from the other side, every point near `x` faces away.
            assert!(grid.normal_at(x, c - u * 3.0).is_none());
        }
        assert!(worst < 0.02, "worst normal error {worst} rad");
        // Far from the model: nothing.
        assert!(
            grid.normal_at(c + glam::Vec3::X * 2.0, c + glam::Vec3::X * 3.0)
                .is_none()
        );
    }
}
