//! `splattrack synth`, `keyframes`, `track`, `eval` and `info` end to end,
//! through the binary: the files of FORMATS.md ("Tracker output", the BOP
//! CSV, overlays, eval's table, plot and CSV), and bad input, which must
//! exit non-zero with one line on stderr naming the file or flag and the
//! problem, never a panic.

mod data_common;

use splattrack::geometry::Pose;
use splattrack::io::{PoseRow, read_poses};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_splattrack"));
    if std::env::var_os("SPLATTRACK_ADAPTER").is_none() {
        c.env("SPLATTRACK_ADAPTER", "cpu");
    }
    c
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("run splattrack")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Runs and expects success; returns stdout.
fn ok(args: &[&str]) -> String {
    let o = run(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{args:?} failed: {err}");
    assert!(!err.contains("panicked"), "{err}");
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Runs and expects a failure with exactly one line on stderr containing
/// every needle, and no panic.
fn fails(args: &[&str], needles: &[&str]) -> String {
    let o = run(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "{args:?} succeeded");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: {err:?} lacks {n:?}");
    }
    err
}

/// A tiny synthetic sequence and its keyframe store, made once through the
/// CLI: 8 frames of the blob at 320x240, a 20k-point model.
struct Fixture {
    root: PathBuf,
    seq: PathBuf,
    model: PathBuf,
    store: PathBuf,
}

const FRAMES: usize = 8;

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_track");
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(&root).unwrap();
        let seq = root.join("seq");
        let out = ok(&[
            "synth",
            "--frames",
            "8",
            "--width",
            "320",
            "--height",
            "240",
            "--points",
            "20000",
            "--out",
            s(&seq),
        ]);
        assert!(out.contains("8 frames"), "{out}");
        let model = seq.join("model.ply");
        let store = root.join("store.stkf");
        let out = ok(&[
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
        assert!(out.contains("12 keyframes"), "{out}");
        assert!(store.is_file());
        Fixture {
            root,
            seq,
            model,
            store,
        }
    })
}

/// A fresh directory under the fixture's root for one test.
fn workdir(name: &str) -> PathBuf {
    let d = fixture().root.join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn partial_files(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().contains("partial"))
        .collect()
}

const HEADER: &str =
    "frame,r11,r12,r13,r21,r22,r23,r31,r32,r33,tx,ty,tz,inliers,residual_px,status,cues";

/// Checks a tracker output file against FORMATS.md and returns its rows.
fn check_tracker_csv(path: &Path) -> Vec<PoseRow> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(HEADER));
    let body: Vec<&str> = lines.collect();
    assert_eq!(body.len(), FRAMES, "{text}");
    for (i, line) in body.iter().enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 17, "{line}");
        assert_eq!(f[0], i.to_string());
        for v in &f[1..13] {
            assert!(v.parse::<f64>().unwrap().is_finite(), "{line}");
        }
        f[13].parse::<usize>().unwrap();
        let res: f64 = f[14].parse().unwrap();
        assert!(res.is_nan() || res >= 0.0, "{line}");
        assert!(f[15] == "tracking" || f[15] == "lost", "{line}");
        // Which cues held: none exactly on a lost frame.
        let cues = ["texture", "contour", "texture+contour"];
        match f[15] {
            "lost" => assert_eq!(f[16], "none", "{line}"),
            _ => assert!(cues.contains(&f[16]) || f[16] == "none", "{line}"),
        }
    }
    // The crate's reader agrees, and every pose is a rotation.
    let rows = read_poses(path).unwrap();
    assert_eq!(rows.len(), FRAMES);
    for r in &rows {
        r.pose.validate().unwrap();
    }
    rows
}

fn ground_truth() -> Vec<Pose> {
    read_poses(&fixture().seq.join("poses.csv"))
        .unwrap()
        .into_iter()
        .map(|r| r.pose)
        .collect()
}

