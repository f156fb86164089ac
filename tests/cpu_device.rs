//! The CPU device (`Device::Cpu`: the host's cores, no GPU object) against
//! lavapipe (the GPU paths): the splatter's reads and gathers, keyframe
//! stores, and the tracker on the real cube, a synthetic textured sequence
//! and an untextured one held by its contour give the same statuses and
//! poses within the tolerances measured here (the host's sums in another
//! order than the GPU's: f32 rounding, which the robust solves carry on).

mod tracking_common;

use splattrack::Device;
use splattrack::geometry::{Intrinsics, Pose};
use splattrack::gpu::shared_test_context;
use splattrack::keyframes::{KeyframeConfig, KeyframeStore};
use splattrack::model::PointModel;
use splattrack::splat::{Attribute, Attributes, GatherMode, GpuModel, SplatTargets, Splatter};
use splattrack::tracker::{Modalities, Status, TrackResult, Tracker, TrackerConfig};
use tracking_common::{Fig10, RealSequence, Scene, camera_320};

/// Both devices: the CPU device and lavapipe.
fn devices() -> [Device; 2] {
    [Device::Cpu, Device::from(shared_test_context())]
}

/// The largest rotation (degrees) and translation (model units) between
/// two runs' poses, asserting the same statuses frame by frame.
fn compare(a: &[TrackResult], b: &[TrackResult]) -> (f64, f64) {
    assert_eq!(a.len(), b.len());
    let (mut rot, mut trans) = (0.0f64, 0.0f64);
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert_eq!(
            x.status, y.status,
            "frame {i}: {:?} / {:?}",
            x.reason, y.reason
        );
        rot = rot.max(x.pose.rotation_error_deg(&y.pose));
        trans = trans.max(x.pose.translation_error(&y.pose));
    }
    (rot, trans)
}

/// Tracks `frames` on `device` from `init`.
fn track(
    device: &Device,
    model: &PointModel,
    cam: Intrinsics,
    store: Option<KeyframeStore>,
    config: TrackerConfig,
    init: Pose,
    frames: impl Iterator<Item = image::RgbImage>,
) -> Vec<TrackResult> {
    let mut t = Tracker::builder(device, model.clone(), cam)
        .maybe_keyframes(store)
        .config(config)
        .initial_pose(init)
        .build()
        .expect("tracker");
    assert_eq!(t.context().is_none(), device.is_cpu());
    frames.map(|f| t.track(&f).expect("track")).collect()
}

