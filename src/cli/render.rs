//! `splattrack render`: one splatted view of a point model, as a picture
//! (.png) or a raw float image (.npy, channel layout of docs/formats.md).

use anyhow::{Context, bail};
use nalgebra::{Matrix3, Vector3};
use splattrack::geometry::{Intrinsics, Pose};
use splattrack::splat::{Attribute, Backend, GpuModel, SplatImage, SplatParams, Splatter, viz};
use std::path::{Path, PathBuf};

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum AttributeArg {
    Color,
    Depth,
    Normal,
    Motion,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The point model (PLY).
    #[arg(long)]
    pub model: PathBuf,
    /// Camera intrinsics (camera.json or an OpenCV camera.yaml).
    #[arg(long)]
    pub camera: PathBuf,
    /// A pose CSV (object-to-camera); see --frame.
    #[arg(long, required_unless_present = "pose", conflicts_with = "pose")]
    pub pose_file: Option<PathBuf>,
    /// The frame index of the row of --pose-file to use (default: the first row).
    #[arg(long, requires = "pose_file")]
    pub frame: Option<usize>,
    /// A pose as 12 comma-separated numbers "r11,r12,...,r33,tx,ty,tz"
    /// (object-to-camera, R row-major).
    #[arg(long, allow_hyphen_values = true)]
    pub pose: Option<String>,
    /// Output: .png (a picture) or .npy (raw float image, NaN where empty).
    #[arg(long)]
    pub out: PathBuf,
    /// What to render.
    #[arg(long, value_enum, default_value = "color")]
    pub attribute: AttributeArg,
    /// The splatter: render, compute or auto (see `track --help`).
    #[arg(long, default_value = "auto")]
    pub splatter: Backend,
}

/// Parses "r11,r12,...,r33,tx,ty,tz".
pub fn parse_pose(s: &str) -> anyhow::Result<Pose> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .with_context(|| format!("--pose: {:?} is not a number", t.trim()))
        })
        .collect::<Result<_, _>>()?;
    if v.len() != 12 {
        bail!(
            "--pose: expected 12 numbers (r11,...,r33,tx,ty,tz), got {}",
            v.len()
        );
    }
    let r = Matrix3::from_row_slice(&v[..9]);
    let t = Vector3::new(v[9], v[10], v[11]);
    let pose = Pose::new(r, t).context("--pose")?;
    Ok(pose.orthonormalized())
}

fn pick_pose(args: &Args) -> anyhow::Result<Pose> {
    if let Some(s) = &args.pose {
        return parse_pose(s);
    }
    let path = args
        .pose_file
        .as_ref()
        .context("--pose or --pose-file is required")?;
    let rows = splattrack::io::read_poses(path)?;
    let row = match args.frame {
        None => rows.first(),
        Some(n) => rows.iter().find(|r| r.frame_index() == Some(n)),
    };
    match (row, args.frame) {
        (Some(r), _) => Ok(r.pose),
        (None, Some(n)) => bail!("{}: no row for frame {n}", path.display()),
        (None, None) => bail!("{}: no pose rows", path.display()),
    }
}

fn attribute(a: AttributeArg) -> Attribute {
    match a {
        AttributeArg::Color => Attribute::Color,
        AttributeArg::Depth => Attribute::Depth,
        AttributeArg::Normal => Attribute::Normal,
        AttributeArg::Motion => Attribute::Motion,
    }
}

enum Output {
    Png,
    Npy,
}

pub fn run(args: Args, target: &super::common::Target) -> anyhow::Result<()> {
    let mut inputs: Vec<&Path> = vec![&args.model, &args.camera];
    inputs.extend(args.pose_file.as_deref());
    splattrack::io::guard::check_output(&args.out, "--out", &inputs)?;
    let kind = match args
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .as_deref()
    {
        Some("png") => Output::Png,
        Some("npy") => Output::Npy,
        _ => bail!(
            "{}: unsupported output type (use .png for a picture or .npy for raw floats)",
            args.out.display()
        ),
    };
    let cam = Intrinsics::load(&args.camera)?;
    if cam.has_distortion() {
        log::warn!(
            "{}: distortion is ignored; the render is of the ideal pinhole camera",
            args.camera.display()
        );
    }
    let pose = pick_pose(&args)?;
    let model = super::common::load_model(&args.model)?;
    let ctx = super::common::device(target)?;
    let splatter = Splatter::with_params(
        &ctx,
        SplatParams {
            backend: args.splatter,
            ..Default::default()
        },
    )?;
    let gm = GpuModel::new(&ctx, &model).with_context(|| args.model.display().to_string())?;
    let attr = attribute(args.attribute);
    let img = splatter
        .render_image(&ctx, &gm, &cam, &pose, attr)
        .context("render")?;
    if img.coverage() == 0 {
        bail!("the model covers no pixel at this pose (it is outside the view)");
    }
    write(&img, attr, kind, &args.out)
}

fn write(img: &SplatImage, attr: Attribute, kind: Output, out: &Path) -> anyhow::Result<()> {
    let ctx = || format!("{}: cannot write", out.display());
    match kind {
        Output::Npy => splattrack::io::npy::write_npy(
            out,
            &img.data,
            img.height as usize,
            img.width as usize,
            img.channels,
        )
        .with_context(ctx)?,
        Output::Png => match attr {
            Attribute::Color => viz::color_picture(img).save(out).with_context(ctx)?,
            Attribute::Depth => viz::depth_picture(img).save(out).with_context(ctx)?,
            Attribute::Normal => viz::normal_picture(img).save(out).with_context(ctx)?,
            _ => viz::motion_picture(img).save(out).with_context(ctx)?,
        },
    }
    Ok(())
}
