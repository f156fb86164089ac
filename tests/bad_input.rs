//! Bad and odd input through the binary: every case ends with
//! one line on stderr naming the file or flag and the problem and a
//! non-zero exit, within a deadline (no hang, no huge allocation), never a
//! panic; odd but valid input (16-bit, grey, RGBA and palette frames,
//! frame names that sort wrongly as text, timestamps as labels) works.
//! Data safety: no command overwrites its inputs or a crashed run's
//! partial output.

mod cli_common;

use cli_common::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// A small synthetic sequence (6 frames of the blob, 160 x 120) and its
/// keyframe store, made once.
struct Fixture {
    root: PathBuf,
    seq: PathBuf,
    model: PathBuf,
    store: PathBuf,
}

const FRAMES: usize = 6;

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bad_input");
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(&root).unwrap();
        let seq = root.join("seq");
        ok(&[
            "synth",
            "--frames",
            "6",
            "--width",
            "160",
            "--height",
            "120",
            "--points",
            "5000",
            "--out",
            s(&seq),
        ]);
        let model = seq.join("model.ply");
        let store = root.join("store.stkf");
        ok(&[
            "keyframes",
            "--model",
            s(&model),
            "--keyframes",
            s(&seq.join("keyframes")),
            "--camera",
            s(&seq.join("camera.json")),
            "--out",
            s(&store),
        ]);
        Fixture {
            root,
            seq,
            model,
            store,
        }
    })
}

fn workdir(name: &str) -> PathBuf {
    let d = fixture().root.join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A copy of the fixture sequence's camera, init.csv and poses.csv in
/// `dir`, with frames/ made by `frame(i, rgb)` saved under `name(i)`.
fn copy_sequence(
    dir: &Path,
    name: impl Fn(usize) -> String,
    frame: impl Fn(&image::RgbImage, &Path),
) -> PathBuf {
    let f = fixture();
    std::fs::create_dir_all(dir.join("frames")).unwrap();
    for file in ["camera.json", "init.csv", "poses.csv"] {
        std::fs::copy(f.seq.join(file), dir.join(file)).unwrap();
    }
    for i in 0..FRAMES {
        let rgb = image::open(f.seq.join(format!("frames/{i:06}.png")))
            .unwrap()
            .to_rgb8();
        frame(&rgb, &dir.join("frames").join(name(i)));
    }
    dir.to_owned()
}

fn track(seq: &Path, out: &Path, extra: &[&str]) -> Vec<String> {
    let f = fixture();
    let mut args = vec![
        "track",
        "--model",
        s(&f.model),
        "--sequence",
        s(seq),
        "--keyframes",
        s(&f.store),
        "--out",
        s(out),
    ];
    args.extend_from_slice(extra);
    ok(&args);
    std::fs::read_to_string(out)
        .unwrap()
        .lines()
        .map(str::to_owned)
        .collect()
}

#[test]
fn a_camera_that_disagrees_with_its_frames_is_refused_before_allocating() {
    let d = workdir("huge_camera");
    let seq = copy_sequence(
        &d.join("seq"),
        |i| format!("{i:06}.png"),
        |rgb, p| rgb.save(p).unwrap(),
    );
    std::fs::write(
        seq.join("camera.json"),
        r#"{"width": 20000, "height": 20000, "fx": 18750, "fy": 18750, "cx": 9999.5, "cy": 9999.5,
            "distortion": [-0.2, 0.05, 0, 0, 0]}"#,
    )
    .unwrap();
    let f = fixture();
    fails(
        &[
            "track",
            "--model",
            s(&f.model),
            "--sequence",
            s(&seq),
            "--out",
            s(&d.join("p.csv")),
        ],
        &["000000.png", "160x120", "20000x20000", "camera.json"],
    );
}

#[test]
fn cameras_with_impossible_focal_lengths_are_refused() {
    let d = workdir("focal");
    let seq = copy_sequence(
        &d.join("seq"),
        |i| format!("{i:06}.png"),
        |rgb, p| rgb.save(p).unwrap(),
    );
    let f = fixture();
    for (fx, want) in [
        ("0", "fx"),
        ("-150", "fx"),
        ("1e300", "field of view"),
        ("1e-9", "field of view"),
    ] {
        std::fs::write(
            seq.join("camera.json"),
            format!(
                r#"{{"width": 160, "height": 120, "fx": {fx}, "fy": 150, "cx": 79.5, "cy": 59.5}}"#
            ),
        )
        .unwrap();
        fails(
            &[
                "track",
                "--model",
                s(&f.model),
                "--sequence",
                s(&seq),
                "--out",
                s(&d.join("p.csv")),
            ],
            &["camera.json", want],
        );
    }
}

