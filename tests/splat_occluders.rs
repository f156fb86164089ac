//! Occluders in the splatter (`Splatter::set_occluders`): other objects
//! splatted into the visibility depth buffer before the model, so that
//! the model's renders leave out what they hide. On every path: the
//! compute and render pass back ends on lavapipe (each forced), the CPU
//! device's host splatter, and the CPU reference (`cpu::*_occluded`).
//!
//! Tolerances. The known answers (two parallel planes) are exact: where
//! the near plane covers a pixel the far one is empty, elsewhere the far
//! one's render is its plain render bit for bit (the occluder changes no
//! depth the model's fragments are tested against there), on every path;
//! pixels within 1 px of the edge of the near plane's coverage are left
//! out (the band where its kernel's truncation meets the far plane's).
//! Against the CPU reference, the tolerances of tests/splat_compute.rs:
//! colour 1e-4, depth 1e-5 relative, predictors 1e-4 relative, and at
//! most 0.5% of the covered pixels disagreeing (rounding flips tests
//! sitting on their thresholds).

use glam::Vec3;
use nalgebra::{Matrix3, Vector3};
use splattrack::Device;
use splattrack::geometry::{Intrinsics, Pose};
use splattrack::model::{PointModel, shapes};
use splattrack::rng::Rng;
use splattrack::splat::gpu_data::CameraUniform;
use splattrack::splat::{
    Attribute, Attributes, Backend, GpuModel, ModelBounds, Occluder, PackedModel, SplatError,
    SplatImage, SplatParams, SplatTargets, Splatter, cpu, pack_model,
};
use std::sync::Arc;

mod splat_common;
use splat_common::{READ, disagreement};
use splat_common::{ctx, differing, random_view, splatter};

/// A splatter and the device it renders on.
struct Path {
    name: &'static str,
    splatter: Splatter,
}

impl Path {
    fn all() -> Vec<Path> {
        vec![
            Path {
                name: "compute",
                splatter: splatter(Backend::Compute),
            },
            Path {
                name: "render pass",
                splatter: splatter(Backend::RenderPass),
            },
            Path {
                name: "CPU device",
                splatter: Splatter::new(&Device::Cpu).unwrap(),
            },
        ]
    }

    fn cpu(&self) -> bool {
        self.splatter.on_cpu()
    }

    /// A new splatter on the same path.
    fn fresh(&self) -> Path {
        Path {
            name: self.name,
            splatter: if self.cpu() {
                Splatter::new(&Device::Cpu).unwrap()
            } else {
                splatter(self.splatter.backend())
            },
        }
    }

    fn model(&self, m: &PointModel) -> Arc<GpuModel> {
        Arc::new(if self.cpu() {
            GpuModel::new(&Device::Cpu, m).unwrap()
        } else {
            GpuModel::new(ctx(), m).unwrap()
        })
    }

    fn targets(&self, cam: &Intrinsics) -> SplatTargets {
        if self.cpu() {
            SplatTargets::new(&Device::Cpu, cam.width, cam.height)
        } else {
            SplatTargets::new(ctx(), cam.width, cam.height)
        }
    }

    /// Every attribute of a full render.
    fn images(&self, m: &GpuModel, cam: &Intrinsics, pose: &Pose) -> Vec<SplatImage> {
        let mut t = self.targets(cam);
        let s = &self.splatter;
        if self.cpu() {
            s.render(&Device::Cpu, m, cam, pose, Attributes::ALL, &mut t)
                .unwrap();
            READ.iter()
                .map(|&a| s.read(&Device::Cpu, &t, a).unwrap())
                .collect()
        } else {
            s.render(ctx(), m, cam, pose, Attributes::ALL, &mut t)
                .unwrap();
            READ.iter()
                .map(|&a| s.read(ctx(), &t, a).unwrap())
                .collect()
        }
    }

    /// A depth-only render's depth and weight.
    fn depth(&self, m: &GpuModel, cam: &Intrinsics, pose: &Pose) -> [SplatImage; 2] {
        let mut t = self.targets(cam);
        let s = &self.splatter;
        if self.cpu() {
            s.render_depth(&Device::Cpu, m, cam, pose, &mut t, None)
                .unwrap();
        } else {
            s.render_depth(ctx(), m, cam, pose, &mut t, None).unwrap();
        }
        let read = |a| {
            if self.cpu() {
                s.read(&Device::Cpu, &t, a).unwrap()
            } else {
                s.read(ctx(), &t, a).unwrap()
            }
        };
        [read(Attribute::Depth), read(Attribute::Weight)]
    }
}

