//! The host splatter (`splat::cpu`) against a literal transcription of
//! shaders/splat.wgsl's two passes: one splat after another over the
//! whole image, on one thread, with no culling beyond the shader's and no
//! term computed ahead. The host splatter culls, bins into bands, keeps
//! pass 1's hits for pass 2 and runs on threads; every pixel still sees
//! the same splats in the same order with the same f32 operations, so
//! its targets are the transcription's bit for bit, on any thread count,
//! for any attribute subset, in windows and across reused scratch.

use glam::{Vec2, Vec3};

mod data_common;
use nalgebra::Vector3;
use splattrack::geometry::{Intrinsics, Pose, look_at};
use splattrack::model::{PointModel, shapes};
use splattrack::rng::Rng;
use splattrack::splat::cpu::{self, Accumulators, HostSplatter};
use splattrack::splat::gpu_data::{CameraUniform, SplatGpu, unpack_color};
use splattrack::splat::{
    Attribute, Attributes, GatherMode, ModelBounds, PackedModel, SplatImage, SplatParams, Window,
    pack_model,
};

struct View {
    rot: [Vec3; 3],
    trans: Vec3,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    w: f32,
    h: f32,
    near: f32,
    far: f32,
    eps: f32,
    lowpass: f32,
}

impl View {
    fn new(u: &CameraUniform) -> Self {
        let v3 = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
        Self {
            rot: [v3(u.rot[0]), v3(u.rot[1]), v3(u.rot[2])],
            trans: v3(u.trans),
            fx: u.intr[0],
            fy: u.intr[1],
            cx: u.intr[2],
            cy: u.intr[3],
            w: u.size[0],
            h: u.size[1],
            near: u.size[2],
            far: u.size[3],
            eps: u.params[0],
            lowpass: u.params[1],
        }
    }

    fn apply(&self, p: Vec3) -> Vec3 {
        Vec3::new(self.rot[0].dot(p), self.rot[1].dot(p), self.rot[2].dot(p))
    }

    fn project(&self, x: Vec3) -> Vec2 {
        Vec2::new(self.fx * x.x / x.z + self.cx, self.fy * x.y / x.z + self.cy)
    }

    fn depth_of(&self, z: f32) -> f32 {
        ((z - self.near) / (self.far - self.near)).clamp(0.0, 1.0)
    }
}

/// A splat after the vertex stage: camera-space data and its pixel range.
struct Setup {
    c: Vec3,
    m: Vec3,
    r: f32,
    proj: Vec2,
    color: Vec3,
    lo: Vec2,
    hi: Vec2,
}

fn tangent(n: Vec3) -> Vec3 {
    let a = n.abs();
    let axis = if a.y <= a.x && a.y <= a.z {
        Vec3::Y
    } else if a.z <= a.x && a.z <= a.y {
        Vec3::Z
    } else {
        Vec3::X
    };
    n.cross(axis).normalize()
}

fn setup(v: &View, s: &SplatGpu, color: u32) -> Option<Setup> {
    let p = Vec3::new(s.pos_radius[0], s.pos_radius[1], s.pos_radius[2]);
    let r = s.pos_radius[3];
    let c = v.apply(p) + v.trans;
    let m = v
        .apply(Vec3::new(s.normal[0], s.normal[1], s.normal[2]))
        .normalize();
    // Same culling as vs_splat (a NaN radius is culled too).
    if c.z <= v.near || m.dot(c) >= 0.0 || r.is_nan() || r <= 0.0 {
        return None;
    }
    let pc = v.project(c);
    let hh = Vec2::splat(v.lowpass);
    let (mut lo, mut hi) = (pc - hh, pc + hh);
    let t = tangent(m);
    let tu = t * r;
    let tv = m.cross(t) * r;
    let k = [c + tu + tv, c + tu - tv, c - tu + tv, c - tu - tv];
    let size = Vec2::new(v.w, v.h);
    if k.iter().any(|k| k.z <= v.near) {
        lo = Vec2::splat(-1.0);
        hi = size;
    } else {
        for k in k {
            let q = v.project(k);
            lo = lo.min(q);
            hi = hi.max(q);
        }
    }
    lo = (lo - 0.5).clamp(Vec2::splat(-1.0), size);
    hi = (hi + 0.5).clamp(Vec2::splat(-1.0), size);
    Some(Setup {
        c,
        m,
        r,
        proj: pc,
        color: Vec3::from(unpack_color(color)),
        lo,
        hi,
    })
}

