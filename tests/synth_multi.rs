//! `splattrack synth --scene`: a sequence of several objects on disk in
//! the layout of docs/formats.md ("Sequence directory"), its ground truth
//! read back with the library's pose reader, and its flags' errors.

mod cli_common;

use cli_common::*;
use splattrack::io::read_poses;
use splattrack::synth::sequence::read_visibility;
use std::path::{Path, PathBuf};

fn root(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("synth_multi")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn images(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .unwrap()
        .filter(|e| {
            let p = e.as_ref().unwrap().path();
            p.extension().is_some_and(|x| x == "png")
        })
        .count()
}

/// Checks a written sequence of `names` over `frames` frames: every
/// object's pose in every frame, ordered by frame then object, frame 0's
/// in init.csv, the visibility of each, the objects' folders.
fn check_sequence(seq: &Path, names: &[&str], frames: usize) {
    assert_eq!(images(&seq.join("frames")), frames);
    let init = read_poses(&seq.join("init.csv")).unwrap();
    let poses = read_poses(&seq.join("poses.csv")).unwrap();
    assert_eq!(init.len(), names.len());
    assert_eq!(poses.len(), names.len() * frames);
    for (j, row) in poses.iter().enumerate() {
        let (i, k) = (j / names.len(), j % names.len());
        assert_eq!(row.object.as_deref(), Some(names[k]), "row {j}");
        assert_eq!(row.frame_index(), Some(i), "row {j}");
    }
    for (a, b) in init.iter().zip(&poses) {
        assert_eq!(a.object, b.object);
        assert_eq!(a.frame_index(), Some(0));
        assert_eq!(a.pose, b.pose);
    }
    let vis = read_visibility(&seq.join("visibility.csv")).unwrap();
    assert_eq!(vis.len(), names.len() * frames);
    for (j, row) in vis.iter().enumerate() {
        assert_eq!(row.object, names[j % names.len()]);
        assert_eq!(row.frame, poses[j].frame);
    }
    // Every object wholly in view at the start.
    assert!(
        vis[..names.len()].iter().all(|r| r.visible == 1.0),
        "{vis:?}"
    );
    for name in names {
        let obj = seq.join("objects").join(name);
        assert!(obj.join("model.ply").is_file(), "{name}");
        let kf = read_poses(&obj.join("keyframes/poses.csv")).unwrap();
        assert_eq!(images(&obj.join("keyframes")), kf.len());
        assert!(kf.len() >= 8 && kf.iter().all(|r| r.object.is_none()));
    }
    // Nothing of the one-object layout.
    assert!(!seq.join("model.ply").exists() && !seq.join("keyframes").exists());
}

#[test]
fn synth_scene_writes_every_objects_ground_truth() {
    let d = root("write");
    let seq = d.join("seq");
    let small = ["--width", "160", "--height", "120", "--points", "500"];
    let mut args = vec!["synth", "--scene", "cross", "--frames", "4"];
    args.extend(small);
    args.extend(["--out", s(&seq)]);
    let out = ok(&args);
    assert!(out.contains("blob:") && out.contains("box:"), "{out}");
    assert!(out.contains("% hidden"), "{out}");
    check_sequence(&seq, &["blob", "box"], 4);

    // Written again over it with other objects, fewer frames and another
    // background: nothing stale is left of the first.
    let mut args = vec![
        "synth",
        "--scene",
        "hide",
        "--objects",
        "blob,blob",
        "--frames",
        "3",
        "--background",
        "clutter",
        "--force",
    ];
    args.extend(small);
    args.extend(["--out", s(&seq)]);
    ok(&args);
    check_sequence(&seq, &["blob", "blob-2"], 3);
    let old = seq.join("objects/box");
    assert!(!old.join("model.ply").exists());
    assert_eq!(images(&old.join("keyframes")), 0);
}

#[test]
fn synth_scene_refuses_bad_flags_in_one_line() {
    let d = root("bad");
    let out = d.join("seq");
    let o = s(&out);
    fails(
        &["synth", "--scene", "cross", "--objects", "blob", "--out", o],
        &["--objects", "scene cross takes 2 objects, got 1"],
    );
    fails(
        &[
            "synth",
            "--scene",
            "cross3",
            "--objects",
            "blob,box",
            "--out",
            o,
        ],
        &["takes 3 objects, got 2"],
    );
    fails(
        &[
            "synth",
            "--scene",
            "cross",
            "--objects",
            "blob,cube",
            "--out",
            o,
        ],
        &["unknown object \"cube\""],
    );
    fails(
        &["synth", "--scene", "zigzag", "--out", o],
        &["unknown scene"],
    );
    fails(
        &["synth", "--objects", "blob,box", "--out", o],
        &["--scene"],
    );
    fails(
        &[
            "synth",
            "--scene",
            "cross",
            "--trajectory",
            "fast",
            "--out",
            o,
        ],
        &["--trajectory"],
    );
    fails(
        &["synth", "--scene", "hide", "--frames", "1", "--out", o],
        &["--frames 1"],
    );
    assert!(!out.exists());
}
