//! Subcommands, one file each; this file holds the shared flags and the
//! dispatch.

mod features;
mod info;

use clap::{Parser, Subcommand};
use splattrack::gpu::{AdapterChoice, GpuContext};

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
    /// The adapter in use; with a model: point count, bounds, diameter, and
    /// which attributes were present or estimated.
    Info(info::Args),
    /// Harris corners of one image, or mutual NCC matches between two.
    Features(features::Args),
}

/// A minimal stderr logger: warnings always, more with -v.
pub fn init_logging(verbose: u8) {
    struct Stderr;
    impl log::Log for Stderr {
        fn enabled(&self, m: &log::Metadata) -> bool {
            m.target().starts_with("splattrack") && m.level() <= log::max_level()
        }
        fn log(&self, r: &log::Record) {
            if self.enabled(r.metadata()) {
                eprintln!("{}: {}", r.level().as_str().to_ascii_lowercase(), r.args());
            }
        }
        fn flush(&self) {}
    }
    static LOGGER: Stderr = Stderr;
    let _ = log::set_logger(&LOGGER);
    log::set_max_level(match verbose {
        0 => log::LevelFilter::Warn,
        1 => log::LevelFilter::Info,
        _ => log::LevelFilter::Debug,
    });
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
        Command::Info(a) => info::run(a, &cli.adapter),
        Command::Features(a) => features::run(a, &cli.adapter),
    }
}
