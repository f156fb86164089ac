//! A CAD model as the only model, through the binary: `track` takes a mesh
//! (OBJ, STL) as it is and samples it; without keyframes or model colours
//! it tracks frame to frame by the outline and says so; `--mode kf+it`
//! there fails pointing to `--mode it`; `model` writes the sampled point
//! model. With `SPLATTRACK_DATA`: the real cube from its mesh.obj alone.

mod cli_common;
mod data_common;

use cli_common::{fails, ok, s};
use splattrack::io::{PoseRow, read_poses};
use splattrack::model::TriangleMesh;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const FRAMES: usize = 8;

/// The synthetic plain box (untextured) at 320x240, and a copy of its
/// sequence without keyframes: camera, frames, init.csv, poses.csv.
struct Fixture {
    root: PathBuf,
    seq: PathBuf,
    bare: PathBuf,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_cad");
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(&root).unwrap();
        let seq = root.join("seq");
        ok(&[
            "synth",
            "--object",
            "plainbox",
            "--frames",
            &FRAMES.to_string(),
            "--width",
            "320",
            "--height",
            "240",
            "--points",
            "20000",
            "--out",
            s(&seq),
        ]);
        let bare = root.join("bare");
        std::fs::create_dir_all(bare.join("frames")).unwrap();
        for f in ["camera.json", "init.csv", "poses.csv"] {
            std::fs::copy(seq.join(f), bare.join(f)).unwrap();
        }
        for e in std::fs::read_dir(seq.join("frames")).unwrap() {
            let p = e.unwrap().path();
            std::fs::copy(&p, bare.join("frames").join(p.file_name().unwrap())).unwrap();
        }
        Fixture { root, seq, bare }
    })
}

/// Rotation (degrees) and translation (model units) errors.
fn errors(a: &PoseRow, b: &PoseRow) -> (f64, f64) {
    (
        a.pose.rotation_error_deg(&b.pose),
        (a.pose.translation - b.pose.translation).norm(),
    )
}

/// A binary STL of `mesh`'s triangles.
fn stl_bytes(mesh: &TriangleMesh) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&(mesh.triangles.len() as u32).to_le_bytes());
    for t in &mesh.triangles {
        b.extend_from_slice(&[0u8; 12]);
        for &i in t {
            for c in mesh.vertices[i as usize].to_array() {
                b.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
}

#[test]
fn a_mesh_without_keyframes_is_tracked_frame_to_frame_by_its_outline() {
    let f = fixture();
    let out = f.root.join("obj.csv");
    let mesh = f.seq.join("mesh.obj");
    let stdout = ok(&[
        "track",
        "--model",
        s(&mesh),
        "--sequence",
        s(&f.bare),
        "--out",
        s(&out),
    ]);
    assert!(stdout.contains("(it mode"), "{stdout}");
    assert!(stdout.contains("cues: contour (no keyframes"), "{stdout}");
    let rows = read_poses(&out).unwrap();
    let gt = read_poses(&f.bare.join("poses.csv")).unwrap();
    assert_eq!(rows.len(), FRAMES);
    let mut tracking = 0;
    for (r, g) in rows.iter().zip(&gt) {
        let (status, cues) = (&r.extra[2].1, &r.extra[3].1);
        if status == "tracking" {
            tracking += 1;
            assert_eq!(cues, "contour", "{r:?}");
            let (rot, tr) = errors(r, g);
            assert!(
                rot < 2.0 && tr < 0.005,
                "frame {}: {rot} deg, {tr}",
                r.frame
            );
        } else {
            assert_eq!(cues, "none", "{r:?}");
        }
    }
    assert!(tracking >= FRAMES - 1, "{tracking} of {FRAMES} tracking");

    // The same mesh as a binary STL: the same triangles, the same sample,
    // the same poses.
    let stl = f.root.join("mesh.stl");
    std::fs::write(&stl, stl_bytes(&TriangleMesh::load_obj(&mesh).unwrap())).unwrap();
    let out_stl = f.root.join("stl.csv");
    ok(&[
        "track",
        "--model",
        s(&stl),
        "--sequence",
        s(&f.bare),
        "--out",
        s(&out_stl),
    ]);
    let cols = |p: &Path| -> Vec<String> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .map(|l| l.split(',').take(13).collect::<Vec<_>>().join(","))
            .collect()
    };
    assert_eq!(cols(&out), cols(&out_stl));
}

#[test]
fn kf_modes_without_a_texture_fail_pointing_to_mode_it() {
    let f = fixture();
    let out = f.root.join("kf.csv");
    let mesh = f.seq.join("mesh.obj");
    for mode in ["kf+it", "kf"] {
        fails(
            &[
                "track",
                "--model",
                s(&mesh),
                "--sequence",
                s(&f.bare),
                "--mode",
                mode,
                "--out",
                s(&out),
            ],
            &[&format!("--mode {mode}"), "keyframes", "--mode it"],
        );
    }
    // No first pose either: nothing to search with.
    let no_init = f.root.join("no_init");
    std::fs::create_dir_all(&no_init).unwrap();
    std::fs::copy(f.bare.join("camera.json"), no_init.join("camera.json")).unwrap();
    std::fs::create_dir_all(no_init.join("frames")).unwrap();
    std::fs::copy(
        f.bare.join("frames/000000.png"),
        no_init.join("frames/000000.png"),
    )
    .unwrap();
    fails(
        &[
            "track",
            "--model",
            s(&mesh),
            "--sequence",
            s(&no_init),
            "--out",
            s(&out),
        ],
        &["no first pose", "--init"],
    );
    assert!(!out.exists());
}

#[test]
fn the_model_command_writes_the_sample_track_makes() {
    let f = fixture();
    let mesh = TriangleMesh::load_obj(f.seq.join("mesh.obj")).unwrap();
    let stl = f.root.join("model_cmd.stl");
    std::fs::write(&stl, stl_bytes(&mesh)).unwrap();
    let ply = f.root.join("model_cmd.ply");
    let stdout = ok(&[
        "model",
        "--mesh",
        s(&stl),
        "--out",
        s(&ply),
        "--points",
        "5000",
    ]);
    assert!(stdout.contains("sampled into 5000 points"), "{stdout}");
    let m = splattrack::PointModel::load(&ply).unwrap();
    assert_eq!(m.len(), 5000);
    assert!(m.colors.is_none());
    // Every point on the mesh's surface: within the box's bounds.
    let (lo, hi) = mesh.vertices.iter().fold(
        (glam::DVec3::INFINITY, glam::DVec3::NEG_INFINITY),
        |(lo, hi), v| (lo.min(*v), hi.max(*v)),
    );
    for p in &m.positions {
        let p = p.as_dvec3();
        assert!(p.cmpge(lo - 1e-6).all() && p.cmple(hi + 1e-6).all(), "{p}");
    }

    // A point model is not a mesh; a truncated STL is refused in one line.
    let cloud = f.seq.join("model.ply");
    fails(
        &["model", "--mesh", s(&cloud), "--out", s(&ply)],
        &["model.ply", "no faces"],
    );
    let bytes = std::fs::read(&stl).unwrap();
    let cut = f.root.join("cut.stl");
    std::fs::write(&cut, &bytes[..bytes.len() - 20]).unwrap();
    fails(
        &["model", "--mesh", s(&cut), "--out", s(&ply)],
        &["cut.stl", "truncated"],
    );
    fails(
        &[
            "track",
            "--model",
            s(&cut),
            "--sequence",
            s(&f.bare),
            "--out",
            s(&ply),
        ],
        &["cut.stl", "truncated"],
    );
}

/// `frame -> gt_ok` of gt_quality.csv.
fn gt_ok(path: &Path) -> std::collections::HashMap<String, bool> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (
                c[0].parse::<usize>().unwrap().to_string(),
                c.last().unwrap().trim() == "1",
            )
        })
        .collect()
}

