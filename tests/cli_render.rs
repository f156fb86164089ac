//! `splattrack render` end to end: bad inputs exit non-zero with one line;
//! .npy depth and motion images have FORMATS.md's layout and agree with the
//! host geometry (analytic sphere depth; `Intrinsics::motion_predictors` at
//! the rendered depth); the real models (`SPLATTRACK_DATA`).

mod data_common;

use nalgebra::{Vector2, Vector3};
use splattrack::geometry::{Intrinsics, Pose};
use splattrack::io::npy::read_npy;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_splattrack"));
    if std::env::var_os("SPLATTRACK_ADAPTER").is_none() {
        c.env("SPLATTRACK_ADAPTER", "cpu");
    }
    c
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "splattrack-cli-render-{name}-{}",
        std::process::id()
    ));
    std::fs::create_dir_all(&d).unwrap();
    d
}

const CAMERA: &str =
    r#"{"width": 160, "height": 120, "fx": 150.0, "fy": 152.0, "cx": 79.5, "cy": 60.25}"#;

/// A unit-diameter sphere (radius 0.5 at the origin) as an ascii PLY.
fn write_scene(dir: &Path) -> (PathBuf, PathBuf) {
    let n = 6000;
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nproperty float radius\nend_header\n"
    );
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let r = 1.2 * (std::f64::consts::PI / n as f64).sqrt();
    for i in 0..n {
        let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
        let rr = (1.0 - z * z).sqrt();
        let phi = golden * i as f64;
        let (x, y) = (rr * phi.cos(), rr * phi.sin());
        s += &format!(
            "{} {} {} {x} {y} {z} {} {} 128 {r}\n",
            0.5 * x,
            0.5 * y,
            0.5 * z,
            (127.0 + 127.0 * x) as u8,
            (127.0 + 127.0 * y) as u8
        );
    }
    let model = dir.join("sphere.ply");
    std::fs::write(&model, s).unwrap();
    let camera = dir.join("camera.json");
    std::fs::write(&camera, CAMERA).unwrap();
    (model, camera)
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().unwrap()
}

fn assert_fails(out: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected failure, stderr: {err}");
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| !l.contains("XDG_RUNTIME_DIR"))
        .collect();
    assert_eq!(lines.len(), 1, "one line expected: {err}");
    assert!(err.contains(needle), "{needle:?} not in {err:?}");
}

const POSE: &str = "1,0,0,0,1,0,0,0,1,0.02,-0.03,2.0";

#[test]
fn bad_inputs_fail_with_one_line() {
    let dir = tmpdir("bad");
    let (model, camera) = write_scene(&dir);
    let (m, c) = (model.to_str().unwrap(), camera.to_str().unwrap());
    let out = dir.join("x.jpg");
    assert_fails(
        &run(&[
            "render",
            "--model",
            m,
            "--camera",
            c,
            "--pose",
            POSE,
            "--out",
            out.to_str().unwrap(),
        ]),
        "x.jpg",
    );
    let out = dir.join("x.npy");
    let o = out.to_str().unwrap();
    assert_fails(
        &run(&[
            "render", "--model", m, "--camera", c, "--pose", "1,0,0", "--out", o,
        ]),
        "12 numbers",
    );
    assert_fails(
        &run(&[
            "render",
            "--model",
            m,
            "--camera",
            c,
            "--pose",
            "1,0,0,0,1,0,0,0,1,a,0,2",
            "--out",
            o,
        ]),
        "\"a\"",
    );
    assert_fails(
        &run(&[
            "render",
            "--model",
            m,
            "--camera",
            c,
            "--pose",
            "2,0,0,0,1,0,0,0,1,0,0,2",
            "--out",
            o,
        ]),
        "rotation",
    );
    let poses = dir.join("poses.csv");
    std::fs::write(
        &poses,
        "frame,r11,r12,r13,r21,r22,r23,r31,r32,r33,tx,ty,tz\n0,1,0,0,0,1,0,0,0,1,0,0,2\n",
    )
    .unwrap();
    assert_fails(
        &run(&[
            "render",
            "--model",
            m,
            "--camera",
            c,
            "--pose-file",
            poses.to_str().unwrap(),
            "--frame",
            "7",
            "--out",
            o,
        ]),
        "frame 7",
    );
    assert_fails(
        &run(&[
            "render",
            "--model",
            m,
            "--camera",
            "/nonexistent/camera.json",
            "--pose",
            POSE,
            "--out",
            o,
        ]),
        "camera.json",
    );
}

/// Renders one attribute to .npy and reads it back: (shape, values).
fn render_npy(
    model: &Path,
    camera: &Path,
    pose: &str,
    attr: &str,
    dir: &Path,
) -> (Vec<usize>, Vec<f32>) {
    let out = dir.join(format!("{attr}.npy"));
    let o = run(&[
        "render",
        "--model",
        model.to_str().unwrap(),
        "--camera",
        camera.to_str().unwrap(),
        "--pose",
        pose,
        "--out",
        out.to_str().unwrap(),
        "--attribute",
        attr,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    read_npy(&out).unwrap()
}

/// Checks an .npy motion image against the host's predictors at the
/// rendered depth; returns the largest relative error (to the pixel's
/// largest predictor) and the number of covered pixels.
fn check_motion_against_host(cam: &Intrinsics, depth: &[f32], motion: &[f32]) -> (f64, usize) {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let (mut worst, mut covered) = (0.0f64, 0);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let z = depth[i];
            let m = &motion[12 * i..12 * i + 12];
            assert_eq!(
                z.is_nan(),
                m[0].is_nan(),
                "({x}, {y}): depth and motion disagree on coverage"
            );
            if z.is_nan() {
                assert!(m.iter().all(|v| v.is_nan()));
                continue;
            }
            covered += 1;
            let l =
                cam.motion_predictors(&cam.unproject(&Vector2::new(x as f64, y as f64), z as f64));
            let scale = l.iter().map(|v| v.abs()).fold(0.0, f64::max);
            for j in 0..6 {
                for r in 0..2 {
                    worst = worst.max((m[2 * j + r] as f64 - l[(r, j)]).abs() / scale);
                }
            }
        }
    }
    (worst, covered)
}

