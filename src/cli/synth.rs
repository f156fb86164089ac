//! `splattrack synth [--object NAME] [--trajectory fig10|fast|turn] [--frames N]
//! [--background plain|shapes|clutter] [--object-px PX] [--exit F] ... --out DIR`.

use super::common::{Choice, choice_name};
use anyhow::{Context, bail};
use splattrack::Intrinsics;
use splattrack::synth::{Background, SynthConfig, SynthObject, Trajectory, sequence};
use std::path::{Path, PathBuf};

/// The built-in objects (`splattrack::synth::objects::OBJECT_NAMES`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Object {
    /// Organic, strong texture.
    Blob,
    /// Printed faces.
    Box,
    /// Self-occluding.
    Torus,
    /// Untextured: one plain colour, curved with two flat cuts (edges).
    Plain,
    /// Untextured box.
    Plainbox,
}

/// The trajectories (`splattrack::synth::Trajectory`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrajectoryArg {
    /// Translations then rotations, like the paper's Fig. 10.
    Fig10,
    /// All at once, ~4x faster.
    Fast,
    /// A full turn about the vertical.
    Turn,
}

/// The backgrounds (`splattrack::synth::Background`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BackgroundArg {
    /// A smooth gradient only.
    Plain,
    /// Flat rectangles and discs over a gradient.
    #[default]
    Shapes,
    /// Noise, lines, shapes and distractor objects in the object's colours.
    Clutter,
}

/// `--background`.
pub fn background_parser() -> Choice<BackgroundArg> {
    Choice::new("background")
}

/// How the scene looks beyond the object and its motion.
#[derive(clap::Args, Debug, Default)]
pub struct SceneArgs {
    /// What is behind the object.
    #[arg(long, default_value = "shapes", value_parser = background_parser())]
    pub background: BackgroundArg,
    /// Lower the background's grey-level contrast to about the object's grey.
    #[arg(long)]
    pub low_contrast: bool,
    /// The fraction (0..0.95) of the object's silhouette outside the image
    /// at the middle frame: it slides out to the right and back.
    #[arg(long, default_value_t = 0.0)]
    pub exit: f64,
    /// Distractor objects in front of the object that hide parts of it.
    #[arg(long, default_value_t = 0)]
    pub occluders: usize,
    /// The object's size in the first frame, pixels across (sets its
    /// distance; the trajectory's translations scale with it).
    #[arg(long, conflicts_with = "distance")]
    pub object_px: Option<f64>,
    /// The object's distance from the camera, metres (default 0.55).
    #[arg(long)]
    pub distance: Option<f64>,
}

/// `--object`.
pub fn object_parser() -> Choice<Object> {
    Choice::new("object")
}

/// `--trajectory`.
pub fn trajectory_parser() -> Choice<TrajectoryArg> {
    Choice::new("trajectory")
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Built-in object.
    #[arg(long, default_value = "blob", value_parser = object_parser())]
    pub object: Object,
    /// How the object moves.
    #[arg(long, default_value = "fig10", value_parser = trajectory_parser())]
    pub trajectory: TrajectoryArg,
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
    #[command(flatten)]
    pub scene: SceneArgs,
    /// The sequence directory to write (must be empty or absent).
    #[arg(long)]
    pub out: PathBuf,
    /// Write into a non-empty directory: first remove what a sequence
    /// holds there (the images of frames/ and keyframes/, their poses.csv,
    /// camera.json, init.csv, poses.csv, model.ply), so no stale frame or
    /// ground truth survives; other files are left alone.
    #[arg(long)]
    pub force: bool,
}

/// The files of a sequence directory that `synth` writes (docs/formats.md).
const SEQUENCE_FILES: [&str; 5] = [
    "camera.json",
    "init.csv",
    "poses.csv",
    "model.ply",
    "keyframes/poses.csv",
];

