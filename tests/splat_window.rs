//! A render into a window of the image (the camera shifted by the
//! window's origin, `splat::Window::camera`) against the full render and
//! against the CPU reference: the tracker renders only the object's
//! window and must see what the full render shows.
//!
//! Tolerances: the window camera computes `u - (cx - x0)` where the full
//! one computes `(u + x0) - cx`, which differ by f32 rounding; as in
//! tests/splat_reference.rs, values where both cover a pixel agree to 1e-4
//! (colour), 1e-5 relative (depth) and 1e-4 relative (predictors), and a
//! rounding that flips a depth or truncation test on its threshold may
//! change at most 0.5% of the covered pixels. Every pixel the full render
//! covers lies inside the window (`Window::of_box` of the model's box grown
//! by its largest splat).

use glam::Vec3;
use nalgebra::Vector3;
use splattrack::geometry::{Intrinsics, Pose, look_at};
use splattrack::gpu::{self, GpuContext};
use splattrack::model::{PointModel, shapes};
use splattrack::rng::Rng;
use splattrack::splat::{
    Attribute, Attributes, GatherMode, GpuModel, SplatImage, SplatParams, SplatTargets, Splatter,
    Window, cpu,
};

fn ctx() -> &'static GpuContext {
    gpu::shared_test_context()
}

const ATTRS: [Attribute; 4] = [
    Attribute::Color,
    Attribute::Depth,
    Attribute::Motion,
    Attribute::Weight,
];

fn gpu_render(
    splatter: &Splatter,
    gm: &GpuModel,
    cam: &Intrinsics,
    pose: &Pose,
) -> (SplatTargets, [SplatImage; 4]) {
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    splatter
        .render(ctx(), gm, cam, pose, Attributes::ALL, &mut t)
        .unwrap();
    let images = ATTRS.map(|a| splatter.read(ctx(), &t, a).unwrap());
    (t, images)
}

/// Pixel (x, y) of `a` against pixel (x + dx, y + dy) of `b` over `a`'s
/// whole image: (covered pixels, pixels that disagree).
fn disagreement(a: &[SplatImage; 4], b: &[SplatImage; 4], dx: u32, dy: u32) -> (usize, usize) {
    let (mut covered, mut bad) = (0, 0);
    for y in 0..a[0].height {
        for x in 0..a[0].width {
            let (va, vb) = (a[1].is_valid(x, y), b[1].is_valid(x + dx, y + dy));
            covered += usize::from(va || vb);
            if va != vb {
                bad += 1;
                continue;
            }
            if !va {
                continue;
            }
            let px = |i: &[SplatImage; 4], k: usize, x: u32, y: u32| i[k].pixel(x, y).to_vec();
            let diff = |k: usize| {
                px(a, k, x, y)
                    .iter()
                    .zip(px(b, k, x + dx, y + dy))
                    .map(|(p, q)| (p - q).abs())
                    .fold(0.0f32, f32::max)
            };
            let z = a[1].pixel(x, y)[0];
            let scale = a[2]
                .pixel(x, y)
                .iter()
                .map(|v| v.abs())
                .fold(1e-6, f32::max);
            if diff(0) > 1e-4 || diff(1) > 1e-5 * z || diff(2) > 1e-4 * scale {
                bad += 1;
            }
        }
    }
    (covered, bad)
}

/// The model's box grown by its largest splat, as the tracker computes it.
fn grown_box(model: &PointModel) -> (Vector3<f64>, Vector3<f64>) {
    let (lo, hi) = model.bounds();
    let pad = model.radii.iter().fold(0.0f32, |m, &r| m.max(r));
    let v = |p: Vec3| Vector3::new(p.x as f64, p.y as f64, p.z as f64);
    (v(lo - Vec3::splat(pad)), v(hi + Vec3::splat(pad)))
}

