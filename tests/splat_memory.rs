//! The GPU memory accounting of the splatter (`GpuModel::gpu_bytes`,
//! `SplatTargets::gpu_bytes`) against the sizes the buffers and textures
//! must have, worked out here from the formats: 32 bytes of geometry and 4
//! of colour a point; 5 RGBA32F accumulators and a 32-bit depth (84 bytes
//! a pixel) and the 112-byte camera uniform per set of targets; after a
//! compute render, the scratch: depth keys and 9 fixed-point sums (40 bytes
//! a pixel), the large-splat list (4 bytes a splat, rounded up to 16), and
//! 16 + 32 + 32 bytes of parameters, bounds and dispatch arguments.

use glam::Vec3;
use nalgebra::Vector3;
use splattrack::geometry::{Intrinsics, look_at};
use splattrack::gpu::{self, GpuContext};
use splattrack::model::shapes;
use splattrack::splat::{Attributes, Backend, GpuModel, SplatParams, SplatTargets, Splatter};

fn ctx() -> &'static GpuContext {
    gpu::shared_test_context()
}

#[test]
fn models_and_targets_account_for_their_buffers() {
    let n = 3001u64;
    let model = shapes::sphere(Vec3::ZERO, 0.5, n as usize, 1.2);
    let gm = GpuModel::new(ctx(), &model).unwrap();
    assert_eq!(gm.len() as u64, n);
    assert_eq!(gm.gpu_bytes(), n * 32 + n * 4);
    // A recoloured copy shares the geometry: it adds its colours only.
    let recoloured = gm.with_colors(ctx(), &vec![[0.5; 3]; n as usize]).unwrap();
    assert_eq!(recoloured.color_bytes(), n * 4);
    assert_eq!(recoloured.geometry_bytes(), gm.geometry_bytes());

    let (w, h) = (100u64, 60u64);
    let pixels = w * h;
    let plain = pixels * (5 * 16 + 4) + 112;
    let cam = Intrinsics::new(w as u32, h as u32, 90.0, 90.0, 49.5, 29.5);
    let pose = look_at(
        &Vector3::new(0.0, 0.0, -2.0),
        &Vector3::zeros(),
        &Vector3::new(0.0, -1.0, 0.0),
    );
    let splatter = |backend| {
        Splatter::with_params(
            ctx(),
            SplatParams {
                backend,
                ..Default::default()
            },
        )
        .unwrap()
    };
    let mut t = SplatTargets::new(ctx(), w as u32, h as u32);
    assert_eq!(t.gpu_bytes(), plain);
    // The render pass adds nothing to the targets.
    splatter(Backend::RenderPass)
        .render(ctx(), &gm, &cam, &pose, Attributes::ALL, &mut t)
        .unwrap();
    assert_eq!(t.gpu_bytes(), plain);
    // The compute splatter adds its scratch on its first render there.
    let compute = splatter(Backend::Compute);
    compute
        .render(ctx(), &gm, &cam, &pose, Attributes::ALL, &mut t)
        .unwrap();
    // The list of large splats is a grow-only buffer rounded up to a
    // power of two (`GrowBuffer`); then the parameters (32) and the
    // bounds' two halves (64).
    let scratch = |splats: u64| {
        pixels * (4 + 9 * 4) + (splats * 4).next_multiple_of(16).next_power_of_two() + 32 + 64
    };
    assert_eq!(t.gpu_bytes(), plain + scratch(n));
    // A larger model grows the list of large splats, a smaller one does not
    // shrink it.
    let big = GpuModel::new(ctx(), &shapes::sphere(Vec3::ZERO, 0.5, 8000, 1.2)).unwrap();
    compute
        .render(ctx(), &big, &cam, &pose, Attributes::COLOR, &mut t)
        .unwrap();
    assert_eq!(t.gpu_bytes(), plain + scratch(8000));
    compute
        .render(ctx(), &gm, &cam, &pose, Attributes::COLOR, &mut t)
        .unwrap();
    assert_eq!(t.gpu_bytes(), plain + scratch(8000));
}
