//! Static backgrounds of synthetic sequences (linear RGB, the camera's
//! size, row-major): a smooth gradient, the default flat shapes, and a
//! cluttered scene made to defeat a search by colour or by edges alone.
//!
//! Everything here is behind the object: the rasteriser draws the object
//! over the finished background, so the object's pixels stay the
//! object's. Distractor objects are drawn by the same rasteriser, into
//! the background.

use super::objects::{Light, SynthObject, Texture};
use super::raster;
use crate::geometry::{Intrinsics, Pose, rotation_exp};
use crate::model::TriangleMesh;
use crate::rng::Rng;
use nalgebra::{Vector2, Vector3};

/// What is behind the object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Background {
    /// A smooth colour gradient, nothing else: the easy case.
    Plain,
    /// Overlapping flat rectangles and discs of random colours over a
    /// gradient ([`background`]).
    #[default]
    Shapes,
    /// Coloured noise at several scales, thin coloured line segments,
    /// filled rectangles, discs and polygons (half of them in the object's
    /// own colours) and distractor objects: other meshes and the object's
    /// own mesh, smaller or larger, with the object's texture, at other
    /// poses, so that neither colour nor texture alone finds the object.
    Clutter,
}

impl Background {
    /// The names [`Background::by_name`] accepts.
    pub const NAMES: [&'static str; 3] = ["plain", "shapes", "clutter"];

    /// The background called `name` (one of [`Background::NAMES`]).
    pub fn by_name(name: &str) -> Option<Self> {
        match name {
            "plain" => Some(Self::Plain),
            "shapes" => Some(Self::Shapes),
            "clutter" => Some(Self::Clutter),
            _ => None,
        }
    }

    /// Its name, as [`Background::by_name`] takes it.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Plain => "plain",
            Self::Shapes => "shapes",
            Self::Clutter => "clutter",
        }
    }
}

fn gradient(cam: &Intrinsics) -> Vec<[f32; 3]> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 / w as f32, (i / w) as f32 / h as f32);
            [0.35 + 0.2 * x, 0.3 + 0.15 * y, 0.4 - 0.1 * x]
        })
        .collect()
}

/// The [`Background::Shapes`] background: overlapping rectangles and discs
/// of random colours at several scales over a smooth gradient.
pub fn background(cam: &Intrinsics, seed: u64) -> Vec<[f32; 3]> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut rng = Rng::new(seed ^ 0xBAC6);
    let mut img = gradient(cam);
    for _ in 0..140 {
        let size = w as f64 * rng.uniform(0.01, 0.12);
        let (cx, cy) = (rng.uniform(0.0, w as f64), rng.uniform(0.0, h as f64));
        let (sx, sy) = (size, size * rng.uniform(0.4, 1.6));
        let c = [
            rng.uniform(0.05, 0.95) as f32,
            rng.uniform(0.05, 0.95) as f32,
            rng.uniform(0.05, 0.95) as f32,
        ];
        let disc = rng.next_f64() < 0.4;
        let (x0, x1) = ((cx - sx).max(0.0) as usize, ((cx + sx) as usize).min(w - 1));
        let (y0, y1) = ((cy - sy).max(0.0) as usize, ((cy + sy) as usize).min(h - 1));
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (dx, dy) = ((x as f64 - cx) / sx, (y as f64 - cy) / sy);
                if !disc || dx * dx + dy * dy < 1.0 {
                    img[y * w + x] = c;
                }
            }
        }
    }
    img
}

/// The background `kind` for `object` seen by `cam` at `distance`
/// (distractors are placed behind it), from `seed`.
pub fn make_background(
    kind: Background,
    cam: &Intrinsics,
    object: &SynthObject,
    distance: f64,
    seed: u64,
) -> Vec<[f32; 3]> {
    match kind {
        Background::Plain => gradient(cam),
        Background::Shapes => background(cam, seed),
        Background::Clutter => clutter(cam, object, distance, seed),
    }
}

/// A random colour: half the time one of the object's own surface
/// colours, else a random one.
fn pick_colour(rng: &mut Rng, palette: &[[f32; 3]]) -> [f32; 3] {
    if !palette.is_empty() && rng.next_f64() < 0.5 {
        palette[rng.below(palette.len() as u64) as usize]
    } else {
        [0; 3].map(|_: i32| rng.uniform(0.03, 0.97) as f32)
    }
}

