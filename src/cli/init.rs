//! `splattrack init`: the pose of one frame from known model points, given
//! as 2-D/3-D correspondences in a CSV (`--points`) or clicked in a window
//! (`--click`, [`click`]). The pose is solved by PnP (RANSAC beyond six
//! points, so that a wrong click is found and named), each point's
//! reprojection error is printed, and a fit worse than `--max-rms` is
//! refused. The overlay shows the model's silhouette at the pose, the given
//! pixels (crosses) and where the pose puts the points (circles).

#[cfg(feature = "view")]
mod click;
mod solve;

use anyhow::{Context, bail};
use image::RgbImage;
use solve::{Fit, ModelView, fit};
use splattrack::geometry::Intrinsics;
use splattrack::io::correspondences::{PointPair, read_named_points, read_point_pairs};
use splattrack::io::{PoseRow, write_poses};
use splattrack::pose::{reprojection_errors, solve_pnp};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The point model (PLY, or an OBJ mesh sampled into points).
    #[arg(long)]
    pub model: PathBuf,
    /// Camera intrinsics (camera.json or an OpenCV camera.yaml).
    #[arg(long)]
    pub camera: PathBuf,
    /// The frame the points are seen in (png or jpg), as the camera took it.
    #[arg(long, visible_alias = "frame")]
    pub image: PathBuf,
    /// 2-D/3-D correspondences: a CSV with the columns u,v,x,y,z (pixel,
    /// then model coordinates), any order, an optional `name` column.
    #[arg(long, required_unless_present = "click", conflicts_with = "click")]
    pub points: Option<PathBuf>,
    /// Click the points of --model-points in a window instead.
    #[arg(long, requires = "model_points")]
    pub click: bool,
    /// Named model points to click: a CSV with the columns name,x,y,z.
    #[arg(long, requires = "click")]
    pub model_points: Option<PathBuf>,
    /// The pose CSV to write (one row, frame 0): the init.csv of `track`.
    #[arg(long)]
    pub out: PathBuf,
    /// The overlay picture to write (default: OUT's name with
    /// `-overlay.png`).
    #[arg(long)]
    pub overlay: Option<PathBuf>,
    /// Refuse a fit whose RMS reprojection error exceeds this, pixels.
    #[arg(long, default_value_t = 4.0)]
    pub max_rms: f64,
    /// With more than 6 points: a point further than this from where the
    /// pose puts it is an outlier (a wrong click), pixels.
    #[arg(long, default_value_t = 8.0)]
    pub threshold: f64,
}

fn default_overlay(out: &Path) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "init".into());
    out.with_file_name(format!("{stem}-overlay.png"))
}

/// Reads the frame and checks it has the camera's size.
fn read_frame(path: &Path, cam: &Intrinsics, camera: &Path) -> anyhow::Result<RgbImage> {
    let img = image::open(path)
        .with_context(|| format!("{}: cannot read the image", path.display()))?
        .into_rgb8();
    if img.dimensions() != (cam.width, cam.height) {
        bail!(
            "{}: the image is {} x {} but {} says {} x {}",
            path.display(),
            img.width(),
            img.height(),
            camera.display(),
            cam.width,
            cam.height
        );
    }
    Ok(img)
}

