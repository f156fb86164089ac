//! A coarser copy of a dense model: the points of each small cube of
//! space that face the same way merged into one splat.
//!
//! A model scanned or sampled finer than the camera resolves it puts
//! several splats in every pixel, and a render costs the splats' pixels:
//! the real cube's 100,000 points fall about three to a pixel at its
//! distance. Merged, a pixel sees the mean of what its points held (their
//! position, normal and colour averaged, a box filter at the cell's size)
//! rather than every point, and the render does a fraction of the work.
//! The surface keeps its shape to within a cell: points are merged only
//! within one cell of a grid and only when their normals lean towards the
//! same face of the cell (the same largest component, with the same
//! sign), so the two sides of a thin wall or of an edge stay apart.

use super::PointModel;
use glam::{DVec3, Vec3};
use std::collections::HashMap;

/// Grid cells along an axis beyond which a merge is not attempted (the
/// cell is then far below the model's size, and nearly every point would
/// stay alone).
const MAX_CELLS_PER_AXIS: f64 = (1u64 << 30) as f64;

/// The points of one merged splat, summed.
#[derive(Default)]
struct Sums {
    count: usize,
    position: DVec3,
    normal: DVec3,
    color: DVec3,
    /// The sum of the members' squared radii.
    area: f64,
    /// The first member (a group of one is copied as it is).
    first: usize,
}

impl PointModel {
    /// This model with the points of each cubic cell of side `cell`
    /// (model units; the grid starts at the bounding box's corner) whose
    /// normals lean the same way merged into one point, in the order of
    /// each group's first point: at the group's mean position, with its
    /// mean normal (normalised) and mean colour, and a radius that covers
    /// the group without growing its area: the smaller of the farthest
    /// member's reach from the mean (its distance plus its radius) and
    /// the square root of the sum of the members' squared radii. A point
    /// alone in its group is kept as it is. Also returns each point's group
    /// (its index in the merged model), to merge what else is kept per
    /// point (a keyframe store's colours:
    /// [`crate::keyframes::KeyframeStore::merged`]). A `cell` that is not
    /// positive and finite, or so small that the grid would exceed 2^30
    /// cells a side, gives a copy of the model, every point its own group.
    pub fn merged(&self, cell: f32) -> (PointModel, Vec<u32>) {
        let (lo, hi) = self.bounds();
        let cell = cell as f64;
        let span = (hi - lo).as_dvec3().max_element() / cell;
        if !(cell > 0.0 && cell.is_finite() && span < MAX_CELLS_PER_AXIS)
            || self.len() > u32::MAX as usize
        {
            return (self.clone(), (0..self.len() as u32).collect());
        }
        let lo = lo.as_dvec3();
        let mut groups: HashMap<(i32, i32, i32, u8), usize> = HashMap::new();
        let mut sums: Vec<Sums> = Vec::new();
        let mut group = Vec::with_capacity(self.len());
        for (i, (p, n)) in self.positions.iter().zip(&self.normals).enumerate() {
            let q = ((p.as_dvec3() - lo) / cell).floor();
            let key = (q.x as i32, q.y as i32, q.z as i32, facing(*n));
            let g = *groups.entry(key).or_insert_with(|| {
                sums.push(Sums {
                    first: i,
                    ..Default::default()
                });
                sums.len() - 1
            });
            group.push(g as u32);
            let s = &mut sums[g];
            let r = self.radii[i] as f64;
            s.count += 1;
            s.position += p.as_dvec3();
            s.normal += n.as_dvec3();
            s.area += r * r;
            if let Some(c) = &self.colors {
                s.color += Vec3::from(c[i]).as_dvec3();
            }
        }
        drop(groups);
        // The farthest reach of each group from its mean, in a second pass.
        let means: Vec<DVec3> = sums.iter().map(|s| s.position / s.count as f64).collect();
        let mut reach = vec![0.0f64; sums.len()];
        for (i, p) in self.positions.iter().enumerate() {
            let g = group[i] as usize;
            let d = (p.as_dvec3() - means[g]).length() + self.radii[i] as f64;
            reach[g] = reach[g].max(d);
        }
        let n = sums.len();
        let mut out = PointModel {
            positions: Vec::with_capacity(n),
            normals: Vec::with_capacity(n),
            radii: Vec::with_capacity(n),
            colors: self.colors.as_ref().map(|_| Vec::with_capacity(n)),
            provenance: self.provenance.clone(),
        };
        for (g, s) in sums.iter().enumerate() {
            let i = s.first;
            if s.count == 1 {
                out.positions.push(self.positions[i]);
                out.normals.push(self.normals[i]);
                out.radii.push(self.radii[i]);
                if let (Some(o), Some(c)) = (&mut out.colors, &self.colors) {
                    o.push(c[i]);
                }
                continue;
            }
            let k = s.count as f64;
            // Within one facing the normals are within 55 degrees of an
            // axis, so their sum is never short.
            let normal = s.normal.normalize_or(self.normals[i].as_dvec3());
            out.positions.push(means[g].as_vec3());
            out.normals.push(normal.as_vec3());
            out.radii.push(reach[g].min(s.area.sqrt()) as f32);
            if let Some(o) = &mut out.colors {
                o.push((s.color / k).as_vec3().clamp(Vec3::ZERO, Vec3::ONE).into());
            }
        }
        (out, group)
    }
}