fn check(model: &PointModel, cam: &Intrinsics, pose: &Pose, label: &str) {
    let splatter = Splatter::new(ctx()).unwrap();
    let gm = GpuModel::new(ctx(), model).unwrap();
    let (lo, hi) = grown_box(model);
    let w = Window::of_box(cam, pose, &lo, &hi, 4.0, 32).expect("in view");
    assert!(
        w.area() * 2 < (cam.width * cam.height) as usize && w.x0 > 0 && w.y0 > 0,
        "{label}: the test wants a proper window, got {w:?}"
    );
    let (full_t, full) = gpu_render(&splatter, &gm, cam, pose);
    let wcam = w.camera(cam);
    let (win_t, win) = gpu_render(&splatter, &gm, &wcam, pose);
    assert_eq!((win[0].width, win[0].height), (w.width, w.height));

    // Nothing is covered outside the window.
    for y in 0..cam.height {
        for x in 0..cam.width {
            let inside =
                (w.x0..w.x0 + w.width).contains(&x) && (w.y0..w.y0 + w.height).contains(&y);
            assert!(
                inside || !full[1].is_valid(x, y),
                "{label}: pixel ({x}, {y}) covered outside {w:?}"
            );
        }
    }
    // The window against the full render.
    let (covered, bad) = disagreement(&win, &full, w.x0, w.y0);
    eprintln!("{label}: {w:?}, {covered} px covered, {bad} differ from the full render");
    assert!(covered > 200, "{label}: only {covered} pixels covered");
    assert!(
        bad as f64 <= 0.005 * covered as f64,
        "{label}: {bad} of {covered} pixels differ from the full render"
    );
    // The window against the CPU reference with the window's camera.
    let acc = cpu::splat(model, &wcam, pose, &SplatParams::default()).unwrap();
    let reference = ATTRS.map(|a| acc.resolve(a));
    let (covered, bad) = disagreement(&win, &reference, 0, 0);
    eprintln!("{label}: {bad} of {covered} px differ from the CPU reference");
    assert!(
        bad as f64 <= 0.005 * covered as f64,
        "{label}: {bad} of {covered} pixels differ from the CPU reference"
    );
    // Gathers at frame positions, shifted into the window.
    let mut rng = Rng::new(3);
    let points: Vec<[f32; 2]> = (0..1000)
        .map(|_| {
            [
                rng.uniform(w.x0 as f64 - 5.0, (w.x0 + w.width) as f64 + 5.0) as f32,
                rng.uniform(w.y0 as f64 - 5.0, (w.y0 + w.height) as f64 + 5.0) as f32,
            ]
        })
        .collect();
    let o = w.origin();
    let local: Vec<[f32; 2]> = points.iter().map(|p| [p[0] - o[0], p[1] - o[1]]).collect();
    let g_full = splatter
        .gather(ctx(), &full_t, &points, GatherMode::Bilinear)
        .unwrap();
    let g_win = splatter
        .gather(ctx(), &win_t, &local, GatherMode::Bilinear)
        .unwrap();
    let mut valid = 0;
    let mut bad = 0;
    for (f, g) in g_full.iter().zip(&g_win) {
        if f.valid != g.valid {
            bad += 1;
            continue;
        }
        if !f.valid {
            continue;
        }
        valid += 1;
        let scale = f.motion.iter().map(|v| v.abs()).fold(1e-6, f32::max);
        let dm = f
            .motion
            .iter()
            .zip(&g.motion)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        if dm > 1e-4 * scale || (f.depth - g.depth).abs() > 1e-5 * f.depth {
            bad += 1;
        }
    }
    eprintln!("{label}: gathers: {valid} valid, {bad} differ");
    assert!(valid > 60, "{label}: only {valid} valid gathers");
    assert!(bad <= 5, "{label}: {bad} of 1000 gathers differ");
}

/// A view of `target` from `dist` away, turned so that the target sits
/// off the image centre (the window then starts inside the image).
fn off_centre_view(rng: &mut Rng, target: Vector3<f64>, dist: f64) -> (Intrinsics, Pose) {
    let cam = Intrinsics::new(320, 240, 300.0, 302.0, 161.3, 118.7);
    let eye = target + rng.unit_vector() * dist;
    let look = look_at(&eye, &target, &rng.unit_vector());
    // Move the object right and down in the camera frame.
    let shift = Vector3::new(0.12 * dist, 0.08 * dist, 0.0);
    let pose = Pose::new(look.rotation, look.translation + shift).unwrap();
    (cam, pose)
}

#[test]
fn window_render_matches_the_full_render_and_the_cpu_reference_on_a_sphere() {
    let mut rng = Rng::new(41);
    let model = shapes::sphere(Vec3::new(0.05, -0.02, 0.01), 0.3, 6000, 1.2);
    let (cam, pose) = off_centre_view(&mut rng, Vector3::new(0.05, -0.02, 0.01), 3.0);
    check(&model, &cam, &pose, "sphere");
}

#[test]
fn window_render_matches_the_full_render_and_the_cpu_reference_on_random_clouds() {
    let mut rng = Rng::new(2026);
    for trial in 0..3 {
        let n = 500 + rng.below(2000) as usize;
        let model = shapes::random_cloud(&mut rng, Vec3::ZERO, 0.3, n, 0.005, 0.05);
        let dist = rng.uniform(2.5, 3.5);
        let (cam, pose) = off_centre_view(&mut rng, Vector3::zeros(), dist);
        check(&model, &cam, &pose, &format!("cloud {trial} ({n} splats)"));
    }
}
