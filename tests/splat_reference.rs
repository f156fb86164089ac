//! The GPU splatter against its CPU reference (src/splat/cpu.rs), which
//! implements the same maths in f32 from the same uniform: random splat
//! clouds (random centres, normals, radii, colours), random poses, random
//! intrinsics and image sizes, plus a dense sphere.
//!
//! Tolerances: the two differ only by f32 rounding (fma, exp, division), so
//! where both cover a pixel colour agrees to 1e-4, depth to 1e-5 relative and
//! predictors to 1e-4 relative (to the pixel's largest predictor). Rounding
//! can flip a depth test or a truncation test (`rho <= 1`) that sits exactly
//! on its threshold, which changes which splats a pixel blends: at most 0.5%
//! of the covered pixels may disagree (coverage or value).

use glam::Vec3;
use nalgebra::Vector3;
use splattrack::geometry::{Intrinsics, Pose};
use splattrack::model::{PointModel, shapes};
use splattrack::rng::Rng;
use splattrack::splat::{
    Attribute, Attributes, Backend, GatherMode, GpuModel, SplatImage, SplatParams, SplatTargets,
    Splatter, cpu,
};

mod splat_common;
use splat_common::{ctx, random_view, splatter};

#[derive(Debug, Default)]
struct Agreement {
    covered: usize,
    coverage_mismatch: usize,
    value_mismatch: usize,
    max_color: f32,
    max_depth_rel: f32,
    max_motion_rel: f32,
}

impl Agreement {
    fn bad_fraction(&self) -> f64 {
        (self.coverage_mismatch + self.value_mismatch) as f64 / self.covered.max(1) as f64
    }
}

fn compare(gpu: [&SplatImage; 3], cpu: [&SplatImage; 3]) -> Agreement {
    let [gc, gd, gm] = gpu;
    let [cc, cd, cm] = cpu;
    let mut a = Agreement::default();
    let mut diffs = (Vec::new(), Vec::new(), Vec::new());
    for y in 0..gc.height {
        for x in 0..gc.width {
            let (vg, vc) = (gd.is_valid(x, y), cd.is_valid(x, y));
            if vg || vc {
                a.covered += 1;
            }
            if vg != vc {
                a.coverage_mismatch += 1;
                continue;
            }
            if !vg {
                continue;
            }
            let dc = gc
                .pixel(x, y)
                .iter()
                .zip(cc.pixel(x, y))
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f32::max);
            let z = cd.pixel(x, y)[0];
            let dd = (gd.pixel(x, y)[0] - z).abs() / z;
            let scale = cm.pixel(x, y).iter().map(|v| v.abs()).fold(1e-6, f32::max);
            let dm = gm
                .pixel(x, y)
                .iter()
                .zip(cm.pixel(x, y))
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f32::max)
                / scale;
            if dc > 1e-4 || dd > 1e-5 || dm > 1e-4 {
                a.value_mismatch += 1;
            } else {
                diffs.0.push(dc);
                diffs.1.push(dd);
                diffs.2.push(dm);
            }
        }
    }
    a.max_color = diffs.0.iter().copied().fold(0.0, f32::max);
    a.max_depth_rel = diffs.1.iter().copied().fold(0.0, f32::max);
    a.max_motion_rel = diffs.2.iter().copied().fold(0.0, f32::max);
    a
}

fn gpu_images(
    splatter: &Splatter,
    model: &PointModel,
    cam: &Intrinsics,
    pose: &Pose,
) -> [SplatImage; 3] {
    let gm = GpuModel::new(ctx(), model).unwrap();
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    splatter
        .render(ctx(), &gm, cam, pose, Attributes::ALL, &mut t)
        .unwrap();
    [Attribute::Color, Attribute::Depth, Attribute::Motion]
        .map(|a| splatter.read(ctx(), &t, a).unwrap())
}

fn check_model(model: &PointModel, cam: &Intrinsics, pose: &Pose, label: &str) -> Agreement {
    let splatter = Splatter::new(ctx()).unwrap();
    let g = gpu_images(&splatter, model, cam, pose);
    let acc = cpu::splat(model, cam, pose, &SplatParams::default()).unwrap();
    let c = [Attribute::Color, Attribute::Depth, Attribute::Motion].map(|a| acc.resolve(a));
    let a = compare([&g[0], &g[1], &g[2]], [&c[0], &c[1], &c[2]]);
    eprintln!("{label}: {cam:?}\n  {a:?}");
    assert!(
        a.covered > 100,
        "{label}: only {} pixels covered",
        a.covered
    );
    assert!(
        a.bad_fraction() <= 0.005,
        "{label}: {:.3}% of covered pixels disagree: {a:?}",
        100.0 * a.bad_fraction()
    );
    a
}