#[test]
fn absurd_corner_counts_are_refused_by_flag() {
    let f = fixture();
    let d = workdir("corners");
    fails(
        &[
            "track",
            "--model",
            s(&f.model),
            "--sequence",
            s(&f.seq),
            "--out",
            s(&d.join("p.csv")),
            "--max-corners",
            "1000000000",
        ],
        &["--max-corners 1000000000", "100000"],
    );
}

/// The fixture's store with `patch` applied to its bytes.
fn patched_store(name: &str, patch: impl Fn(&mut Vec<u8>)) -> PathBuf {
    let mut b = std::fs::read(&fixture().store).unwrap();
    patch(&mut b);
    let p = fixture().root.join(name);
    std::fs::write(&p, b).unwrap();
    p
}

#[test]
fn hostile_keyframe_stores_are_refused() {
    let f = fixture();
    let d = workdir("stores");
    // Header: magic, u64 points, u64 fingerprint, u64 count, 3 f64 centre.
    let zero = patched_store("zero.stkf", |b| {
        b[24..32].copy_from_slice(&0u64.to_le_bytes());
        b.truncate(56);
    });
    let many = patched_store("many.stkf", |b| {
        b[24..32].copy_from_slice(&u64::MAX.to_le_bytes())
    });
    let far = patched_store("far.stkf", |b| {
        b[32..40].copy_from_slice(&1e6f64.to_le_bytes())
    });
    let nan = patched_store("nan.stkf", |b| {
        b[40..48].copy_from_slice(&f64::NAN.to_le_bytes())
    });
    for (store, want) in [
        (&zero, "no keyframe"),
        (&many, "exceed the file size"),
        (&far, "centre"),
        (&nan, "centre"),
    ] {
        fails(
            &[
                "track",
                "--model",
                s(&f.model),
                "--sequence",
                s(&f.seq),
                "--keyframes",
                s(store),
                "--out",
                s(&d.join("p.csv")),
            ],
            &[s(store), want],
        );
    }
}

/// A PNG with a palette (colour type 3) of 256 greys, indexed by luma,
/// written by hand (stored deflate blocks): the image crate writes none.
fn write_palette_png(rgb: &image::RgbImage, path: &Path) {
    fn crc32(data: &[u8]) -> u32 {
        let mut c = 0xffff_ffffu32;
        for &b in data {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xedb8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }
    fn chunk(out: &mut Vec<u8>, kind: &[u8], data: &[u8]) {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend_from_slice(&crc32(&body).to_be_bytes());
    }
    let (w, h) = rgb.dimensions();
    let mut raw = Vec::new();
    for y in 0..h {
        raw.push(0u8);
        for x in 0..w {
            let p = rgb.get_pixel(x, y).0;
            raw.push(((p[0] as u32 * 77 + p[1] as u32 * 150 + p[2] as u32 * 29) >> 8) as u8);
        }
    }
    let (mut a, mut b) = (1u32, 0u32);
    for &v in &raw {
        a = (a + v as u32) % 65521;
        b = (b + a) % 65521;
    }
    let mut z = vec![0x78, 0x01];
    let blocks: Vec<&[u8]> = raw.chunks(65535).collect();
    for (i, blk) in blocks.iter().enumerate() {
        z.push((i + 1 == blocks.len()) as u8);
        z.extend_from_slice(&(blk.len() as u16).to_le_bytes());
        z.extend_from_slice(&(!(blk.len() as u16)).to_le_bytes());
        z.extend_from_slice(blk);
    }
    z.extend_from_slice(&((b << 16) | a).to_be_bytes());
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 3, 0, 0, 0]);
    chunk(&mut png, b"IHDR", &ihdr);
    let palette: Vec<u8> = (0..=255u8).flat_map(|v| [v, v, v]).collect();
    chunk(&mut png, b"PLTE", &palette);
    chunk(&mut png, b"IDAT", &z);
    chunk(&mut png, b"IEND", &[]);
    std::fs::write(path, png).unwrap();
}

