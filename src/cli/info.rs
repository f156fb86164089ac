//! `splattrack info [--model M.ply]`.

use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A point model (PLY) to describe.
    #[arg(long)]
    pub model: Option<PathBuf>,
}

pub fn run(args: Args, adapter: &Option<String>) -> anyhow::Result<()> {
    let ctx = super::gpu(adapter)?;
    println!("adapter:   {}", ctx.describe());
    println!(
        "driver:    {} {}",
        ctx.info.driver,
        ctx.info.driver_info.trim()
    );
    println!(
        "timestamps: {}",
        if ctx.has_timestamps() { "yes" } else { "no" }
    );
    let err = splattrack::gpu::selftest::run(&ctx, 4096).context("GPU self-test")?;
    anyhow::ensure!(err <= 1.0, "GPU self-test: results differ from the CPU by {err} eps");
    println!("self-test: ok (compute dispatch and readback agree with the CPU)");
    if let Some(path) = args.model {
        let _ = path;
    }
    Ok(())
}
