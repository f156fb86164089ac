//! Embedding splattrack: track an object through a sequence directory with
//! the library API, the way `splattrack track` does, in one page.
//!
//! ```sh
//! cargo run --release --example track_sequence -- MODEL.ply SEQUENCE_DIR [N] [STORE.stkf]
//! cargo run --release --example track_sequence -- \
//!     ../shared/data/visp_rbt_cube/model.ply ../shared/data/visp_rbt_cube 10
//! ```
//!
//! `N` limits the run to the first N frames. `STORE.stkf` is a keyframe
//! store: loaded when the file exists and was built for this model, else
//! built from `SEQUENCE_DIR/keyframes` and saved there, so the next run
//! skips the build. The GPU adapter comes from `$SPLATTRACK_ADAPTER` (`cpu` for
//! lavapipe), as for the command line.

use splattrack::PointModel;
use splattrack::app::{
    KeyframeOrigin, TrackInputs, TrackRun, build_keyframes, load_keyframes, load_or_build_keyframes,
};
use splattrack::gpu::{AdapterChoice, GpuContext};
use splattrack::io::{Sequence, read_poses};
use splattrack::tracker::{Mode, TrackerConfig};
use std::error::Error;
use std::path::{Path, PathBuf};

type Result<T> = std::result::Result<T, Box<dyn Error>>;

fn main() -> std::process::ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if !(2..=4).contains(&args.len()) {
        eprintln!("usage: track_sequence MODEL.ply SEQUENCE_DIR [N] [STORE.stkf]");
        return std::process::ExitCode::from(2);
    }
    let limit = match args.get(2).map(|n| n.parse::<usize>()) {
        None => None,
        Some(Ok(n)) => Some(n),
        Some(Err(e)) => {
            eprintln!("N = {:?}: {e}", args[2]);
            return std::process::ExitCode::from(2);
        }
    };
    match run(
        Path::new(&args[0]),
        Path::new(&args[1]),
        limit,
        args.get(3).map(PathBuf::from),
    ) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // Every error of the crate names the file and the problem.
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(
    model_path: &Path,
    seq_dir: &Path,
    limit: Option<usize>,
    store: Option<PathBuf>,
) -> Result<()> {
    // 1. The GPU: one context for everything (splatting, Harris, NCC).
    let ctx = GpuContext::new(&AdapterChoice::from_env()?)?;
    println!("adapter: {}", ctx.describe());

    // 2. The point model (normals and radii are estimated if the PLY lacks
    //    them) and the sequence: camera.json, frames/, init.csv. The
    //    sequence yields its frames undistorted, for the camera
    //    `tracking_camera()`.
    let model = PointModel::load(model_path)?;
    let sequence = Sequence::open(seq_dir)?;
    let init = read_poses(&sequence.init_path())?[0].pose;

    // 3. Keyframes: images of the object at known poses, turned into
    //    per-point colours once per object, and cached in STORE.stkf.
    //    Without any, the tracker textures the novel views with the
    //    model's own colours, if it has some.
    let cam = sequence.camera;
    let keyframes = match (store.as_deref(), sequence.keyframes_dir()) {
        (Some(cache), Some(dir)) => {
            let (store, origin) = load_or_build_keyframes(&ctx, &model, &cam, &dir, cache)?;
            let how = match origin {
                KeyframeOrigin::Loaded => "loaded from",
                KeyframeOrigin::Built => "built and saved to",
            };
            println!(
                "keyframes: {} {how} {}",
                store.keyframes.len(),
                cache.display()
            );
            Some(store)
        }
        (Some(file), None) => Some(load_keyframes(&ctx, &model, &cam, file)?),
        (None, Some(dir)) => Some(build_keyframes(&ctx, &model, &cam, &dir)?),
        (None, None) => None,
    };
    let inputs = TrackInputs {
        model: std::sync::Arc::new(model),
        camera: sequence.camera,
        camera_path: sequence.camera_path.clone(),
        sequence: Some(sequence),
        init: Some(init),
        keyframes: keyframes.map(std::sync::Arc::new),
    };

    // Ground truth, when the sequence has it, to print the error as we go.
    let gt = match inputs.sequence.as_ref().and_then(|s| s.ground_truth_path()) {
        Some(p) => Some(read_poses(&p)?),
        None => None,
    };

    // 4. The tracker, in the paper's hybrid mode (IT, then KF), over the
    //    frames in order; each frame's result is the pose, the inlier
    //    count, the residual and whether the track holds.
    let config = TrackerConfig {
        mode: Mode::KfIt,
        ..Default::default()
    };
    println!("frame  status     inliers  residual_px  tx        ty        tz        rot_err_deg");
    TrackRun::new(&ctx, &inputs, config)
        .limit(limit)
        .run(|frame, r| {
            let i = frame.index;
            let t = r.pose.translation;
            let err = gt
                .as_ref()
                .and_then(|g| g.get(i))
                .map_or("-".to_string(), |g| {
                    format!("{:.2}", r.pose.rotation_error_deg(&g.pose))
                });
            println!(
                "{i:>5}  {:<9}  {:>7}  {:>11.3}  {:>8.4}  {:>8.4}  {:>8.4}  {err}",
                r.status.name(),
                r.inliers,
                r.residual_px,
                t.x,
                t.y,
                t.z,
            );
            if let Some(reason) = &r.reason {
                println!("       ({reason})");
            }
        })?;
    Ok(())
}
