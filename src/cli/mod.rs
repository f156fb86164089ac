//! Subcommands, one file each (what they share in [`common`]); this file
//! holds the global flags and the dispatch. The work is the library's ([`splattrack::app`]
//! for tracking); the commands parse flags, print and draw progress.

mod common;
mod demo;
mod eval;
mod features;
mod info;
mod init;
mod keyframes;
mod model;
mod progress;
mod render;
mod synth;
mod track;

use clap::{Parser, Subcommand};

pub use common::init_logging;

#[derive(Parser, Debug)]
#[command(
    name = "splattrack",
    version,
    about = "Track a rigid object's 6-DoF pose in video from a point-based 3D model (GPU surface splatting)"
)]
pub struct Cli {
    /// GPU adapter: auto, discrete, integrated, cpu, or part of its name
    /// (default: $SPLATTRACK_ADAPTER, else auto).
    #[arg(long, global = true)]
    pub adapter: Option<String>,
    /// Where to run: gpu (a GPU adapter, lavapipe included), cpu (the
    /// host's cores, no GPU driver needed) or auto (a GPU adapter when one
    /// opens, else cpu) (default: $SPLATTRACK_DEVICE, else auto).
    #[arg(long, global = true, value_name = "auto|gpu|cpu")]
    pub compute: Option<String>,
    /// More log output (-v: info, -vv: debug).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// The main job on a built-in default: synthesise a sequence, track it in
    /// each mode, evaluate, and write the plot and overlays.
    Demo(demo::Args),
    /// The adapter in use; with a model: point count, bounds, diameter, and
    /// which attributes were present or estimated.
    Info(info::Args),
    /// One splatted view of a point model: a picture (.png; motion: a
    /// motion-field visualisation) or a raw float image (.npy).
    Render(render::Args),
    /// Harris corners of one image, or mutual NCC matches between two.
    Features(features::Args),
    /// The pose of one frame from at least 4 known model points, given in a
    /// CSV or clicked in a window; writes init.csv and an overlay.
    Init(init::Args),
    /// Build a keyframe store (per-point colours from keyframe images) once
    /// per object.
    Keyframes(keyframes::Args),
    /// Sample a mesh (OBJ, STL, PLY with faces) into the point model
    /// `track` makes of it, and write it (PLY).
    Model(model::Args),
    /// Track an object through a sequence; writes one pose per frame.
    Track(Box<track::Args>),
    /// Errors of tracked poses against ground truth: table, success rates, plot.
    Eval(eval::Args),
    /// Write a synthetic sequence with exact ground truth.
    Synth(synth::Args),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    let target = common::Target {
        adapter: cli.adapter,
        compute: cli.compute,
    };
    match cli.command {
        Command::Demo(a) => demo::run(a, &target),
        Command::Info(a) => info::run(a, &target),
        Command::Render(a) => render::run(a, &target),
        Command::Features(a) => features::run(a, &target),
        Command::Init(a) => init::run(a, &target),
        Command::Keyframes(a) => keyframes::run(a, &target),
        Command::Model(a) => model::run(a),
        Command::Track(a) => track::run(*a, &target),
        Command::Eval(a) => eval::run(a),
        Command::Synth(a) => synth::run(a),
    }
}
