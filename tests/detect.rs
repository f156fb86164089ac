//! The search's detection by features in clutter: a textured object over
//! coloured noise and thin coloured lines is found (near a keyframe's
//! view, and turned in the image plane), and a frame of clutter alone,
//! with another textured object in it, is not. Frames rendered by the
//! synth CPU triangle rasteriser (never the splatter under test).

mod tracking_common;

use nalgebra::{Matrix3, Vector3};
use splattrack::geometry::{Intrinsics, Pose, rotation_exp};
use splattrack::gpu::shared_test_context;
use splattrack::rng::Rng;
use splattrack::synth::raster;
use splattrack::synth::{Light, SynthObject, to_image};
use splattrack::tracker::{LostReason, Status, Tracker, TrackerConfig};
use std::time::Instant;
use tracking_common::Scene;

/// Coloured noise (each pixel its own colour) crossed by thin line
/// segments of random colours, lengths and directions.
fn clutter(cam: &Intrinsics, seed: u64) -> Vec<[f32; 3]> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut rng = Rng::new(seed);
    let mut img: Vec<[f32; 3]> = (0..w * h)
        .map(|_| std::array::from_fn(|_| rng.uniform(0.1, 0.9) as f32))
        .collect();
    for _ in 0..120 {
        let c: [f32; 3] = std::array::from_fn(|_| rng.uniform(0.0, 1.0) as f32);
        let (x0, y0) = (rng.uniform(0.0, w as f64), rng.uniform(0.0, h as f64));
        let a = rng.uniform(0.0, std::f64::consts::TAU);
        let len = rng.uniform(0.05, 0.5) * w as f64;
        let thick = rng.uniform(0.5, 1.5);
        let steps = (len * 2.0) as usize;
        for s in 0..steps {
            let d = s as f64 / 2.0;
            let (cx, cy) = (x0 + d * a.cos(), y0 + d * a.sin());
            let r = thick.ceil() as isize;
            for dy in -r..=r {
                for dx in -r..=r {
                    let (x, y) = (cx as isize + dx, cy as isize + dy);
                    let off = ((x as f64 - cx) * a.sin() - (y as f64 - cy) * a.cos()).abs();
                    if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h && off <= thick {
                        img[y as usize * w + x as usize] = c;
                    }
                }
            }
        }
    }
    img
}

/// `scene`'s object at `pose` over `bg`, as an 8-bit frame.
fn frame(object: &SynthObject, cam: &Intrinsics, pose: &Pose, bg: &[[f32; 3]]) -> image::RgbImage {
    let r = raster::render(object, pose, cam, &Light::moving(0.1), bg, 3);
    to_image(&r.rgb, cam, 0.01, &mut Rng::new(9))
}

/// `pose` turned by `angle` degrees about the line of sight through the
/// object's centre `c`.
fn rolled(pose: &Pose, c: &Vector3<f64>, angle: f64) -> Pose {
    let centre = pose.transform_point(c);
    let ray = centre.normalize();
    let r = rotation_exp(&(ray * angle.to_radians()));
    Pose::new(r * pose.rotation, r * (pose.translation - centre) + centre).unwrap()
}

#[test]
fn a_textured_object_is_found_in_clutter_and_clutter_alone_is_not() {
    let ctx = shared_test_context();
    let cam = Intrinsics::new(640, 480, 600.0, 600.0, 319.5, 239.5);
    let scene = Scene::new("blob", cam, 60_000);
    let store = scene.keyframe_store(0.55);
    let bg = clutter(&cam, 17);
    let c = splattrack::splat::ModelBounds::of(&scene.model).center;
    let kf = store.keyframes[1].pose;
    // Near a keyframe's view (1 degree off, moved in the image), and that
    // view turned 40 degrees in the image plane.
    let near = rotation_exp(&Vector3::new(0.012, -0.01, 0.0)) * kf.rotation;
    let near = Pose::new(near, kf.translation + Vector3::new(0.04, -0.03, 0.03)).unwrap();
    let cases = [
        ("near a keyframe", near),
        ("turned 40 deg", rolled(&kf, &c, 40.0)),
    ];
    for (what, pose) in cases {
        let img = frame(&scene.object, &cam, &pose, &bg);
        let mut t = Tracker::builder(ctx, scene.model.clone(), cam)
            .keyframes(store.clone())
            .config(TrackerConfig::default())
            .build()
            .unwrap();
        let t0 = Instant::now();
        let r = t.track(&img).unwrap();
        let rot = r.pose.rotation_error_deg(&pose);
        let tr = r.pose.translation_error(&pose);
        eprintln!(
            "{what}: {} {rot:.2} deg {:.1} mm in {:.2} s",
            r.status,
            tr * 1e3,
            t0.elapsed().as_secs_f64()
        );
        assert_eq!(r.status, Status::Tracking, "{what}: {:?}", r.reason);
        assert!(rot < 2.0 && tr < 0.01, "{what}: {rot:.2} deg, {tr:.4} m");
    }
    // Clutter with another textured object in it (the box) and no blob.
    let other = SynthObject::by_name("box").unwrap();
    let elsewhere = Pose::new(Matrix3::identity(), Vector3::new(0.05, 0.0, 0.6)).unwrap();
    let img = frame(&other, &cam, &elsewhere, &bg);
    let mut t = Tracker::builder(ctx, scene.model.clone(), cam)
        .keyframes(store)
        .config(TrackerConfig::default())
        .build()
        .unwrap();
    for _ in 0..2 {
        let r = t.track(&img).unwrap();
        assert_eq!(
            (r.status, r.reason),
            (Status::Lost, Some(LostReason::NotFound))
        );
    }
}