#[test]
fn gpu_matches_cpu_on_random_clouds_and_poses() {
    let mut rng = Rng::new(2024);
    for trial in 0..6 {
        let n = 300 + rng.below(3000) as usize;
        let extent = 1.0;
        // Radii from sub-pixel to tens of pixels.
        let model = shapes::random_cloud(&mut rng, Vec3::ZERO, extent, n, 0.005, 0.25);
        let dist = rng.uniform(2.5, 6.0);
        let (cam, pose) = random_view(&mut rng, Vector3::zeros(), dist);
        check_model(&model, &cam, &pose, &format!("cloud {trial} ({n} splats)"));
    }
}

#[test]
fn gpu_matches_cpu_on_a_dense_sphere() {
    let mut rng = Rng::new(7);
    let model = shapes::sphere(Vec3::new(0.1, -0.2, 0.3), 1.0, 8000, 1.2);
    let (cam, pose) = random_view(&mut rng, Vector3::new(0.1, -0.2, 0.3), 3.5);
    check_model(&model, &cam, &pose, "sphere");
}

#[test]
fn gpu_resolve_matches_cpu_for_normals_and_weights() {
    let mut rng = Rng::new(11);
    let model = shapes::random_cloud(&mut rng, Vec3::ZERO, 1.0, 2000, 0.02, 0.2);
    let (cam, pose) = random_view(&mut rng, Vector3::zeros(), 4.0);
    let splatter = Splatter::new(ctx()).unwrap();
    let gm = GpuModel::new(ctx(), &model).unwrap();
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    splatter
        .render(ctx(), &gm, &cam, &pose, Attributes::GEOMETRY, &mut t)
        .unwrap();
    let acc = cpu::splat(&model, &cam, &pose, &SplatParams::default()).unwrap();
    for a in [Attribute::Normal, Attribute::Weight] {
        let g = splatter.read(ctx(), &t, a).unwrap();
        let c = acc.resolve(a);
        let bad = g
            .data
            .iter()
            .zip(&c.data)
            .filter(|(g, c)| !((g.is_nan() && c.is_nan()) || (*g - *c).abs() <= 1e-4))
            .count();
        assert!(
            bad as f64 <= 0.005 * g.data.len() as f64,
            "{a:?}: {bad} of {} values differ",
            g.data.len()
        );
    }
    // Motion was not rendered into these targets: a typed error, not garbage.
    assert!(splatter.read(ctx(), &t, Attribute::Motion).is_err());
}

#[test]
fn gather_matches_cpu_sampling_of_full_images() {
    // Tolerance: f32 rounding of the bilinear weights, 1e-4 relative.
    let mut rng = Rng::new(5);
    let model = shapes::sphere(Vec3::ZERO, 1.0, 6000, 1.2);
    let (cam, pose) = random_view(&mut rng, Vector3::zeros(), 3.0);
    let splatter = Splatter::new(ctx()).unwrap();
    let gm = GpuModel::new(ctx(), &model).unwrap();
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    splatter
        .render(ctx(), &gm, &cam, &pose, Attributes::ALL, &mut t)
        .unwrap();
    // The averaged depth of a full render, to compare gather's with.
    let depth = splatter.read(ctx(), &t, Attribute::Depth).unwrap();
    // Gather needs the predictors only: its depth comes from them.
    splatter
        .render(ctx(), &gm, &cam, &pose, Attributes::MOTION, &mut t)
        .unwrap();
    let motion = splatter.read(ctx(), &t, Attribute::Motion).unwrap();
    let mut points: Vec<[f32; 2]> = (0..500)
        .map(|_| {
            [
                rng.uniform(-2.0, cam.width as f64 + 1.0) as f32,
                rng.uniform(-2.0, cam.height as f64 + 1.0) as f32,
            ]
        })
        .collect();
    // Exact pixel centres, image corners and a NaN.
    points.extend([
        [0.0, 0.0],
        [cam.width as f32 - 1.0, cam.height as f32 - 1.0],
        [f32::NAN, 3.0],
    ]);
    points.push([cam.cx as f32, cam.cy as f32]);
    for mode in [GatherMode::Nearest, GatherMode::Bilinear] {
        let g = splatter.gather(ctx(), &t, &points, mode).unwrap();
        let c = cpu::sample_at(&motion, cam.fx as f32, &points, mode);
        assert_eq!(g.len(), points.len());
        let mut valid = 0;
        let mut worst = 0f32;
        for (i, (g, c)) in g.iter().zip(&c).enumerate() {
            assert_eq!(g.valid, c.valid, "{mode:?} point {i} {:?}", points[i]);
            if !g.valid {
                assert!(g.depth.is_nan() && g.motion.iter().all(|v| v.is_nan()));
                continue;
            }
            valid += 1;
            let scale = c.motion.iter().map(|v| v.abs()).fold(1e-6, f32::max);
            for k in 0..12 {
                assert!(
                    (g.motion[k] - c.motion[k]).abs() <= 1e-4 * scale,
                    "{mode:?} point {i}"
                );
            }
            assert!(
                (g.depth - c.depth).abs() <= 1e-5 * c.depth,
                "{mode:?} point {i}"
            );
            // The predictors' depth (a weighted harmonic mean of the
            // fragments') against the render's arithmetic mean at the same
            // pixel: the fragments blended at a pixel lie within the
            // visibility push-back of each other, so the two means agree
            // far better than the push-back (measured 6.4e-6 relative; the
            // bound is 1e-4). Compared in Nearest mode, where both are the
            // same pixel's.
            if mode == GatherMode::Nearest {
                let [x, y] = points[i];
                let (px, py) = ((x + 0.5).floor() as u32, (y + 0.5).floor() as u32);
                let d = depth.pixel(px, py)[0];
                worst = worst.max(((g.depth - d) / d).abs());
            }
        }
        eprintln!("{mode:?}: predictors' depth against the averaged depth, worst {worst:.2e}");
        assert!(worst <= 1e-4, "{mode:?}: {worst}");
        assert!(valid > 50, "{mode:?}: only {valid} valid samples");
        // The centre of the image shows the sphere.
        assert!(g.last().unwrap().valid);
    }
}

