//! `splattrack synth [--object NAME] [--trajectory fig10|fast|turn] [--frames N]
//! [--background plain|shapes|clutter] [--object-px PX] [--exit F] ... --out DIR`,
//! or with `--scene cross|hide|mixed|cross3 [--objects A,B]` a sequence of
//! several objects.

use super::common::{Choice, choice_name};
use anyhow::{Context, bail};
use splattrack::Intrinsics;
use splattrack::synth::{
    Background, Layout, MultiConfig, SynthConfig, SynthObject, Trajectory, sequence,
};
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

/// The scenes of several objects (`splattrack::synth::Layout`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayoutArg {
    /// Two objects cross; the nearer hides about half of the farther.
    Cross,
    /// The nearer hides the farther wholly for a stretch.
    Hide,
    /// A textured and an untextured object cross (at most ~40% hidden).
    Mixed,
    /// Three objects at three depths cross.
    Cross3,
}

/// `--scene`.
pub fn layout_parser() -> Choice<LayoutArg> {
    Choice::new("scene")
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
    /// A sequence of several objects that cross and hide each other,
    /// with visibility.csv and a folder per object (docs/formats.md).
    #[arg(
        long = "scene",
        value_parser = layout_parser(),
        conflicts_with_all = ["object", "trajectory", "exit", "occluders", "object_px", "distance", "low_contrast"]
    )]
    pub layout: Option<LayoutArg>,
    /// The scene's built-in objects, farthest first, comma-separated
    /// (default: blob,box for cross; box,blob for hide; blob,plain for
    /// mixed; blob,torus,box for cross3).
    #[arg(long, value_delimiter = ',', requires = "layout", value_parser = object_parser())]
    pub objects: Vec<Object>,
    /// Number of frames (default 120; 90 with --scene).
    #[arg(long)]
    pub frames: Option<usize>,
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
    /// camera.json, init.csv, poses.csv, visibility.csv, model.ply,
    /// mesh.obj, and in each objects/NAME/ its model, mesh, keyframe images
    /// and their poses.csv), so no stale frame or ground truth survives;
    /// other files are left alone.
    #[arg(long)]
    pub force: bool,
}

/// The files of a sequence directory that `synth` writes (docs/formats.md).
const SEQUENCE_FILES: [&str; 7] = [
    "camera.json",
    "init.csv",
    "poses.csv",
    "model.ply",
    "mesh.obj",
    "keyframes/poses.csv",
    "visibility.csv",
];

/// The files of an object's folder in a sequence of several objects.
const OBJECT_FILES: [&str; 3] = ["model.ply", "mesh.obj", "keyframes/poses.csv"];

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
    let mut image_dirs = vec![dir.join("frames"), dir.join("keyframes")];
    let objects = dir.join("objects");
    if objects.is_dir() {
        let entries = std::fs::read_dir(&objects)
            .with_context(|| format!("{}: cannot read", objects.display()))?;
        for entry in entries {
            let obj = entry
                .with_context(|| format!("{}: cannot read", objects.display()))?
                .path();
            for name in OBJECT_FILES {
                let p = obj.join(name);
                if p.is_file() {
                    std::fs::remove_file(&p)
                        .with_context(|| format!("{}: cannot remove", p.display()))?;
                }
            }
            image_dirs.push(obj.join("keyframes"));
        }
    }
    for d in image_dirs {
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

/// Checks the flags both kinds of sequence share: the frame count (or
/// `default_frames`) and the camera they describe.
fn common(args: &Args, default_frames: usize) -> anyhow::Result<(usize, Intrinsics)> {
    let frames = args.frames.unwrap_or(default_frames);
    if frames < 2 {
        bail!("--frames {frames}: a sequence needs at least 2 frames");
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
    let camera = Intrinsics::new(
        args.width,
        args.height,
        f,
        f,
        (args.width as f64 - 1.0) / 2.0,
        (args.height as f64 - 1.0) / 2.0,
    );
    Ok((frames, camera))
}

/// The configuration of a sequence of several objects the flags describe
/// (checked), or `None` without `--scene`.
pub fn multi_config(args: &Args) -> anyhow::Result<Option<MultiConfig>> {
    let Some(layout) = args.layout else {
        return Ok(None);
    };
    let layout = Layout::by_name(&choice_name(&layout)).context("a scene the library lacks")?;
    let defaults = MultiConfig::default();
    let (frames, camera) = common(args, defaults.frames)?;
    if !args.objects.is_empty() && args.objects.len() != layout.object_count() {
        bail!(
            "--objects: scene {} takes {} objects, got {}",
            layout.name(),
            layout.object_count(),
            args.objects.len()
        );
    }
    let background = Background::by_name(&choice_name(&args.scene.background))
        .context("a background the library lacks")?;
    Ok(Some(MultiConfig {
        layout,
        objects: args.objects.iter().map(choice_name).collect(),
        frames,
        camera,
        noise: args.noise,
        seed: args.seed,
        background,
        ..defaults
    }))
}

/// Builds the configuration the flags describe (checked).
pub fn config(args: &Args) -> anyhow::Result<SynthConfig> {
    let trajectory = Trajectory::by_name(&choice_name(&args.trajectory))
        .context("a trajectory the library lacks")?;
    let (frames, camera) = common(args, SynthConfig::default().frames)?;
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
    let defaults = SynthConfig::default();
    let cfg = SynthConfig {
        object: choice_name(&args.object),
        trajectory,
        frames,
        camera,
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

/// Writes the sequence of several objects with a progress bar and says
/// what each object's occlusion came to.
fn run_multi(args: &Args, cfg: &MultiConfig) -> anyhow::Result<()> {
    prepare_out(&args.out, args.force)?;
    let progress = super::progress::bars("synth ", 1);
    let s = sequence::write_multi_sequence(cfg, &args.out, args.points, Some(&progress))?;
    println!(
        "wrote {} ({} scene, {} background): {} frames, {} objects, {} keyframes each, models with {} points",
        s.dir.display(),
        cfg.layout.name(),
        cfg.background.name(),
        s.frames,
        s.names.len(),
        s.keyframes,
        s.model_points
    );
    for (k, name) in s.names.iter().enumerate() {
        println!(
            "  {name}: {:.0} px across, at most {:.0}% hidden, {} frames wholly hidden",
            s.sizes_px[k],
            100.0 * s.peak_hidden(k),
            s.frames_hidden(k)
        );
    }
    Ok(())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(cfg) = multi_config(&args)? {
        return run_multi(&args, &cfg);
    }
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
        let layouts: Vec<String> = LayoutArg::value_variants()
            .iter()
            .map(choice_name)
            .collect();
        assert_eq!(layouts, Layout::NAMES);
        assert_eq!(
            choice_name(&BackgroundArg::default()),
            SynthConfig::default().background.name()
        );
    }
}
