//! `splattrack track` and `eval` with several objects, through the
//! binary: two synthetic objects side by side in one sequence tracked in
//! one run (one pose file with the object column, every frame of both,
//! the refused and BOP files, overlays), eval's figures per object, a
//! one-model run written as one tracker alone writes it, and bad input
//! (duplicate names, an object missing from an init file, per-model
//! flags in the wrong number) failing in one line.

mod cli_common;

use cli_common::{fails, ok, s};
use splattrack::geometry::{Intrinsics, Pose};
use splattrack::io::{PoseRow, read_poses, write_poses};
use splattrack::synth::{Light, SynthConfig, SynthObject, SynthScene, raster, to_image};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const FRAMES: usize = 5;
/// The objects, in the order of their names (the order a sequence's
/// objects/ folder gives).
const OBJECTS: [(&str, &str); 2] = [("blob", "blob"), ("box", "box")];

struct Fixture {
    root: PathBuf,
    seq: PathBuf,
}

/// Object `k`'s pose in frame `i`: its scene's trajectory (slow: the
/// trajectory of 60 frames), moved a quarter of its distance to the left
/// (the first) or the right (the second), so that they never overlap.
fn pose(scene: &SynthScene, k: usize, i: usize) -> Pose {
    let mut p = scene.pose(i);
    let side = if k == 0 { -1.0 } else { 1.0 };
    p.translation.x += side * 0.25 * p.translation.z;
    p
}

/// A sequence of two objects, written once: camera.json, frames/,
/// objects/NAME/model.ply, init.csv and poses.csv with the object column.
fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_multi");
        let _ = std::fs::remove_dir_all(&root);
        let seq = root.join("seq");
        std::fs::create_dir_all(seq.join("frames")).unwrap();
        let cam = Intrinsics::new(320, 240, 300.0, 300.0, 159.5, 119.5);
        let scenes: Vec<SynthScene> = OBJECTS
            .iter()
            .enumerate()
            .map(|(k, (name, object))| {
                let object = SynthObject::by_name(object).unwrap();
                let config = SynthConfig {
                    object: object.name.into(),
                    frames: 60,
                    camera: cam,
                    seed: k as u64 + 1,
                    ..Default::default()
                }
                .with_object_px(&object, 100.0);
                let dir = seq.join("objects").join(name);
                std::fs::create_dir_all(&dir).unwrap();
                splattrack::synth::sequence::sample_model(&object, 6000, 3)
                    .unwrap()
                    .save_ply(dir.join("model.ply"))
                    .unwrap();
                SynthScene::new(config, object)
            })
            .collect();
        std::fs::write(
            seq.join("camera.json"),
            "{\"width\": 320, \"height\": 240, \"fx\": 300, \"fy\": 300, \"cx\": 159.5, \"cy\": 119.5}\n",
        )
        .unwrap();
        let mut rows = Vec::new();
        for i in 0..FRAMES {
            let light = Light::moving(i as f64 * 0.05);
            let mut rgb = scenes[0].background.clone();
            for (k, scene) in scenes.iter().enumerate() {
                let p = pose(scene, k, i);
                rgb = raster::render(&scene.object, &p, &cam, &light, &rgb, 3).rgb;
                rows.push(PoseRow::new(format!("{i:06}"), p).of_object(OBJECTS[k].0));
            }
            let mut rng = splattrack::rng::Rng::new(i as u64);
            to_image(&rgb, &cam, 0.01, &mut rng)
                .save(seq.join("frames").join(format!("{i:06}.png")))
                .unwrap();
        }
        write_poses(&seq.join("poses.csv"), &rows).unwrap();
        write_poses(&seq.join("init.csv"), &rows[..2]).unwrap();
        Fixture { root, seq }
    })
}

fn workdir(name: &str) -> PathBuf {
    let d = fixture().root.join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn model(k: usize) -> PathBuf {
    fixture()
        .seq
        .join("objects")
        .join(OBJECTS[k].0)
        .join("model.ply")
}

/// Object `name`'s rows of a file with the object column.
fn rows_of<'a>(rows: &'a [PoseRow], name: &str) -> Vec<&'a PoseRow> {
    rows.iter()
        .filter(|r| r.object.as_deref() == Some(name))
        .collect()
}

