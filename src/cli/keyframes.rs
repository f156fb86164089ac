//! `splattrack keyframes --model M.ply --keyframes DIR --camera camera.json --out store.stkf`.

use splattrack::Intrinsics;
use splattrack::app::load_keyframes;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The object's point model (PLY).
    #[arg(long)]
    pub model: PathBuf,
    /// A directory with keyframe images and poses.csv.
    #[arg(long)]
    pub keyframes: PathBuf,
    /// The camera of the keyframe images (camera.json or OpenCV YAML).
    #[arg(long)]
    pub camera: PathBuf,
    /// The store to write (load it with `track --keyframes FILE`).
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(args: Args, target: &super::common::Target) -> anyhow::Result<()> {
    splattrack::io::guard::check_output(
        &args.out,
        "--out",
        &[&args.model, &args.camera, &args.keyframes.join("poses.csv")],
    )?;
    let ctx = super::common::device(target)?;
    let model = super::common::load_model(&args.model)?;
    let cam = Intrinsics::load(&args.camera)?;
    let store = load_keyframes(&ctx, &model, &cam, &args.keyframes)?;
    store.save(&args.out)?;
    for k in &store.keyframes {
        println!(
            "{:<16} {:>7} of {} points visible",
            k.name,
            k.visible_count(),
            store.points
        );
    }
    println!(
        "wrote {} ({} keyframes)",
        args.out.display(),
        store.keyframes.len()
    );
    Ok(())
}
