//! Where the object sits in the image: its apparent size, the distance
//! that gives a requested size, and how much of it lies outside the
//! image. All measured on the rasteriser's silhouette (pixel-centre
//! samples), on a canvas around the image large enough to hold the whole
//! object.

use super::raster;
use crate::geometry::{Intrinsics, Pose};
use crate::model::TriangleMesh;

/// The silhouette of `mesh` at `pose` on a canvas of `cam`'s focal length
/// holding both the image and the whole object: (canvas, left and top
/// offset of the image in it, per-pixel depth).
fn canvas_depth(
    mesh: &TriangleMesh,
    pose: &Pose,
    cam: &Intrinsics,
) -> (Intrinsics, i64, i64, Vec<f32>) {
    // The bounding sphere about the origin, projected (generously).
    let radius = mesh.vertices.iter().map(|v| v.length()).fold(0.0, f64::max);
    let c = pose.translation;
    let z = (c.z - radius).max(1e-3);
    let (u, v) = (cam.fx * c.x / c.z + cam.cx, cam.fy * c.y / c.z + cam.cy);
    let r = cam.fx.max(cam.fy) * radius / z + 2.0;
    let left = (u - r).floor().min(0.0) as i64;
    let top = (v - r).floor().min(0.0) as i64;
    let right = ((u + r).ceil() as i64).max(cam.width as i64);
    let bottom = ((v + r).ceil() as i64).max(cam.height as i64);
    let mut big = *cam;
    big.width = (right - left) as u32;
    big.height = (bottom - top) as u32;
    big.cx = cam.cx - left as f64;
    big.cy = cam.cy - top as f64;
    let depth = raster::depth(mesh, pose, &big);
    (big, -left, -top, depth)
}

/// The larger side, in pixels, of the bounding box of `mesh`'s silhouette
/// at `pose` seen by `cam` (parts outside the image included).
pub fn apparent_size_px(mesh: &TriangleMesh, pose: &Pose, cam: &Intrinsics) -> f64 {
    let (big, _, _, depth) = canvas_depth(mesh, pose, cam);
    let w = big.width as usize;
    let (mut x0, mut x1, mut y0, mut y1) = (usize::MAX, 0, usize::MAX, 0);
    for (k, d) in depth.iter().enumerate() {
        if d.is_finite() {
            let (x, y) = (k % w, k / w);
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
    }
    if x0 > x1 {
        return 0.0;
    }
    ((x1 - x0 + 1).max(y1 - y0 + 1)) as f64
}

/// The fraction of the silhouette of `mesh` at `pose` that lies outside
/// `cam`'s image (0 with all of it in view, 1 with none).
pub fn outside_fraction(mesh: &TriangleMesh, pose: &Pose, cam: &Intrinsics) -> f64 {
    let (big, ox, oy, depth) = canvas_depth(mesh, pose, cam);
    let w = big.width as usize;
    let (mut total, mut inside) = (0usize, 0usize);
    for (k, d) in depth.iter().enumerate() {
        if d.is_finite() {
            total += 1;
            let (x, y) = ((k % w) as i64 - ox, (k / w) as i64 - oy);
            if x >= 0 && y >= 0 && x < cam.width as i64 && y < cam.height as i64 {
                inside += 1;
            }
        }
    }
    if total == 0 {
        return 1.0;
    }
    1.0 - inside as f64 / total as f64
}

/// The distance along the line of sight of `view` (a pose whose centre is
/// the object's) at which `mesh` appears `px` pixels across
/// ([`apparent_size_px`]): `view(d)` gives the pose at distance `d`.
pub fn distance_for_size(
    mesh: &TriangleMesh,
    cam: &Intrinsics,
    px: f64,
    view: impl Fn(f64) -> Pose,
) -> f64 {
    // The size goes nearly as 1 / d: a few fixed-point steps converge.
    let mut d = 0.55;
    for _ in 0..6 {
        let s = apparent_size_px(mesh, &view(d), cam);
        if s <= 0.0 {
            break;
        }
        d *= s / px;
    }
    d
}

/// The sideways shift (metres along camera x) that puts `fraction` of the
/// silhouette of `mesh` at `pose` outside the image's right edge.
pub fn shift_for_exit(mesh: &TriangleMesh, pose: &Pose, cam: &Intrinsics, fraction: f64) -> f64 {
    let at = |x: f64| {
        let mut p = *pose;
        p.translation.x += x;
        outside_fraction(mesh, &p, cam)
    };
    if fraction <= at(0.0) {
        return 0.0;
    }
    // Far enough right to be wholly out: an image width plus the object.
    let z = pose.translation.z;
    let size = apparent_size_px(mesh, pose, cam);
    let (mut lo, mut hi) = (0.0, z * (cam.width as f64 + 2.0 * size) / cam.fx);
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        if at(mid) < fraction {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}
