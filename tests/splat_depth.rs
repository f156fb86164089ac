//! The depth-only render (`Splatter::render_depth`: the visibility pass
//! alone, for the contour modality's silhouettes) against its CPU
//! reference (`cpu::visibility_depth`) on random clouds, on both back ends;
//! its coverage against a full render's; its depth against the known
//! answer of a plane; and what may and may not be read after it.
//!
//! Tolerances. Depth: 1e-5 relative where both cover a pixel (the compute
//! back end rebuilds z from the [0, 1] depth bits, the render pass writes
//! it directly: f32 rounding of the linear depth map). Coverage: as in
//! tests/splat_compute.rs, rounding may flip a truncation test sitting on
//! its threshold, so at most 0.5% of the covered pixels may disagree with
//! the reference; against a full render on the same back end the support
//! is the same kernel test, so at most 0.1%.

use glam::Vec3;
use nalgebra::Vector3;
use splattrack::geometry::{Intrinsics, Pose, look_at};
use splattrack::gpu::GpuTimer;
use splattrack::model::{PointModel, shapes};
use splattrack::rng::Rng;
use splattrack::splat::{
    Attribute, Attributes, Backend, GatherMode, GpuModel, ModelBounds, SplatError, SplatImage,
    SplatParams, SplatTargets, Splatter, cpu, pack_model,
};

mod splat_common;
use splat_common::{ctx, random_view, splatter};

/// The depth-only render read back: depth and weight.
fn depth_render(
    s: &Splatter,
    model: &PointModel,
    cam: &Intrinsics,
    pose: &Pose,
) -> (SplatImage, SplatImage) {
    let gm = GpuModel::new(ctx(), model).unwrap();
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    s.render_depth(ctx(), &gm, cam, pose, &mut t, None).unwrap();
    assert!(t.depth_only() && t.rendered().is_none());
    (
        s.read(ctx(), &t, Attribute::Depth).unwrap(),
        s.read(ctx(), &t, Attribute::Weight).unwrap(),
    )
}

fn reference(model: &PointModel, cam: &Intrinsics, pose: &Pose) -> SplatImage {
    let params = SplatParams::default();
    let packed = pack_model(model, &params).unwrap();
    let uniform = ModelBounds::of(model).view(cam, pose, &params).unwrap();
    cpu::visibility_depth(&packed, &uniform)
}

/// Covered pixels (either image) and those whose coverage or depth
/// (1e-5 relative) disagree.
fn disagreement(a: &SplatImage, b: &SplatImage) -> (usize, usize) {
    let (mut covered, mut bad) = (0, 0);
    for (p, q) in a.data.iter().zip(&b.data) {
        if p.is_nan() && q.is_nan() {
            continue;
        }
        covered += 1;
        if p.is_nan() != q.is_nan() || (p - q).abs() > 1e-5 * q.abs() {
            bad += 1;
        }
    }
    (covered, bad)
}

#[test]
fn depth_only_renders_match_the_cpu_reference_on_both_back_ends() {
    let mut rng = Rng::new(2026);
    for trial in 0..4 {
        let n = 300 + rng.below(3000) as usize;
        // Radii from sub-pixel to tens of pixels (some walked by a
        // workgroup on the compute back end).
        let model = shapes::random_cloud(&mut rng, Vec3::ZERO, 1.0, n, 0.005, 0.3);
        let dist = rng.uniform(2.5, 6.0);
        let (cam, pose) = random_view(&mut rng, Vector3::zeros(), dist);
        let want = reference(&model, &cam, &pose);
        for backend in [Backend::Compute, Backend::RenderPass] {
            let (depth, weight) = depth_render(&splatter(backend), &model, &cam, &pose);
            let (covered, bad) = disagreement(&depth, &want);
            eprintln!("cloud {trial} ({n} splats), {backend}: {bad} of {covered} pixels disagree");
            assert!(covered > 100, "only {covered} pixels covered");
            assert!(
                bad as f64 <= 0.005 * covered as f64,
                "cloud {trial}, {backend}: {bad} of {covered} covered pixels disagree"
            );
            // The weight is 1 exactly where the depth is finite, else 0.
            for (z, w) in depth.data.iter().zip(&weight.data) {
                assert_eq!(*w, if z.is_nan() { 0.0 } else { 1.0 });
            }
        }
    }
}

#[test]
fn depth_only_coverage_is_the_full_renders() {
    // The contour's silhouette (and the inset calibrated on it) comes from
    // this coverage: it must be a full render's, and its depth within the
    // push-back (epsilon radii along the ray) behind the averaged depth.
    let mut rng = Rng::new(7);
    let model = shapes::sphere(Vec3::new(0.1, 0.0, -0.2), 1.0, 6000, 1.2);
    let r_max = model.radii.iter().fold(0.0f32, |m, &r| m.max(r));
    let (cam, pose) = random_view(&mut rng, Vector3::zeros(), 3.5);
    for backend in [Backend::Compute, Backend::RenderPass] {
        let s = splatter(backend);
        let (depth, _) = depth_render(&s, &model, &cam, &pose);
        let gm = GpuModel::new(ctx(), &model).unwrap();
        let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
        s.render(ctx(), &gm, &cam, &pose, Attributes::GEOMETRY, &mut t)
            .unwrap();
        let full = s.read(ctx(), &t, Attribute::Depth).unwrap();
        let (mut covered, mut differ, mut behind) = (0usize, 0usize, 0.0f32);
        for (v, f) in depth.data.iter().zip(&full.data) {
            covered += (!v.is_nan() || !f.is_nan()) as usize;
            if v.is_nan() != f.is_nan() {
                differ += 1;
            } else if !v.is_nan() {
                assert!(
                    *v >= f - 1e-5 * f,
                    "{backend}: visibility depth {v} before {f}"
                );
                behind = behind.max(v - f);
            }
        }
        eprintln!(
            "{backend}: {differ} of {covered} pixels differ in coverage; depth at most {behind:.4} behind (largest radius {r_max:.4})"
        );
        assert!(covered > 1000);
        assert!(
            differ as f64 <= 0.001 * covered as f64,
            "{backend}: {differ} of {covered}"
        );
        // The push-back along the ray is epsilon (1) radius at most.
        assert!(behind <= r_max * 1.001, "{backend}: {behind} > {r_max}");
    }
}

