//! `splattrack init` end to end: correspondences of a synthetic sequence's
//! model points, projected with a frame's ground-truth pose (plus noise),
//! give back that pose in init.csv; a wrong point is named as an outlier;
//! bad input is refused in one line naming the file. The click path runs in
//! a real window under a display (`DISPLAY=:99`, Xvfb and xdotool), driven
//! by xdotool.

#[path = "cli_common/mod.rs"]
mod cli_common;

use cli_common::{fails, ok, s};
use nalgebra::{Vector2, Vector3};
use splattrack::geometry::{Intrinsics, Pose};
use splattrack::io::read_poses;
use splattrack::rng::Rng;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The frame whose pose is solved.
const FRAME: usize = 2;

struct Scene {
    dir: PathBuf,
    model: PathBuf,
    camera: PathBuf,
    cam: Intrinsics,
    gt: Pose,
    /// Eight well-spread model points.
    points: Vec<Vector3<f64>>,
}

fn scene() -> &'static Scene {
    static SCENE: OnceLock<Scene> = OnceLock::new();
    SCENE.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("splattrack-cli-init-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        ok(&[
            "synth",
            "--object",
            "box",
            "--trajectory",
            "fast",
            "--frames",
            "3",
            "--out",
            s(&dir),
        ]);
        let cam = Intrinsics::load(&dir.join("camera.json")).unwrap();
        let gt = read_poses(&dir.join("poses.csv")).unwrap()[FRAME].pose;
        let model = splattrack::PointModel::load(dir.join("model.ply")).unwrap();
        // Farthest-point sampling from the first point, among the points
        // facing the camera (as a user would pick visible ones).
        let all: Vec<Vector3<f64>> = model
            .positions
            .iter()
            .zip(&model.normals)
            .filter(|(p, n)| {
                let p = Vector3::new(p.x as f64, p.y as f64, p.z as f64);
                let n = Vector3::new(n.x as f64, n.y as f64, n.z as f64);
                (gt.rotation * n).dot(&gt.transform_point(&p)) < 0.0
            })
            .map(|(p, _)| Vector3::new(p.x as f64, p.y as f64, p.z as f64))
            .collect();
        let mut points = vec![all[0]];
        while points.len() < 8 {
            let far = all
                .iter()
                .max_by(|a, b| {
                    let d = |x: &Vector3<f64>| {
                        points
                            .iter()
                            .map(|q| (x - q).norm())
                            .fold(f64::INFINITY, f64::min)
                    };
                    d(a).total_cmp(&d(b))
                })
                .unwrap();
            points.push(*far);
        }
        Scene {
            model: dir.join("model.ply"),
            camera: dir.join("camera.json"),
            dir,
            cam,
            gt,
            points,
        }
    })
}

fn frame(sc: &Scene) -> PathBuf {
    sc.dir.join("frames").join(format!("{FRAME:06}.png"))
}

fn pixels(sc: &Scene, noise: f64, seed: u64) -> Vec<Vector2<f64>> {
    let mut rng = Rng::new(seed);
    sc.points
        .iter()
        .map(|p| {
            sc.cam.project(&sc.gt.transform_point(p)).unwrap()
                + Vector2::new(rng.normal(), rng.normal()) * noise
        })
        .collect()
}

fn write_corr(path: &Path, pts: &[Vector3<f64>], pix: &[Vector2<f64>]) {
    let mut t = String::from("u,v,x,y,z,name\n");
    for (i, (p, q)) in pts.iter().zip(pix).enumerate() {
        t += &format!("{},{},{},{},{},p{i}\n", q.x, q.y, p.x, p.y, p.z);
    }
    std::fs::write(path, t).unwrap();
}

fn init_args<'a>(sc: &'a Scene, frame: &'a Path, corr: &'a Path, out: &'a Path) -> Vec<&'a str> {
    vec![
        "init",
        "--model",
        s(&sc.model),
        "--camera",
        s(&sc.camera),
        "--image",
        s(frame),
        "--points",
        s(corr),
        "--out",
        s(out),
    ]
}

fn read_init(out: &Path) -> Pose {
    let rows = read_poses(out).unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].frame_index(), Some(0));
    rows[0].pose
}

/// Within `deg` degrees and `m` metres of `gt`.
fn assert_close(p: &Pose, gt: &Pose, deg: f64, m: f64) {
    let (dr, dt) = (p.rotation_error_deg(gt), p.translation_error(gt));
    eprintln!("{dr:.3} deg, {:.2} mm from the ground truth", dt * 1e3);
    assert!(dr < deg && dt < m, "{dr} deg, {dt} m");
}