/// The splatter on the CPU device reads and gathers what lavapipe's does:
/// colour and normals within 2e-3 (measured 6e-6 and 3e-6), coverage
/// within 0.2% of the pixels
/// (measured: every pixel the same), predictors and depth at the gathered
/// points within 1e-3 relative; the CPU device's splatter refuses GPU
/// targets.
#[test]
fn the_host_splatter_reads_and_gathers_what_the_gpu_does() {
    let scene = Scene::new("blob", camera_320(), 20_000);
    let pose = splattrack::geometry::look_at(
        &nalgebra::Vector3::new(0.3, -0.2, -0.45),
        &nalgebra::Vector3::zeros(),
        &nalgebra::Vector3::new(0.0, -1.0, 0.0),
    );
    let mut out = Vec::new();
    for device in devices() {
        let splatter = Splatter::new(&device).unwrap();
        let model = GpuModel::new(&device, &scene.model).unwrap();
        let mut targets = SplatTargets::new(&device, 320, 240);
        splatter
            .render(
                &device,
                &model,
                &scene.cam,
                &pose,
                Attributes::ALL,
                &mut targets,
            )
            .unwrap();
        let color = splatter.read(&device, &targets, Attribute::Color).unwrap();
        let normal = splatter.read(&device, &targets, Attribute::Normal).unwrap();
        let pts: Vec<[f32; 2]> = (0..200)
            .map(|i| [100.0 + (i % 20) as f32 * 6.3, 70.0 + (i / 20) as f32 * 9.7])
            .collect();
        let samples = splatter
            .gather(&device, &targets, &pts, GatherMode::Bilinear)
            .unwrap();
        out.push((color, samples, normal));
    }
    let cpu_splatter = Splatter::new(&Device::Cpu).unwrap();
    let gpu_targets = SplatTargets::new(shared_test_context(), 8, 8);
    assert!(
        cpu_splatter
            .read(&Device::Cpu, &gpu_targets, Attribute::Color)
            .is_err()
    );
    let ((ca, sa, na), (cb, sb, nb)) = (&out[0], &out[1]);
    let n = ca.data.len() / 3;
    let coverage_diff = (0..n)
        .filter(|&i| ca.data[3 * i].is_nan() != cb.data[3 * i].is_nan())
        .count();
    let colour_diff = ca
        .data
        .iter()
        .zip(&cb.data)
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    // The normals (the check's shading fit reads them back from either
    // device) as closely as the colour.
    let normal_diff = na
        .data
        .iter()
        .zip(&nb.data)
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    eprintln!(
        "coverage differs at {coverage_diff} of {n} pixels, colour by {colour_diff}, normals by {normal_diff}"
    );
    assert!(coverage_diff * 500 <= n, "{coverage_diff} of {n} pixels");
    assert!(colour_diff < 2e-3, "colour differs by {colour_diff}");
    assert!(normal_diff < 2e-3, "normals differ by {normal_diff}");
    let mut valid = 0;
    for (a, b) in sa.iter().zip(sb) {
        if !(a.valid && b.valid) {
            continue;
        }
        valid += 1;
        let rel = |x: f32, y: f32| (x - y).abs() / y.abs().max(1.0);
        assert!(rel(a.depth, b.depth) < 1e-3, "{} / {}", a.depth, b.depth);
        for (x, y) in a.motion.iter().zip(&b.motion) {
            assert!(rel(*x, *y) < 1e-3, "{x} / {y}");
        }
    }
    assert!(valid > 100, "{valid} points gathered on both");
}

/// The real cube's first 20 frames, default settings, keyframe stores
/// built on each device: the same statuses (all tracking), poses within
/// 0.05 degrees and 0.2 mm (measured 0.0004 degrees, 2 um).
#[test]
fn the_real_cube_tracks_the_same_on_the_cpu_device() {
    let Some(real) = RealSequence::load("visp_rbt_cube") else {
        return;
    };
    let runs: Vec<Vec<TrackResult>> = devices()
        .iter()
        .map(|device| {
            let splatter = Splatter::new(device).unwrap();
            let store = KeyframeStore::build_from_dir(
                device,
                &splatter,
                &real.model,
                &real.seq.camera,
                &real.dir.join("keyframes"),
                &KeyframeConfig::default(),
            )
            .expect("keyframe store");
            track(
                device,
                &real.model,
                real.seq.tracking_camera(),
                Some(store),
                TrackerConfig::default(),
                real.gt[0].pose,
                (0..20).map(|i| real.image(i)),
            )
        })
        .collect();
    let (rot, trans) = compare(&runs[0], &runs[1]);
    eprintln!(
        "cube: CPU device against lavapipe: {rot:.5} deg, {:.4} mm",
        trans * 1e3
    );
    assert!(runs[0].iter().all(|r| r.status == Status::Tracking));
    assert!(rot < 0.05 && trans < 2e-4, "{rot} deg, {trans} m");
}

