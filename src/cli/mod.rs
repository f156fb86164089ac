//! Subcommands, one file each; this file holds the shared flags, the
//! logger and the dispatch. The work is the library's ([`splattrack::app`]
//! for tracking); the commands parse flags, print and draw progress.

mod demo;
mod eval;
mod features;
mod info;
mod keyframes;
mod progress;
mod render;
mod synth;
mod track;

use clap::builder::{PossibleValue, TypedValueParser};
use clap::{Parser, Subcommand, ValueEnum};
use splattrack::PointModel;
use splattrack::gpu::{AdapterChoice, GpuContext};
use splattrack::model::LoadOptions;
use std::io::Write;
use std::marker::PhantomData;

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
    /// Build a keyframe store (per-point colours from keyframe images) once
    /// per object.
    Keyframes(keyframes::Args),
    /// Track an object through a sequence; writes one pose per frame.
    Track(Box<track::Args>),
    /// Errors of tracked poses against ground truth: table, success rates, plot.
    Eval(eval::Args),
    /// Write a synthetic sequence with exact ground truth.
    Synth(synth::Args),
}

/// The logger: `RUST_LOG` when set (env_logger's syntax), else warnings
/// from this crate and errors from others, `-v` this crate's info, `-vv`
/// debug from every crate (wgpu and naga included). One line a message:
/// `level: message`, other crates' messages naming their module.
pub fn init_logging(verbose: u8) {
    let filters = match std::env::var("RUST_LOG") {
        Ok(s) if !s.trim().is_empty() => s,
        _ => match verbose {
            0 => "error,splattrack=warn",
            1 => "error,splattrack=info",
            _ => "debug",
        }
        .to_string(),
    };
    env_logger::Builder::new()
        .parse_filters(&filters)
        .format(|f, r| {
            let level = r.level().as_str().to_ascii_lowercase();
            if r.target().starts_with("splattrack") {
                writeln!(f, "{level}: {}", r.args())
            } else {
                writeln!(f, "{level}: {}: {}", r.target(), r.args())
            }
        })
        .target(env_logger::Target::Stderr)
        .init();
}

/// A parser for an enumerated flag ([`ValueEnum`]: its values listed in
/// `--help`) that refuses a bad value in one line naming it and the
/// choices: `unknown NOUN "x" (use a, b, c)`.
pub struct Choice<E> {
    noun: &'static str,
    values: PhantomData<fn() -> E>,
}

impl<E> Choice<E> {
    pub fn new(noun: &'static str) -> Self {
        Self {
            noun,
            values: PhantomData,
        }
    }
}

impl<E> Clone for Choice<E> {
    fn clone(&self) -> Self {
        Self::new(self.noun)
    }
}

impl<E: ValueEnum + Clone + Send + Sync + 'static> TypedValueParser for Choice<E> {
    type Value = E;

    fn parse_ref(
        &self,
        _cmd: &clap::Command,
        _arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<E, clap::Error> {
        let s = value.to_string_lossy();
        E::from_str(&s, false).map_err(|_| {
            let names: Vec<String> = E::value_variants()
                .iter()
                .filter_map(|v| v.to_possible_value())
                .map(|p| p.get_name().to_owned())
                .collect();
            clap::Error::raw(
                clap::error::ErrorKind::InvalidValue,
                format!("unknown {} {s:?} (use {})\n", self.noun, names.join(", ")),
            )
        })
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(
            E::value_variants()
                .iter()
                .filter_map(ValueEnum::to_possible_value),
        ))
    }
}

/// The name a [`ValueEnum`] value has on the command line.
pub fn choice_name<E: ValueEnum>(v: &E) -> String {
    v.to_possible_value()
        .map(|p| p.get_name().to_owned())
        .unwrap_or_default()
}

/// The GPU context for `--adapter` (or the environment).
pub fn gpu(adapter: &Option<String>) -> anyhow::Result<GpuContext> {
    let choice = match adapter {
        Some(a) => a.parse()?,
        None => AdapterChoice::from_env()?,
    };
    Ok(GpuContext::new(&choice)?)
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Demo(a) => demo::run(a, &cli.adapter),
        Command::Info(a) => info::run(a, &cli.adapter),
        Command::Render(a) => render::run(a, &cli.adapter),
        Command::Features(a) => features::run(a, &cli.adapter),
        Command::Keyframes(a) => keyframes::run(a, &cli.adapter),
        Command::Track(a) => track::run(*a, &cli.adapter),
        Command::Eval(a) => eval::run(a),
        Command::Synth(a) => synth::run(a),
    }
}

/// How the commands load point models: with progress bars for clouds large
/// enough to take a while.
pub fn model_options() -> LoadOptions {
    LoadOptions {
        progress: Some(progress::bars("", 200_000)),
        ..Default::default()
    }
}

/// Loads a point model with [`model_options`].
pub fn load_model(path: &std::path::Path) -> anyhow::Result<PointModel> {
    Ok(PointModel::load_with(path, &model_options())?)
}
