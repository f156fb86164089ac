//! Bad input to the splatter gives typed errors, never a panic or an empty
//! image that looks like a result.

use glam::Vec3;
use nalgebra::{Matrix3, Vector3};
use splattrack::geometry::{Intrinsics, Pose};
use splattrack::gpu;
use splattrack::model::shapes;
use splattrack::splat::{Attribute, Attributes, GpuModel, SplatError, SplatTargets, Splatter};

#[test]
fn bad_models_poses_and_targets_are_typed_errors() {
    let ctx = gpu::shared_test_context();
    let splatter = Splatter::new(ctx).unwrap();
    let good = shapes::sphere(Vec3::ZERO, 0.5, 500, 1.2);

    let mut empty = good.clone();
    empty.positions.clear();
    empty.normals.clear();
    empty.radii.clear();
    empty.colors = None;
    assert!(matches!(
        GpuModel::new(ctx, &empty),
        Err(SplatError::EmptyModel)
    ));

    let mut short = good.clone();
    short.radii.pop();
    assert!(matches!(
        GpuModel::new(ctx, &short),
        Err(SplatError::Inconsistent { what: "radii", .. })
    ));

    for bad in [
        |m: &mut splattrack::model::PointModel| m.radii[7] = 0.0,
        |m: &mut splattrack::model::PointModel| m.radii[7] = f32::NAN,
        |m: &mut splattrack::model::PointModel| m.positions[7].x = f32::INFINITY,
        |m: &mut splattrack::model::PointModel| m.normals[7] = Vec3::ZERO,
    ] {
        let mut m = good.clone();
        bad(&mut m);
        assert!(matches!(
            GpuModel::new(ctx, &m),
            Err(SplatError::BadPoint { index: 7 })
        ));
    }

    let gm = GpuModel::new(ctx, &good).unwrap();
    let cam = Intrinsics::new(64, 48, 60.0, 60.0, 31.5, 23.5);
    let behind = Pose::new(Matrix3::identity(), Vector3::new(0.0, 0.0, -3.0)).unwrap();
    assert!(matches!(
        splatter.render_image(ctx, &gm, &cam, &behind, Attribute::Depth),
        Err(SplatError::BehindCamera { .. })
    ));
    let not_rigid = Pose {
        rotation: Matrix3::identity() * 2.0,
        translation: Vector3::new(0.0, 0.0, 3.0),
    };
    assert!(matches!(
        splatter.render_image(ctx, &gm, &cam, &not_rigid, Attribute::Depth),
        Err(SplatError::Pose(_))
    ));
    let mut bad_cam = cam;
    bad_cam.fx = -1.0;
    let front = Pose::new(Matrix3::identity(), Vector3::new(0.0, 0.0, 3.0)).unwrap();
    assert!(matches!(
        splatter.render_image(ctx, &gm, &bad_cam, &front, Attribute::Depth),
        Err(SplatError::Camera(_))
    ));
    let mut targets = SplatTargets::new(ctx, 32, 32);
    assert!(matches!(
        splatter.render(ctx, &gm, &cam, &front, Attributes::ALL, &mut targets),
        Err(SplatError::SizeMismatch { .. })
    ));
    // Nothing rendered yet: reading or gathering is an error.
    let targets = SplatTargets::new(ctx, 64, 48);
    assert!(matches!(
        splatter.read(ctx, &targets, Attribute::Color),
        Err(SplatError::NotRendered(_))
    ));
    assert!(
        splatter
            .gather(ctx, &targets, &[[1.0, 1.0]], Default::default())
            .is_err()
    );
    // The camera inside the object: a valid (partial) render, not an error.
    let inside = Pose::new(Matrix3::identity(), Vector3::new(0.0, 0.0, 0.2)).unwrap();
    splatter
        .render_image(ctx, &gm, &cam, &inside, Attribute::Depth)
        .unwrap();
}