#[test]
fn sixteen_bit_grey_rgba_and_palette_frames_are_tracked() {
    let d = workdir("formats");
    let reference = track(&fixture().seq, &d.join("rgb8.csv"), &[]);
    type Writer = Box<dyn Fn(&image::RgbImage, &Path)>;
    let kinds: Vec<(&str, Writer, bool)> = vec![
        (
            "rgb16",
            Box::new(|rgb, p| {
                image::DynamicImage::ImageRgb8(rgb.clone())
                    .to_rgb16()
                    .save(p)
                    .unwrap()
            }),
            true,
        ),
        (
            "rgba8",
            Box::new(|rgb, p| {
                image::DynamicImage::ImageRgb8(rgb.clone())
                    .to_rgba8()
                    .save(p)
                    .unwrap()
            }),
            true,
        ),
        (
            "grey8",
            Box::new(|rgb, p| {
                image::DynamicImage::ImageRgb8(rgb.clone())
                    .to_luma8()
                    .save(p)
                    .unwrap()
            }),
            false,
        ),
        (
            "grey16",
            Box::new(|rgb, p| {
                image::DynamicImage::ImageRgb8(rgb.clone())
                    .to_luma16()
                    .save(p)
                    .unwrap()
            }),
            false,
        ),
        ("palette", Box::new(write_palette_png), false),
    ];
    for (kind, write, lossless) in kinds {
        let seq = copy_sequence(&d.join(kind), |i| format!("{i:06}.png"), write);
        let rows = track(&seq, &d.join(format!("{kind}.csv")), &[]);
        assert_eq!(rows.len(), FRAMES + 1, "{kind}");
        if lossless {
            // The same pixels once decoded to 8-bit RGB: the same poses.
            assert_eq!(rows, reference, "{kind}");
        }
    }
}

#[test]
fn frames_named_without_padding_come_in_numeric_order() {
    let d = workdir("names");
    let reference = track(&fixture().seq, &d.join("padded.csv"), &[]);
    // 0, 5, 10, 15, 20, 25: text order would put 10..25 before 5.
    let seq = copy_sequence(
        &d.join("seq"),
        |i| format!("{}.png", i * 5),
        |rgb, p| rgb.save(p).unwrap(),
    );
    let rows = track(&seq, &d.join("unpadded.csv"), &[]);
    assert_eq!(rows, reference);
}

#[test]
fn eval_plots_frames_labelled_by_microsecond_timestamps() {
    let d = workdir("timestamps");
    let f = fixture();
    let gt = std::fs::read_to_string(f.seq.join("poses.csv")).unwrap();
    let relabel = |text: &str| -> String {
        let mut out = String::new();
        for (i, line) in text.lines().enumerate() {
            if i == 0 {
                out += line;
            } else {
                let rest = line.split_once(',').unwrap().1;
                out += &format!("\n{},{rest}", 1_600_000_000_000_000u64 + 33_333 * i as u64);
            }
        }
        out + "\n"
    };
    std::fs::write(d.join("gt.csv"), relabel(&gt)).unwrap();
    let mut one = relabel(&gt);
    one = one.lines().take(2).collect::<Vec<_>>().join("\n") + "\n";
    std::fs::write(d.join("one.csv"), &one).unwrap();
    for est in ["gt.csv", "one.csv"] {
        let plot = d.join(format!("{est}.png"));
        ok(&[
            "eval",
            "--poses",
            s(&d.join(est)),
            "--gt",
            s(&d.join("gt.csv")),
            "--plot",
            s(&plot),
        ]);
        assert!(plot.is_file());
    }
}

#[test]
fn odd_shaped_images_do_not_ask_for_a_huge_canvas() {
    let d = workdir("odd");
    let (a, b) = (d.join("tall.png"), d.join("wide.png"));
    image::GrayImage::from_pixel(1, 60_000, image::Luma([128]))
        .save(&a)
        .unwrap();
    image::GrayImage::from_pixel(60_000, 1, image::Luma([128]))
        .save(&b)
        .unwrap();
    fails(
        &[
            "features",
            "--image",
            s(&a),
            "--image",
            s(&b),
            "--cpu",
            "--out",
            s(&d.join("m.png")),
        ],
        &["tall.png", "wide.png", "Mpx"],
    );
    let huge = d.join("huge.png");
    image::GrayImage::new(9000, 9000).save(&huge).unwrap();
    fails(
        &[
            "features",
            "--image",
            s(&huge),
            "--cpu",
            "--out",
            s(&d.join("c.png")),
        ],
        &["huge.png", "Mpx"],
    );
}

