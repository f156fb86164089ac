//! `splattrack demo [--out DIR]`: the main job on a built-in default.
//! Synthesises a sequence (a textured organic shape along a Fig. 10-style
//! trajectory), builds its keyframes, tracks it in the three modes, prints
//! the error table and writes the plot and overlays.

use super::synth;
use anyhow::Context;
use splattrack::app::{TrackInputs, TrackRun};
use splattrack::eval::{self, EvalOptions};
use splattrack::splat::Backend;
use splattrack::tracker::{Mode, TrackerConfig};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Where to put everything.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Built-in object.
    #[arg(long, default_value = "blob", value_parser = synth::object_parser())]
    pub object: synth::Object,
    /// How the object moves.
    #[arg(long, default_value = "fig10", value_parser = synth::trajectory_parser())]
    pub trajectory: synth::TrajectoryArg,
    #[arg(long, default_value_t = 100)]
    pub frames: usize,
    /// Image width and height (the focal length follows the width).
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// The splatter: render, compute or auto (see `track --help`).
    #[arg(long, default_value = "auto")]
    pub splatter: Backend,
}

pub fn run(args: Args, target: &super::common::Target) -> anyhow::Result<()> {
    let ctx = super::common::device(target)?;
    println!("splattrack demo on {}", ctx.describe());
    let seq_dir = args.out.join("sequence");
    let synth_args = synth::Args {
        object: args.object,
        trajectory: args.trajectory,
        layout: None,
        objects: Vec::new(),
        frames: Some(args.frames),
        width: args.width,
        height: args.height,
        points: 60_000,
        noise: 0.01,
        seed: 1,
        scene: synth::SceneArgs::default(),
        out: seq_dir.clone(),
        force: true,
    };
    let cfg = synth::config(&synth_args)?;
    // The demo's own sequence folder: regenerated on each run.
    synth::prepare_out(&seq_dir, true)?;
    let summary = synth::write(&cfg, &seq_dir, synth_args.points)?;
    println!(
        "1. synthesised {} frames of the {} object along the {} trajectory: {}",
        summary.frames,
        cfg.object,
        cfg.trajectory.name(),
        seq_dir.display()
    );
    let model = seq_dir.join("model.ply");
    let inputs = TrackInputs::load(
        &ctx,
        &model,
        &super::common::model_options(),
        &seq_dir,
        None,
        None,
    )?;
    println!(
        "2. built {} keyframes from {}",
        inputs.keyframes.as_ref().map_or(0, |k| k.keyframes.len()),
        seq_dir.join("keyframes").display()
    );
    let gt = splattrack::io::read_poses(&seq_dir.join("poses.csv"))?;
    let opts = EvalOptions {
        diameter: Some(inputs.model.diameter() as f64),
        ..Default::default()
    };
    let mut evals = Vec::new();
    let mut timings = Vec::new();
    for mode in Mode::ALL {
        let name = mode.name().replace('+', "");
        let out = args.out.join(format!("poses_{name}.csv"));
        let overlay = args.out.join(format!("overlay_{name}"));
        let config = TrackerConfig {
            mode,
            splatter: args.splatter,
            ..Default::default()
        };
        let label = format!("3. track {:>5} ", mode.name());
        let mut run = TrackRun::new(&ctx, &inputs, config)
            .poses(&out)
            .progress(Some(super::progress::bars(label, 1)));
        if mode == Mode::KfIt {
            run = run.overlays(&overlay, (args.frames / 6).max(1));
        }
        let stats = run.run(|_, _| {})?;
        let est = splattrack::io::read_poses(&out)?;
        evals.push(
            eval::evaluate(mode.name(), &est, &gt, &opts)
                .with_context(|| format!("evaluating {}", out.display()))?,
        );
        timings.push(stats);
    }
    println!(
        "3. tracked the sequence in the three modes: {}",
        args.out.join("poses_{it,kf,kfit}.csv").display()
    );
    println!("4. errors against the ground truth:");
    let summaries: Vec<_> = evals.iter().map(|e| e.summary.clone()).collect();
    print!("{}", eval::table(&summaries, "m"));
    for (m, t) in Mode::ALL.iter().zip(&timings) {
        println!(
            "   {:<6} {:.1} ms per frame (median {:.1})",
            m.name(),
            t.mean.total,
            t.median_ms
        );
    }
    let plot = args.out.join("errors.png");
    eval::error_plot(
        &evals,
        &format!("{} / {}", cfg.object, cfg.trajectory.name()),
    )
    .save(&plot)
    .with_context(|| format!("{}: cannot write", plot.display()))?;
    println!(
        "5. wrote the error plot {} and overlays in {}",
        plot.display(),
        args.out.join("overlay_kfit").display()
    );
    Ok(())
}