#[test]
fn track_with_a_store_writes_poses_overlays_and_bop_results() {
    let f = fixture();
    let d = workdir("track_store");
    let out = d.join("poses.csv");
    let overlay = d.join("overlay");
    let bop = d.join("bop.csv");
    let stdout = ok(&[
        "track",
        "--model",
        s(&f.model),
        "--sequence",
        s(&f.seq),
        "--keyframes",
        s(&f.store),
        "--out",
        s(&out),
        "--overlay",
        s(&overlay),
        "--bop",
        s(&bop),
    ]);
    assert!(stdout.contains("tracked 8 frames"), "{stdout}");
    let rows = check_tracker_csv(&out);
    assert!(partial_files(&d).is_empty(), "{:?}", partial_files(&d));
    // Frame 0 starts at init.csv (the ground truth): it must stay close.
    let gt = ground_truth();
    let e0 = rows[0].pose.rotation_error_deg(&gt[0]);
    assert!(e0 < 2.0, "frame 0: {e0} deg");
    // Overlays: one picture per frame, the frame's size.
    for i in 0..FRAMES {
        let img = image::open(overlay.join(format!("{i:06}.png"))).unwrap();
        assert_eq!((img.width(), img.height()), (320, 240));
    }
    // BOP: its header, one row per frame, R as 9 numbers and t in mm.
    let text = std::fs::read_to_string(&bop).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("scene_id,im_id,obj_id,score,R,t,time"));
    let body: Vec<&str> = lines.collect();
    assert_eq!(body.len(), FRAMES);
    for (i, line) in body.iter().enumerate() {
        let c: Vec<&str> = line.split(',').collect();
        assert_eq!(c.len(), 7, "{line}");
        assert_eq!(c[1], i.to_string());
        let r: Vec<f64> = c[4].split(' ').map(|v| v.parse().unwrap()).collect();
        let t: Vec<f64> = c[5].split(' ').map(|v| v.parse().unwrap()).collect();
        let p = rows[i].pose.to_row_major();
        assert_eq!(r.len(), 9);
        assert_eq!(t.len(), 3);
        for k in 0..9 {
            assert!((r[k] - p[k]).abs() < 1e-6, "{line}");
        }
        for k in 0..3 {
            assert!((t[k] - 1000.0 * p[9 + k]).abs() < 1e-3, "{line}");
        }
        let score: f64 = c[3].parse().unwrap();
        let tracking = rows[i]
            .extra
            .iter()
            .any(|(k, v)| k == "status" && v == "tracking");
        assert_eq!(score, if tracking { 1.0 } else { 0.0 });
        assert!(c[6].parse::<f64>().unwrap() > 0.0);
    }
}