#[test]
fn two_objects_in_one_run_give_one_file_and_per_object_figures() {
    let f = fixture();
    let dir = workdir("two");
    let (out, bop, refused, overlay) = (
        dir.join("poses.csv"),
        dir.join("bop.csv"),
        dir.join("refused.csv"),
        dir.join("overlay"),
    );
    // No --model: the sequence's objects/, sorted by name; their first
    // poses from init.csv by name.
    let stdout = ok(&[
        "track",
        "--sequence",
        s(&f.seq),
        "--out",
        s(&out),
        "--bop",
        s(&bop),
        "--refused",
        s(&refused),
        "--overlay",
        s(&overlay),
        "--profile",
    ]);
    assert!(stdout.contains("of 2 objects"), "{stdout}");
    assert!(
        stdout.contains("object blob:") && stdout.contains("object box:"),
        "{stdout}"
    );
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(
        text.starts_with("object,frame,r11,") && text.lines().next().unwrap().ends_with(",cues"),
        "{text}"
    );
    let rows = read_poses(&out).unwrap();
    assert_eq!(rows.len(), 2 * FRAMES, "{text}");
    // Ordered by frame, then by object in the run's order.
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r.object.as_deref(), Some(OBJECTS[k % 2].0));
        assert_eq!(r.frame_index(), Some(k / 2));
    }
    let gt = read_poses(&f.seq.join("poses.csv")).unwrap();
    for (name, _) in OBJECTS {
        for (e, g) in rows_of(&rows, name).iter().zip(rows_of(&gt, name)) {
            let status = &e.extra.iter().find(|(k, _)| k == "status").unwrap().1;
            assert_eq!(status, "tracking", "{name} frame {}", e.frame);
            let (t, r) = (
                e.pose.translation_error(&g.pose),
                e.pose.rotation_error_deg(&g.pose),
            );
            assert!(
                t < 0.03 && r < 5.0,
                "{name} frame {}: {t} m, {r} deg off",
                e.frame
            );
        }
    }
    // BOP: each object's rows with its position as obj_id (the names are
    // not BOP's obj_NNNNNN).
    let bop_text = std::fs::read_to_string(&bop).unwrap();
    let ids: Vec<&str> = bop_text
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(2).unwrap())
        .collect();
    assert_eq!(ids.len(), 2 * FRAMES);
    assert!(ids.chunks(2).all(|c| c == ["1", "2"]), "{bop_text}");
    // The refused file has the object column (and no row: nothing lost).
    let refused_text = std::fs::read_to_string(&refused).unwrap();
    assert!(refused_text.starts_with("object,frame,"), "{refused_text}");
    assert_eq!(std::fs::read_dir(&overlay).unwrap().count(), FRAMES);
    // Each object's outline in its colour: the first as one object's
    // (green while tracking), the second its own.
    let picture = image::open(overlay.join("000000.png")).unwrap().to_rgb8();
    for (k, name) in ["blob", "box"].iter().enumerate() {
        let c = splattrack::view::object_colour(k, splattrack::tracker::Status::Tracking);
        assert!(picture.pixels().any(|p| p.0 == c), "{name}'s outline");
    }
    assert!(!dir.join("poses.csv.partial").exists());

    // eval: one row per object, the names alone.
    let table = ok(&[
        "eval",
        "--poses",
        s(&out),
        "--gt",
        s(&f.seq.join("poses.csv")),
        "--model",
        &format!("box={}", s(&model(1))),
        "--model",
        s(&model(0)),
        "--csv",
        s(&dir.join("errors.csv")),
    ]);
    let names: Vec<&str> = table
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|w| OBJECTS.iter().any(|(n, _)| n == w))
        .collect();
    assert!(names.starts_with(&["blob", "box"]), "{table}");
    let csv = std::fs::read_to_string(dir.join("errors.csv")).unwrap();
    for (name, _) in OBJECTS {
        let n = csv
            .lines()
            .filter(|l| l.starts_with(&format!("{name},")))
            .count();
        assert_eq!(n, FRAMES, "{csv}");
    }

    // The same run with the models named on the command line and a first
    // pose file per model: the same poses.
    let inits: Vec<PathBuf> = (0..2)
        .map(|k| {
            let p = dir.join(format!("init{k}.csv"));
            write_poses(&p, &[PoseRow::new("0", gt[k].pose)]).unwrap();
            p
        })
        .collect();
    let again = dir.join("again.csv");
    ok(&[
        "track",
        "--sequence",
        s(&f.seq),
        "--model",
        &format!("blob={}", s(&model(0))),
        "--model",
        &format!("box={}", s(&model(1))),
        "--init",
        s(&inits[0]),
        "--init",
        s(&inits[1]),
        "--modalities",
        "auto",
        "--out",
        s(&again),
    ]);
    let again = read_poses(&again).unwrap();
    assert_eq!(again.len(), rows.len());
    for (a, b) in again.iter().zip(&rows) {
        assert_eq!((&a.object, &a.frame), (&b.object, &b.frame));
        assert!(a.pose.translation_error(&b.pose) < 1e-6);
    }
}

