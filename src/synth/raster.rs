//! An ordinary CPU triangle rasteriser for ground-truth images.
//!
//! Synthetic sequences must not be rendered by the splatter under test
//! (docs/how-it-works.md), or the splatter's own errors would cancel out. This
//! is a plain z-buffered scan conversion with perspective-correct
//! interpolation, sampled exactly at pixel centres in OpenCV's convention
//! (pixel (u, v) is the point (u, v) of the image plane), with an optional
//! n x n supersampling grid centred on each pixel centre (so it adds blur,
//! never a shift).
//!
//! It is also the splatter's independent reference in tests: [`depth`]
//! gives the z-buffer of any [`TriangleMesh`] at the pixel centres.

use super::objects::{Light, SynthObject};
use crate::geometry::{Intrinsics, Pose};
use crate::model::TriangleMesh;
use glam::DVec3;
use nalgebra::{Vector2, Vector3};

/// What one rendering produced: a linear RGB image in 0..1, the depth
/// (camera z at the pixel centre; NaN off the object) and the object's
/// coverage of the pixel (0..1).
pub struct Rendering {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Linear RGB in 0..1, row-major.
    pub rgb: Vec<[f32; 3]>,
    /// Camera-space z at each pixel centre; NaN off the object.
    pub depth: Vec<f32>,
    /// Fraction of the pixel's samples on the object (0..1).
    pub coverage: Vec<f32>,
}

struct ProjectedVertex {
    /// Image position, OpenCV pixels.
    uv: Vector2<f64>,
    inv_z: f64,
    cam: Vector3<f64>,
}

fn na(v: DVec3) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}

/// The nearest triangle at every sample of an `s x s` grid per pixel.
struct Samples {
    /// Samples per pixel and axis.
    s: usize,
    /// Samples per row.
    sw: usize,
    /// Camera z of the nearest surface; infinite where none.
    zbuf: Vec<f64>,
    /// The nearest triangle; `u32::MAX` where none.
    hit: Vec<u32>,
    /// Perspective-correct barycentrics of the triangle's first two vertices.
    bary: Vec<[f32; 2]>,
    /// The mesh `hit` indexes (position in the list rasterised).
    mesh: Vec<u8>,
    /// Per sample, bit `m` set where mesh `m` covers it, hidden or not
    /// (empty unless asked for).
    alone: Vec<u32>,
}

impl Samples {
    /// Camera z at the centre sample of pixel (x, y) (`s` odd); NaN off the mesh.
    fn centre_depth(&self, x: usize, y: usize) -> f32 {
        let s = self.s;
        let k = (y * s + s / 2) * self.sw + x * s + s / 2;
        if self.hit[k] == u32::MAX {
            f32::NAN
        } else {
            self.zbuf[k] as f32
        }
    }
}

/// The z-buffer of `mesh` at `pose`: camera z at every pixel centre
/// (OpenCV convention), NaN where the mesh does not cover it.
pub fn depth(mesh: &TriangleMesh, pose: &Pose, cam: &Intrinsics) -> Vec<f32> {
    let samples = rasterise(mesh, pose, cam, 1);
    let w = cam.width as usize;
    (0..w * cam.height as usize)
        .map(|k| samples.centre_depth(k % w, k / w))
        .collect()
}

/// Scan-converts `mesh` at `pose` into an `s x s` sample grid per pixel.
fn rasterise(mesh: &TriangleMesh, pose: &Pose, cam: &Intrinsics, s: usize) -> Samples {
    rasterise_many(&[(mesh, pose)], cam, s, false)
}