/// Makes `dir` ready for a new sequence: absent or empty is fine; a
/// non-empty one is refused without `force`, and with it the sequence
/// files and images there are removed first.
pub fn prepare_out(dir: &Path, force: bool) -> anyhow::Result<()> {
    let mut entries = match std::fs::read_dir(dir) {
        Ok(rd) => rd,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e).with_context(|| format!("{}: cannot read", dir.display())),
    };
    if entries.next().is_none() {
        return Ok(());
    }
    if !force {
        bail!(
            "{}: not empty (it may hold a sequence and its ground truth); use an empty directory or --force to replace the sequence there",
            dir.display()
        );
    }
    for name in SEQUENCE_FILES {
        let p = dir.join(name);
        if p.is_file() {
            std::fs::remove_file(&p).with_context(|| format!("{}: cannot remove", p.display()))?;
        }
    }
    for sub in ["frames", "keyframes"] {
        let d = dir.join(sub);
        if !d.is_dir() {
            continue;
        }
        for img in splattrack::io::sequence::list_images(&d)? {
            std::fs::remove_file(&img)
                .with_context(|| format!("{}: cannot remove", img.display()))?;
        }
    }
    Ok(())
}

/// Builds the configuration the flags describe (checked).
pub fn config(args: &Args) -> anyhow::Result<SynthConfig> {
    let trajectory = Trajectory::by_name(&choice_name(&args.trajectory))
        .context("a trajectory the library lacks")?;
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
    let sc = &args.scene;
    if !(sc.exit.is_finite() && (0.0..=0.95).contains(&sc.exit)) {
        bail!("--exit {}: must be in 0..0.95", sc.exit);
    }
    if sc.occluders > 20 {
        bail!("--occluders {}: at most 20", sc.occluders);
    }
    if let Some(d) = sc.distance
        && !(d.is_finite() && (0.05..=100.0).contains(&d))
    {
        bail!("--distance {d}: must be in 0.05..100 metres");
    }
    let short = args.width.min(args.height) as f64;
    if let Some(px) = sc.object_px
        && !(px.is_finite() && px >= 8.0 && px <= 2.0 * short)
    {
        bail!("--object-px {px}: must be in 8..{}", 2.0 * short);
    }
    let background = Background::by_name(&choice_name(&sc.background))
        .context("a background the library lacks")?;
    // Focal length scaled with the width: the same field of view (56 deg).
    let f = 600.0 * args.width as f64 / 640.0;
    let defaults = SynthConfig::default();
    let cfg = SynthConfig {
        object: choice_name(&args.object),
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
        background,
        low_contrast: sc.low_contrast,
        exit: sc.exit,
        occluders: sc.occluders,
        distance: sc.distance.unwrap_or(defaults.distance),
        ..defaults
    };
    Ok(match sc.object_px {
        Some(px) => {
            let object =
                SynthObject::by_name(&cfg.object).context("an object the library lacks")?;
            cfg.with_object_px(&object, px)
        }
        None => cfg,
    })
}

/// Writes the sequence with a progress bar.
pub fn write(
    cfg: &SynthConfig,
    dir: &Path,
    points: usize,
) -> anyhow::Result<sequence::SequenceSummary> {
    let progress = super::progress::bars("synth ", 1);
    Ok(sequence::write_sequence(cfg, dir, points, Some(&progress))?)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let cfg = config(&args)?;
    prepare_out(&args.out, args.force)?;
    let s = write(&cfg, &args.out, args.points)?;
    println!(
        "wrote {} ({} object, {} trajectory, {} background, {:.3} m away): {} frames, {} keyframes, model.ply with {} points (diameter {:.3} m)",
        s.dir.display(),
        cfg.object,
        cfg.trajectory.name(),
        cfg.background.name(),
        cfg.distance,
        s.frames,
        s.keyframes,
        s.model_points,
        s.diameter
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    #[test]
    fn flag_values_are_the_library_names() {
        let objects: Vec<String> = Object::value_variants().iter().map(choice_name).collect();
        assert_eq!(objects, splattrack::synth::objects::OBJECT_NAMES);
        let trajectories: Vec<String> = TrajectoryArg::value_variants()
            .iter()
            .map(choice_name)
            .collect();
        assert_eq!(trajectories, Trajectory::NAMES);
        let backgrounds: Vec<String> = BackgroundArg::value_variants()
            .iter()
            .map(choice_name)
            .collect();
        assert_eq!(backgrounds, Background::NAMES);
        assert_eq!(
            choice_name(&BackgroundArg::default()),
            SynthConfig::default().background.name()
        );
    }
}