/// `intersect` of shaders/splat.wgsl: (X, w, |d|), or None outside the
/// support. `uv` is the pixel centre in OpenCV coordinates.
fn intersect(v: &View, s: &Setup, uv: Vec2) -> Option<(Vec3, f32, f32)> {
    let d = Vec3::new((uv.x - v.cx) / v.fx, (uv.y - v.cy) / v.fy, 1.0);
    let ray_len = d.length();
    let denom = s.m.dot(d);
    let mut rho_obj2 = 1e30f32;
    let mut x = d * s.c.z;
    if denom.abs() > 1e-12 {
        let t = s.m.dot(s.c) / denom;
        if t > v.near {
            let xi = d * t;
            let q = xi - s.c;
            rho_obj2 = q.dot(q) / (s.r * s.r);
            let reach = s.r + 3.0 * v.lowpass * s.c.z / v.fx.min(v.fy);
            if rho_obj2 <= 1.0 || q.dot(q) <= reach * reach {
                x = xi;
            }
        }
    }
    let e = (uv - s.proj) / v.lowpass;
    let rho2 = rho_obj2.min(e.dot(e));
    if rho2 > 1.0 || x.z <= v.near {
        return None;
    }
    Some((x, (-2.0 * rho2).exp(), ray_len))
}

/// Iterates over the pixels whose centres the GPU rasteriser would shade
/// for this splat's quad (centres inside `[lo, hi]`).
fn pixels(v: &View, s: &Setup) -> impl Iterator<Item = (u32, u32)> {
    let x0 = s.lo.x.ceil().max(0.0) as u32;
    let y0 = s.lo.y.ceil().max(0.0) as u32;
    let x1 = (s.hi.x.floor().min(v.w - 1.0)).max(-1.0) as i64;
    let y1 = (s.hi.y.floor().min(v.h - 1.0)).max(-1.0) as i64;
    (y0 as i64..=y1).flat_map(move |y| (x0 as i64..=x1).map(move |x| (x as u32, y as u32)))
}

/// `jac` of shaders/splat.wgsl: `J(X) v`.
fn jac(v: &View, x: Vec3, d: Vec3) -> [f32; 2] {
    let iz = 1.0 / x.z;
    [
        v.fx * iz * (d.x - x.x * iz * d.z),
        v.fy * iz * (d.y - x.y * iz * d.z),
    ]
}

fn motion(v: &View, x: Vec3) -> [f32; 12] {
    let g = [
        Vec3::X,
        Vec3::Y,
        Vec3::Z,
        Vec3::new(0.0, -x.z, x.y),
        Vec3::new(x.z, 0.0, -x.x),
        Vec3::new(-x.y, x.x, 0.0),
    ];
    let mut out = [0.0; 12];
    for (j, gj) in g.iter().enumerate() {
        let l = jac(v, x, *gj);
        out[2 * j] = l[0];
        out[2 * j + 1] = l[1];
    }
    out
}

/// The splats of `model` that reach the view, set up for rasterising.
fn setups(v: &View, model: &PackedModel) -> Vec<Setup> {
    model
        .splats
        .iter()
        .zip(&model.colors)
        .filter_map(|(s, &c)| setup(v, s, c))
        .collect()
}