/// CPU seconds this process has used (user + system, from /proc; 0 where
/// that cannot be read).
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the command's closing parenthesis: utime is the 12th
    // and stime the 13th of them, in clock ticks (100 a second on Linux).
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<f64> = rest
        .split_whitespace()
        .map(|v| v.parse().unwrap_or(0.0))
        .collect();
    (f.get(11).copied().unwrap_or(0.0) + f.get(12).copied().unwrap_or(0.0)) / 100.0
}

#[test]
#[ignore = "a timing (seconds on lavapipe): the search on every tenth frame of the real cube"]
fn search_time_on_the_real_cube() {
    let Some(real) = tracking_common::RealSequence::load("visp_rbt_cube") else {
        return;
    };
    let mut t = Tracker::builder(shared_test_context(), real.model.clone(), real.seq.camera)
        .keyframes(real.store.clone())
        .config(TrackerConfig::default())
        .build()
        .unwrap();
    let (mut wall, mut cpu) = (Vec::new(), Vec::new());
    for i in (0..real.seq.frames.len()).step_by(10) {
        let img = real.image(i);
        let (t0, c0) = (Instant::now(), cpu_seconds());
        let found = t.find(&img).unwrap();
        wall.push(t0.elapsed().as_secs_f64());
        cpu.push(cpu_seconds() - c0);
        let err = found.map(|p| p.rotation_error_deg(&real.gt[i].pose));
        eprintln!(
            "frame {i}: {:.2} s ({:.2} s CPU), {err:?} deg",
            wall[wall.len() - 1],
            cpu[cpu.len() - 1]
        );
    }
    for v in [&mut wall, &mut cpu] {
        v.sort_by(f64::total_cmp);
    }
    eprintln!(
        "SEARCH real cube: median {:.2} s ({:.2} s CPU), max {:.2} s",
        wall[wall.len() / 2],
        cpu[cpu.len() / 2],
        wall[wall.len() - 1]
    );
}

#[test]
#[ignore = "minutes on lavapipe: starts from every tenth frame over clutter"]
fn every_tenth_frame_over_clutter() {
    use splattrack::synth::{Trajectory, trajectory_pose};
    let ctx = shared_test_context();
    let cam = Intrinsics::new(640, 480, 600.0, 600.0, 319.5, 239.5);
    for object in ["blob", "box", "torus"] {
        let scene = Scene::new(object, cam, 60_000);
        let store = scene.keyframe_store(0.55);
        let bg = clutter(&cam, 23);
        let (mut found, mut wrong, mut secs) = (0, 0, Vec::new());
        for start in (0..100).step_by(10) {
            let mut t = Tracker::builder(ctx, scene.model.clone(), cam)
                .keyframes(store.clone())
                .config(TrackerConfig::default())
                .build()
                .unwrap();
            let mut ok = false;
            for i in start..start + 3 {
                let gt = trajectory_pose(Trajectory::Fig10, 0.55, i, 100);
                let img = frame(&scene.object, &cam, &gt, &bg);
                let t0 = Instant::now();
                let r = t.track(&img).unwrap();
                if i == start {
                    secs.push(t0.elapsed().as_secs_f64());
                }
                let rot = r.pose.rotation_error_deg(&gt);
                let tr = r.pose.translation_error(&gt);
                if r.status == Status::Tracking {
                    ok |= rot <= 5.0 && tr <= 0.05;
                    if rot > 10.0 {
                        wrong += 1;
                    }
                }
            }
            found += usize::from(ok);
        }
        secs.sort_by(f64::total_cmp);
        eprintln!(
            "CLUTTER {object}: {found}/10 found by the third frame, {wrong} tracking frames > 10 deg off, \
             first frame {:.2} s median",
            secs[secs.len() / 2]
        );
    }
}