#[test]
fn put_off_gathers_give_the_immediate_ones_samples_and_flush_only_when_needed() {
    // Gathers share their points' buffer and parameters, both uploaded by
    // `Queue::write_buffer`, which takes effect before the submission it
    // precedes: a gather recorded while the last is still put off in a
    // batch submits that one first (else it would read the new points).
    // A gather whose predecessor a readback has submitted since needs no
    // such submission (the tracker's KF gather after IT's chain). A
    // context of its own, so that other tests' submissions are not
    // counted. Exact: the same pass on the same inputs.
    use splattrack::gpu::own_test_context;
    let c = own_test_context();
    let mut rng = Rng::new(23);
    let model = shapes::sphere(Vec3::ZERO, 1.0, 4000, 1.2);
    let (cam, pose) = random_view(&mut rng, Vector3::zeros(), 3.0);
    let splatter = Splatter::new(&c).unwrap();
    let gm = GpuModel::new(&c, &model).unwrap();
    let mut t = SplatTargets::new(&c, cam.width, cam.height);
    splatter
        .render(&c, &gm, &cam, &pose, Attributes::MOTION, &mut t)
        .unwrap();
    let sets: Vec<Vec<[f32; 2]>> = [40usize, 7, 90]
        .iter()
        .map(|&n| {
            (0..n)
                .map(|_| {
                    [
                        rng.uniform(0.0, cam.width as f64) as f32,
                        rng.uniform(0.0, cam.height as f64) as f32,
                    ]
                })
                .collect()
        })
        .collect();
    let mode = GatherMode::Bilinear;
    let want: Vec<_> = sets
        .iter()
        .map(|p| splatter.gather(&c, &t, p, mode).unwrap())
        .collect();
    let same = |a: &[splattrack::splat::GatherSample], b: &[splattrack::splat::GatherSample]| {
        a.len() == b.len()
            && a.iter().zip(b).all(|(a, b)| {
                a.valid == b.valid
                    && a.depth.to_bits() == b.depth.to_bits()
                    && a.motion
                        .iter()
                        .zip(&b.motion)
                        .all(|(x, y)| x.to_bits() == y.to_bits())
            })
    };
    // Three gathers put off in a row: each after the first submits the
    // one before (two submissions), the readback the last (one more).
    {
        let _batch = c.batch();
        let subs = c.stats().submissions;
        let pending: Vec<_> = sets
            .iter()
            .map(|p| splatter.gather_later(&c, &t, p, mode).unwrap())
            .collect();
        assert_eq!(c.stats().submissions - subs, 2, "put-off gathers flushed");
        for (i, (p, w)) in pending.into_iter().zip(&want).enumerate() {
            assert!(same(&p.wait(&c).unwrap(), w), "put-off gather {i}");
        }
        assert_eq!(c.stats().submissions - subs, 3, "one readback for all");
    }
    // A gather waited for, then a render put off, then the next gather:
    // the readback submitted the first, so the render goes with the
    // second's readback (one submission), not alone before it.
    {
        let _batch = c.batch();
        let first = splatter.gather_later(&c, &t, &sets[0], mode).unwrap();
        assert!(same(&first.wait(&c).unwrap(), &want[0]));
        let subs = c.stats().submissions;
        splatter
            .render(&c, &gm, &cam, &pose, Attributes::MOTION, &mut t)
            .unwrap();
        let second = splatter.gather_later(&c, &t, &sets[2], mode).unwrap();
        assert_eq!(
            c.stats().submissions,
            subs,
            "nothing submitted before the wait"
        );
        assert!(same(&second.wait(&c).unwrap(), &want[2]));
        assert_eq!(
            c.stats().submissions - subs,
            1,
            "the render with the readback"
        );
    }
}