#[test]
fn track_without_a_store_uses_the_sequence_keyframes_and_eval_reports() {
    let f = fixture();
    let d = workdir("track_dir");
    let out = d.join("poses.csv");
    // No --keyframes: SEQUENCE/keyframes; --mode it as well.
    let stdout = ok(&[
        "track",
        "--model",
        s(&f.model),
        "--sequence",
        s(&f.seq),
        "--out",
        s(&out),
        "--profile",
    ]);
    let rows = check_tracker_csv(&out);
    // --profile: every stage of the step and its parts, then the GPU
    // passes by stage where the adapter has timestamp queries.
    for stage in [
        "features (frame Harris)",
        "IT",
        "render + gather",
        "KF",
        "render + read",
        "Harris",
        "NCC + gather + refine",
        "contour",
        "pose check",
        "search",
        "total",
    ] {
        assert!(stdout.contains(stage), "no {stage:?} in {stdout}");
    }
    if splattrack::gpu::shared_test_context().has_timestamps() {
        for pass in ["KF splat visibility", "check splat attributes"] {
            assert!(stdout.contains(pass), "no {pass:?} in {stdout}");
        }
        // Corners and matches run on the host on a CPU adapter (lavapipe
        // in CI), in the shaders elsewhere.
        let ctx = splattrack::gpu::shared_test_context();
        assert_eq!(
            stdout.contains("features harris"),
            !ctx.is_cpu(),
            "{stdout}"
        );
        assert_eq!(stdout.contains("IT ncc"), !ctx.is_cpu(), "{stdout}");
        assert!(!stdout.contains("under-report"), "{stdout}");
    }
    let it = d.join("it.csv");
    ok(&[
        "track",
        "--model",
        s(&f.model),
        "--sequence",
        s(&f.seq),
        "--mode",
        "it",
        "--out",
        s(&it),
    ]);
    check_tracker_csv(&it);
    assert!(partial_files(&d).is_empty());
    // Corners and matches in the shaders whatever the adapter
    // (`--feature-backend gpu`): their passes are timed, and on a CPU
    // adapter the table says which of its timestamps not to trust.
    let gpu = d.join("features_gpu.csv");
    let stdout = ok(&[
        "track",
        "--model",
        s(&f.model),
        "--sequence",
        s(&f.seq),
        "--feature-backend",
        "gpu",
        "--out",
        s(&gpu),
        "--profile",
    ]);
    check_tracker_csv(&gpu);
    let ctx = splattrack::gpu::shared_test_context();
    if ctx.has_timestamps() {
        assert!(stdout.contains("features harris"), "{stdout}");
        assert!(stdout.contains("IT ncc"), "{stdout}");
        assert_eq!(
            stdout.contains("timestamps of the Harris and NCC passes under-report"),
            ctx.is_cpu(),
            "{stdout}"
        );
    }
    // A GPU's frame loop on any adapter (`--resident on`): the frame's
    // grey levels stay on the GPU, matching and the pose check run there,
    // and a few values per feature come back instead of the view's grey
    // levels (`off`, the default on CPU adapters).
    let bytes_read = |resident: &str| {
        let out = d.join(format!("resident_{resident}.csv"));
        let stdout = ok(&[
            "track",
            "--model",
            s(&f.model),
            "--sequence",
            s(&f.seq),
            "--feature-backend",
            "gpu",
            "--resident",
            resident,
            "--out",
            s(&out),
            "--profile",
        ]);
        check_tracker_csv(&out);
        let field = |label: &str, k: usize| -> f64 {
            let line = stdout
                .lines()
                .find(|l| l.contains(label))
                .unwrap_or_else(|| panic!("no {label:?} line: {stdout}"));
            line.split_whitespace().nth(k).unwrap().parse().unwrap()
        };
        // Each readback is a submission, shared with the work before it
        // (the chains of passes go with the readbacks that end them:
        // `GpuContext::batch`); no other work is submitted alone (a gather
        // flushes the one before only while that one is still put off).
        let (readbacks, submissions) = (field("read back from the GPU", 8), field("GPU work", 2));
        assert!(
            readbacks >= 1.0 && submissions >= readbacks && submissions <= readbacks + 0.1,
            "{readbacks} readbacks, {submissions} submissions a frame: {stdout}"
        );
        // A batch's passes are recorded into one encoder
        // (`GpuContext::encoder`): about one command buffer a submission.
        let buffers = field("GPU work", 4);
        assert!(
            buffers >= submissions && buffers <= submissions + 1.0,
            "{buffers} command buffers in {submissions} submissions a frame: {stdout}"
        );
        // Passes are counted: an untimed frame records its chains of
        // stages in one pass each (`gpu::PassChain`), the profile's timer
        // one a stage; the GPU loop's chains have several stages.
        let line = stdout.lines().find(|l| l.contains("GPU work")).unwrap();
        let word = |k: usize| -> f64 {
            line.split_whitespace()
                .nth(k)
                .unwrap()
                .trim_start_matches('(')
                .parse()
                .unwrap()
        };
        let (untimed, timed) = (word(13), word(15));
        assert!(
            untimed >= 1.0 && untimed <= timed,
            "{untimed} passes, {timed} timed apart: {line}"
        );
        // (Where the adapter has timestamps: else nothing is timed apart.)
        if resident == "on" && stdout.contains("GPU passes per frame") {
            assert!(
                untimed * 2.0 < timed,
                "{untimed} passes, {timed} timed apart: {line}"
            );
        }
        // Uploads are counted, and parameters unchanged since the frame
        // before are not uploaded again (`gpu::Uniform`).
        let uploads = field("GPU work", 7);
        let line = stdout.lines().find(|l| l.contains("GPU work")).unwrap();
        let skipped: f64 = line.split_whitespace().nth(9).unwrap()[1..]
            .parse()
            .unwrap();
        assert!(
            uploads >= 1.0 && skipped > 0.0,
            "{uploads} uploads, {skipped} skipped: {line}"
        );
        field("read back from the GPU", 5)
    };
    let (on, off) = (bytes_read("on"), bytes_read("off"));
    assert!(
        on > 0.0 && on * 4.0 < off,
        "read back {on} bytes a frame resident, {off} not"
    );

    // eval: the table on stdout, the plot and the per-frame CSV.
    let plot = d.join("errors.png");
    let csv = d.join("errors.csv");
    let gt_path = f.seq.join("poses.csv");
    let table = ok(&[
        "eval",
        "--poses",
        s(&out),
        "--poses",
        s(&it),
        "--gt",
        s(&gt_path),
        "--model",
        s(&f.model),
        "--plot",
        s(&plot),
        "--csv",
        s(&csv),
    ]);
    let lines: Vec<&str> = table.lines().collect();
    for col in [
        "run", "frames", "lost", "rot mean", "rot max", "5deg/5cm", "2deg/2%",
    ] {
        assert!(lines[0].contains(col), "{table}");
    }
    let poses_row = lines
        .iter()
        .find(|l| l.starts_with("poses "))
        .expect(&table);
    let it_row = lines.iter().find(|l| l.starts_with("it ")).expect(&table);
    for row in [poses_row, it_row] {
        let c: Vec<&str> = row.split_whitespace().collect();
        assert_eq!(c[1], "8", "{row}");
    }
    let img = image::open(&plot).unwrap();
    assert!(img.width() > 200 && img.height() > 200);
    // The per-frame errors agree with errors computed here from the files.
    let gt = ground_truth();
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut l = text.lines();
    assert_eq!(
        l.next(),
        Some(
            "run,frame,rotation_deg,translation,translation_pct,lost,excluded,along_ray,across_ray"
        )
    );
    let body: Vec<Vec<&str>> = l.map(|x| x.split(',').collect()).collect();
    assert_eq!(body.len(), 2 * FRAMES);
    let diameter = splattrack::PointModel::load(&f.model).unwrap().diameter() as f64;
    for c in body.iter().filter(|c| c[0] == "poses") {
        let i: usize = c[1].parse().unwrap();
        let rot: f64 = c[2].parse().unwrap();
        let tr: f64 = c[3].parse().unwrap();
        let pct: f64 = c[4].parse().unwrap();
        let want_rot = rows[i].pose.rotation_error_deg(&gt[i]);
        let want_tr = (rows[i].pose.translation - gt[i].translation).norm();
        assert!(
            (rot - want_rot).abs() < 1e-5,
            "frame {i}: {rot} vs {want_rot}"
        );
        assert!((tr - want_tr).abs() < 1e-6, "frame {i}: {tr} vs {want_tr}");
        assert!((pct - 100.0 * want_tr / diameter).abs() < 1e-3);
    }
}