/// Which face of a cube the normal `n` leans towards: its largest
/// component's axis, and the sign (0..6).
fn facing(n: Vec3) -> u8 {
    let a = n.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    2 * axis + u8::from(n[axis as usize] < 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{AttributeSource, Provenance};

    fn model(positions: Vec<Vec3>, normals: Vec<Vec3>, radius: f32) -> PointModel {
        let n = positions.len();
        PointModel {
            positions,
            normals,
            radii: vec![radius; n],
            colors: Some((0..n).map(|i| [i as f32 / n as f32, 0.5, 1.0]).collect()),
            provenance: Provenance {
                path: None,
                normals: AttributeSource::Loaded,
                radii: AttributeSource::Loaded,
                colors: AttributeSource::Loaded,
                dropped_non_finite: 0,
                normals_reestimated: 0,
            },
        }
    }

    /// A square plate of `side` x `side` points `step` apart in z = 0,
    /// facing +z.
    fn plate(side: usize, step: f32) -> PointModel {
        let positions = (0..side * side)
            .map(|i| Vec3::new((i % side) as f32 * step, (i / side) as f32 * step, 0.0))
            .collect();
        model(positions, vec![Vec3::Z; side * side], step)
    }

    #[test]
    fn a_plate_merges_four_to_one_with_means_and_a_covering_radius() {
        let m = plate(8, 1.0);
        let (c, group) = m.merged(2.0);
        c.validate().expect("a valid model");
        assert_eq!(c.len(), 16);
        assert_eq!(&group[..10], &[0, 0, 1, 1, 2, 2, 3, 3, 0, 0]);
        // The first group: points (0,0), (1,0), (0,1), (1,1).
        assert_eq!(c.positions[0], Vec3::new(0.5, 0.5, 0.0));
        assert_eq!(c.normals[0], Vec3::Z);
        // Covering area: sqrt(4) = 2; the farthest reach sqrt(0.5) + 1.
        assert!((c.radii[0] - (0.5f32.sqrt() + 1.0)).abs() < 1e-6);
        let want = [0.0, 1.0, 8.0, 9.0].map(|i| i / 64.0);
        let red = c.colors.as_ref().unwrap()[0][0];
        assert!((red - want.iter().sum::<f32>() / 4.0).abs() < 1e-6);
        // Every point's area is kept: sum of squared radii.
        let before: f32 = m.radii.iter().map(|r| r * r).sum();
        let after: f32 = c.radii.iter().map(|r| r * r).sum();
        assert!(after <= before * 1.0001, "{after} > {before}");
    }

    #[test]
    fn opposite_faces_and_lone_points_are_kept_apart() {
        // Two points in one cell, facing away from each other (a thin
        // wall), and one point alone.
        let m = model(
            vec![Vec3::ZERO, Vec3::new(0.1, 0.0, 0.0), Vec3::splat(5.0)],
            vec![Vec3::Z, -Vec3::Z, Vec3::X],
            0.2,
        );
        let (c, group) = m.merged(1.0);
        assert_eq!(c.len(), 3);
        assert_eq!(group, [0, 1, 2]);
        assert_eq!(c.positions, m.positions);
        assert_eq!(c.normals, m.normals);
        assert_eq!(c.radii, m.radii);
        assert_eq!(c.colors, m.colors);
    }

    #[test]
    fn a_cell_out_of_range_gives_the_model_back() {
        let m = plate(4, 1.0);
        for cell in [0.0, -1.0, f32::NAN, f32::INFINITY, 1e-12] {
            let (c, group) = m.merged(cell);
            assert_eq!(c.positions, m.positions, "cell {cell}");
            assert_eq!(group, (0..16).collect::<Vec<u32>>());
        }
        // A cell finer than the spacing merges nothing.
        assert_eq!(m.merged(0.5).0.len(), m.len());
    }
}
