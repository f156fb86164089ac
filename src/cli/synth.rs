//! `splattrack synth [--object NAME] [--trajectory fig10|fast|turn] [--frames N] --out DIR`.

use anyhow::bail;
use indicatif::{ProgressBar, ProgressStyle};
use splattrack::Intrinsics;
use splattrack::progress::{ProgressEvent, ProgressFn};
use splattrack::synth::{SynthConfig, Trajectory, objects::OBJECT_NAMES, sequence};
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Built-in object: blob (organic, strong texture), box (printed faces),
    /// torus (self-occluding).
    #[arg(long, default_value = "blob")]
    pub object: String,
    /// fig10 (translations then rotations, like the paper's Fig. 10), fast
    /// (all at once, ~4x faster) or turn (a full turn about the vertical).
    #[arg(long, default_value = "fig10")]
    pub trajectory: String,
    #[arg(long, default_value_t = 120)]
    pub frames: usize,
    /// Image width and height.
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// Points sampled from the mesh for model.ply.
    #[arg(long, default_value_t = 100_000)]
    pub points: usize,
    /// Sensor noise (standard deviation, 0..1 intensities).
    #[arg(long, default_value_t = 0.01)]
    pub noise: f64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The sequence directory to write.
    #[arg(long)]
    pub out: PathBuf,
}

/// Builds the configuration the flags describe (checked).
pub fn config(args: &Args) -> anyhow::Result<SynthConfig> {
    if !OBJECT_NAMES.contains(&args.object.as_str()) {
        bail!(
            "unknown object {:?} (built-in objects: {})",
            args.object,
            OBJECT_NAMES.join(", ")
        );
    }
    let Some(trajectory) = Trajectory::by_name(&args.trajectory) else {
        bail!(
            "unknown trajectory {:?} (use {})",
            args.trajectory,
            Trajectory::NAMES.join(", ")
        );
    };
    if args.frames < 2 {
        bail!(
            "--frames {}: a sequence needs at least 2 frames",
            args.frames
        );
    }
    if !(16..=4096).contains(&args.width) || !(16..=4096).contains(&args.height) {
        bail!(
            "image size {}x{}: each side must be 16..4096",
            args.width,
            args.height
        );
    }
    if !(args.noise.is_finite() && (0.0..=0.5).contains(&args.noise)) {
        bail!("--noise {}: must be in 0..0.5", args.noise);
    }
    if args.points < 100 {
        bail!(
            "--points {}: too few to model the surface (at least 100)",
            args.points
        );
    }
    // Focal length scaled with the width: the same field of view (56 deg).
    let f = 600.0 * args.width as f64 / 640.0;
    Ok(SynthConfig {
        object: args.object.clone(),
        trajectory,
        frames: args.frames,
        camera: Intrinsics::new(
            args.width,
            args.height,
            f,
            f,
            (args.width as f64 - 1.0) / 2.0,
            (args.height as f64 - 1.0) / 2.0,
        ),
        noise: args.noise,
        seed: args.seed,
        ..Default::default()
    })
}

/// Writes the sequence with a progress bar.
pub fn write(
    cfg: &SynthConfig,
    dir: &Path,
    points: usize,
) -> anyhow::Result<sequence::SequenceSummary> {
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template("synth {bar:40} {pos}/{len} images [{elapsed} < {eta}]")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let drawn = bar.clone();
    let progress: ProgressFn = Arc::new(move |e: ProgressEvent| {
        drawn.set_length(e.total);
        drawn.set_position(e.done);
    });
    let s = sequence::write_sequence(cfg, dir, points, Some(&progress))?;
    bar.finish_and_clear();
    Ok(s)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let cfg = config(&args)?;
    let s = write(&cfg, &args.out, args.points)?;
    println!(
        "wrote {} ({} object, {} trajectory): {} frames, {} keyframes, model.ply with {} points (diameter {:.3} m)",
        s.dir.display(),
        cfg.object,
        cfg.trajectory.name(),
        s.frames,
        s.keyframes,
        s.model_points,
        s.diameter
    );
    Ok(())
}