/// Colours of the object's surface: its texture at random mesh vertices.
fn palette(object: &SynthObject, rng: &mut Rng) -> Vec<[f32; 3]> {
    let m = &object.mesh;
    (0..64)
        .map(|_| {
            let i = rng.below(m.vertices.len() as u64) as usize;
            let v = m.vertices[i];
            let n = m.normals.as_ref().map_or(v.normalize(), |n| n[i]);
            object
                .texture
                .albedo(&Vector3::new(v.x, v.y, v.z), &Vector3::new(n.x, n.y, n.z))
        })
        .collect()
}

/// Adds coloured value noise to `img`: random colours in -1/2..1/2 on
/// lattices of `octaves` cell sizes (pixels), bilinearly interpolated,
/// times each octave's weight.
fn add_noise(img: &mut [[f32; 3]], w: usize, h: usize, octaves: &[(f64, f32)], rng: &mut Rng) {
    for &(cell, weight) in octaves {
        let (gw, gh) = (
            (w as f64 / cell) as usize + 2,
            (h as f64 / cell) as usize + 2,
        );
        let lattice: Vec<[f32; 3]> = (0..gw * gh)
            .map(|_| [0; 3].map(|_: i32| rng.next_f64() as f32 - 0.5))
            .collect();
        for y in 0..h {
            let fy = y as f64 / cell;
            let (j, ty) = (fy as usize, (fy.fract()) as f32);
            for x in 0..w {
                let fx = x as f64 / cell;
                let (i, tx) = (fx as usize, (fx.fract()) as f32);
                let at = |i: usize, j: usize| lattice[j * gw + i];
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
                let p = &mut img[y * w + x];
                for k in 0..3 {
                    let top = a[k] + (b[k] - a[k]) * tx;
                    let bottom = c[k] + (d[k] - c[k]) * tx;
                    p[k] = (p[k] + weight * (top + (bottom - top) * ty)).clamp(0.0, 1.0);
                }
            }
        }
    }
}

/// Fills the convex polygon `poly` (image points, either winding).
fn fill_polygon(img: &mut [[f32; 3]], w: usize, h: usize, poly: &[Vector2<f64>], c: [f32; 3]) {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in poly {
        (x0, x1, y0, y1) = (x0.min(p.x), x1.max(p.x), y0.min(p.y), y1.max(p.y));
    }
    let xr = (x0.max(0.0).ceil() as usize)..=(x1.min(w as f64 - 1.0).max(-1.0) as usize);
    let yr = (y0.max(0.0).ceil() as usize)..=(y1.min(h as f64 - 1.0).max(-1.0) as usize);
    if x1 < 0.0 || y1 < 0.0 {
        return;
    }
    for y in yr {
        for x in xr.clone() {
            let q = Vector2::new(x as f64, y as f64);
            let mut sign = 0i8;
            let inside = (0..poly.len()).all(|k| {
                let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
                let cr = (b - a).perp(&(q - a));
                // On an edge: inside, and no side to remember.
                if cr == 0.0 {
                    return true;
                }
                let s = if cr > 0.0 { 1 } else { -1 };
                if sign == 0 {
                    sign = s;
                }
                s == sign
            });
            if inside {
                img[y * w + x] = c;
            }
        }
    }
}

/// Draws an antialiased segment from `a` to `b` of `width` pixels.
fn draw_segment(
    img: &mut [[f32; 3]],
    w: usize,
    h: usize,
    (a, b): (Vector2<f64>, Vector2<f64>),
    width: f64,
    c: [f32; 3],
) {
    let r = width / 2.0 + 1.0;
    let x0 = (a.x.min(b.x) - r).max(0.0) as usize;
    let x1 = ((a.x.max(b.x) + r).max(0.0) as usize).min(w - 1);
    let y0 = (a.y.min(b.y) - r).max(0.0) as usize;
    let y1 = ((a.y.max(b.y) + r).max(0.0) as usize).min(h - 1);
    let ab = b - a;
    let len2 = ab.norm_squared().max(1e-12);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let q = Vector2::new(x as f64, y as f64);
            let t = ((q - a).dot(&ab) / len2).clamp(0.0, 1.0);
            let d = (q - (a + ab * t)).norm();
            let alpha = (width / 2.0 + 0.5 - d).clamp(0.0, 1.0) as f32;
            if alpha > 0.0 {
                let p = &mut img[y * w + x];
                for k in 0..3 {
                    p[k] += alpha * (c[k] - p[k]);
                }
            }
        }
    }
}

/// `mesh` scaled by `s` about its origin (normals unchanged).
fn scaled(mesh: &TriangleMesh, s: f64) -> TriangleMesh {
    TriangleMesh {
        vertices: mesh.vertices.iter().map(|v| *v * s).collect(),
        ..mesh.clone()
    }
}