/// Scan-converts every mesh at its pose into one `s x s` sample grid per
/// pixel with one depth test, so the nearest surface of any mesh wins;
/// with `alone`, also notes which meshes cover each sample.
fn rasterise_many(
    meshes: &[(&TriangleMesh, &Pose)],
    cam: &Intrinsics,
    s: usize,
    alone: bool,
) -> Samples {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let (sw, sh) = (w * s, h * s);
    let mut zbuf = vec![f64::INFINITY; sw * sh];
    let mut hit: Vec<u32> = vec![u32::MAX; sw * sh];
    let mut bary: Vec<[f32; 2]> = vec![[0.0; 2]; sw * sh];
    let mut which: Vec<u8> = vec![0; sw * sh];
    let mut covered: Vec<u32> = if alone { vec![0; sw * sh] } else { Vec::new() };
    for (m, (mesh, pose)) in meshes.iter().enumerate() {
        let bit = 1u32 << m;
        let verts: Vec<ProjectedVertex> = mesh
            .vertices
            .iter()
            .map(|v| {
                let c = pose.transform_point(&na(*v));
                let inv_z = 1.0 / c.z;
                ProjectedVertex {
                    uv: Vector2::new(cam.fx * c.x * inv_z + cam.cx, cam.fy * c.y * inv_z + cam.cy),
                    inv_z,
                    cam: c,
                }
            })
            .collect();
        const NEAR: f64 = 1e-3;
        for (ti, tri) in mesh.triangles.iter().enumerate() {
            let [a, b, c] = tri.map(|i| &verts[i as usize]);
            if a.cam.z < NEAR || b.cam.z < NEAR || c.cam.z < NEAR {
                continue;
            }
            // Supersample-space coordinates: sample (i, j) sits at pixel
            // (i / s + offset, ...) i.e. p_ss = (p + 0.5) s - 0.5.
            let to_ss =
                |p: &Vector2<f64>| ((p.x + 0.5) * s as f64 - 0.5, (p.y + 0.5) * s as f64 - 0.5);
            let (ax, ay) = to_ss(&a.uv);
            let (bx, by) = to_ss(&b.uv);
            let (cx, cy) = to_ss(&c.uv);
            let area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
            if area.abs() < 1e-12 {
                continue;
            }
            let xmin = ax.min(bx).min(cx).ceil().max(0.0) as i64;
            let xmax = ax.max(bx).max(cx).floor().min(sw as f64 - 1.0) as i64;
            let ymin = ay.min(by).min(cy).ceil().max(0.0) as i64;
            let ymax = ay.max(by).max(cy).floor().min(sh as f64 - 1.0) as i64;
            if xmin > xmax || ymin > ymax {
                continue;
            }
            let inv_area = 1.0 / area;
            for y in ymin..=ymax {
                let py = y as f64;
                for x in xmin..=xmax {
                    let px = x as f64;
                    // Edge functions; a top-left rule is unnecessary since a
                    // shared-edge double hit is resolved by the depth test.
                    let w0 = ((bx - px) * (cy - py) - (by - py) * (cx - px)) * inv_area;
                    let w1 = ((cx - px) * (ay - py) - (cy - py) * (ax - px)) * inv_area;
                    let w2 = 1.0 - w0 - w1;
                    if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                        continue;
                    }
                    let inv_z = w0 * a.inv_z + w1 * b.inv_z + w2 * c.inv_z;
                    let z = 1.0 / inv_z;
                    let k = y as usize * sw + x as usize;
                    if alone {
                        covered[k] |= bit;
                    }
                    if z < zbuf[k] {
                        zbuf[k] = z;
                        hit[k] = ti as u32;
                        which[k] = m as u8;
                        // Perspective-correct barycentrics of vertices a and b.
                        bary[k] = [(w0 * a.inv_z * z) as f32, (w1 * b.inv_z * z) as f32];
                    }
                }
            }
        }
    }
    Samples {
        s,
        sw,
        zbuf,
        hit,
        bary,
        mesh: which,
        alone: covered,
    }
}

/// A mesh's exact outline, to compare image positions against: its
/// coverage rasterised at `scale` times the camera's resolution (pixel
/// centres mapped as OpenCV's, `x' = scale (x + 1/2) - 1/2`), independent
/// of the splatter.
pub struct ExactOutline {
    scale: f64,
    width: usize,
    height: usize,
    depth: Vec<f32>,
}