#[test]
fn correspondences_give_the_ground_truth_pose() {
    let sc = scene();
    let corr = sc.dir.join("corr.csv");
    let out = sc.dir.join("init.csv.out");
    write_corr(&corr, &sc.points, &pixels(sc, 0.3, 1));
    let f = frame(sc);
    let stdout = ok(&init_args(sc, &f, &corr, &out));
    let pose = read_init(&out);
    assert_close(&pose, &sc.gt, 0.5, 0.002);
    // One line a point with its error, then the RMS; no outliers.
    for i in 0..8 {
        assert!(stdout.contains(&format!("p{i} ")), "{stdout}");
    }
    assert!(!stdout.contains("outlier"), "{stdout}");
    let rms_line = stdout.lines().find(|l| l.starts_with("RMS")).unwrap();
    let rms: f64 = rms_line.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!(rms > 0.05 && rms < 0.6, "{rms_line}");
    // The overlay: the frame's size, and the model drawn on it.
    let overlay = sc.dir.join("init.csv-overlay.png");
    let img = image::open(&overlay).unwrap().into_rgb8();
    assert_eq!(img.dimensions(), (sc.cam.width, sc.cam.height));
    let raw = image::open(&f).unwrap().into_rgb8();
    let changed = img
        .pixels()
        .zip(raw.pixels())
        .filter(|(a, b)| a != b)
        .count();
    assert!(changed > 1000, "{changed} pixels drawn");
}

#[test]
fn a_wrong_point_is_left_out_and_named() {
    let sc = scene();
    let corr = sc.dir.join("corr-outlier.csv");
    let out = sc.dir.join("init-outlier.csv");
    let mut pix = pixels(sc, 0.3, 2);
    pix[5] += Vector2::new(40.0, -25.0);
    write_corr(&corr, &sc.points, &pix);
    let f = frame(sc);
    let mut args = init_args(sc, &f, &corr, &out);
    let overlay = sc.dir.join("outlier.png");
    args.extend(["--overlay", s(&overlay)]);
    let stdout = ok(&args);
    // Seven good points left: a little less precise along the view.
    assert_close(&read_init(&out), &sc.gt, 0.5, 0.003);
    let flagged: Vec<&str> = stdout
        .lines()
        .filter(|l| l.trim_end().ends_with(" outlier"))
        .collect();
    assert_eq!(flagged.len(), 1, "{stdout}");
    assert!(flagged[0].starts_with("p5 "), "{stdout}");
    assert!(
        stdout.contains("over 7 of 8 points; left out as outliers: p5"),
        "{stdout}"
    );
    assert!(overlay.exists());
}

#[test]
fn bad_input_is_refused_in_one_line_naming_the_file() {
    let sc = scene();
    let f = frame(sc);
    let out = sc.dir.join("never.csv");
    let pix = pixels(sc, 0.0, 3);
    let run = |name: &str, text: &str, needles: &[&str]| {
        let corr = sc.dir.join(name);
        std::fs::write(&corr, text).unwrap();
        fails(&init_args(sc, &f, &corr, &out), needles);
        assert!(!out.exists(), "{name}");
    };
    run(
        "nocol.csv",
        "u,v,x,y\n1,2,3,4\n",
        &["nocol.csv", "missing column z"],
    );
    let three: String = (0..3).fold("u,v,x,y,z\n".into(), |t, i| {
        let (p, q) = (sc.points[i], pix[i]);
        t + &format!("{},{},{},{},{}\n", q.x, q.y, p.x, p.y, p.z)
    });
    run(
        "three.csv",
        &three,
        &["three.csv", "3 correspondences", "at least 4"],
    );
    let line: String = (0..6).fold("u,v,x,y,z\n".into(), |t, i| {
        let p = sc.points[0] * (i as f64 * 0.2);
        let q = sc.cam.project(&sc.gt.transform_point(&p)).unwrap();
        t + &format!("{},{},{},{},{}\n", q.x, q.y, p.x, p.y, p.z)
    });
    run("line.csv", &line, &["line.csv", "collinear model points"]);
    // Pixels swapped between points: no pose fits them.
    let mut swapped = pix.clone();
    swapped.swap(0, 3);
    swapped.swap(1, 4);
    let corr = sc.dir.join("swapped.csv");
    write_corr(&corr, &sc.points[..5], &swapped[..5]);
    fails(
        &init_args(sc, &f, &corr, &out),
        &["swapped.csv", "more than --max-rms"],
    );
    assert!(!out.exists());
    let missing = sc.dir.join("missing.csv");
    fails(
        &init_args(sc, &f, &missing, &out),
        &["missing.csv", "cannot read"],
    );
    // A frame that is not the camera's size.
    let small = sc.dir.join("small.png");
    image::RgbImage::new(32, 24).save(&small).unwrap();
    let corr = sc.dir.join("good.csv");
    write_corr(&corr, &sc.points, &pix);
    fails(
        &init_args(sc, &small, &corr, &out),
        &["small.png", "32 x 24"],
    );
    // --click needs a display (none here: DISPLAY and WAYLAND_DISPLAY unset).
    let pts = sc.dir.join("pts-nodisplay.csv");
    std::fs::write(
        &pts,
        "name,x,y,z\na,0,0,0\nb,0.01,0,0\nc,0,0.01,0\nd,0,0,0.01\n",
    )
    .unwrap();
    let (model, cam) = (sc.model.clone(), sc.camera.clone());
    cli_common::fails_env(
        &[
            "init",
            "--model",
            s(&model),
            "--camera",
            s(&cam),
            "--image",
            s(&f),
            "--click",
            "--model-points",
            s(&pts),
            "--out",
            s(&out),
        ],
        &[
            ("DISPLAY", ""),
            ("WAYLAND_DISPLAY", ""),
            ("WAYLAND_SOCKET", ""),
        ],
        &["--click needs a display", "--points"],
    );
    assert!(!out.exists());
    // --click needs its named points.
    let model = sc.dir.join("model.ply");
    let cam = sc.dir.join("camera.json");
    fails(
        &[
            "init",
            "--model",
            s(&model),
            "--camera",
            s(&cam),
            "--image",
            s(&f),
            "--click",
            "--out",
            s(&out),
        ],
        &["--model-points"],
    );
}