#[test]
fn bad_track_input_fails_with_one_line() {
    let f = fixture();
    let d = workdir("bad_track");
    let out = d.join("poses.csv");
    let model = s(&f.model);
    let seq = s(&f.seq);
    let o = s(&out);

    // A sequence directory that does not exist.
    let missing = d.join("no-such-sequence");
    fails(
        &[
            "track",
            "--model",
            model,
            "--sequence",
            s(&missing),
            "--out",
            o,
        ],
        &["no-such-sequence", "not a directory"],
    );

    // A sequence without frames.
    let empty = d.join("empty");
    std::fs::create_dir_all(empty.join("frames")).unwrap();
    std::fs::copy(f.seq.join("camera.json"), empty.join("camera.json")).unwrap();
    std::fs::copy(f.seq.join("init.csv"), empty.join("init.csv")).unwrap();
    fails(
        &[
            "track",
            "--model",
            model,
            "--sequence",
            s(&empty),
            "--out",
            o,
        ],
        &["frames", "no frames"],
    );

    // A corrupt model file: a header promising more than the file holds.
    let corrupt = d.join("corrupt.ply");
    std::fs::write(
        &corrupt,
        "ply\nformat ascii 1.0\nelement vertex 10\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n",
    )
    .unwrap();
    fails(
        &[
            "track",
            "--model",
            s(&corrupt),
            "--sequence",
            seq,
            "--out",
            o,
        ],
        &["corrupt.ply"],
    );
    // A Harris back end that does not exist.
    fails(
        &[
            "track",
            "--model",
            model,
            "--sequence",
            seq,
            "--out",
            o,
            "--feature-backend",
            "tpu",
        ],
        &["--feature-backend", "expected gpu, host or auto"],
    );
    fails(
        &[
            "track",
            "--model",
            model,
            "--sequence",
            seq,
            "--out",
            o,
            "--resident",
            "maybe",
        ],
        &["--resident", "auto, on, off"],
    );

    // Not a PLY at all.
    let garbage = d.join("garbage.ply");
    std::fs::write(&garbage, [0u8, 159, 146, 150, 1, 2, 3]).unwrap();
    fails(
        &[
            "track",
            "--model",
            s(&garbage),
            "--sequence",
            seq,
            "--out",
            o,
        ],
        &["garbage.ply"],
    );

    // An init file whose rotation is not a rotation.
    let init = d.join("bad_init.csv");
    std::fs::write(
        &init,
        "frame,r11,r12,r13,r21,r22,r23,r31,r32,r33,tx,ty,tz\n0,2,0,0,0,1,0,0,0,1,0,0,0.5\n",
    )
    .unwrap();
    fails(
        &[
            "track",
            "--model",
            model,
            "--sequence",
            seq,
            "--init",
            s(&init),
            "--out",
            o,
        ],
        &["bad_init.csv", "not a rotation"],
    );

    // A keyframe store built for another model: the same model with one
    // point moved.
    let mut other = splattrack::PointModel::load(&f.model).unwrap();
    other.positions[0].x += 1e-3;
    let other_path = d.join("other.ply");
    other.save_ply(&other_path).unwrap();
    fails(
        &[
            "track",
            "--model",
            s(&other_path),
            "--sequence",
            seq,
            "--keyframes",
            s(&f.store),
            "--out",
            o,
        ],
        &["store.stkf", "another model"],
    );

    // An unknown mode names the flag.
    fails(
        &[
            "track",
            "--model",
            model,
            "--sequence",
            seq,
            "--mode",
            "sideways",
            "--out",
            o,
        ],
        &["--mode", "sideways"],
    );
    // A contour setting out of its range names the flag and the range.
    fails(
        &[
            "track",
            "--model",
            model,
            "--sequence",
            seq,
            "--modalities",
            "contour",
            "--contour-sectors",
            "65",
            "--out",
            o,
        ],
        &["--contour-sectors 65", "[0, 64]"],
    );
    // A missing required flag is named too.
    fails(&["track", "--model", model, "--sequence", seq], &["--out"]);
    assert!(!out.exists(), "a failed run left {}", out.display());
}