/// The synthetic blob (textured) on the Fig. 10 trajectory, KF+IT, the
/// keyframe stores built on each device: the same statuses and poses
/// within 0.05 degrees and 0.5 mm (measured 0.0005 degrees, 1 um); the
/// CPU device's within 1 degree of the rasteriser's ground truth
/// (measured 0.24).
#[test]
fn a_synthetic_textured_sequence_tracks_the_same_on_the_cpu_device() {
    let fig = Fig10::blob(0..10);
    let images = fig.scene.keyframe_images(0.55);
    let runs: Vec<Vec<TrackResult>> = devices()
        .iter()
        .map(|device| {
            let splatter = Splatter::new(device).unwrap();
            let store = KeyframeStore::build(
                device,
                &splatter,
                &fig.scene.model,
                &fig.scene.cam,
                &images,
                &KeyframeConfig::default(),
            )
            .unwrap();
            track(
                device,
                &fig.scene.model,
                fig.scene.cam,
                Some(store),
                TrackerConfig::default(),
                fig.frames[0].pose,
                fig.frames.iter().map(|f| f.image.clone()),
            )
        })
        .collect();
    let (rot, trans) = compare(&runs[0], &runs[1]);
    let worst_gt = runs[0]
        .iter()
        .zip(&fig.frames)
        .map(|(r, f)| r.pose.rotation_error_deg(&f.pose))
        .fold(0.0f64, f64::max);
    eprintln!(
        "blob: CPU device against lavapipe: {rot:.5} deg, {trans:.6}; against the truth {worst_gt:.3} deg"
    );
    assert!(runs[0].iter().all(|r| r.status == Status::Tracking));
    assert!(rot < 0.05 && trans < 5e-4, "{rot} deg, {trans}");
    assert!(worst_gt < 1.0, "{worst_gt} deg from the truth");
}

/// The untextured `plain` on the Fig. 10 trajectory at 320x240: the
/// camera, a 30k-point model and the first `n` frames.
fn plain_scene(n: usize) -> (Intrinsics, PointModel, Vec<splattrack::synth::SynthFrame>) {
    use splattrack::synth::{SynthConfig, SynthObject, Trajectory, background, render_frame};
    let camera = camera_320();
    let cfg = SynthConfig {
        object: "plain".into(),
        trajectory: Trajectory::Fig10,
        frames: 60,
        camera,
        ..Default::default()
    };
    let object = SynthObject::by_name(&cfg.object).unwrap();
    let model = splattrack::synth::sequence::sample_model(&object, 30_000, cfg.seed).unwrap();
    let bg = background(&camera, cfg.seed);
    let frames = (0..n)
        .map(|i| render_frame(&cfg, &object, &bg, i))
        .collect();
    (camera, model, frames)
}

/// The untextured object held by its contour alone (no keyframes): the
/// same statuses, poses within 2 degrees and 2 mm (0.4% of the distance),
/// and both devices within 3 degrees of the ground truth. The contour's
/// discrete choices (which points are inliers) carry the renders'
/// last-bit differences (the depth within 1.2e-7,
/// [`depth_only_renders_agree`]) further than the texture steps do, and
/// the CPU device's check scores the contour's last render where lavapipe
/// renders again
/// ([`the_contours_view_stands_for_the_checks_render_on_the_cpu_device`]):
/// measured 1.00 degrees and 1.4 mm apart after 8 frames, both within
/// 1.36 degrees of the truth. Both fit the shading in every check after
/// the first (the view of the model's plain colours shows no texture).
#[test]
fn an_untextured_sequence_tracks_the_same_by_its_contour_on_the_cpu_device() {
    let (camera, model, frames) = plain_scene(8);
    let config = TrackerConfig {
        modalities: Modalities::CONTOUR,
        ..Default::default()
    };
    let runs: Vec<Vec<TrackResult>> = devices()
        .iter()
        .map(|device| {
            track(
                device,
                &model,
                camera,
                None,
                config.clone(),
                frames[0].pose,
                frames.iter().map(|f| f.image.clone()),
            )
        })
        .collect();
    let (rot, trans) = compare(&runs[0], &runs[1]);
    let worst_gt = runs
        .iter()
        .flat_map(|run| run.iter().zip(&frames))
        .map(|(r, f)| r.pose.rotation_error_deg(&f.pose))
        .fold(0.0f64, f64::max);
    eprintln!(
        "plain, contour: CPU device against lavapipe: {rot:.5} deg, {trans:.6}; against the truth {worst_gt:.3} deg"
    );
    assert!(runs[0].iter().all(|r| r.status == Status::Tracking));
    assert!(rot < 2.0 && trans < 2e-3, "{rot} deg, {trans}");
    assert!(worst_gt < 3.0, "{worst_gt} deg from the truth");
    // The view untextured, each check after the first fits the shading on
    // both devices (on lavapipe from the coverage and normals read back),
    // to within the poses' difference: measured 15% apart at most.
    for (i, (a, b)) in runs[0].iter().zip(&runs[1]).enumerate().skip(1) {
        let rms = |r: &TrackResult| r.verify.and_then(|v| v.shading_rms);
        let (Some(a), Some(b)) = (rms(a), rms(b)) else {
            panic!("frame {i}: no shading fit on one device");
        };
        assert!((a - b).abs() <= 0.25 * a.max(b), "frame {i}: {a} / {b}");
    }
}

