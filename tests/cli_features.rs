//! `splattrack features` end to end: corners and matches on synthetic
//! pictures written as PNG, and one-line errors on bad input.

use splattrack::features::patterns::{self, Warp};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("cli_features_{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_splattrack"))
        .args(args)
        .env("SPLATTRACK_ADAPTER", "cpu")
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap()
}

fn write_png(img: &splattrack::features::GreyImage, path: &Path) {
    img.to_luma8().save(path).unwrap();
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn csv_rows(path: &Path) -> (String, Vec<Vec<f32>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_owned();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (header, rows)
}

#[test]
fn corners_of_one_image() {
    let d = dir("corners");
    let (img, truth) = patterns::checkerboard(160, 120, [30.4, 20.7], 15.0, 0.2, 6, 5);
    let a = d.join("a.png");
    write_png(&img, &a);
    let (out, csv) = (d.join("viz.png"), d.join("c.csv"));
    let o = run(&[
        "features",
        "--image",
        s(&a),
        "--out",
        s(&out),
        "--csv",
        s(&csv),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (header, rows) = csv_rows(&csv);
    assert_eq!(header, "x,y,score");
    // Every X-junction found (8-bit quantisation: within 1 px).
    for t in &truth {
        assert!(
            rows.iter().any(|r| (r[0] - t[0]).hypot(r[1] - t[1]) < 1.0),
            "{t:?} missing"
        );
    }
    let viz = image::open(&out).unwrap();
    assert_eq!((viz.width(), viz.height()), (160, 120));
    // --max bounds the count.
    let o = run(&[
        "features",
        "--image",
        s(&a),
        "--max",
        "5",
        "--out",
        s(&out),
        "--csv",
        s(&csv),
    ]);
    assert!(o.status.success());
    assert_eq!(csv_rows(&csv).1.len(), 5);
}

#[test]
fn matches_of_two_images_recover_the_shift() {
    let d = dir("matches");
    let a = patterns::smooth_noise(200, 150, 2.0, 3);
    let warp = Warp {
        shift: [4.0, -3.0],
        angle: 0.0,
        centre: [100.0, 75.0],
        gain: 1.0,
        bias: 0.0,
    };
    let b = warp.image(&a);
    let (pa, pb) = (d.join("a.png"), d.join("b.png"));
    write_png(&a, &pa);
    write_png(&b, &pb);
    let (out, csv) = (d.join("viz.png"), d.join("m.csv"));
    for extra in [&[][..], &["--cpu"][..], &["--side-by-side"][..]] {
        let mut args = vec![
            "features",
            "--image",
            s(&pa),
            "--image",
            s(&pb),
            "--out",
            s(&out),
            "--csv",
            s(&csv),
        ];
        args.extend_from_slice(extra);
        let o = run(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let (header, rows) = csv_rows(&csv);
        assert_eq!(header, "xa,ya,xb,yb,score");
        assert!(rows.len() >= 30, "{} matches", rows.len());
        let good = rows
            .iter()
            .filter(|r| (r[2] - r[0] - 4.0).hypot(r[3] - r[1] + 3.0) < 1.0)
            .count();
        assert!(good * 10 >= rows.len() * 9, "{good} of {}", rows.len());
        assert!(rows.iter().all(|r| r[4] >= 0.8 && r[4] <= 1.0 + 1e-5));
        let viz = image::open(&out).unwrap();
        let w = if extra == ["--side-by-side"] {
            400
        } else {
            200
        };
        assert_eq!((viz.width(), viz.height()), (w, 150));
    }
}

/// Fails with exit status 1 and one line on stderr containing `needle`.
fn assert_fails(args: &[&str], needle: &str) {
    let o = run(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{args:?} succeeded");
    assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
    assert!(err.contains(needle), "{args:?}: {err:?} lacks {needle:?}");
}

#[test]
fn bad_input_fails_with_one_line_naming_the_file() {
    let d = dir("errors");
    let good = d.join("good.png");
    write_png(&patterns::smooth_noise(40, 30, 1.5, 1), &good);
    let corrupt = d.join("corrupt.png");
    std::fs::write(&corrupt, b"\x89PNG\r\n\x1a\nnot really a png").unwrap();
    let missing = d.join("missing.png");
    let out = d.join("viz.png");
    assert_fails(
        &["features", "--image", s(&missing), "--out", s(&out)],
        "missing.png",
    );
    assert_fails(
        &["features", "--image", s(&corrupt), "--out", s(&out)],
        "corrupt.png",
    );
    assert_fails(
        &[
            "features",
            "--image",
            s(&good),
            "--image",
            s(&corrupt),
            "--out",
            s(&out),
        ],
        "corrupt.png",
    );
    assert_fails(
        &[
            "features",
            "--image",
            s(&good),
            "--max",
            "0",
            "--out",
            s(&out),
        ],
        "--max",
    );
    let unwritable = d.join("no/such/dir/viz.png");
    assert_fails(
        &["features", "--image", s(&good), "--out", s(&unwritable)],
        "viz.png",
    );
    let bad_csv = d.join("no/such/dir/c.csv");
    assert_fails(
        &[
            "features",
            "--image",
            s(&good),
            "--out",
            s(&out),
            "--csv",
            s(&bad_csv),
        ],
        "c.csv",
    );
    assert_fails(
        &[
            "features",
            "--image",
            s(&good),
            "--out",
            s(&d.join("viz.txt")),
        ],
        "viz.txt",
    );
    assert_fails(
        &[
            "features",
            "--image",
            s(&good),
            "--image",
            s(&good),
            "--image",
            s(&good),
            "--out",
            s(&out),
        ],
        "--image",
    );
    // A 1x1 image and images of different sizes are fine: no corners.
    let tiny = d.join("tiny.png");
    image::GrayImage::new(1, 1).save(&tiny).unwrap();
    let o = run(&[
        "features",
        "--image",
        s(&tiny),
        "--image",
        s(&good),
        "--out",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