fn identity() -> Pose {
    Pose::new(Matrix3::identity(), Vector3::zeros()).unwrap()
}

/// The two planes, in camera coordinates (identity poses), facing the
/// camera: the far one at z = 1.5 (x, y in [-0.5, 0.5]), the near one at
/// z = 1.0 covering the far one's left half (x in [-0.8, 0], y in
/// [-0.4, 0.4], which seen from the camera holds the far one's x < 0).
fn planes() -> (Intrinsics, PointModel, PointModel) {
    let cam = Intrinsics::new(128, 96, 100.0, 100.0, 63.5, 47.5);
    let facing = Vec3::new(0.0, 0.0, -1.0);
    let far = shapes::plane(Vec3::new(0.0, 0.0, 1.5), facing, 0.5, 60, 1.0);
    let near = shapes::plane(Vec3::new(-0.4, 0.0, 1.0), facing, 0.4, 60, 1.0);
    (cam, far, near)
}

/// The pixels `cover` reaches (weight > 0), and those within 1 px of its
/// edge (either side).
fn mask_and_band(cover: &SplatImage) -> (Vec<bool>, Vec<bool>) {
    let (w, h) = (cover.width as i64, cover.height as i64);
    let on: Vec<bool> = cover.data.iter().map(|&v| v > 0.0).collect();
    let mut band = vec![false; on.len()];
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            for (dx, dy) in [
                (-1, 0),
                (1, 0),
                (0, -1),
                (0, 1),
                (-1, -1),
                (1, 1),
                (-1, 1),
                (1, -1),
            ] {
                let (u, v) = (x + dx, y + dy);
                if u >= 0 && v >= 0 && u < w && v < h && on[(v * w + u) as usize] != on[i] {
                    band[i] = true;
                }
            }
        }
    }
    (on, band)
}