/// Where and how large [`distractors`] are.
pub(crate) struct Placement {
    /// How many.
    pub count: usize,
    /// Range of their centres' depth, in units of the object's distance.
    pub depth: (f64, f64),
    /// Range of their centres' image positions (top-left, bottom-right).
    pub region: (Vector2<f64>, Vector2<f64>),
    /// Range of their size (bounding-box diagonal) in units of the object's.
    pub size: (f64, f64),
    /// Whether every third is the object's own mesh, clearly smaller or
    /// larger (never for an untextured object, whose own mesh at another
    /// scale and depth would look exactly like it).
    pub own: bool,
}

/// Distractor objects for `object` seen by `cam` at `distance`: the other
/// built-in meshes (and its own, see [`Placement::own`]), all with the
/// object's texture, at random orientations, placed as `at` says.
pub(crate) fn distractors(
    object: &SynthObject,
    cam: &Intrinsics,
    distance: f64,
    at: &Placement,
    rng: &mut Rng,
) -> Vec<(SynthObject, Pose)> {
    let own_ok = at.own && !matches!(object.texture, Texture::Plain(_));
    // Other shapes: the built-in meshes unlike the object's own (the box
    // and the plain box share one).
    let mut meshes: Vec<TriangleMesh> = Vec::new();
    for o in super::objects::OBJECT_NAMES
        .iter()
        .filter_map(|n| SynthObject::by_name(n))
    {
        let known = |m: &TriangleMesh| m.vertices == o.mesh.vertices;
        if !known(&object.mesh) && !meshes.iter().any(known) {
            meshes.push(o.mesh);
        }
    }
    let size = object.mesh.diameter();
    (0..at.count)
        .map(|k| {
            let own = own_ok && k % 3 == 0;
            let (mesh, s) = if own {
                let s = if rng.next_f64() < 0.5 {
                    rng.uniform(0.45, 0.7)
                } else {
                    rng.uniform(1.4, 1.8)
                };
                (&object.mesh, s)
            } else {
                let m = &meshes[rng.below(meshes.len() as u64) as usize];
                (m, size / m.diameter() * rng.uniform(at.size.0, at.size.1))
            };
            let z = distance * rng.uniform(at.depth.0, at.depth.1);
            let (lo, hi) = at.region;
            let uv = Vector2::new(rng.uniform(lo.x, hi.x), rng.uniform(lo.y, hi.y));
            let axis = rng.unit_vector();
            let rotation = rotation_exp(&(axis * rng.uniform(0.0, std::f64::consts::PI)));
            let pose = Pose {
                rotation,
                translation: cam.unproject(&uv, z),
            };
            let d = SynthObject {
                name: "distractor",
                description: "a distractor in the object's colours",
                mesh: scaled(mesh, s),
                texture: object.texture.clone(),
            };
            (d, pose)
        })
        .collect()
}

/// The [`Background::Clutter`] background.
fn clutter(cam: &Intrinsics, object: &SynthObject, distance: f64, seed: u64) -> Vec<[f32; 3]> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut rng = Rng::new(seed ^ 0xC1_0773);
    let palette = palette(object, &mut rng);
    // Coloured noise at several scales around mid grey.
    let mut img = vec![[0.5f32; 3]; w * h];
    let coarse = [(90.0, 0.8f32), (30.0, 0.6), (9.0, 0.4), (3.0, 0.2)];
    add_noise(&mut img, w, h, &coarse, &mut rng);
    // Filled shapes at several scales: counts per area of a 640x480 frame.
    let per_area = (w * h) as f64 / (640.0 * 480.0);
    let scale = (w.max(h) as f64) / 640.0;
    for _ in 0..(90.0 * per_area).ceil() as usize {
        let c = pick_colour(&mut rng, &palette);
        let centre = Vector2::new(rng.uniform(0.0, w as f64), rng.uniform(0.0, h as f64));
        let r = scale * 6.0 * (rng.uniform(0.0, 2.5f64)).exp();
        let angle = rng.uniform(0.0, std::f64::consts::TAU);
        let (vertices, aspect) = match rng.below(3) {
            0 => (4, rng.uniform(0.3, 1.0)),       // rectangle
            1 => (32, rng.uniform(0.5, 1.0)),      // disc or ellipse
            _ => (3 + rng.below(4) as usize, 1.0), // polygon
        };
        let poly: Vec<Vector2<f64>> = (0..vertices)
            .map(|k| {
                let a = if vertices == 4 {
                    std::f64::consts::FRAC_PI_4 + k as f64 * std::f64::consts::FRAC_PI_2
                } else {
                    k as f64 * std::f64::consts::TAU / vertices as f64
                };
                let (x, y) = (r * a.cos(), r * aspect * a.sin());
                centre
                    + Vector2::new(
                        x * angle.cos() - y * angle.sin(),
                        x * angle.sin() + y * angle.cos(),
                    )
            })
            .collect();
        fill_polygon(&mut img, w, h, &poly, c);
    }
    for _ in 0..(70.0 * per_area).ceil() as usize {
        let c = pick_colour(&mut rng, &palette);
        let a = Vector2::new(rng.uniform(0.0, w as f64), rng.uniform(0.0, h as f64));
        let len = scale * rng.uniform(15.0, 220.0);
        let angle = rng.uniform(0.0, std::f64::consts::TAU);
        let b = a + Vector2::new(angle.cos(), angle.sin()) * len;
        draw_segment(&mut img, w, h, (a, b), rng.uniform(0.8, 2.5), c);
    }
    // Fine grain over everything flat: shapes look printed, not painted.
    add_noise(
        &mut img,
        w,
        h,
        &[(5.0, 0.2), (2.0, 0.15), (1.0, 0.15)],
        &mut rng,
    );
    let at = Placement {
        count: 7,
        depth: (1.2, 2.2),
        region: (Vector2::zeros(), Vector2::new(w as f64, h as f64)),
        size: (0.6, 1.3),
        own: true,
    };
    for (d, pose) in distractors(object, cam, distance, &at, &mut rng) {
        let light = Light::moving(rng.uniform(0.0, 3.0));
        img = raster::render(&d, &pose, cam, &light, &img, 2).rgb;
    }
    img
}