#[test]
fn a_plane_facing_the_camera_has_its_known_pushed_back_depth() {
    // A plane at z = 2 facing the camera, splats of radius r: through
    // pixel (u, v) the nearest surface is at z = 2 on every splat, pushed
    // back by r along the ray: z = 2 + r / |d|, d = ((u - cx) / fx,
    // (v - cy) / fy, 1).
    let model = shapes::plane(
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -1.0),
        0.6,
        80,
        1.0,
    );
    let r = model.radii[0] as f64;
    assert!(model.radii.iter().all(|&x| x as f64 == r));
    let cam = Intrinsics::new(100, 80, 90.0, 92.0, 49.5, 39.5);
    let pose = Pose::new(nalgebra::Matrix3::identity(), Vector3::new(0.0, 0.0, 2.0)).unwrap();
    for backend in [Backend::Compute, Backend::RenderPass] {
        let (depth, _) = depth_render(&splatter(backend), &model, &cam, &pose);
        let mut checked = 0;
        // The plane spans |x|, |y| < 0.6 at z = 2, 27 px either side of
        // the principal point: the pixels within 20 px of it.
        for v in 20..60u32 {
            for u in 30..70u32 {
                let d = Vector3::new(
                    (u as f64 - cam.cx) / cam.fx,
                    (v as f64 - cam.cy) / cam.fy,
                    1.0,
                );
                let want = 2.0 + r / d.norm();
                let got = depth.pixel(u, v)[0] as f64;
                assert!(
                    (got - want).abs() <= 1e-5 * want,
                    "{backend}: ({u}, {v}): {got} != {want}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 1600);
        // Beyond the plane's edge (x = 0.6 at z = 2: 27 px from cx, plus
        // one splat radius), nothing.
        assert!(depth.pixel(5, 40)[0].is_nan() && depth.pixel(95, 40)[0].is_nan());
    }
}

#[test]
fn after_a_depth_only_render_only_depth_and_weight_read_and_full_renders_are_unchanged() {
    let model = shapes::sphere(Vec3::ZERO, 0.5, 3000, 1.2);
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
    for backend in [Backend::Compute, Backend::RenderPass] {
        let s = splatter(backend);
        let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
        // A full render, a depth-only one elsewhere in the same targets,
        // then a full one again: nothing of the others may remain.
        s.render(ctx(), &gm, &cam, &far, Attributes::ALL, &mut t)
            .unwrap();
        s.render_depth(ctx(), &gm, &cam, &near, &mut t, None)
            .unwrap();
        for a in [Attribute::Color, Attribute::Normal, Attribute::Motion] {
            assert!(matches!(
                s.read(ctx(), &t, a),
                Err(SplatError::NotRendered(x)) if x == a
            ));
        }
        assert!(matches!(
            s.gather(ctx(), &t, &[[60.0, 45.0]], GatherMode::Nearest),
            Err(SplatError::NotRendered(_))
        ));
        let depth = s.read(ctx(), &t, Attribute::Depth).unwrap();
        let (alone, _) = depth_render(&s, &model, &cam, &near);
        assert_eq!(
            splat_common::differing(&depth, &alone),
            0,
            "{backend}: depth after a full render"
        );
        s.render(ctx(), &gm, &cam, &far, Attributes::ALL, &mut t)
            .unwrap();
        assert!(!t.depth_only() && t.rendered() == Some(Attributes::ALL));
        let mut fresh = SplatTargets::new(ctx(), cam.width, cam.height);
        s.render(ctx(), &gm, &cam, &far, Attributes::ALL, &mut fresh)
            .unwrap();
        for a in [
            Attribute::Color,
            Attribute::Depth,
            Attribute::Normal,
            Attribute::Motion,
            Attribute::Weight,
        ] {
            let (x, y) = (
                s.read(ctx(), &t, a).unwrap(),
                s.read(ctx(), &fresh, a).unwrap(),
            );
            assert_eq!(
                splat_common::differing(&x, &y),
                0,
                "{backend}: {a:?} after a depth-only render"
            );
        }
    }
}

#[test]
fn depth_only_passes_are_timed() {
    let model = shapes::sphere(Vec3::ZERO, 0.5, 2000, 1.2);
    let gm = GpuModel::new(ctx(), &model).unwrap();
    let cam = Intrinsics::new(96, 72, 90.0, 90.0, 47.5, 35.5);
    let pose = look_at(
        &Vector3::new(0.0, 0.0, -2.0),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    for (backend, passes) in [
        (Backend::Compute, &["visibility", "depth"][..]),
        (Backend::RenderPass, &["visibility"][..]),
    ] {
        let s = splatter(backend);
        let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
        let mut timer = GpuTimer::new(ctx(), 2);
        s.render_depth(ctx(), &gm, &cam, &pose, &mut t, Some(&mut timer))
            .unwrap();
        let r = timer.read(ctx()).unwrap();
        if ctx().has_timestamps() {
            for pass in passes {
                let ms = r.get(pass).unwrap_or_else(|| panic!("{pass} not timed"));
                assert!(ms.is_finite() && ms >= 0.0, "{pass}: {ms} ms");
            }
            assert!(r.get("attributes").is_none());
        }
    }
}