#[test]
fn a_frame_of_the_wrong_size_stops_tracking_without_a_complete_looking_file() {
    let f = fixture();
    let d = workdir("wrong_size");
    // A copy of the sequence with frame 3 replaced by a smaller picture.
    let seq = d.join("seq");
    std::fs::create_dir_all(seq.join("frames")).unwrap();
    for name in ["camera.json", "init.csv", "poses.csv"] {
        std::fs::copy(f.seq.join(name), seq.join(name)).unwrap();
    }
    for i in 0..FRAMES {
        let name = format!("frames/{i:06}.png");
        std::fs::copy(f.seq.join(&name), seq.join(&name)).unwrap();
    }
    image::RgbImage::from_pixel(100, 80, image::Rgb([200, 10, 10]))
        .save(seq.join("frames/000003.png"))
        .unwrap();
    let out = d.join("poses.csv");
    fails(
        &[
            "track",
            "--model",
            s(&f.model),
            "--sequence",
            s(&seq),
            "--keyframes",
            s(&f.store),
            "--out",
            s(&out),
        ],
        &["000003.png", "100x80", "320x240"],
    );
    // Never a file that looks complete: at most the partial file with the
    // frames finished before the bad one.
    assert!(!out.exists());
    for p in partial_files(&d) {
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.lines().count() <= 4, "{}: {text}", p.display());
    }
}

