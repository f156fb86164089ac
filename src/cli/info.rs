//! `splattrack info [--model M.ply]`.

use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A point model (PLY) to describe.
    #[arg(long)]
    pub model: Option<PathBuf>,
}

pub fn run(args: Args, target: &super::common::Target) -> anyhow::Result<()> {
    let ctx = match super::common::device(target)? {
        splattrack::Device::Gpu(ctx) => ctx,
        splattrack::Device::Cpu => {
            println!("device:    the CPU (native, no GPU adapter)");
            return describe_model(&args);
        }
    };
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
    anyhow::ensure!(
        err <= 1.0,
        "GPU self-test: results differ from the CPU by {err} eps"
    );
    println!("self-test: ok (compute dispatch and readback agree with the CPU)");
    let backend = splattrack::splat::Backend::Auto
        .resolve(&ctx)
        .context("--splatter")?;
    let env = std::env::var(splattrack::splat::SPLATTER_ENV).ok();
    let by_size = backend == splattrack::splat::Backend::Compute
        && ctx.is_cpu()
        && env
            .as_deref()
            .and_then(splattrack::splat::Backend::parse)
            .is_none_or(|b| b == splattrack::splat::Backend::Auto);
    if by_size {
        println!(
            "splatter:  {backend}, render for splats over {} px in radius (what --splatter auto picks here)",
            splattrack::splat::AUTO_CPU_RENDER_PASS_ABOVE_PX
        );
    } else {
        println!("splatter:  {backend} (what --splatter auto picks here)");
    }
    describe_model(&args)
}

/// The model's lines (`--model`), on any device.
fn describe_model(args: &Args) -> anyhow::Result<()> {
    if let Some(path) = &args.model {
        let m = super::common::load_model(path)?;
        let (lo, hi) = m.bounds();
        let src = |s: splattrack::model::AttributeSource| match s {
            splattrack::model::AttributeSource::Loaded => "from the file",
            splattrack::model::AttributeSource::Estimated => "estimated from neighbours",
            splattrack::model::AttributeSource::FromMesh => "from the mesh",
            splattrack::model::AttributeSource::Absent => "absent",
        };
        let p = &m.provenance;
        println!("model:     {}", path.display());
        println!("points:    {}", m.len());
        println!(
            "bounds:    [{:.4}, {:.4}, {:.4}] .. [{:.4}, {:.4}, {:.4}]",
            lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
        );
        println!(
            "diameter:  {:.4} (bounding-box diagonal, model units)",
            m.diameter()
        );
        println!("normals:   {}", src(p.normals));
        if p.normals_reestimated > 0 {
            println!(
                "           ({} zero or invalid normals re-estimated)",
                p.normals_reestimated
            );
        }
        let mean_r = m.radii.iter().map(|&r| r as f64).sum::<f64>() / m.len() as f64;
        println!("radii:     {} (mean {mean_r:.5})", src(p.radii));
        println!("colours:   {}", src(p.colors));
        if p.dropped_non_finite > 0 {
            println!(
                "dropped:   {} points with NaN or infinite coordinates",
                p.dropped_non_finite
            );
        }
    }
    Ok(())
}
