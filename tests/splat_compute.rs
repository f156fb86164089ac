//! The compute back end of the splatter (`Backend::Compute`,
//! shaders/splat_compute.wgsl) against the CPU reference (src/splat/cpu.rs),
//! against the render-pass back end, and against an independent triangle
//! rasterisation of a mesh (synth's CPU rasteriser), so that every consumer
//! of the splatter gets the same images from either back end.
//!
//! Tolerances. The compute path sums fixed-point values (2^-20 units of
//! normalised quantities) where the render pass blends f32, and rebuilds the
//! predictors from sum(w / z) (exact algebra, different rounding): where
//! both cover a pixel colour agrees to 1e-4, depth to 1e-5 relative and the
//! predictors to 1e-4 relative (to the pixel's largest predictor), as in
//! tests/splat_reference.rs; as there, rounding may flip a depth or
//! truncation test sitting on its threshold, so at most 0.5% of the covered
//! pixels may disagree. Against the mesh: the criteria of
//! tests/splat_mesh.rs (IoU >= 0.97, depth median <= 0.2% and p99 <= 1.5%
//! of the diameter, predictors median <= 1% and p95 <= 5%).

use glam::Vec3;
use nalgebra::{Vector2, Vector3};
use splattrack::geometry::{Intrinsics, Pose, look_at};
use splattrack::gpu::GpuTimer;
use splattrack::model::{AttributeSource, PointModel, TriangleMesh, shapes};
use splattrack::rng::Rng;
use splattrack::splat::{
    Attribute, Attributes, Backend, GatherMode, GpuModel, SplatImage, SplatParams, SplatTargets,
    Splatter, Window, cpu,
};
use splattrack::synth::raster;

mod splat_common;
use splat_common::{READ, ctx, disagreement, random_view, splatter};

fn images(s: &Splatter, model: &PointModel, cam: &Intrinsics, pose: &Pose) -> Vec<SplatImage> {
    let gm = GpuModel::new(ctx(), model).unwrap();
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    s.render(ctx(), &gm, cam, pose, Attributes::ALL, &mut t)
        .unwrap();
    READ.iter()
        .map(|&a| s.read(ctx(), &t, a).unwrap())
        .collect()
}

fn cpu_images(model: &PointModel, cam: &Intrinsics, pose: &Pose) -> Vec<SplatImage> {
    let acc = cpu::splat(model, cam, pose, &SplatParams::default()).unwrap();
    READ.iter().map(|&a| acc.resolve(a)).collect()
}

fn check(model: &PointModel, cam: &Intrinsics, pose: &Pose, label: &str) {
    let compute = images(&splatter(Backend::Compute), model, cam, pose);
    let render = images(&splatter(Backend::RenderPass), model, cam, pose);
    let reference = cpu_images(model, cam, pose);
    // The render pass against the reference too: the other tests of the
    // suite splat with `auto`, the compute splatter on lavapipe.
    for (one, other, name) in [
        (&compute, &reference, "compute vs CPU reference"),
        (&compute, &render, "compute vs render pass"),
        (&render, &reference, "render pass vs CPU reference"),
    ] {
        let (covered, bad) = disagreement(one, other);
        eprintln!("{label}: {name}: {bad} of {covered} covered pixels disagree");
        assert!(covered > 100, "{label}: only {covered} pixels covered");
        assert!(
            bad as f64 <= 0.005 * covered as f64,
            "{label}: {name}: {bad} of {covered} covered pixels disagree"
        );
    }
}

#[test]
fn compute_matches_cpu_and_render_pass_on_random_clouds() {
    let mut rng = Rng::new(4242);
    for trial in 0..5 {
        let n = 300 + rng.below(3000) as usize;
        // Radii from sub-pixel to tens of pixels.
        let model = shapes::random_cloud(&mut rng, Vec3::ZERO, 1.0, n, 0.005, 0.25);
        let dist = rng.uniform(2.5, 6.0);
        let (cam, pose) = random_view(&mut rng, Vector3::zeros(), dist);
        check(&model, &cam, &pose, &format!("cloud {trial} ({n} splats)"));
    }
}