impl ExactOutline {
    /// The outline of `mesh` at `pose` seen by `cam`, at `scale` (an
    /// integer factor) times its resolution.
    pub fn new(mesh: &TriangleMesh, pose: &Pose, cam: &Intrinsics, scale: u32) -> Self {
        let s = scale as f64;
        let mut big = *cam;
        (big.width, big.height) = (cam.width * scale, cam.height * scale);
        (big.fx, big.fy) = (cam.fx * s, cam.fy * s);
        (big.cx, big.cy) = (s * (cam.cx + 0.5) - 0.5, s * (cam.cy + 0.5) - 0.5);
        Self {
            scale: s,
            width: big.width as usize,
            height: big.height as usize,
            depth: depth(mesh, pose, &big),
        }
    }

    /// Whether the mesh covers the image point `p` (camera pixels; to the
    /// nearest fine sample).
    pub fn covers(&self, p: Vector2<f64>) -> bool {
        let s = self.scale;
        let (x, y) = (
            (s * (p.x + 0.5) - 0.5).round(),
            (s * (p.y + 0.5) - 0.5).round(),
        );
        x >= 0.0
            && y >= 0.0
            && x < self.width as f64
            && y < self.height as f64
            && self.depth[y as usize * self.width + x as usize].is_finite()
    }

    /// Where the outline crosses the line from `p` along the unit `normal`
    /// (offset, pixels, positive along `normal`): the first step from
    /// covered to empty, every 1/20 px from `reach` px behind `p` to
    /// `reach` px ahead, at the step's middle; `None` without one.
    pub fn boundary_along(&self, p: Vector2<f64>, normal: Vector2<f64>, reach: f64) -> Option<f64> {
        let n = (reach / 0.05).round() as i64;
        (-n..n)
            .map(|i| (i as f64 * 0.05, (i + 1) as f64 * 0.05))
            .find(|&(a, b)| self.covers(p + normal * a) && !self.covers(p + normal * b))
            .map(|(a, b)| 0.5 * (a + b))
    }
}

/// Renders `object` at `pose` over `background` (linear RGB, the camera's
/// size, row-major) with `samples` x `samples` supersampling. Shading uses
/// the mesh's vertex normals (its face normals where it has none).
pub fn render(
    object: &SynthObject,
    pose: &Pose,
    cam: &Intrinsics,
    light: &Light,
    background: &[[f32; 3]],
    samples: usize,
) -> Rendering {
    let joint = render_many(&[(object, pose)], cam, light, background, samples);
    Rendering {
        width: joint.width,
        height: joint.height,
        rgb: joint.rgb,
        depth: joint.depth,
        coverage: joint.coverage.into_iter().next().unwrap_or_default(),
    }
}

/// The most objects [`render_many`] takes (one bit each per sample).
pub const MAX_OBJECTS: usize = 32;

/// What [`render_many`] produced: the image, the nearest surface's depth,
/// which object each pixel shows and how much of each object is seen.
pub struct JointRendering {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Linear RGB in 0..1, row-major.
    pub rgb: Vec<[f32; 3]>,
    /// Camera-space z of the nearest surface at each pixel centre; NaN
    /// where no object is.
    pub depth: Vec<f32>,
    /// The object (its index in the list rendered) seen at each pixel
    /// centre; [`NO_OBJECT`] where none is. With an even number of
    /// samples, the object of the sample nearest the centre.
    pub id: Vec<u8>,
    /// Per object, the fraction of each pixel's samples where it is the
    /// nearest surface (0..1).
    pub coverage: Vec<Vec<f32>>,
    /// Per object, the samples where it is the nearest surface.
    pub visible_samples: Vec<u64>,
    /// Per object, the samples it covers, hidden or not: what it would
    /// cover rendered alone.
    pub silhouette_samples: Vec<u64>,
}

impl JointRendering {
    /// The fraction (0..1) of object `k`'s silhouette that is visible: 1
    /// where nothing hides it, 0 where it is wholly hidden or not in the
    /// image at all.
    pub fn visible_fraction(&self, k: usize) -> f64 {
        match self.silhouette_samples[k] {
            0 => 0.0,
            n => self.visible_samples[k] as f64 / n as f64,
        }
    }
}

/// [`JointRendering::id`] where no object is seen.
pub const NO_OBJECT: u8 = u8::MAX;