/// Passes 1 and 2, one splat after another over the whole image.
pub fn naive_splat(model: &PackedModel, uniform: &CameraUniform) -> Accumulators {
    let v = View::new(uniform);
    let (w, h) = (v.w as usize, v.h as usize);
    let setups = setups(&v, model);
    let uv = |x: u32, y: u32| Vec2::new(x as f32, y as f32);
    let (depth, _) = visibility(&v, &setups);
    // Pass 2: attributes, depth test less-or-equal, no depth writes.
    let mut t: [Vec<[f32; 4]>; 5] = std::array::from_fn(|_| vec![[0.0; 4]; w * h]);
    for s in &setups {
        for (x, y) in pixels(&v, s) {
            let Some((xx, wt, _)) = intersect(&v, s, uv(x, y)) else {
                continue;
            };
            let i = y as usize * w + x as usize;
            if v.depth_of(xx.z) > depth[i] {
                continue;
            }
            let l = motion(&v, xx);
            let add = |acc: &mut [f32; 4], a: [f32; 4]| {
                for k in 0..4 {
                    acc[k] += a[k] * wt;
                }
            };
            add(&mut t[0][i], [s.color.x, s.color.y, s.color.z, 1.0]);
            add(&mut t[1][i], [xx.z, s.m.x, s.m.y, s.m.z]);
            add(&mut t[2][i], [l[0], l[1], l[2], l[3]]);
            add(&mut t[3][i], [l[4], l[5], l[6], l[7]]);
            add(&mut t[4][i], [l[8], l[9], l[10], l[11]]);
        }
    }
    Accumulators {
        width: w as u32,
        height: h as u32,
        targets: t,
    }
}

/// Pass 1 (visibility): per pixel, the nearest depth ([0, 1], 1 where
/// empty) pushed back by epsilon along the ray, and the camera-space z it
/// stands for (the pushed-back z of the first splat to reach it, in the
/// order the rasteriser draws them; NaN where empty).
fn visibility(v: &View, setups: &[Setup]) -> (Vec<f32>, Vec<f32>) {
    let (w, h) = (v.w as usize, v.h as usize);
    let uv = |x: u32, y: u32| Vec2::new(x as f32, y as f32);
    let mut depth = vec![1.0f32; w * h];
    let mut z = vec![f32::NAN; w * h];
    for s in setups {
        for (x, y) in pixels(v, s) {
            if let Some((xx, _, len)) = intersect(v, s, uv(x, y)) {
                let zp = xx.z + v.eps * s.r / len;
                let dd = v.depth_of(zp);
                let i = y as usize * w + x as usize;
                if dd < depth[i] {
                    depth[i] = dd;
                    z[i] = zp;
                }
            }
        }
    }
    (depth, z)
}

/// How many values differ bit for bit (NaN equal to NaN).
fn differing(a: &[f32], b: &[f32]) -> usize {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .filter(|(p, q)| p.to_bits() != q.to_bits() && !(p.is_nan() && q.is_nan()))
        .count()
}

fn flat(t: &[[f32; 4]]) -> &[f32] {
    t.as_flattened()
}

fn view_of(model: &PointModel, cam: &Intrinsics, pose: &Pose) -> (PackedModel, CameraUniform) {
    let params = SplatParams::default();
    let packed = pack_model(model, &params).unwrap();
    let uniform = ModelBounds::of(model).view(cam, pose, &params).unwrap();
    (packed, uniform)
}

/// Every thread count, every attribute subset (each also keeping its
/// visibility depth) and the depth-only pass against the transcription;
/// returns the pixels covered.
fn check(packed: &PackedModel, uniform: &CameraUniform, label: &str) -> usize {
    let naive = naive_splat(packed, uniform);
    let v = View::new(uniform);
    let (_, z) = visibility(&v, &setups(&v, packed));
    let covered = naive.targets[0].iter().filter(|p| p[3] > 0.0).count();
    let mut out = Accumulators::default();
    for threads in [1, 2, 3, 7] {
        let mut host = HostSplatter::with_threads(threads);
        assert_eq!(host.threads(), threads);
        for attrs in [
            Attributes::ALL,
            Attributes::COLOR,
            Attributes::GEOMETRY,
            Attributes::MOTION,
        ] {
            host.render(packed, uniform, attrs, &mut out);
            assert_eq!((out.width, out.height), (naive.width, naive.height));
            assert_eq!(out.attributes(), attrs, "{label}");
            let wanted = [
                true,
                attrs.geometry,
                attrs.motion,
                attrs.motion,
                attrs.motion,
            ];
            for (k, want) in wanted.into_iter().enumerate() {
                if want {
                    let bad = differing(flat(&out.targets[k]), flat(&naive.targets[k]));
                    assert_eq!(bad, 0, "{label}: T{k}, {threads} threads, {attrs:?}");
                } else {
                    assert!(out.targets[k].is_empty(), "{label}: T{k} left out");
                }
            }
            // The same render keeping its visibility depth: the same sums,
            // and the depth-only pass's depth.
            let mut kept = Accumulators::default();
            let mut depth = SplatImage {
                width: 0,
                height: 0,
                channels: 1,
                data: Vec::new(),
            };
            host.render_occluded_with_depth(packed, uniform, &[], attrs, &mut kept, &mut depth);
            for k in 0..5 {
                let bad = differing(flat(&kept.targets[k]), flat(&out.targets[k]));
                assert_eq!(bad, 0, "{label}: kept T{k}, {threads} threads, {attrs:?}");
            }
            let bad = differing(&depth.data, &z);
            assert_eq!(bad, 0, "{label}: kept depth, {threads} threads, {attrs:?}");
        }
        let mut depth = SplatImage {
            width: 0,
            height: 0,
            channels: 1,
            data: Vec::new(),
        };
        host.render_depth(packed, uniform, &mut depth);
        assert_eq!(
            differing(&depth.data, &z),
            0,
            "{label}: depth, {threads} threads"
        );
    }
    let all = cpu::splat_packed(packed, uniform);
    for k in 0..5 {
        assert_eq!(differing(flat(&all.targets[k]), flat(&naive.targets[k])), 0);
    }
    assert_eq!(
        differing(&cpu::visibility_depth(packed, uniform).data, &z),
        0
    );
    covered
}