/// Whether two values are the same bits (NaN equal to NaN).
fn same(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

/// Renders `model` behind `occluders` (identity poses) on `p` and checks
/// the known answer: where they are `in_front` of it, empty wherever an
/// occluder's own render covers the pixel, the plain render bit for bit
/// elsewhere (the 1 px band around the occluders' coverage left out);
/// where they are behind it, the plain render bit for bit everywhere.
/// Returns the pixels checked hidden and kept.
fn hides_exactly(
    p: &mut Path,
    cam: &Intrinsics,
    model: &GpuModel,
    occluders: &[Arc<GpuModel>],
    in_front: bool,
) -> (usize, usize) {
    let pose = identity();
    p.splatter.set_occluders(Vec::new()).unwrap();
    let plain = p.images(model, cam, &pose);
    let mut cover = SplatImage {
        data: vec![0.0; (cam.width * cam.height) as usize],
        ..plain[4].clone()
    };
    for o in occluders {
        let w = p.images(o, cam, &pose).remove(4);
        for (c, v) in cover.data.iter_mut().zip(&w.data) {
            *c += v;
        }
    }
    let (mut hidden, mut band) = mask_and_band(&cover);
    if !in_front {
        hidden.fill(false);
        band.fill(false);
    }
    let list = occluders
        .iter()
        .map(|m| Occluder {
            model: m.clone(),
            pose,
        })
        .collect();
    p.splatter.set_occluders(list).unwrap();
    let occluded = p.images(model, cam, &pose);
    let (mut empty, mut kept) = (0, 0);
    for i in 0..hidden.len() {
        if band[i] || plain[4].data[i] <= 0.0 {
            continue;
        }
        if hidden[i] {
            assert_eq!(occluded[4].data[i], 0.0, "{}: pixel {i} not hidden", p.name);
            assert!(occluded[1].data[i].is_nan(), "{}: depth at {i}", p.name);
            empty += 1;
            continue;
        }
        for (k, (a, b)) in occluded.iter().zip(&plain).enumerate() {
            let c = a.channels;
            for j in i * c..(i + 1) * c {
                assert!(
                    same(a.data[j], b.data[j]),
                    "{}: {:?} at pixel {i}: {} vs {} plain",
                    p.name,
                    READ[k],
                    a.data[j],
                    b.data[j]
                );
            }
        }
        kept += 1;
    }
    (empty, kept)
}

#[test]
fn a_near_plane_hides_exactly_what_it_covers_of_a_far_one() {
    let (cam, far, near) = planes();
    for mut p in Path::all() {
        let (far_m, near_m) = (p.model(&far), p.model(&near));
        let (empty, kept) =
            hides_exactly(&mut p, &cam, &far_m, std::slice::from_ref(&near_m), true);
        eprintln!("{}: {empty} pixels hidden, {kept} kept", p.name);
        assert!(
            empty > 2000 && kept > 2000,
            "{}: {empty} hidden, {kept} kept",
            p.name
        );
        // The far plane as the near one's occluder: the near one's plain
        // render, every pixel.
        let (empty, kept) =
            hides_exactly(&mut p, &cam, &near_m, std::slice::from_ref(&far_m), false);
        assert_eq!(empty, 0, "{}: the near plane hidden by the far one", p.name);
        assert!(kept > 2000, "{}: {kept} kept", p.name);
    }
}

#[test]
fn several_occluders_of_large_splats_hide_a_plane_of_large_splats() {
    // Splats of 17-20 px radius: footprints over 32 x 32 pixels, which
    // the compute splatter lists and walks a workgroup each, the model's
    // and each of three occluders' in turn (three strips at depths 1.0,
    // 1.1 and 1.2, one above the other, over the far plane's left part).
    let (cam, _, _) = planes();
    let facing = Vec3::new(0.0, 0.0, -1.0);
    let far = shapes::plane(Vec3::new(0.0, 0.0, 1.5), facing, 0.5, 6, 1.6);
    let strips: Vec<PointModel> = (0..3)
        .map(|k| {
            let z = 1.0 + 0.1 * k as f32;
            let y = (k as f32 - 1.0) * 0.3 * z;
            shapes::plane(Vec3::new(-0.3 * z, y, z), facing, 0.15 * z, 3, 2.0)
        })
        .collect();
    for mut p in Path::all() {
        let far_m = p.model(&far);
        let occluders: Vec<Arc<GpuModel>> = strips.iter().map(|m| p.model(m)).collect();
        let (empty, kept) = hides_exactly(&mut p, &cam, &far_m, &occluders, true);
        eprintln!(
            "{}: large splats: {empty} pixels hidden, {kept} kept",
            p.name
        );
        assert!(
            empty > 1000 && kept > 1000,
            "{}: {empty} hidden, {kept} kept",
            p.name
        );
    }
}

#[test]
fn a_depth_only_render_is_empty_where_an_occluder_hides_the_model() {
    let (cam, far, near) = planes();
    let pose = identity();
    for path in Path::all() {
        let mut p = path;
        let (far_m, near_m) = (p.model(&far), p.model(&near));
        let [plain, plain_w] = p.depth(&far_m, &cam, &pose);
        let [_, cover] = p.depth(&near_m, &cam, &pose);
        let (hidden, band) = mask_and_band(&cover);
        p.splatter
            .set_occluders(vec![Occluder {
                model: near_m.clone(),
                pose,
            }])
            .unwrap();
        let [depth, weight] = p.depth(&far_m, &cam, &pose);
        let (mut empty, mut kept) = (0, 0);
        for i in 0..hidden.len() {
            // Never the occluder's depth (about 1.0): the far plane's or none.
            assert!(
                depth.data[i].is_nan() || depth.data[i] > 1.45,
                "{}: {i}",
                p.name
            );
            if band[i] || plain_w.data[i] == 0.0 {
                continue;
            }
            if hidden[i] {
                assert!(depth.data[i].is_nan(), "{}: pixel {i} not hidden", p.name);
                assert_eq!(weight.data[i], 0.0, "{}: weight at {i}", p.name);
                empty += 1;
            } else {
                assert!(
                    same(depth.data[i], plain.data[i]),
                    "{}: depth at {i}",
                    p.name
                );
                assert_eq!(weight.data[i], 1.0, "{}: weight at {i}", p.name);
                kept += 1;
            }
        }
        eprintln!("{}: depth-only: {empty} pixels hidden, {kept} kept", p.name);
        assert!(
            empty > 2000 && kept > 2000,
            "{}: {empty} hidden, {kept} kept",
            p.name
        );
    }
}

/// The CPU reference of `model` at `pose` behind `occluders`.
fn reference(
    model: &PointModel,
    cam: &Intrinsics,
    pose: &Pose,
    occluders: &[(&PointModel, Pose)],
) -> (Vec<SplatImage>, SplatImage) {
    let params = SplatParams::default();
    let view: CameraUniform = ModelBounds::of(model).view(cam, pose, &params).unwrap();
    let packed: Vec<(PackedModel, CameraUniform)> = occluders
        .iter()
        .map(|(m, p)| {
            let v = cpu::occluder_view(m, cam, p, &params, &view).unwrap();
            (pack_model(m, &params).unwrap(), v)
        })
        .collect();
    let list: Vec<(&PackedModel, CameraUniform)> = packed.iter().map(|(m, v)| (m, *v)).collect();
    let own = pack_model(model, &params).unwrap();
    let acc = cpu::splat_packed_occluded(&own, &view, &list);
    let depth = cpu::visibility_depth_occluded(&own, &view, &list);
    (READ.iter().map(|&a| acc.resolve(a)).collect(), depth)
}

#[test]
fn every_path_matches_the_cpu_reference_behind_random_occluders() {
    let mut rng = Rng::new(5150);
    let paths = Path::all();
    for trial in 0..3 {
        let n = 1500 + rng.below(2000) as usize;
        let model = shapes::random_cloud(&mut rng, Vec3::ZERO, 1.0, n, 0.01, 0.12);
        let dist = rng.uniform(3.0, 4.5);
        let (cam, pose) = random_view(&mut rng, Vector3::zeros(), dist);
        // Two occluders between the camera and the model, off its axis,
        // and one behind it.
        let toward = -pose.translation.normalize();
        let mut occluders = Vec::new();
        for k in 0..3 {
            let m = shapes::random_cloud(&mut rng, Vec3::ZERO, 0.3, 600, 0.01, 0.06);
            let along = if k == 2 { -1.5 } else { rng.uniform(0.8, 1.8) };
            let side = Vector3::new(rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), 0.0);
            let t = pose.translation + toward * along + side;
            occluders.push((m, Pose::new(pose.rotation, t).unwrap()));
        }
        let refs: Vec<(&PointModel, Pose)> = occluders.iter().map(|(m, p)| (m, *p)).collect();
        let (want, want_depth) = reference(&model, &cam, &pose, &refs);
        let (plain, _) = reference(&model, &cam, &pose, &[]);
        let hidden = plain[1].coverage().saturating_sub(want[1].coverage());
        let label = format!("trial {trial} ({n} splats)");
        assert!(hidden > 200, "{label}: only {hidden} pixels hidden");
        for path in &paths {
            let mut p = path.fresh();
            let list = occluders
                .iter()
                .map(|(m, p)| Occluder {
                    model: path.model(m),
                    pose: *p,
                })
                .collect();
            p.splatter.set_occluders(list).unwrap();
            let gm = p.model(&model);
            let got = p.images(&gm, &cam, &pose);
            let (covered, bad) = disagreement(&got, &want);
            eprintln!(
                "{label}: {}: {bad} of {covered} covered pixels disagree, {hidden} hidden",
                p.name
            );
            assert!(covered > 100, "{label}: {}: {covered} covered", p.name);
            assert!(
                bad as f64 <= 0.005 * covered as f64,
                "{label}: {}: {bad} of {covered} disagree",
                p.name
            );
            let [depth, _] = p.depth(&gm, &cam, &pose);
            let bad_depth = depth
                .data
                .iter()
                .zip(&want_depth.data)
                .filter(|(a, b)| {
                    a.is_nan() != b.is_nan() || (!a.is_nan() && (*a - *b).abs() > 1e-5 * b.abs())
                })
                .count();
            let covered_depth = want_depth.coverage().max(1);
            assert!(
                bad_depth as f64 <= 0.005 * covered_depth as f64,
                "{label}: {}: depth-only: {bad_depth} of {covered_depth} disagree",
                p.name
            );
        }
    }
}