#[test]
fn no_command_overwrites_its_inputs_or_a_crashed_runs_output() {
    let f = fixture();
    let d = workdir("safety");
    // A crashed run's partial output survives a rerun.
    let out = d.join("poses.csv");
    let partial = d.join("poses.csv.partial");
    std::fs::write(&partial, "frame,...\n0,the only record\n").unwrap();
    track(&f.seq, &out, &["--frames", "2"]);
    assert_eq!(
        std::fs::read_to_string(d.join("poses.csv.partial.1")).unwrap(),
        "frame,...\n0,the only record\n"
    );
    assert!(!partial.exists());
    // Overlays into the frames folder, poses over init.csv or the model,
    // BOP results over the pose output: refused, inputs untouched.
    let frames = f.seq.join("frames");
    let before = std::fs::read(frames.join("000000.png")).unwrap();
    let base = [
        "track",
        "--model",
        s(&f.model),
        "--sequence",
        s(&f.seq),
        "--frames",
        "2",
    ];
    let with = |extra: &[&str]| -> Vec<String> {
        base.iter().chain(extra).map(|v| v.to_string()).collect()
    };
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            with(&["--out", s(&d.join("a.csv")), "--overlay", s(&frames)]),
            "frames",
        ),
        (with(&["--out", s(&f.seq.join("init.csv"))]), "init.csv"),
        (with(&["--out", s(&f.seq.join("poses.csv"))]), "poses.csv"),
        (with(&["--out", s(&f.model)]), "model.ply"),
        (
            with(&["--out", s(&d.join("b.csv")), "--bop", s(&d.join("b.csv"))]),
            "b.csv",
        ),
    ];
    for (args, want) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        fails(&args, &["would overwrite the input", want]);
    }
    assert_eq!(std::fs::read(frames.join("000000.png")).unwrap(), before);
    // The other commands' outputs over their inputs.
    let gt = f.seq.join("poses.csv");
    let gt_before = std::fs::read(&gt).unwrap();
    let frame0 = frames.join("000000.png");
    let camera = f.seq.join("camera.json");
    let kf_dir = f.seq.join("keyframes");
    let others: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["eval", "--poses", s(&out), "--gt", s(&gt), "--csv", s(&gt)],
            "poses.csv",
        ),
        (
            vec![
                "eval",
                "--poses",
                s(&out),
                "--gt",
                s(&gt),
                "--plot",
                s(&out),
            ],
            "poses.csv",
        ),
        (
            vec![
                "features",
                "--image",
                s(&frame0),
                "--cpu",
                "--out",
                s(&frame0),
            ],
            "000000.png",
        ),
        (
            vec![
                "render",
                "--model",
                s(&f.model),
                "--camera",
                s(&camera),
                "--pose-file",
                s(&gt),
                "--out",
                s(&f.model),
            ],
            "model.ply",
        ),
        (
            vec![
                "keyframes",
                "--model",
                s(&f.model),
                "--keyframes",
                s(&kf_dir),
                "--camera",
                s(&camera),
                "--out",
                s(&f.model),
            ],
            "model.ply",
        ),
    ];
    for (args, want) in others {
        fails(&args, &["would overwrite the input", want]);
    }
    assert_eq!(std::fs::read(&gt).unwrap(), gt_before);
    assert_eq!(std::fs::read(frames.join("000000.png")).unwrap(), before);
    // synth refuses a non-empty folder; --force replaces the sequence
    // there, stale frames included.
    let seq = d.join("synth");
    let synth = |frames: &str, force: bool| {
        let mut a = vec![
            "synth",
            "--frames",
            frames,
            "--width",
            "64",
            "--height",
            "48",
            "--points",
            "500",
            "--out",
            s(&seq),
        ];
        if force {
            a.push("--force");
        }
        run(&a)
    };
    assert!(synth("5", false).0);
    let gt = std::fs::read_to_string(seq.join("poses.csv")).unwrap();
    let (success, _, err) = synth("3", false);
    assert!(
        !success && err.contains("not empty") && err.contains("--force"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(seq.join("poses.csv")).unwrap(), gt);
    std::fs::write(seq.join("notes.txt"), "mine").unwrap();
    assert!(synth("3", true).0);
    let left = splattrack::io::sequence::list_images(&seq.join("frames")).unwrap();
    assert_eq!(left.len(), 3, "stale frames: {left:?}");
    assert_eq!(
        std::fs::read_to_string(seq.join("poses.csv"))
            .unwrap()
            .lines()
            .count(),
        4
    );
    assert_eq!(
        std::fs::read_to_string(seq.join("notes.txt")).unwrap(),
        "mine"
    );
}