#[test]
fn one_model_writes_what_one_tracker_alone_writes() {
    use splattrack::app::result_row;
    use splattrack::io::poses::{format_row, header};
    use splattrack::tracker::{Tracker, TrackerConfig};
    let f = fixture();
    let dir = workdir("one");
    let out = dir.join("poses.csv");
    // One model, its first pose found by its name in the shared init.csv.
    let stdout = ok(&[
        "track",
        "--sequence",
        s(&f.seq),
        "--model",
        s(&model(1)),
        "--out",
        s(&out),
    ]);
    assert!(!stdout.contains("objects"), "{stdout}");
    // The tracker alone, as the library runs it, on the same device.
    let device = splattrack::Device::new(
        splattrack::DeviceChoice::Auto,
        &splattrack::AdapterChoice::from_env().unwrap(),
    )
    .unwrap();
    let seq = splattrack::io::sequence::Sequence::open(&f.seq).unwrap();
    let init = read_poses(&f.seq.join("init.csv")).unwrap()[1].pose;
    let model = splattrack::PointModel::load(model(1)).unwrap();
    let config = TrackerConfig {
        auto_modalities: true,
        ..Default::default()
    };
    let mut tracker = Tracker::builder(&device, model, seq.camera)
        .config(config)
        .initial_pose(init)
        .build()
        .unwrap();
    let mut want = header(&splattrack::app::RESULT_COLUMNS) + "\n";
    for (i, path) in seq.frames.iter().enumerate() {
        let img = image::open(path).unwrap().to_rgb8();
        let r = tracker.track(&img).unwrap();
        want += &(format_row(&result_row(&seq.frame_label(i), &r)) + "\n");
    }
    assert_eq!(std::fs::read_to_string(&out).unwrap(), want);
}

#[test]
fn bad_several_object_input_fails_with_one_line() {
    let f = fixture();
    let dir = workdir("bad");
    let out = dir.join("poses.csv");
    let (seq, a, b) = (s(&f.seq), model(0), model(1));
    let track = |extra: &[&str]| -> Vec<String> {
        ["track", "--sequence", seq, "--out", s(&out)]
            .iter()
            .chain(extra)
            .map(|a| a.to_string())
            .collect()
    };
    let fails = |args: &[String], needles: &[&str]| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        fails(&args, needles)
    };
    // Two models of one name.
    fails(
        &track(&["--model", s(&a), "--model", &format!("blob={}", s(&b))]),
        &["two objects are named \"blob\"", "--model NAME=PATH"],
    );
    // An init file without one of the objects.
    let partial_init = dir.join("init_blob.csv");
    let init = read_poses(&f.seq.join("init.csv")).unwrap();
    write_poses(&partial_init, &init[..1]).unwrap();
    fails(
        &track(&["--init", s(&partial_init)]),
        &["init_blob.csv", "no row for object \"box\""],
    );
    // A plain file given once for several models.
    let plain = dir.join("plain.csv");
    write_poses(&plain, &[PoseRow::new("0", init[0].pose)]).unwrap();
    fails(
        &track(&["--init", s(&plain)]),
        &["plain.csv", "no object column"],
    );
    // Per-model flags in the wrong number.
    fails(
        &track(&["--model", s(&a), "--model", s(&b), "--keyframes", s(&dir)]),
        &[
            "--keyframes is given 1 times for 2 models",
            "once per --model",
        ],
    );
    fails(
        &track(&[
            "--modalities",
            "texture",
            "--modalities",
            "contour",
            "--modalities",
            "auto",
        ]),
        &["--modalities is given 3 times for 2 models"],
    );
    fails(&track(&["--obj-id", "3"]), &["--obj-id", "several models"]);
    assert!(!out.exists() && !dir.join("poses.csv.partial").exists());
    // eval: an estimate's object the ground truth lacks, named with the file.
    let est = dir.join("est.csv");
    let gt = read_poses(&f.seq.join("poses.csv")).unwrap();
    let renamed: Vec<PoseRow> = gt
        .iter()
        .map(|r| {
            r.clone()
                .of_object(r.object.as_deref().unwrap().replace("box", "mug"))
        })
        .collect();
    write_poses(&est, &renamed).unwrap();
    cli_common::fails(
        &[
            "eval",
            "--poses",
            s(&est),
            "--gt",
            s(&f.seq.join("poses.csv")),
        ],
        &["est.csv", "object \"mug\"", "not in the ground truth"],
    );
}