#[test]
fn bad_eval_and_synth_input_fails_with_one_line() {
    let f = fixture();
    let d = workdir("bad_eval");
    let gt = f.seq.join("poses.csv");
    // Estimates for frames the ground truth does not have.
    let other = d.join("elsewhere.csv");
    std::fs::write(
        &other,
        "frame,r11,r12,r13,r21,r22,r23,r31,r32,r33,tx,ty,tz\n77,1,0,0,0,1,0,0,0,1,0,0,0.5\n78,1,0,0,0,1,0,0,0,1,0,0,0.5\n",
    )
    .unwrap();
    fails(
        &["eval", "--poses", s(&other), "--gt", s(&gt)],
        &["elsewhere.csv", "no frame"],
    );
    // A missing poses file.
    let missing = d.join("missing.csv");
    fails(
        &["eval", "--poses", s(&missing), "--gt", s(&gt)],
        &["missing.csv"],
    );
    let out = d.join("synth");
    fails(
        &["synth", "--object", "nope", "--out", s(&out)],
        &["nope", "unknown object"],
    );
    fails(
        &["synth", "--frames", "1", "--out", s(&out)],
        &["--frames 1", "at least 2"],
    );
    fails(
        &["synth", "--trajectory", "zigzag", "--out", s(&out)],
        &["zigzag"],
    );
    assert!(!out.join("frames").exists());
}

/// The `points:` and `diameter:` values `info` prints.
fn info_values(model: &Path) -> (usize, f64, String) {
    let out = ok(&["info", "--model", s(model)]);
    let field = |name: &str| {
        out.lines()
            .find_map(|l| l.strip_prefix(name))
            .unwrap_or_else(|| panic!("no {name} in {out}"))
            .trim()
            .to_string()
    };
    let points = field("points:").parse().unwrap();
    let diameter = field("diameter:")
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(out.contains("self-test: ok"), "{out}");
    (points, diameter, out)
}

/// The vertex count a PLY header declares, read here.
fn ply_vertex_count(path: &Path) -> usize {
    let bytes = std::fs::read(path).unwrap();
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]).into_owned();
    head.lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .unwrap()
        .trim()
        .parse()
        .unwrap()
}

#[test]
fn info_describes_shared_and_synthetic_models() {
    let Some(data) = data_common::real_data("") else {
        return;
    };
    let mut seen = 0;
    for entry in std::fs::read_dir(&data).unwrap() {
        let model = entry.unwrap().path().join("model.ply");
        if !model.is_file() {
            continue;
        }
        let (points, diameter, out) = info_values(&model);
        assert_eq!(points, ply_vertex_count(&model), "{out}");
        let m = splattrack::PointModel::load(&model).unwrap();
        assert!((diameter - m.diameter() as f64).abs() < 1e-3, "{out}");
        assert!(out.contains("colours:   from the file"), "{out}");
        seen += 1;
    }
    assert!(seen >= 2, "models in {}: {seen}", data.display());
    // The cube is 8.5 cm across: its bounding-box diagonal is sqrt(3) x that.
    let (_, d, _) = info_values(&data.join("visp_rbt_cube/model.ply"));
    assert!((d - 0.085 * 3f64.sqrt()).abs() < 1e-3, "{d}");

    // The model synth wrote: its point count, and the blob's size (the
    // mesh's bounding-box diagonal, which the samples nearly reach).
    let f = fixture();
    let (points, diameter, out) = info_values(&f.model);
    assert_eq!(points, 20_000, "{out}");
    let mesh_diag = splattrack::synth::SynthObject::blob().mesh.diameter();
    assert!(
        diameter <= mesh_diag + 1e-4 && diameter > 0.97 * mesh_diag,
        "{diameter} vs the mesh's {mesh_diag}"
    );
    for attr in ["normals:   from the file", "colours:   from the file"] {
        assert!(out.contains(attr), "{out}");
    }
}

