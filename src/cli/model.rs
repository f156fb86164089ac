//! `splattrack model --mesh IN --out model.ply [--points N]`: a mesh (OBJ,
//! STL, PLY with faces) sampled into the point model `track` makes of it,
//! written out to be inspected or reused.

use anyhow::bail;
use splattrack::PointModel;
use splattrack::model::{AttributeSource, DEFAULT_MESH_POINTS};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The mesh: .obj, .stl (binary or ASCII) or .ply with faces.
    #[arg(long)]
    pub mesh: PathBuf,
    /// The point model to write (PLY, binary; docs/formats.md "Point model").
    #[arg(long)]
    pub out: PathBuf,
    /// Points sampled over the surface (what `track` samples: 100000).
    #[arg(long, default_value_t = DEFAULT_MESH_POINTS)]
    pub points: usize,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    splattrack::io::guard::check_output(&args.out, "--out", &[&args.mesh])?;
    if args.points == 0 {
        bail!("--points 0: sample at least 1 point");
    }
    let model =
        PointModel::load_any_with(&args.mesh, args.points, &super::common::model_options())?;
    if model.provenance.normals != AttributeSource::FromMesh {
        bail!(
            "{}: no faces: it is a point model already (track takes it as it is)",
            args.mesh.display()
        );
    }
    model.save_ply(&args.out)?;
    println!(
        "{}: sampled into {} points ({}; diameter {:.4} in the mesh's units), written to {}",
        args.mesh.display(),
        model.len(),
        if model.colors.is_some() {
            "with the vertex colours"
        } else {
            "no colours"
        },
        model.diameter(),
        args.out.display()
    );
    Ok(())
}