#[test]
fn depth_of_a_render_without_geometry_comes_from_its_predictors() {
    // A render of the predictors alone (what the tracker's KF step makes)
    // reads as depth the harmonic mean the translation predictor gives:
    // against the CPU reference of the same sums (1e-5 relative), gather's
    // depth at the same pixel centres (the same expression: equal on lavapipe,
    // within 4 ulp where a driver compiles the two shaders differently) and the
    // averaged depth of a render with the geometry (2e-4 relative: the
    // fragments blended at a pixel lie within the visibility push-back of
    // each other; measured 8.3e-5 at the sphere's outline, against 6.4e-6
    // at `gather_matches_cpu_sampling_of_full_images`'s random points). Coverage is the
    // weight's in all three. Both back ends (the same accumulator layout).
    let mut rng = Rng::new(31);
    let model = shapes::sphere(Vec3::new(0.2, 0.1, -0.1), 1.0, 6000, 1.2);
    let (cam, pose) = random_view(&mut rng, Vector3::new(0.2, 0.1, -0.1), 3.2);
    for backend in [Backend::Compute, Backend::RenderPass] {
        depth_from_motion_on(&splatter(backend), &model, &cam, &pose, backend);
    }
}

fn depth_from_motion_on(
    splatter: &Splatter,
    model: &PointModel,
    cam: &Intrinsics,
    pose: &Pose,
    backend: Backend,
) {
    let (cam, pose) = (*cam, *pose);
    let gm = GpuModel::new(ctx(), model).unwrap();
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    splatter
        .render(ctx(), &gm, &cam, &pose, Attributes::GEOMETRY, &mut t)
        .unwrap();
    let averaged = splatter.read(ctx(), &t, Attribute::Depth).unwrap();
    splatter
        .render(ctx(), &gm, &cam, &pose, Attributes::MOTION, &mut t)
        .unwrap();
    let depth = splatter.read(ctx(), &t, Attribute::Depth).unwrap();
    let weight = splatter.read(ctx(), &t, Attribute::Weight).unwrap();
    assert_eq!(depth.channels, 1);
    let acc = cpu::splat(model, &cam, &pose, &SplatParams::default()).unwrap();
    let reference = acc.depth_from_motion(cam.fx as f32);
    let centres: Vec<[f32; 2]> = (0..cam.height)
        .flat_map(|y| (0..cam.width).map(move |x| [x as f32, y as f32]))
        .collect();
    let gathered = splatter
        .gather(ctx(), &t, &centres, GatherMode::Nearest)
        .unwrap();
    let (mut covered, mut off_cpu, mut worst_avg) = (0usize, 0usize, 0f32);
    for (i, &d) in depth.data.iter().enumerate() {
        assert_eq!(d.is_finite(), weight.data[i] > 0.0, "pixel {i}: coverage");
        let g = gathered[i].depth;
        // The same expression in two shaders: equal on lavapipe, within an
        // ulp or two where the driver contracts them differently (an H200:
        // 2.8776095 against 2.8776093).
        assert!(
            (d.is_nan() && g.is_nan()) || (d - g).abs() <= 4.0 * f32::EPSILON * d.abs(),
            "pixel {i}: {d} against gather's {g}"
        );
        if !d.is_finite() {
            continue;
        }
        covered += 1;
        let c = reference.data[i];
        if !(c.is_finite() && (d - c).abs() <= 1e-5 * c) {
            off_cpu += 1;
        }
        let a = averaged.data[i];
        assert!(a.is_finite(), "pixel {i}: covered without geometry only");
        worst_avg = worst_avg.max(((d - a) / a).abs());
    }
    eprintln!(
        "{backend:?}: {covered} covered pixels, {off_cpu} off the CPU reference, worst against the averaged depth {worst_avg:.2e}"
    );
    assert!(covered > 1000, "{backend:?}: only {covered} covered pixels");
    // Rounding may flip a threshold test at a few pixels (module docs).
    assert!(
        off_cpu as f64 <= 0.005 * covered as f64,
        "{backend:?}: {off_cpu} of {covered}"
    );
    assert!(worst_avg <= 2e-4, "{backend:?}: {worst_avg}");
    // Normals were not rendered: still a typed error.
    assert!(splatter.read(ctx(), &t, Attribute::Normal).is_err());
}