pub fn run(args: Args, target: &super::common::Target) -> anyhow::Result<()> {
    let overlay_path = args
        .overlay
        .clone()
        .unwrap_or_else(|| default_overlay(&args.out));
    let mut inputs: Vec<&Path> = vec![&args.model, &args.camera, &args.image];
    inputs.extend(args.points.as_deref());
    inputs.extend(args.model_points.as_deref());
    splattrack::io::guard::check_output(&args.out, "--out", &inputs)?;
    inputs.push(&args.out);
    splattrack::io::guard::check_output(&overlay_path, "--overlay", &inputs)?;
    if !(args.max_rms > 0.0 && args.threshold > 0.0) {
        bail!("--max-rms and --threshold must be positive numbers of pixels");
    }
    let cam = Intrinsics::load(&args.camera)?;
    let frame = read_frame(&args.image, &cam, &args.camera)?;
    // The points first: bad input is refused before the model loads.
    match (&args.points, &args.model_points) {
        (Some(corr), _) => {
            let pairs = read_point_pairs(corr)?;
            let source = corr.display().to_string();
            let result = fit(&pairs, &cam, args.max_rms, args.threshold, &source);
            let model = super::common::load_model(&args.model)?;
            let view = ModelView::new(&model, target);
            match result {
                Ok(fit) => {
                    let img = view.overlay(&frame, &cam, &pairs, &fit)?;
                    finish(&args, &overlay_path, &pairs, &fit, &img)
                }
                Err(e) => Err(draw_refused(
                    e,
                    &view,
                    &frame,
                    &cam,
                    &pairs,
                    &overlay_path,
                    &source,
                )),
            }
        }
        (None, Some(pts)) => {
            let named = read_named_points(pts)?;
            let model = super::common::load_model(&args.model)?;
            let view = ModelView::new(&model, target);
            let (pairs, fit) = click_points(&args, &cam, &frame, &named, &view)?;
            let img = view.overlay(&frame, &cam, &pairs, &fit)?;
            finish(&args, &overlay_path, &pairs, &fit, &img)
        }
        (None, None) => bail!("give --points corr.csv, or --click with --model-points pts.csv"),
    }
}

/// A refused fit's error, after drawing the least-squares pose of all the
/// points (when one exists) in the overlay, to show which point is off.
fn draw_refused(
    e: anyhow::Error,
    view: &ModelView<'_>,
    frame: &RgbImage,
    cam: &Intrinsics,
    pairs: &[PointPair],
    overlay_path: &Path,
    source: &str,
) -> anyhow::Error {
    let points: Vec<_> = pairs.iter().map(|p| p.point).collect();
    let pixels: Vec<_> = pairs.iter().map(|p| p.pixel).collect();
    let Ok(solution) = solve_pnp(&points, &pixels, cam) else {
        return e;
    };
    let errors = reprojection_errors(&solution.pose, &points, &pixels, cam);
    let refused = Fit { solution, errors };
    match view.overlay(frame, cam, pairs, &refused) {
        Ok(img) if img.save(overlay_path).is_ok() => e.context(format!(
            "{source}: refused (the pose is drawn in {})",
            overlay_path.display()
        )),
        _ => e,
    }
}

#[cfg(feature = "view")]
fn click_points(
    args: &Args,
    cam: &Intrinsics,
    frame: &RgbImage,
    named: &[splattrack::io::correspondences::NamedPoint],
    view: &ModelView<'_>,
) -> anyhow::Result<(Vec<PointPair>, Fit)> {
    click::collect(cam, frame, named, view, args.max_rms, args.threshold)
}

#[cfg(not(feature = "view"))]
fn click_points(
    _: &Args,
    _: &Intrinsics,
    _: &RgbImage,
    _: &[splattrack::io::correspondences::NamedPoint],
    _: &ModelView<'_>,
) -> anyhow::Result<(Vec<PointPair>, Fit)> {
    bail!("--click: this splattrack was built without the window (cargo feature `view`)")
}

/// Prints the report, writes the overlay and init.csv.
fn finish(
    args: &Args,
    overlay_path: &Path,
    pairs: &[PointPair],
    fit: &Fit,
    img: &RgbImage,
) -> anyhow::Result<()> {
    for line in solve::report(pairs, fit) {
        println!("{line}");
    }
    img.save(overlay_path)
        .with_context(|| format!("{}: cannot write", overlay_path.display()))?;
    write_poses(&args.out, &[PoseRow::new("0", fit.solution.pose)])?;
    println!(
        "wrote {} (check the pose on {})",
        args.out.display(),
        overlay_path.display()
    );
    Ok(())
}