#[test]
fn refused_estimates_are_written_with_their_stage_reason_and_scores() {
    let f = fixture();
    let d = workdir("refused");
    let truth = ground_truth();
    // Started 60 degrees off (turned about the camera's y axis), in IT
    // mode: frame 0's initial pose fails the check on appearance, and the
    // frames after it refuse whatever IT makes of it.
    let r =
        splattrack::geometry::rotation_exp(&nalgebra::Vector3::new(0.0, 60f64.to_radians(), 0.0));
    let off = Pose::new(r * truth[0].rotation, truth[0].translation).unwrap();
    let init = d.join("off.csv");
    splattrack::io::write_poses(&init, &[PoseRow::new("0", off)]).unwrap();
    let (out, refused) = (d.join("poses.csv"), d.join("refused.csv"));
    let stdout = ok(&[
        "track",
        "--model",
        s(&f.model),
        "--sequence",
        s(&f.seq),
        "--mode",
        "it",
        "--init",
        s(&init),
        "--out",
        s(&out),
        "--refused",
        s(&refused),
    ]);
    let poses = check_tracker_csv(&out);
    let text = std::fs::read_to_string(&refused).unwrap();
    assert_eq!(
        text.lines().next(),
        Some(
            "frame,r11,r12,r13,r21,r22,r23,r31,r32,r33,tx,ty,tz,stage,reason,zncc,edge_support,inliers,residual_px"
        )
    );
    eprintln!("{text}");
    let rows = read_poses(&refused).unwrap();
    assert!(
        stdout.contains(&format!("{} refused estimates in", rows.len())),
        "{stdout}"
    );
    let value = |row: &PoseRow, k: &str| {
        row.extra
            .iter()
            .find(|(name, _)| name == k)
            .map(|(_, v)| v.clone())
            .unwrap()
    };
    // Each row is a lost frame's, with a known stage and reason.
    for row in &rows {
        let i: usize = row.frame.parse().unwrap();
        assert_eq!(value(&poses[i], "status"), "lost", "{row:?}");
        row.pose.validate().unwrap();
        assert!(
            ["it", "kf", "contour", "search", "initial"].contains(&value(row, "stage").as_str()),
            "{row:?}"
        );
        assert!(!value(row, "reason").is_empty(), "{row:?}");
    }
    // Frame 0: the initial pose itself, refused by the check on
    // appearance, with the check's scores (ZNCC under 0.4).
    let first = &rows[0];
    assert_eq!(first.frame, "0");
    assert!(first.pose.rotation_error_deg(&off) < 1e-4, "{first:?}");
    assert_eq!(value(first, "stage"), "initial");
    assert_eq!(value(first, "reason"), "appearance");
    let zncc: f64 = value(first, "zncc").parse().unwrap();
    assert!(zncc < 0.4, "{first:?}");
    let edges: f64 = value(first, "edge_support").parse().unwrap();
    assert!((0.0..=1.0).contains(&edges), "{first:?}");
    // From the right pose nothing is refused: a header alone.
    let (out, refused) = (d.join("right.csv"), d.join("right_refused.csv"));
    let stdout = ok(&[
        "track",
        "--model",
        s(&f.model),
        "--sequence",
        s(&f.seq),
        "--keyframes",
        s(&f.store),
        "--out",
        s(&out),
        "--refused",
        s(&refused),
    ]);
    assert!(stdout.contains("0 refused estimates in"), "{stdout}");
    let text = std::fs::read_to_string(&refused).unwrap();
    assert_eq!(text.lines().count(), 1, "{text}");
    assert!(partial_files(&d).is_empty());
    // The refused file is an output like the others: never an input.
    fails(
        &[
            "track",
            "--model",
            s(&f.model),
            "--sequence",
            s(&f.seq),
            "--out",
            s(&d.join("x.csv")),
            "--refused",
            s(&f.model),
        ],
        &["--refused"],
    );
    let same = d.join("same.csv");
    fails(
        &[
            "track",
            "--model",
            s(&f.model),
            "--sequence",
            s(&f.seq),
            "--out",
            s(&same),
            "--refused",
            s(&same),
        ],
        &["--refused and --out name the same file"],
    );
}