/// A depth-only render of the untextured object (the contour's) on the
/// CPU device and on lavapipe: the same coverage (measured: every pixel)
/// and the depth within 1e-6 (measured 1.2e-7, one f32 step at 0.55).
#[test]
fn depth_only_renders_agree() {
    let (camera, model, frames) = plain_scene(1);
    let pose = frames[0].pose;
    let mut out = Vec::new();
    for device in devices() {
        let splatter = Splatter::new(&device).unwrap();
        let gm = GpuModel::new(&device, &model).unwrap();
        let mut targets = SplatTargets::new(&device, 320, 240);
        splatter
            .render_depth(&device, &gm, &camera, &pose, &mut targets, None)
            .unwrap();
        out.push(splatter.read(&device, &targets, Attribute::Depth).unwrap());
    }
    let (a, b) = (&out[0], &out[1]);
    let cov = a
        .data
        .iter()
        .zip(&b.data)
        .filter(|(x, y)| x.is_nan() != y.is_nan())
        .count();
    let dz = a
        .data
        .iter()
        .zip(&b.data)
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max);
    eprintln!(
        "depth only: coverage differs at {cov} pixels of {}, depth by {dz}",
        a.coverage()
    );
    assert!(cov <= a.coverage() / 500, "{cov}");
    assert!(dz < 1e-6, "{dz}");
}

/// Without a first pose the tracker searches each frame (templates, the
/// features' detection): the real cube's first 3 frames found on the CPU
/// device as on lavapipe, the same statuses and poses within 0.05 degrees
/// and 0.2 mm (measured: all 3 found, 0.00005 degrees apart).
#[test]
fn a_search_without_a_first_pose_finds_the_cube_on_the_cpu_device() {
    let Some(real) = RealSequence::load("visp_rbt_cube") else {
        return;
    };
    let runs: Vec<Vec<TrackResult>> = devices()
        .iter()
        .map(|device| {
            let mut t = Tracker::builder(device, real.model.clone(), real.seq.tracking_camera())
                .keyframes(real.store.clone())
                .build()
                .expect("tracker");
            (0..3).map(|i| t.track(&real.image(i)).unwrap()).collect()
        })
        .collect();
    let (rot, trans) = compare(&runs[0], &runs[1]);
    let found = runs[0]
        .iter()
        .filter(|r| r.status == Status::Tracking)
        .count();
    eprintln!("search: {found} of 3 found; CPU device against lavapipe: {rot:.5} deg, {trans:.6}");
    assert!(found >= 2, "{found} of 3 frames found");
    assert!(rot < 0.05 && trans < 2e-4, "{rot} deg, {trans}");
}