#[test]
fn renders_without_occluders_are_unchanged_bit_for_bit() {
    let mut rng = Rng::new(31);
    let model = shapes::random_cloud(&mut rng, Vec3::ZERO, 1.0, 3000, 0.01, 0.15);
    let (cam, pose) = random_view(&mut rng, Vector3::zeros(), 3.5);
    let toward = -pose.translation.normalize();
    let blocker = shapes::random_cloud(&mut rng, Vec3::ZERO, 0.6, 600, 0.01, 0.08);
    let front = Pose::new(pose.rotation, pose.translation + toward * 1.5).unwrap();
    // Off the image, and behind the model (within its depth range, where
    // it still splats into the depth buffer, but nowhere nearer).
    let aside = Pose::new(
        pose.rotation,
        pose.translation + Vector3::new(40.0, 0.0, 0.0),
    )
    .unwrap();
    let behind = Pose::new(pose.rotation, pose.translation - toward * 1.3).unwrap();
    for path in Path::all() {
        let mut p = path;
        let gm = p.model(&model);
        let before = p.images(&gm, &cam, &pose);
        let [before_depth, _] = p.depth(&gm, &cam, &pose);
        let b = p.model(&blocker);
        let hidden_by = |at: Pose| {
            vec![Occluder {
                model: b.clone(),
                pose: at,
            }]
        };
        for (what, set) in [
            ("an occluder in front", hidden_by(front)),
            ("none again", Vec::new()),
            ("an occluder off the image", hidden_by(aside)),
            ("an occluder behind", hidden_by(behind)),
        ] {
            p.splatter.set_occluders(set).unwrap();
            let now = p.images(&gm, &cam, &pose);
            let [depth, _] = p.depth(&gm, &cam, &pose);
            let changed: usize = now.iter().zip(&before).map(|(a, b)| differing(a, b)).sum();
            let changed_depth = differing(&depth, &before_depth);
            if what == "an occluder in front" {
                // The test can tell: this one hides part of the model.
                assert!(
                    changed > 100,
                    "{}: {what}: {changed} values changed",
                    p.name
                );
                continue;
            }
            assert_eq!(changed, 0, "{}: {what}: values changed", p.name);
            assert_eq!(changed_depth, 0, "{}: {what}: depth changed", p.name);
        }
    }
}