#[test]
fn the_host_splatter_gives_the_transcription_s_sums_on_random_clouds() {
    let mut rng = Rng::new(11);
    for case in 0..8 {
        let extent = rng.uniform(0.3, 1.0) as f32;
        let n = 200 + rng.below(3000) as usize;
        let model = shapes::random_cloud(&mut rng, Vec3::ZERO, extent, n, 0.005, 0.25);
        let (cam, pose) = random_view(&mut rng, 2.0 + 2.0 * extent as f64);
        let (packed, uniform) = view_of(&model, &cam, &pose);
        let covered = check(&packed, &uniform, &format!("cloud {case}"));
        assert!(covered > 100, "cloud {case}: {covered} pixels covered");
    }
}

#[test]
fn the_host_splatter_gives_the_transcription_s_sums_on_a_dense_sphere_full_and_in_a_window() {
    let model = shapes::sphere(Vec3::new(0.1, -0.2, 0.3), 1.0, 20_000, 1.2);
    let cam = Intrinsics::new(320, 240, 300.0, 301.0, 159.3, 120.6);
    let pose = look_at(
        &Vector3::new(0.5, -0.4, -3.5),
        &Vector3::new(0.1, -0.2, 0.3),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let (packed, uniform) = view_of(&model, &cam, &pose);
    assert!(check(&packed, &uniform, "sphere") > 10_000);
    let win = Window {
        x0: 96,
        y0: 40,
        width: 120,
        height: 88,
    };
    let (packed, uniform) = view_of(&model, &win.camera(&cam), &pose);
    assert!(check(&packed, &uniform, "sphere in a window") > 5_000);
}

#[test]
fn splats_reaching_the_near_plane_and_the_image_border_are_the_transcription_s() {
    // The camera inside a cloud: splats behind it, across the near plane
    // (their quads cover the whole image) and beyond every border.
    let mut rng = Rng::new(5);
    let model = shapes::random_cloud(&mut rng, Vec3::ZERO, 1.0, 3000, 0.02, 0.3);
    let pose = look_at(
        &Vector3::new(0.1, 0.05, -0.15),
        &Vector3::new(0.0, 0.0, 1.0),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let cam = Intrinsics::new(160, 120, 140.0, 140.0, 80.0, 60.0);
    let (packed, uniform) = view_of(&model, &cam, &pose);
    assert!(check(&packed, &uniform, "inside") > 1_000);
}

#[test]
fn reused_scratch_gives_fresh_renders_and_bad_views_give_empty_images() {
    let model = shapes::sphere(Vec3::ZERO, 0.5, 6000, 1.2);
    let pose = look_at(
        &Vector3::new(0.3, -0.4, -1.9),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let mut host = HostSplatter::with_threads(2);
    let mut out = Accumulators::default();
    for (w, h) in [(640, 480), (96, 64), (200, 300), (640, 480)] {
        let cam = Intrinsics::new(w, h, 500.0, 500.0, w as f64 / 2.0, h as f64 / 2.0);
        let (packed, uniform) = view_of(&model, &cam, &pose);
        host.render(&packed, &uniform, Attributes::ALL, &mut out);
        let fresh = naive_splat(&packed, &uniform);
        for k in 0..5 {
            assert_eq!(differing(flat(&out.targets[k]), flat(&fresh.targets[k])), 0);
        }
    }
    // Sizes the uniform cannot hold (NaN, negative, zero) and no splats.
    let (packed, good) = view_of(
        &model,
        &Intrinsics::new(64, 48, 50.0, 50.0, 32.0, 24.0),
        &pose,
    );
    for size in [[f32::NAN, 48.0], [-64.0, 48.0], [0.0, 48.0], [64.0, 0.0]] {
        let mut u = good;
        u.size[0] = size[0];
        u.size[1] = size[1];
        host.render(&packed, &u, Attributes::ALL, &mut out);
        assert_eq!(out.width as usize * out.height as usize, 0);
        assert!(out.targets.iter().all(|t| t.is_empty()));
        assert!(out.resolve(Attribute::Color).data.is_empty());
    }
    let empty = PackedModel {
        splats: Vec::new(),
        colors: Vec::new(),
    };
    host.render(&empty, &good, Attributes::ALL, &mut out);
    assert!(out.targets.iter().all(|t| t.iter().all(|p| *p == [0.0; 4])));
    assert!(
        out.resolve(Attribute::Depth)
            .data
            .iter()
            .all(|v| v.is_nan())
    );
}

#[test]
fn gathers_on_the_accumulators_are_samples_of_the_resolved_predictors() {
    let model = shapes::sphere(Vec3::ZERO, 1.0, 6000, 1.2);
    let cam = Intrinsics::new(160, 120, 150.0, 150.0, 80.0, 60.0);
    let pose = look_at(
        &Vector3::new(0.2, 0.1, -3.0),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let (packed, uniform) = view_of(&model, &cam, &pose);
    let mut rng = Rng::new(3);
    let mut points: Vec<[f32; 2]> = (0..500)
        .map(|_| {
            [
                rng.uniform(-2.0, 162.0) as f32,
                rng.uniform(-2.0, 122.0) as f32,
            ]
        })
        .collect();
    points.extend([
        [f32::NAN, 3.0],
        [80.0, f32::INFINITY],
        [159.0, 119.0],
        [0.0, 0.0],
    ]);
    let mut out = Accumulators::default();
    let mut host = HostSplatter::new();
    host.render(&packed, &uniform, Attributes::MOTION, &mut out);
    let fx = cam.fx as f32;
    for mode in [GatherMode::Nearest, GatherMode::Bilinear] {
        let direct = out.gather(fx, &points, mode);
        let resolved = cpu::sample_at(&out.resolve(Attribute::Motion), fx, &points, mode);
        assert!(direct.iter().filter(|s| s.valid).count() > 100);
        for (a, b) in direct.iter().zip(&resolved) {
            assert_eq!(a.valid, b.valid);
            let (a, b) = (
                [a.motion.as_slice(), &[a.depth]].concat(),
                [b.motion.as_slice(), &[b.depth]].concat(),
            );
            assert_eq!(differing(&a, &b), 0);
        }
    }
    // Without the predictors: nothing valid, depth from motion empty.
    host.render(&packed, &uniform, Attributes::GEOMETRY, &mut out);
    assert!(
        out.gather(fx, &points, GatherMode::Bilinear)
            .iter()
            .all(|s| !s.valid)
    );
    assert!(out.depth_from_motion(fx).data.iter().all(|v| v.is_nan()));
    assert!(
        out.resolve(Attribute::Motion)
            .data
            .iter()
            .all(|v| v.is_nan())
    );
    assert!(
        out.resolve(Attribute::Depth)
            .data
            .iter()
            .any(|v| !v.is_nan())
    );
}

#[test]
fn the_real_cube_in_its_window_is_the_transcription_s() {
    let Some(dir) = data_common::real_data("visp_rbt_cube") else {
        return;
    };
    let model = PointModel::load(dir.join("model.ply")).unwrap();
    let cam = Intrinsics::load(&dir.join("camera.json")).unwrap();
    let pose = splattrack::io::read_poses(&dir.join("init.csv")).unwrap()[0].pose;
    let (lo, hi) = model.positions.iter().fold(
        (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), p| {
            let p = Vector3::new(p.x as f64, p.y as f64, p.z as f64);
            (lo.inf(&p), hi.sup(&p))
        },
    );
    let win = Window::of_box(&cam, &pose, &lo, &hi, 8.0, 8).unwrap();
    let (packed, uniform) = view_of(&model, &win.camera(&cam), &pose);
    assert!(check(&packed, &uniform, "cube") > 10_000);
}

/// A random camera looking at the origin from `dist` away.
fn random_view(rng: &mut Rng, dist: f64) -> (Intrinsics, Pose) {
    let w = 64 + rng.below(200) as u32;
    let h = 48 + rng.below(150) as u32;
    let f = rng.uniform(0.8, 1.6) * w as f64;
    let cam = Intrinsics::new(
        w,
        h,
        f,
        f * rng.uniform(0.9, 1.1),
        w as f64 / 2.0 + rng.uniform(-8.0, 8.0),
        h as f64 / 2.0 + rng.uniform(-8.0, 8.0),
    );
    let pose = look_at(
        &(rng.unit_vector() * dist),
        &Vector3::zeros(),
        &rng.unit_vector(),
    );
    (cam, pose)
}

/// Time a render takes, the transcription against the host splatter on 1
/// and 2 threads, interleaved so that a busy machine slows all alike
/// (medians of 15; colour + predictors against all of the transcription's
/// groups). Run with `cargo test --release --test splat_host -- --ignored
/// --nocapture`; docs/performance.md has its figures.
#[test]
#[ignore = "a timing, not a check"]
fn time_against_the_transcription() {
    let mut scenes = Vec::new();
    if let Some(dir) = data_common::real_data("visp_rbt_cube") {
        let model = PointModel::load(dir.join("model.ply")).unwrap();
        let cam = Intrinsics::load(&dir.join("camera.json")).unwrap();
        let pose = splattrack::io::read_poses(&dir.join("init.csv")).unwrap()[0].pose;
        let (lo, hi) = model.positions.iter().fold(
            (
                Vector3::repeat(f64::INFINITY),
                Vector3::repeat(f64::NEG_INFINITY),
            ),
            |(lo, hi), p| {
                let p = Vector3::new(p.x as f64, p.y as f64, p.z as f64);
                (lo.inf(&p), hi.sup(&p))
            },
        );
        let win = Window::of_box(&cam, &pose, &lo, &hi, 16.0, 8).unwrap();
        scenes.push(("cube, window", view_of(&model, &win.camera(&cam), &pose)));
    }
    let sphere = shapes::sphere(Vec3::ZERO, 0.5, 100_000, 1.2);
    let cam = Intrinsics::new(640, 480, 600.0, 600.0, 319.5, 239.5);
    let up = Vector3::new(0.0, -1.0, 0.0);
    let far = look_at(&Vector3::new(0.3, -0.4, -1.9), &Vector3::zeros(), &up);
    let near = look_at(&Vector3::new(0.0, 0.0, -0.75), &Vector3::zeros(), &up);
    scenes.push(("sphere 100k, 640x480", view_of(&sphere, &cam, &far)));
    scenes.push(("sphere 100k filling 640x480", view_of(&sphere, &cam, &near)));
    for (name, (packed, uniform)) in &scenes {
        let mut hosts = [HostSplatter::with_threads(1), HostSplatter::with_threads(2)];
        let mut out = Accumulators::default();
        let mut ms = [Vec::new(), Vec::new(), Vec::new()];
        for _ in 0..15 {
            let t = std::time::Instant::now();
            std::hint::black_box(naive_splat(packed, uniform));
            ms[0].push(t.elapsed().as_secs_f64() * 1e3);
            for (k, host) in hosts.iter_mut().enumerate() {
                let t = std::time::Instant::now();
                host.render(packed, uniform, Attributes::MOTION, &mut out);
                ms[k + 1].push(t.elapsed().as_secs_f64() * 1e3);
            }
        }
        let [a, b, c] = ms.map(|mut v| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        });
        println!(
            "{name}: transcription {a:.1} ms, host 1 thread {b:.1} ms ({:.1}x), 2 threads {c:.1} ms ({:.1}x)",
            a / b,
            a / c
        );
    }
}