/// Renders every object at its pose into one image over `background`
/// (linear RGB, the camera's size, row-major), with one depth test over all
/// their surfaces, so each pixel sample shows the nearest object and
/// occlusion between them is exact. Shading as in [`render`].
///
/// # Panics
///
/// With more than [`MAX_OBJECTS`] objects.
pub fn render_many(
    objects: &[(&SynthObject, &Pose)],
    cam: &Intrinsics,
    light: &Light,
    background: &[[f32; 3]],
    samples: usize,
) -> JointRendering {
    assert!(
        objects.len() <= MAX_OBJECTS,
        "at most {MAX_OBJECTS} objects"
    );
    let (w, h) = (cam.width as usize, cam.height as usize);
    let s = samples.max(1);
    let meshes: Vec<(&TriangleMesh, &Pose)> = objects.iter().map(|(o, p)| (&o.mesh, *p)).collect();
    let grid = rasterise_many(&meshes, cam, s, objects.len() > 1);
    let (sw, zbuf, hit, bary) = (grid.sw, &grid.zbuf, &grid.hit, &grid.bary);
    let n_obj = objects.len();
    let mut out = JointRendering {
        width: cam.width,
        height: cam.height,
        rgb: vec![[0.0; 3]; w * h],
        depth: vec![f32::NAN; w * h],
        id: vec![NO_OBJECT; w * h],
        coverage: vec![vec![0.0; w * h]; n_obj],
        visible_samples: vec![0; n_obj],
        silhouette_samples: vec![0; n_obj],
    };
    let inv_n = 1.0 / (s * s) as f32;
    let mut cover = vec![0u32; n_obj];
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0.0f32; 3];
            cover.fill(0);
            let mut nearest = f64::INFINITY;
            for j in 0..s {
                for i in 0..s {
                    let k = (y * s + j) * sw + x * s + i;
                    if let Some(bits) = grid.alone.get(k) {
                        for (m, n) in out.silhouette_samples.iter_mut().enumerate() {
                            *n += u64::from(bits >> m & 1);
                        }
                    }
                    let t = hit[k];
                    if t == u32::MAX {
                        let bg = background[y * w + x];
                        for c in 0..3 {
                            acc[c] += bg[c];
                        }
                        continue;
                    }
                    let m = grid.mesh[k] as usize;
                    let (object, pose) = objects[m];
                    let albedo_shade = shade(object, pose, light, t, bary[k]);
                    for c in 0..3 {
                        acc[c] += albedo_shade[c];
                    }
                    cover[m] += 1;
                    nearest = nearest.min(zbuf[k]);
                }
            }
            let o = y * w + x;
            let any = cover.iter().any(|&c| c > 0);
            // Depth at the pixel centre itself where a sample sits there
            // (odd `samples`), else the nearest sample's.
            let depth = if s % 2 == 1 {
                grid.centre_depth(x, y)
            } else if any {
                nearest as f32
            } else {
                f32::NAN
            };
            let centre = (y * s + s / 2) * sw + x * s + s / 2;
            if hit[centre] != u32::MAX {
                out.id[o] = grid.mesh[centre];
            }
            out.rgb[o] = acc.map(|v| v * inv_n);
            out.depth[o] = depth;
            for (m, &c) in cover.iter().enumerate() {
                out.coverage[m][o] = c as f32 * inv_n;
                out.visible_samples[m] += u64::from(c);
            }
        }
    }
    if grid.alone.is_empty() {
        // One object: what it covers is what is seen.
        out.silhouette_samples.clone_from(&out.visible_samples);
    }
    out
}

/// The fraction (0..1) of each mesh's silhouette that is visible with all
/// of them at their poses (one depth test over all, `s x s` samples per
/// pixel): what [`render_many`] measures, without shading.
///
/// # Panics
///
/// With more than [`MAX_OBJECTS`] meshes.
pub fn visible_fractions(
    meshes: &[(&TriangleMesh, &Pose)],
    cam: &Intrinsics,
    samples: usize,
) -> Vec<f64> {
    assert!(meshes.len() <= MAX_OBJECTS, "at most {MAX_OBJECTS} meshes");
    let grid = rasterise_many(meshes, cam, samples.max(1), true);
    let mut seen = vec![0u64; meshes.len()];
    let mut all = vec![0u64; meshes.len()];
    for (k, bits) in grid.alone.iter().enumerate() {
        if grid.hit[k] != u32::MAX {
            seen[grid.mesh[k] as usize] += 1;
        }
        for (m, n) in all.iter_mut().enumerate() {
            *n += u64::from(bits >> m & 1);
        }
    }
    seen.iter()
        .zip(&all)
        .map(|(&v, &n)| if n == 0 { 0.0 } else { v as f64 / n as f64 })
        .collect()
}