/// Luminance of a linear RGB colour (Rec. 709 weights).
pub(crate) fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Lowers the background's grey-level contrast around `grey`: every
/// pixel's luminance becomes `grey` plus a fifth of its departure from the
/// mean luminance, its hue kept.
pub(crate) fn lower_contrast(img: &mut [[f32; 3]], grey: f32) {
    let mean = img.iter().map(|&c| luminance(c)).sum::<f32>() / img.len().max(1) as f32;
    for p in img.iter_mut() {
        let l = luminance(*p);
        let target = (grey + 0.2 * (l - mean)).clamp(0.02, 0.98);
        let k = if l > 1e-4 { target / l } else { 0.0 };
        *p = if l > 1e-4 {
            p.map(|v| (v * k).clamp(0.0, 1.0))
        } else {
            [target; 3]
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polygons_and_segments_fill_what_they_should() {
        let (w, h) = (40, 30);
        let mut img = vec![[0.0f32; 3]; w * h];
        let sq =
            [(5.0, 5.0), (15.0, 5.0), (15.0, 12.0), (5.0, 12.0)].map(|(x, y)| Vector2::new(x, y));
        fill_polygon(&mut img, w, h, &sq, [1.0; 3]);
        let filled = img.iter().filter(|c| c[0] == 1.0).count();
        assert_eq!(filled, 11 * 8);
        // Partly off the image: clipped, no panic.
        let off = [(-10.0, -10.0), (3.0, -10.0), (3.0, 2.0)].map(|(x, y)| Vector2::new(x, y));
        fill_polygon(&mut img, w, h, &off, [0.5; 3]);
        let mut img = vec![[0.0f32; 3]; w * h];
        let seg = (Vector2::new(2.0, 20.0), Vector2::new(37.0, 20.0));
        draw_segment(&mut img, w, h, seg, 1.0, [1.0; 3]);
        assert_eq!(img[20 * w + 20][0], 1.0);
        assert_eq!(img[22 * w + 20][0], 0.0);
        assert_eq!(img[20 * w + 39][0], 0.0);
    }

    #[test]
    fn lowered_contrast_centres_the_grey_levels_on_the_target() {
        let cam = Intrinsics::new(64, 48, 60.0, 60.0, 31.5, 23.5);
        let mut img = background(&cam, 3);
        let spread = |img: &[[f32; 3]]| {
            let l: Vec<f32> = img.iter().map(|&c| luminance(c)).collect();
            let m = l.iter().sum::<f32>() / l.len() as f32;
            (
                m,
                (l.iter().map(|v| (v - m).powi(2)).sum::<f32>() / l.len() as f32).sqrt(),
            )
        };
        let (_, before) = spread(&img);
        lower_contrast(&mut img, 0.4);
        let (mean, after) = spread(&img);
        assert!((mean - 0.4).abs() < 0.02, "{mean}");
        assert!(after < 0.3 * before, "{after} vs {before}");
    }
}