#[test]
fn npy_depth_and_motion_match_the_host_geometry() {
    // Tolerances: depth within 0.2% of the analytic sphere where the
    // surface faces the camera (incidence < 70 degrees); predictors within
    // 0.5% of the host's at the rendered depth at every covered pixel
    // (the splatter blends predictors of nearby surface points, so they are
    // the host's at a point whose depth is the blended depth only to first
    // order).
    let dir = tmpdir("npy");
    let (model, camera) = write_scene(&dir);
    let cam = Intrinsics::load(&camera).unwrap();
    let (shape, depth) = render_npy(&model, &camera, POSE, "depth", &dir);
    assert_eq!(shape, vec![120, 160, 1]);
    let (shape, motion) = render_npy(&model, &camera, POSE, "motion", &dir);
    assert_eq!(shape, vec![120, 160, 12]);
    let (shape, color) = render_npy(&model, &camera, POSE, "color", &dir);
    assert_eq!(shape, vec![120, 160, 3]);
    assert!(color.iter().all(|v| v.is_nan() || (0.0..=1.0).contains(v)));
    let (shape, normal) = render_npy(&model, &camera, POSE, "normal", &dir);
    assert_eq!(shape, vec![120, 160, 3]);
    for n in normal.chunks(3).filter(|n| !n[0].is_nan()) {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-4);
    }
    let (worst, covered) = check_motion_against_host(&cam, &depth, &motion);
    assert!(
        covered > 3000 && worst < 5e-3,
        "covered {covered}, worst {worst}"
    );
    let t = Vector3::new(0.02, -0.03, 2.0);
    for y in 0..120 {
        for x in 0..160 {
            let z = depth[y * 160 + x];
            if z.is_nan() {
                continue;
            }
            let d = cam.unproject(&Vector2::new(x as f64, y as f64), 1.0);
            let (a, b, c) = (d.dot(&d), -d.dot(&t), t.dot(&t) - 0.25);
            let disc = b * b - a * c;
            if disc <= 0.0 {
                continue;
            }
            let zt = (-b - disc.sqrt()) / a;
            let nrm = (d * zt - t).normalize();
            if nrm.dot(&-d.normalize()) > 20f64.to_radians().sin() {
                assert!((z as f64 - zt).abs() / zt < 2e-3, "({x}, {y}): {z} vs {zt}");
            }
        }
    }
    // Pictures of every attribute decode.
    for attr in ["color", "depth", "normal", "motion"] {
        let out = dir.join(format!("{attr}.png"));
        let o = run(&[
            "render",
            "--model",
            model.to_str().unwrap(),
            "--camera",
            camera.to_str().unwrap(),
            "--pose",
            POSE,
            "--out",
            out.to_str().unwrap(),
            "--attribute",
            attr,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        image::open(&out).unwrap();
    }
    // Behind the camera: an error, not an empty image.
    let out = dir.join("behind.npy");
    assert_fails(
        &run(&[
            "render",
            "--model",
            model.to_str().unwrap(),
            "--camera",
            camera.to_str().unwrap(),
            "--pose",
            "1,0,0,0,1,0,0,0,1,0,0,-2",
            "--out",
            out.to_str().unwrap(),
        ]),
        "behind the camera",
    );
    assert!(!out.exists());
}

fn pose_string(p: &Pose) -> String {
    let r = p.rotation;
    let t = p.translation;
    let mut v: Vec<String> = (0..3)
        .flat_map(|i| (0..3).map(move |j| r[(i, j)].to_string()))
        .collect();
    v.extend([t.x, t.y, t.z].map(|x| x.to_string()));
    v.join(",")
}

#[test]
fn real_models_render_depth_and_motion_consistent_with_the_host() {
    // At the init.csv pose of each ViSP sequence: depth within the model's
    // extent at the pose, predictors equal to the host's at the rendered
    // depth (0.5%), a plausible number of covered pixels.
    for name in ["visp_rbt_cube", "visp_rbt_dragon"] {
        let Some(seq) = data_common::real_data(name) else {
            return;
        };
        let dir = tmpdir(name);
        let cam = Intrinsics::load(&seq.join("camera.json")).unwrap();
        let pose = splattrack::io::read_poses(&seq.join("init.csv")).unwrap()[0].pose;
        let ps = pose_string(&pose);
        let model = seq.join("model.ply");
        let (_, depth) = render_npy(&model, &seq.join("camera.json"), &ps, "depth", &dir);
        let (_, motion) = render_npy(&model, &seq.join("camera.json"), &ps, "motion", &dir);
        let (worst, covered) = check_motion_against_host(&cam.undistorted(), &depth, &motion);
        eprintln!("{name}: {covered} px covered, worst predictor error {worst:.2e}");
        assert!(covered > 2000, "{name}: {covered}");
        assert!(worst < 5e-3, "{name}: {worst}");
        let zc = pose.translation.z;
        for z in depth.iter().filter(|z| !z.is_nan()) {
            assert!(
                (*z as f64 - zc).abs() < 0.3,
                "{name}: depth {z} far from the object's {zc}"
            );
        }
    }
}