/// On the CPU device the contour alone renders its views as the check's
/// (textured by the keyframe the check takes, their visibility depth
/// kept: the contour reads what a depth-only render gives), and the check
/// scores the last one where the rounds after it converged and moved its
/// points within `contour.reproject_px`, while the views show no texture
/// of their own: about one render a frame instead of two on the
/// untextured object (with its keyframes' shading), and none saved on the
/// textured blob, whose ZNCC a pixel's offset changes (measured: 0.68
/// against 0.82 fresh at one frame). The untextured object's scores
/// against a fresh render at the reported pose (`novel_view`, scored by
/// `verify::score` over the whole frame): ZNCC within 0.05 and edge
/// support within 0.1, the view lying up to a pixel off along the outline
/// where the edge test searches 2 px (measured: at most 0.031 and 0.017
/// apart).
#[test]
fn the_contours_view_stands_for_the_checks_render_on_the_cpu_device() {
    use splattrack::features::GreyImage;
    use splattrack::synth::{SynthConfig, Trajectory, render_frame};
    use splattrack::tracker::verify::score;
    let config = TrackerConfig {
        modalities: Modalities::CONTOUR,
        ..Default::default()
    };
    let cam = camera_320();
    let run = |object: &str, frames: std::ops::Range<usize>| {
        let scene = Scene::new(object, cam, 30_000);
        let cfg = SynthConfig {
            object: object.into(),
            camera: cam,
            frames: 100,
            trajectory: Trajectory::Fig10,
            ..Default::default()
        };
        let store = scene.keyframe_store(cfg.distance);
        let frames: Vec<_> = frames
            .map(|i| render_frame(&cfg, &scene.object, &scene.bg, i))
            .collect();
        let results = track(
            &Device::Cpu,
            &scene.model,
            cam,
            Some(store.clone()),
            config.clone(),
            frames[0].pose,
            frames.iter().map(|fr| fr.image.clone()),
        );
        assert!(
            results.iter().all(|r| r.status == Status::Tracking),
            "{object}"
        );
        // Frames whose check scored the contour's view.
        let served = results
            .iter()
            .filter(|r| r.times.renders <= r.times.contour_renders)
            .count();
        let renders: f64 = results.iter().map(|r| r.times.renders).sum();
        eprintln!(
            "{object}: {renders} renders in {} frames, the check's view served in {served}",
            results.len()
        );
        (scene, store, frames, results, served)
    };
    let (_, _, _, results, served) = run("blob", 50..56);
    assert_eq!(served, 0, "blob: {served} of {}", results.len());
    let (scene, store, frames, results, served) = run("plain", 0..10);
    let n = results.len();
    let renders: f64 = results.iter().map(|r| r.times.renders).sum();
    assert!(
        renders <= 1.5 * n as f64,
        "plain: {renders} renders in {n} frames"
    );
    assert!(2 * served >= n, "plain: served in {served} of {n} frames");
    let mut fresh = Tracker::builder(Device::Cpu, scene.model.clone(), cam)
        .keyframes(store)
        .config(config.clone())
        .initial_pose(frames[0].pose)
        .build()
        .expect("tracker");
    for (i, (r, frame)) in results.iter().zip(&frames).enumerate() {
        let s = r.verify.expect("a tracked frame's scores");
        let v = fresh.novel_view(&r.pose).expect("novel view");
        let rgb = image::RgbImage::from_raw(v.width, v.height, v.color).expect("view size");
        let view = GreyImage::from_rgb8(&rgb);
        let again = score(
            &GreyImage::from_rgb8(&frame.image),
            &v.mask,
            Some(&view.data),
            s.visible,
            1,
            &config.verify,
        );
        let (z, z0) = (s.zncc.expect("zncc"), again.zncc.expect("zncc"));
        let (e, e0) = (
            s.edge_support.expect("edges"),
            again.edge_support.expect("edges"),
        );
        eprintln!("frame {i}: ZNCC {z:.4} (fresh {z0:.4}), edges {e:.3} (fresh {e0:.3})");
        assert!((z - z0).abs() <= 0.05, "frame {i}: ZNCC {z} against {z0}");
        assert!((e - e0).abs() <= 0.1, "frame {i}: edges {e} against {e0}");
    }
}