/// The shaded colour of `object` at its triangle `t`, at the point of
/// perspective-correct barycentrics `bary` (of its first two vertices).
fn shade(object: &SynthObject, pose: &Pose, light: &Light, t: u32, bary: [f32; 2]) -> [f32; 3] {
    let mesh = &object.mesh;
    let [ia, ib, ic] = mesh.triangles[t as usize];
    let [ba, bb] = bary;
    let bc = 1.0 - ba - bb;
    let [pa, pb, pc] = [ia, ib, ic].map(|i| na(mesh.vertices[i as usize]));
    let p = pa * ba as f64 + pb * bb as f64 + pc * bc as f64;
    let n = match &mesh.normals {
        Some(normals) => {
            let [na_, nb, nc] = [ia, ib, ic].map(|i| na(normals[i as usize]));
            (na_ * ba as f64 + nb * bb as f64 + nc * bc as f64).normalize()
        }
        None => (pb - pa).cross(&(pc - pa)).normalize(),
    };
    let albedo = object.texture.albedo(&p, &n);
    let n_cam = pose.rotation * n;
    let shade = light.shade(&n_cam) as f32;
    albedo.map(|a| a * shade)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    /// Known answer: a box seen face on, centred on the optical axis, has
    /// its front face as outline, whose edges project to `c ± f h / z`.
    /// The coverage and the boundary along a line agree with them to the
    /// fine raster's resolution (1/8 px) plus the search step (1/20 px).
    #[test]
    fn the_exact_outline_of_a_box_seen_face_on_is_its_front_face() {
        let cam = Intrinsics::new(160, 120, 150.0, 150.0, 79.5, 59.5);
        let half = DVec3::new(0.03, 0.02, 0.01);
        let mesh = TriangleMesh::cuboid(half, 1);
        let z = 0.4;
        let pose = Pose::new(Matrix3::identity(), Vector3::new(0.0, 0.0, z)).unwrap();
        let outline = ExactOutline::new(&mesh, &pose, &cam, 8);
        // The front face at depth z - half.z.
        let right = cam.cx + cam.fx * half.x / (z - half.z);
        let bottom = cam.cy + cam.fy * half.y / (z - half.z);
        let tol = 1.0 / 8.0 + 0.05;
        assert!(outline.covers(Vector2::new(cam.cx, cam.cy)));
        assert!(outline.covers(Vector2::new(right - 0.3, bottom - 0.3)));
        assert!(!outline.covers(Vector2::new(right + 0.3, cam.cy)));
        assert!(!outline.covers(Vector2::new(cam.cx, bottom + 0.3)));
        for (p, n, want) in [
            (Vector2::new(right - 1.3, 61.2), Vector2::new(1.0, 0.0), 1.3),
            (
                Vector2::new(70.4, bottom + 0.8),
                Vector2::new(0.0, 1.0),
                -0.8,
            ),
        ] {
            let b = outline.boundary_along(p, n, 3.0).expect("a boundary");
            assert!((b - want).abs() < tol, "{b} against {want}");
        }
        // At 45 degrees to the right edge: along the line, 1 / cos 45
        // times the distance to the edge.
        let n = Vector2::new(1.0, 1.0).normalize();
        let p = Vector2::new(right - 1.0, cam.cy);
        let b = outline.boundary_along(p, n, 3.0).expect("a boundary");
        assert!((b - 2f64.sqrt()).abs() < tol * 2f64.sqrt(), "{b}");
        // No boundary within reach inside the face.
        assert_eq!(
            outline.boundary_along(Vector2::new(cam.cx, cam.cy), n, 3.0),
            None
        );
    }
}