#[test]
fn compute_renders_do_not_depend_on_the_models_point_order() {
    // GpuModel stores the splats in `spatial_order`; the compute splatter's
    // integer sums make a render the same bit for bit whatever the file's
    // order, and colours given later (`with_colors`, in the model's order)
    // land on their own points.
    let mut rng = Rng::new(77);
    let mut model = shapes::random_cloud(&mut rng, Vec3::ZERO, 1.0, 4000, 0.005, 0.2);
    let colors: Vec<[f32; 3]> = (0..model.positions.len())
        .map(|_| {
            [
                rng.uniform(0.0, 1.0) as f32,
                rng.uniform(0.0, 1.0) as f32,
                rng.uniform(0.0, 1.0) as f32,
            ]
        })
        .collect();
    model.colors = Some(colors.clone());
    let mut shuffled = model.clone();
    let n = model.positions.len();
    let mut perm: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        perm.swap(i, rng.below(i as u64 + 1) as usize);
    }
    shuffled.positions = perm.iter().map(|&i| model.positions[i]).collect();
    shuffled.normals = perm.iter().map(|&i| model.normals[i]).collect();
    shuffled.radii = perm.iter().map(|&i| model.radii[i]).collect();
    shuffled.colors = Some(perm.iter().map(|&i| colors[i]).collect());
    let (cam, pose) = random_view(&mut rng, Vector3::zeros(), 3.5);
    let s = splatter(Backend::Compute);
    let a = images(&s, &model, &cam, &pose);
    let b = images(&s, &shuffled, &cam, &pose);
    // Recoloured after upload: the model without colours, then `with_colors`.
    let mut plain = model.clone();
    plain.colors = None;
    let gm = GpuModel::new(ctx(), &plain)
        .unwrap()
        .with_colors(ctx(), &colors)
        .unwrap();
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    s.render(ctx(), &gm, &cam, &pose, Attributes::ALL, &mut t)
        .unwrap();
    let c = s.read(ctx(), &t, Attribute::Color).unwrap();
    assert!(
        a[0].coverage() > 1000,
        "too little covered: {}",
        a[0].coverage()
    );
    for (k, (x, y)) in a.iter().zip(&b).enumerate() {
        let same = x
            .data
            .iter()
            .zip(&y.data)
            .all(|(p, q)| p.to_bits() == q.to_bits());
        assert!(same, "{:?} differs with the points shuffled", READ[k]);
    }
    let same = a[0]
        .data
        .iter()
        .zip(&c.data)
        .all(|(p, q)| p.to_bits() == q.to_bits());
    assert!(same, "with_colors put colours on other points");
}

#[test]
fn compute_matches_cpu_and_render_pass_on_a_dense_sphere() {
    let mut rng = Rng::new(8);
    let model = shapes::sphere(Vec3::new(0.1, -0.2, 0.3), 1.0, 8000, 1.2);
    let (cam, pose) = random_view(&mut rng, Vector3::new(0.1, -0.2, 0.3), 3.5);
    check(&model, &cam, &pose, "sphere");
}

#[test]
fn large_footprints_shared_by_a_workgroup_agree() {
    // Splats hundreds to thousands of pixels wide (over BIG_SPLAT_PIXELS:
    // walked by a workgroup), mixed with small ones (one thread each).
    let mut rng = Rng::new(99);
    let model = large_and_small(&mut rng);
    let (cam, pose) = random_view(&mut rng, Vector3::zeros(), 3.0);
    check(&model, &cam, &pose, "large and small splats");
}

#[test]
fn consecutive_renders_into_the_same_targets_match_fresh_ones() {
    // A render uses one half of the splats' bounds (box and list of large
    // splats) and zeroes the other for the next: five renders in a row
    // into the same targets (one depth-only), with large splats, each
    // the same bit for bit as a render into fresh targets.
    let mut rng = Rng::new(123);
    let model = large_and_small(&mut rng);
    let gm = GpuModel::new(ctx(), &model).unwrap();
    let s = splatter(Backend::Compute);
    let cam = Intrinsics::new(160, 120, 150.0, 150.0, 80.0, 60.0);
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    for k in 0..5 {
        let eye = rng.unit_vector() * rng.uniform(2.5, 3.5);
        let pose = look_at(&eye, &Vector3::zeros(), &rng.unit_vector());
        let render = |t: &mut SplatTargets| -> Vec<SplatImage> {
            if k == 2 {
                s.render_depth(ctx(), &gm, &cam, &pose, t, None).unwrap();
                vec![s.read(ctx(), t, Attribute::Depth).unwrap()]
            } else {
                s.render(ctx(), &gm, &cam, &pose, Attributes::ALL, t)
                    .unwrap();
                READ.iter().map(|&a| s.read(ctx(), t, a).unwrap()).collect()
            }
        };
        let reused = render(&mut t);
        let fresh = render(&mut SplatTargets::new(ctx(), cam.width, cam.height));
        for (a, b) in reused.iter().zip(&fresh) {
            assert_eq!(splat_common::differing(a, b), 0, "render {k}");
        }
        let large = (0..model.len())
            .filter(|&i| {
                let p = model.positions[i];
                let z = pose
                    .transform_point(&Vector3::new(p.x as f64, p.y as f64, p.z as f64))
                    .z;
                z > 0.0 && cam.fx * model.radii[i] as f64 / z > 16.0
            })
            .count();
        assert!(large >= 5, "render {k}: {large} large splats");
    }
}