/// The click path in a real window: xdotool clicks each named point where
/// the ground truth puts it, then presses Enter. Needs a display
/// (`Xvfb :99 & DISPLAY=:99 cargo test --release --test cli_init -- --ignored`)
/// and the xdotool program; fails (never skips) without them.
#[test]
#[ignore = "needs a display (Xvfb will do) and xdotool"]
fn clicking_the_points_in_the_window_gives_the_pose() {
    use std::process::{Command, Stdio};
    use std::time::{Duration, Instant};
    let sc = scene();
    let f = frame(sc);
    let pts = sc.dir.join("pts.csv");
    let mut t = String::from("name,x,y,z\n");
    for (i, p) in sc.points.iter().enumerate() {
        t += &format!("corner {i},{},{},{}\n", p.x, p.y, p.z);
    }
    std::fs::write(&pts, t).unwrap();
    let out = sc.dir.join("clicked.csv");
    let mut child = Command::new(env!("CARGO_BIN_EXE_splattrack"))
        .env(
            "SPLATTRACK_ADAPTER",
            std::env::var("SPLATTRACK_ADAPTER").unwrap_or("cpu".into()),
        )
        .args([
            "init",
            "--model",
            s(&sc.dir.join("model.ply")),
            "--camera",
            s(&sc.dir.join("camera.json")),
            "--image",
            s(&f),
            "--click",
            "--model-points",
            s(&pts),
            "--out",
            s(&out),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let xdo = |args: &[&str]| {
        let o = Command::new("xdotool")
            .args(args)
            .output()
            .expect("the xdotool program");
        String::from_utf8_lossy(&o.stdout).trim().to_owned()
    };
    let start = Instant::now();
    let window = loop {
        let w = xdo(&["search", "--name", "splattrack init"]);
        if !w.is_empty() {
            break w.lines().next().unwrap().to_owned();
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no window; stderr: {:?}",
            child.try_wait()
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    // Let the window take the picture's size and draw it.
    std::thread::sleep(Duration::from_secs(3));
    let band = splattrack::view::Layout::for_width(sc.cam.width).band as f64;
    let _ = xdo(&["windowfocus", "--sync", &window]);
    for q in pixels(sc, 0.0, 4) {
        let (x, y) = (q.x.round(), (q.y + band).round());
        xdo(&[
            "mousemove",
            "--window",
            &window,
            &format!("{x}"),
            &format!("{y}"),
            "click",
            "1",
        ]);
        std::thread::sleep(Duration::from_millis(300));
    }
    // The review is solved and drawn; accept it.
    std::thread::sleep(Duration::from_secs(3));
    xdo(&["key", "--window", &window, "Return"]);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            panic!("init --click did not finish");
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let o = child.wait_with_output().unwrap();
    assert!(status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Whole-pixel clicks: within a degree and a few millimetres.
    assert_close(&read_init(&out), &sc.gt, 1.0, 0.005);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("over 8 of 8 points"), "{stdout}");
}