#[test]
fn the_real_cube_from_its_cad_mesh_alone() {
    let Some(dir) = data_common::real_data("visp_rbt_cube") else {
        return;
    };
    let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_cad_real");
    let _ = std::fs::remove_dir_all(&root);
    let seq = root.join("seq");
    std::fs::create_dir_all(seq.join("frames")).unwrap();
    for f in ["camera.json", "init.csv"] {
        std::fs::copy(dir.join(f), seq.join(f)).unwrap();
    }
    for e in std::fs::read_dir(dir.join("frames")).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, seq.join("frames").join(p.file_name().unwrap())).unwrap();
    }
    let out = root.join("poses.csv");
    let stdout = ok(&[
        "track",
        "--model",
        s(&dir.join("mesh.obj")),
        "--sequence",
        s(&seq),
        "--out",
        s(&out),
    ]);
    assert!(stdout.contains("cues: contour"), "{stdout}");
    let rows = read_poses(&out).unwrap();
    let gt = read_poses(&dir.join("poses.csv")).unwrap();
    let good = gt_ok(&dir.join("gt_quality.csv"));
    let (mut n, mut within) = (0, 0);
    for (r, g) in rows.iter().zip(&gt) {
        if !good[&r.frame.parse::<usize>().unwrap().to_string()] {
            continue;
        }
        n += 1;
        if r.extra[2].1 != "tracking" {
            continue;
        }
        // Never wrong: every pose reported tracking is on the cube (the
        // worst measured: 6.34 degrees, 7.11 before the check's render
        // seeded the contour, while a hand holds it).
        let (rot, tr) = errors(r, g);
        assert!(
            rot < 8.0 && tr < 0.03,
            "frame {}: {rot} deg, {tr} m",
            r.frame
        );
        within += usize::from(rot < 5.0 && tr < 0.05);
    }
    // Measured 85 of 86 (98.8%; 83 before the check's render seeded the
    // contour's first round). From frame 62 a hand holds the cube's
    // top right corner and the undamped contour drifts (a turn about the
    // vertical with a move along the ray) until the check refuses it; the
    // damped second step from the previous pose passes. Without it: 56.
    assert!(within * 100 >= 93 * n, "{within} of {n} gt_ok frames");
}