/// 60 splats of footprints from about 20 x 20 to 100 x 100 pixels at
/// 150 px focal length and distance 3 (many over BIG_SPLAT_PIXELS, 32 x 32:
/// walked by a workgroup; the rest by one thread each), among 2000 small
/// ones.
fn large_and_small(rng: &mut Rng) -> PointModel {
    let mut model = shapes::random_cloud(rng, Vec3::ZERO, 1.0, 60, 0.2, 0.6);
    let small = shapes::random_cloud(rng, Vec3::ZERO, 1.0, 2000, 0.005, 0.03);
    model.positions.extend(&small.positions);
    model.normals.extend(&small.normals);
    model.radii.extend(&small.radii);
    if let (Some(c), Some(d)) = (&mut model.colors, &small.colors) {
        c.extend(d);
    }
    model
}

/// Splats whose projected radius exceeds 16 px (footprints over 32 x 32)
/// and whose disc reaches over the image border.
fn large_across_border(model: &PointModel, cam: &Intrinsics, pose: &Pose) -> usize {
    (0..model.len())
        .filter(|&i| {
            let p = model.positions[i];
            let x = pose.transform_point(&Vector3::new(p.x as f64, p.y as f64, p.z as f64));
            if x.z <= 0.0 {
                return false;
            }
            let r = cam.fx * model.radii[i] as f64 / x.z;
            let (u, v) = (cam.fx * x.x / x.z + cam.cx, cam.fy * x.y / x.z + cam.cy);
            let inside = u > -r && v > -r && u < cam.width as f64 + r && v < cam.height as f64 + r;
            let crosses = u < r || v < r || u > cam.width as f64 - r || v > cam.height as f64 - r;
            r > 16.0 && inside && crosses
        })
        .count()
}

