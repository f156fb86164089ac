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
//! store: loaded when the file exists, else built from
//! `SEQUENCE_DIR/keyframes` and saved there, so the next run skips the
//! build. The GPU adapter comes from `$SPLATTRACK_ADAPTER` (`cpu` for
//! lavapipe), as for the command line.

use splattrack::geometry::Undistorter;
use splattrack::gpu::{AdapterChoice, GpuContext};
use splattrack::io::{Sequence, read_poses};
use splattrack::keyframes::{KeyframeConfig, KeyframeStore, load_keyframe_images};
use splattrack::splat::Splatter;
use splattrack::tracker::{Mode, Tracker, TrackerConfig};
use splattrack::{Intrinsics, PointModel};
use std::error::Error;
use std::path::{Path, PathBuf};
use std::sync::Arc;

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
    let ctx = Arc::new(GpuContext::new(&AdapterChoice::from_env()?)?);
    println!("adapter: {}", ctx.describe());

    // 2. The point model (normals and radii are estimated if the PLY lacks
    //    them) and the sequence: camera.json, frames/, init.csv.
    let model = PointModel::load(model_path)?;
    let seq = Sequence::open(seq_dir)?;
    // The tracker wants undistorted frames and the matching pinhole camera.
    let undistort = seq
        .camera
        .has_distortion()
        .then(|| Undistorter::new(&seq.camera));
    let cam = seq.camera.undistorted();
    let initial = read_poses(&seq.init_path())?[0].pose;

    // 3. Keyframes: images of the object at known poses, turned into
    //    per-point colours once per object.
    let keyframes = keyframe_store(&ctx, &model, &seq, undistort.as_ref(), store.as_deref())?;

    // 4. The tracker, in the paper's hybrid mode (IT, then KF).
    let config = TrackerConfig {
        mode: Mode::KfIt,
        ..Default::default()
    };
    let mut tracker = Tracker::new(ctx.clone(), model, cam, keyframes, config, initial)?;

    // Ground truth, when the sequence has it, to print the error as we go.
    let gt = match seq.ground_truth_path() {
        Some(p) => Some(read_poses(&p)?),
        None => None,
    };

    // 5. Feed the frames in order; each call returns the pose, the inlier
    //    count, the residual and whether the track holds.
    let n = limit.unwrap_or(usize::MAX).min(seq.frames.len());
    println!("frame  status     inliers  residual_px  tx        ty        tz        rot_err_deg");
    for (i, path) in seq.frames.iter().take(n).enumerate() {
        let mut frame = image::open(path)
            .map_err(|e| format!("{}: {e}", path.display()))?
            .to_rgb8();
        if let Some(u) = &undistort {
            frame = u.apply(&frame)?;
        }
        let r = tracker
            .track(&frame)
            .map_err(|e| format!("{}: {e}", path.display()))?;
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
    }
    Ok(())
}

/// Loads the store at `path` when it exists (refusing one built for another
/// model), else builds it from the sequence's keyframes/ and saves it there.
/// `None` when there is neither: the tracker then textures the novel views
/// with the model's own colours, if it has any.
fn keyframe_store(
    ctx: &GpuContext,
    model: &PointModel,
    seq: &Sequence,
    undistort: Option<&Undistorter>,
    path: Option<&Path>,
) -> Result<Option<KeyframeStore>> {
    if let Some(p) = path.filter(|p| p.is_file()) {
        let store = KeyframeStore::load(p)?;
        store.check_model(model, p)?;
        println!(
            "keyframes: {} loaded from {}",
            store.keyframes.len(),
            p.display()
        );
        return Ok(Some(store));
    }
    let Some(dir) = seq.keyframes_dir() else {
        return Ok(None);
    };
    let rows = read_poses(&dir.join("poses.csv"))?;
    let mut images = load_keyframe_images(&dir, &rows, &seq.camera)?;
    if let Some(u) = undistort {
        for (_, img, _) in &mut images {
            *img = u.apply(img)?;
        }
    }
    let cam: Intrinsics = seq.camera.undistorted();
    let splatter = Splatter::new(ctx)?;
    let store = KeyframeStore::build(
        ctx,
        &splatter,
        model,
        &cam,
        &images,
        &KeyframeConfig::default(),
    )?;
    for k in &store.keyframes {
        println!(
            "keyframe {}: {} of {} points visible",
            k.name,
            k.visible_count(),
            model.len()
        );
    }
    if let Some(p) = path {
        store.save(p)?;
        println!("keyframes: saved to {}", p.display());
    }
    Ok(Some(store))
}