#[test]
fn occluders_of_the_other_device_are_refused_and_sets_are_generations() {
    let (cam, far, near) = planes();
    let pose = identity();
    let mut gpu = splatter(Backend::Compute);
    let mut host = Splatter::new(&Device::Cpu).unwrap();
    let on_host = Arc::new(GpuModel::new(&Device::Cpu, &near).unwrap());
    let on_gpu = Arc::new(GpuModel::new(ctx(), &near).unwrap());
    let one = |m: &Arc<GpuModel>| {
        vec![Occluder {
            model: m.clone(),
            pose,
        }]
    };
    for (s, wrong) in [(&mut gpu, &on_host), (&mut host, &on_gpu)] {
        let err = s.set_occluders(one(wrong)).unwrap_err();
        assert!(matches!(err, SplatError::WrongDevice(_)), "{err}");
        assert!(s.occluders().is_empty());
        assert_eq!(s.occluder_generation(), 0);
    }
    // Too many.
    let many = (0..splattrack::splat::MAX_OCCLUDERS + 1)
        .map(|_| Occluder {
            model: on_gpu.clone(),
            pose,
        })
        .collect();
    assert!(gpu.set_occluders(many).is_err());

    // Targets know the set of their last render; their last view is gone
    // once the set changes, not when the same set is given again.
    let far_m = GpuModel::new(ctx(), &far).unwrap();
    let mut t = SplatTargets::new(ctx(), cam.width, cam.height);
    gpu.set_occluders(one(&on_gpu)).unwrap();
    let g1 = gpu.occluder_generation();
    assert_ne!(g1, 0);
    assert_eq!(gpu.occluders().len(), 1);
    gpu.render(ctx(), &far_m, &cam, &pose, Attributes::COLOR, &mut t)
        .unwrap();
    assert_eq!(t.occluder_generation(), Some(g1));
    assert!(t.last_view().is_some());
    gpu.set_occluders(one(&on_gpu)).unwrap();
    assert_eq!(gpu.occluder_generation(), g1);
    assert!(t.last_view().is_some());
    let moved = Pose::new(Matrix3::identity(), Vector3::new(0.0, 0.0, 0.1)).unwrap();
    gpu.set_occluders(vec![Occluder {
        model: on_gpu.clone(),
        pose: moved,
    }])
    .unwrap();
    assert_ne!(gpu.occluder_generation(), g1);
    assert!(t.last_view().is_none(), "a render behind other occluders");
    gpu.render(ctx(), &far_m, &cam, &pose, Attributes::COLOR, &mut t)
        .unwrap();
    assert_eq!(t.occluder_generation(), Some(gpu.occluder_generation()));
    assert!(t.last_view().is_some());
}