#[test]
fn large_splats_across_the_image_border_agree() {
    // The cloud's centre projected near each corner and edge: footprints
    // over 32 x 32 pixels clipped by the border, on both walks.
    let model = large_and_small(&mut Rng::new(17));
    let pose = look_at(
        &Vector3::new(0.4, -0.3, -3.0),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    for (cx, cy) in [(4.0, 4.0), (156.0, 116.0), (80.0, 118.0), (-20.0, 60.0)] {
        let cam = Intrinsics::new(160, 120, 150.0, 150.0, cx, cy);
        let crossing = large_across_border(&model, &cam, &pose);
        assert!(
            crossing >= 5,
            "principal point ({cx}, {cy}): {crossing} large splats cross the border"
        );
        check(
            &model,
            &cam,
            &pose,
            &format!("border ({cx}, {cy}), {crossing} large splats across it"),
        );
    }
}

#[test]
fn large_splats_in_windows_agree_with_the_full_render() {
    // Renders into windows (the tracker's crops: the camera shifted by the
    // window's origin) against the CPU reference and the render pass at the
    // window's camera, and against the same pixels of the full render.
    let model = large_and_small(&mut Rng::new(23));
    let cam = Intrinsics::new(200, 150, 150.0, 150.0, 99.5, 74.5);
    let pose = look_at(
        &Vector3::new(-0.2, 0.3, -3.0),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let compute = splatter(Backend::Compute);
    let full = images(&compute, &model, &cam, &pose);
    for win in [
        Window {
            x0: 37,
            y0: 21,
            width: 96,
            height: 80,
        },
        Window {
            x0: 120,
            y0: 90,
            width: 80,
            height: 60,
        },
        Window {
            x0: 0,
            y0: 70,
            width: 64,
            height: 80,
        },
    ] {
        let wcam = win.camera(&cam);
        let label = format!("window {win:?}");
        assert!(
            large_across_border(&model, &wcam, &pose) >= 3,
            "{label}: too few large splats cross its border"
        );
        check(&model, &wcam, &pose, &label);
        let part = images(&compute, &model, &wcam, &pose);
        let (mut covered, mut bad) = (0, 0);
        for y in 0..win.height {
            for x in 0..win.width {
                let (fx, fy) = (x + win.x0, y + win.y0);
                let (a, b) = (part[1].is_valid(x, y), full[1].is_valid(fx, fy));
                covered += (a || b) as usize;
                let same = a == b
                    && (!a
                        || (part[0]
                            .pixel(x, y)
                            .iter()
                            .zip(full[0].pixel(fx, fy))
                            .all(|(p, q)| (p - q).abs() <= 1e-4)
                            && (part[1].pixel(x, y)[0] - full[1].pixel(fx, fy)[0]).abs()
                                <= 1e-5 * full[1].pixel(fx, fy)[0]));
                bad += !same as usize;
            }
        }
        eprintln!("{label}: {bad} of {covered} covered pixels differ from the full render");
        assert!(covered > 1000, "{label}: only {covered} pixels covered");
        assert!(
            bad as f64 <= 0.005 * covered as f64,
            "{label}: {bad} of {covered} pixels differ from the full render"
        );
    }
}

#[test]
fn a_splat_crossing_the_near_plane_covers_the_image_on_both_back_ends() {
    // One big disc, tilted towards the camera so that it reaches behind the
    // near plane: the whole-image footprint of vs_splat / setup, and a near
    // plane a thousandth of the depth (the bounding sphere holds the camera).
    let mut model = shapes::random_cloud(&mut Rng::new(1), Vec3::ZERO, 0.3, 200, 0.01, 0.05);
    model.positions.push(Vec3::new(0.0, 0.0, 0.0));
    model.normals.push(Vec3::new(0.0, 0.6, -0.8));
    model.radii.push(3.0);
    if let Some(c) = &mut model.colors {
        c.push([0.2, 0.4, 0.6]);
    }
    let cam = Intrinsics::new(64, 48, 60.0, 60.0, 31.5, 23.5);
    let pose = look_at(
        &Vector3::new(0.0, 0.0, -1.0),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    check(&model, &cam, &pose, "near plane");
}

#[test]
fn gather_and_partial_renders_agree_between_back_ends() {
    let mut rng = Rng::new(5);
    let model = shapes::sphere(Vec3::ZERO, 1.0, 6000, 1.2);
    let (cam, pose) = random_view(&mut rng, Vector3::zeros(), 3.0);
    let gm = GpuModel::new(ctx(), &model).unwrap();
    let points: Vec<[f32; 2]> = (0..400)
        .map(|_| {
            [
                rng.uniform(-2.0, cam.width as f64 + 1.0) as f32,
                rng.uniform(-2.0, cam.height as f64 + 1.0) as f32,
            ]
        })
        .collect();
    let run = |b: Backend| {
        let s = splatter(b);
        let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
        s.render(ctx(), &gm, &cam, &pose, Attributes::ALL, &mut t)
            .unwrap();
        let g = s.gather(ctx(), &t, &points, GatherMode::Bilinear).unwrap();
        // A colour-only render: colour and weight only, then motion is a
        // typed error; a geometry render has normals.
        s.render(ctx(), &gm, &cam, &pose, Attributes::COLOR, &mut t)
            .unwrap();
        let c = s.read(ctx(), &t, Attribute::Color).unwrap();
        assert!(s.read(ctx(), &t, Attribute::Motion).is_err());
        s.render(ctx(), &gm, &cam, &pose, Attributes::GEOMETRY, &mut t)
            .unwrap();
        let n = s.read(ctx(), &t, Attribute::Normal).unwrap();
        (g, c, n)
    };
    let (gc, cc, nc) = run(Backend::Compute);
    let (gr, cr, nr) = run(Backend::RenderPass);
    let mut valid = 0;
    for (i, (a, b)) in gc.iter().zip(&gr).enumerate() {
        assert_eq!(a.valid, b.valid, "point {i} {:?}", points[i]);
        if !a.valid {
            continue;
        }
        valid += 1;
        let scale = b.motion.iter().map(|v| v.abs()).fold(1e-6, f32::max);
        for k in 0..12 {
            assert!(
                (a.motion[k] - b.motion[k]).abs() <= 1e-4 * scale,
                "point {i}"
            );
        }
        assert!((a.depth - b.depth).abs() <= 1e-5 * b.depth, "point {i}");
    }
    assert!(valid > 50, "only {valid} valid samples");
    for (a, b, what) in [(&cc, &cr, "colour"), (&nc, &nr, "normal")] {
        let bad = a
            .data
            .iter()
            .zip(&b.data)
            .filter(|(p, q)| !((p.is_nan() && q.is_nan()) || (*p - *q).abs() <= 1e-4))
            .count();
        assert!(
            bad as f64 <= 0.005 * a.data.len() as f64,
            "{what}: {bad} of {} values differ",
            a.data.len()
        );
    }
}

#[test]
fn reused_targets_keep_nothing_of_the_previous_render() {
    // The compute back end clears only what it touched: a large view, then
    // a small one elsewhere into the same targets, must equal the small
    // one rendered alone (and the CPU reference).
    let model = shapes::sphere(Vec3::ZERO, 0.5, 4000, 1.2);
    let gm = GpuModel::new(ctx(), &model).unwrap();
    let cam = Intrinsics::new(120, 90, 110.0, 110.0, 59.5, 44.5);
    let near = look_at(
        &Vector3::new(0.0, 0.2, -1.3),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let far = look_at(
        &Vector3::new(1.5, 0.3, -5.0),
        &Vector3::new(0.4, 0.0, 0.0),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let s = splatter(Backend::Compute);
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    s.render(ctx(), &gm, &cam, &near, Attributes::ALL, &mut t)
        .unwrap();
    s.render(ctx(), &gm, &cam, &far, Attributes::ALL, &mut t)
        .unwrap();
    let reused: Vec<SplatImage> = READ
        .iter()
        .map(|&a| s.read(ctx(), &t, a).unwrap())
        .collect();
    let fresh = images(&s, &model, &cam, &far);
    // Integer sums do not depend on the order of the atomics: bit for bit.
    for (k, (a, b)) in reused.iter().zip(&fresh).enumerate() {
        let differ = splat_common::differing(a, b);
        assert_eq!(differ, 0, "{:?}: {differ} values differ", READ[k]);
    }
    let (covered, bad) = disagreement(&reused, &cpu_images(&model, &cam, &far));
    assert!(covered > 50 && bad as f64 <= 0.005 * covered as f64);
    assert!(
        covered < (cam.width * cam.height / 2) as usize,
        "the far view is small"
    );
    // A depth-only render after the large view, likewise: the depth (and
    // weight) of the far view alone, nothing of the near one around it.
    let depth_only = |t: &mut SplatTargets| {
        s.render_depth(ctx(), &gm, &cam, &far, t, None).unwrap();
        [Attribute::Depth, Attribute::Weight].map(|a| s.read(ctx(), t, a).unwrap())
    };
    s.render(ctx(), &gm, &cam, &near, Attributes::ALL, &mut t)
        .unwrap();
    let reused = depth_only(&mut t);
    let fresh = depth_only(&mut SplatTargets::new(ctx(), cam.width, cam.height));
    for (a, b) in reused.iter().zip(&fresh) {
        assert_eq!(splat_common::differing(a, b), 0);
    }
    let seen = fresh[1].data.iter().filter(|&&w| w > 0.0).count();
    assert!(
        seen > 50 && seen < (cam.width * cam.height / 2) as usize,
        "{seen}"
    );
}

#[test]
fn reused_targets_render_each_models_colours_and_geometry() {
    // The compute back end keeps the bind groups of recent models
    // (a keyframe's colours, the bare geometry): renders into the same
    // targets alternating between two colourings of one geometry, a
    // second geometry, and back, each equal bit for bit to the model
    // rendered alone into fresh targets.
    let sphere = shapes::sphere(Vec3::ZERO, 0.5, 3000, 1.2);
    let mut rng = Rng::new(11);
    let mut recoloured = sphere.clone();
    let colours: Vec<[f32; 3]> = (0..sphere.positions.len())
        .map(|_| [0; 3].map(|_: u8| rng.uniform(0.0, 1.0) as f32))
        .collect();
    recoloured.colors = Some(colours.clone());
    let other = shapes::sphere(Vec3::new(0.2, 0.0, 0.1), 0.3, 2000, 1.2);
    let geometry = GpuModel::new(ctx(), &sphere).unwrap();
    let painted = geometry.with_colors(ctx(), &colours).unwrap();
    let second = GpuModel::new(ctx(), &other).unwrap();
    let cam = Intrinsics::new(120, 90, 110.0, 110.0, 59.5, 44.5);
    let pose = look_at(
        &Vector3::new(0.0, 0.2, -1.3),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let s = splatter(Backend::Compute);
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    let order: [(&GpuModel, &PointModel); 6] = [
        (&geometry, &sphere),
        (&painted, &recoloured),
        (&geometry, &sphere),
        (&second, &other),
        (&painted, &recoloured),
        (&geometry, &sphere),
    ];
    for (i, (gm, model)) in order.into_iter().enumerate() {
        s.render(ctx(), gm, &cam, &pose, Attributes::ALL, &mut t)
            .unwrap();
        let fresh = images(&s, model, &cam, &pose);
        for (k, &a) in READ.iter().enumerate() {
            let got = s.read(ctx(), &t, a).unwrap();
            let differ = splat_common::differing(&got, &fresh[k]);
            assert_eq!(differ, 0, "render {i}, {a:?}: {differ} values differ");
        }
    }
}

#[test]
fn compute_passes_are_timed_like_the_render_pass() {
    let model = shapes::sphere(Vec3::ZERO, 0.5, 2000, 1.2);
    let gm = GpuModel::new(ctx(), &model).unwrap();
    let cam = Intrinsics::new(96, 72, 90.0, 90.0, 47.5, 35.5);
    let pose = look_at(
        &Vector3::new(0.0, 0.0, -2.0),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let s = splatter(Backend::Compute);
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    let mut timer = GpuTimer::new(ctx(), 2);
    s.render_timed(
        ctx(),
        &gm,
        &cam,
        &pose,
        Attributes::ALL,
        &mut t,
        Some(&mut timer),
    )
    .unwrap();
    let r = timer.read(ctx()).unwrap();
    if ctx().has_timestamps() {
        for pass in ["visibility", "attributes"] {
            let ms = r.get(pass).unwrap_or_else(|| panic!("{pass} not timed"));
            assert!(ms.is_finite() && ms >= 0.0, "{pass}: {ms} ms");
        }
    }
}

#[test]
fn auto_picks_the_compute_splatter_where_supported_and_the_flag_names_parse() {
    for (s, b) in [
        ("render", Backend::RenderPass),
        ("compute", Backend::Compute),
        ("auto", Backend::Auto),
        (" Compute ", Backend::Compute),
    ] {
        assert_eq!(Backend::parse(s), Some(b));
        assert_eq!(s.parse::<Backend>().unwrap(), b);
    }
    assert!(Backend::parse("raster").is_none());
    assert!("gpu".parse::<Backend>().is_err());
    for b in [Backend::Auto, Backend::RenderPass, Backend::Compute] {
        assert_eq!(Backend::parse(b.name()), Some(b));
    }
    // The rule (the environment variable, when a run sets it, wins).
    if std::env::var(splattrack::splat::SPLATTER_ENV).is_err() {
        // Five storage textures per stage: lavapipe and every desktop GPU.
        let want = if ctx().limits.max_storage_textures_per_shader_stage >= 5 {
            Backend::Compute
        } else {
            Backend::RenderPass
        };
        assert_eq!(Backend::Auto.resolve(ctx()).unwrap(), want);
        assert_eq!(Splatter::new(ctx()).unwrap().backend(), want);
    }
}

#[test]
fn auto_sends_large_splats_through_the_render_pass_on_cpu_adapters() {
    // A sparse sphere close up (median splat radius over
    // AUTO_CPU_RENDER_PASS_ABOVE_PX on screen) and a dense one far away.
    let sparse = GpuModel::new(ctx(), &shapes::sphere(Vec3::ZERO, 0.5, 400, 1.2)).unwrap();
    let dense = GpuModel::new(ctx(), &shapes::sphere(Vec3::ZERO, 0.5, 20_000, 1.2)).unwrap();
    let cam = Intrinsics::new(160, 120, 150.0, 150.0, 79.5, 59.5);
    let at = |d: f64| {
        look_at(
            &Vector3::new(0.0, 0.0, -d),
            &Vector3::zeros(),
            &Vector3::new(0.0, -1.0, 0.0),
        )
    };
    let typical = |m: &GpuModel, d: f64| cam.fx * m.bounds.median_splat_radius / d;
    assert!(typical(&sparse, 1.5) > splattrack::splat::AUTO_CPU_RENDER_PASS_ABOVE_PX);
    assert!(typical(&dense, 4.0) < splattrack::splat::AUTO_CPU_RENDER_PASS_ABOVE_PX);
    let explicit = splatter(Backend::Compute);
    assert_eq!(
        explicit.backend_for(&sparse, &cam, &at(1.5)),
        Backend::Compute
    );
    assert_eq!(
        explicit.backend_for(&dense, &cam, &at(4.0)),
        Backend::Compute
    );
    let render = splatter(Backend::RenderPass);
    assert_eq!(
        render.backend_for(&dense, &cam, &at(4.0)),
        Backend::RenderPass
    );
    if std::env::var(splattrack::splat::SPLATTER_ENV).is_ok() {
        return; // a run that forces a back end
    }
    let auto = Splatter::new(ctx()).unwrap();
    if auto.backend() != Backend::Compute {
        assert_eq!(
            auto.backend_for(&dense, &cam, &at(4.0)),
            Backend::RenderPass
        );
        return;
    }
    let large = if ctx().is_cpu() {
        Backend::RenderPass
    } else {
        Backend::Compute
    };
    assert_eq!(auto.backend_for(&sparse, &cam, &at(1.5)), large);
    assert_eq!(auto.backend_for(&dense, &cam, &at(4.0)), Backend::Compute);
    // Whichever renders, the images are that back end's, bit for bit.
    for (m, d) in [(&sparse, 1.5), (&dense, 4.0)] {
        let read = |s: &Splatter| {
            let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
            s.render(ctx(), m, &cam, &at(d), Attributes::ALL, &mut t)
                .unwrap();
            s.read(ctx(), &t, Attribute::Motion).unwrap().data
        };
        let chosen = splatter(auto.backend_for(m, &cam, &at(d)));
        let (a, b) = (read(&auto), read(&chosen));
        assert!(a.iter().any(|v| !v.is_nan()));
        assert!(
            a.iter()
                .zip(&b)
                .all(|(p, q)| p.to_bits() == q.to_bits() || (p.is_nan() && q.is_nan()))
        );
    }
}

/// tests/splat_mesh.rs's check, on the compute back end, at 320x240.
fn against_mesh(mesh: &TriangleMesh, n: usize, diameter: f64, dist: f64, label: &str) {
    let cam = Intrinsics::new(320, 240, 300.0, 301.0, 159.2, 120.4);
    let mut model = mesh.sample(n, 17).unwrap();
    let r = 2.0 * (mesh.area() / n as f64).sqrt();
    model.radii.fill(r as f32);
    model.provenance.radii = AttributeSource::Estimated;
    let s = splatter(Backend::Compute);
    let gm = GpuModel::new(ctx(), &model).unwrap();
    let mut targets = SplatTargets::new(ctx(), cam.width, cam.height);
    for k in 0..2 {
        let a = 2.1 * k as f64 + 0.4;
        let eye = Vector3::new(a.cos(), a.sin(), 0.6 - 0.5 * k as f64).normalize() * dist;
        let pose = look_at(&eye, &Vector3::zeros(), &Vector3::new(0.0, 0.0, 1.0));
        s.render(ctx(), &gm, &cam, &pose, Attributes::ALL, &mut targets)
            .unwrap();
        let depth = s.read(ctx(), &targets, Attribute::Depth).unwrap();
        let motion = s.read(ctx(), &targets, Attribute::Motion).unwrap();
        let mesh_depth = raster::depth(mesh, &pose, &cam);
        let (w, h) = (cam.width, cam.height);
        let covered = |x: u32, y: u32| !mesh_depth[(y * w + x) as usize].is_nan();
        let (mut inter, mut union) = (0usize, 0usize);
        let (mut dz, mut dl) = (Vec::new(), Vec::new());
        for y in 2..h - 2 {
            for x in 2..w - 2 {
                let (sv, mv) = (depth.is_valid(x, y), covered(x, y));
                inter += (sv && mv) as usize;
                union += (sv || mv) as usize;
                let interior = (-2..=2i32).all(|j| {
                    (-2..=2i32).all(|i| covered((x as i32 + i) as u32, (y as i32 + j) as u32))
                });
                if !sv || !interior {
                    continue;
                }
                let zm = mesh_depth[(y * w + x) as usize] as f64;
                dz.push((depth.pixel(x, y)[0] as f64 - zm).abs() / diameter);
                let l =
                    cam.motion_predictors(&cam.unproject(&Vector2::new(x as f64, y as f64), zm));
                let mp = motion.pixel(x, y);
                let err = (0..12)
                    .map(|k| (mp[k] as f64 - l[(k % 2, k / 2)]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                dl.push(err / l.norm());
            }
        }
        assert!(
            dz.len() > 500,
            "{label} pose {k}: {} interior pixels",
            dz.len()
        );
        let pct = |v: &mut Vec<f64>, p: f64| {
            v.sort_by(|a, b| a.total_cmp(b));
            v[((v.len() - 1) as f64 * p).round() as usize]
        };
        let iou = inter as f64 / union as f64;
        let (zm, z99) = (pct(&mut dz, 0.5), pct(&mut dz, 0.99));
        let (lm, l95) = (pct(&mut dl, 0.5), pct(&mut dl, 0.95));
        eprintln!(
            "{label} pose {k} (compute): IoU {iou:.4}, depth/diameter median {:.3}% p99 {:.3}%, predictors median {:.3}% p95 {:.3}%",
            100.0 * zm,
            100.0 * z99,
            100.0 * lm,
            100.0 * l95
        );
        assert!(iou >= 0.97, "{label} pose {k}: IoU {iou}");
        assert!(zm <= 0.002 && z99 <= 0.015, "{label} pose {k}: depth");
        assert!(lm <= 0.01 && l95 <= 0.05, "{label} pose {k}: predictors");
    }
}

#[test]
fn compute_splatted_sphere_and_torus_match_their_meshes() {
    against_mesh(
        &TriangleMesh::sphere(0.5, 48, 96),
        60_000,
        1.0,
        2.0,
        "sphere",
    );
    against_mesh(
        &TriangleMesh::torus(0.45, 0.18, 96, 48),
        80_000,
        2.0 * 0.63,
        2.2,
        "torus",
    );
}

#[test]
fn repeated_renders_and_reads_bind_nothing_anew_on_either_back_end() {
    // Bind groups are kept across renders (by targets and model) and
    // across reads and gathers (by targets and output): once two sets of
    // targets have been rendered into, read and gathered from, doing it
    // again makes no bind group. A context of its own, so that other
    // tests' bind groups are not counted.
    let c = splattrack::gpu::own_test_context();
    let model = shapes::sphere(Vec3::ZERO, 0.5, 3000, 1.2);
    let gm = GpuModel::new(&c, &model).unwrap();
    let cam = Intrinsics::new(96, 72, 90.0, 90.0, 47.5, 35.5);
    let pose = look_at(
        &Vector3::new(0.2, 0.1, -1.6),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let points = [[40.0f32, 30.0], [50.0, 40.0]];
    for backend in [Backend::Compute, Backend::RenderPass] {
        let s = Splatter::with_params(
            &c,
            SplatParams {
                backend,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(s.backend(), backend);
        let mut a = SplatTargets::new(&c, cam.width, cam.height);
        let mut b = SplatTargets::new(&c, cam.width, cam.height);
        let round = |t: &mut SplatTargets| {
            s.render(&c, &gm, &cam, &pose, Attributes::ALL, t).unwrap();
            s.read(&c, t, Attribute::Color).unwrap();
            s.gather(&c, t, &points, GatherMode::Bilinear).unwrap();
        };
        round(&mut a);
        round(&mut b);
        let made = c.stats().bind_groups_created;
        for _ in 0..3 {
            round(&mut a);
            round(&mut b);
        }
        assert_eq!(c.stats().bind_groups_created, made, "{backend:?}");
    }
}
