//! `splattrack features --image A.png [--image B.png] [--max N] --out viz.png
//! [--csv F.csv]`: Harris corners of A, or mutual NCC matches A -> B.

use anyhow::{Context, ensure};
use image::RgbImage;
use splattrack::draw;
use splattrack::features::{
    Corner, GreyImage, Harris, HarrisConfig, Match, NccConfig, NccMatcher, harris_cpu,
    ncc_match_cpu,
};
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Input image (png or jpg); give it twice to match A -> B.
    #[arg(long = "image", required = true, num_args = 1)]
    pub images: Vec<PathBuf>,
    /// At most this many corners per image.
    #[arg(long, default_value_t = 900)]
    pub max: usize,
    /// Picture of the corners (one image) or the matches (two images, side by side).
    #[arg(long)]
    pub out: PathBuf,
    /// CSV of the corners (x,y,score) or matches (xa,ya,xb,yb,score).
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Harris: keep corners whose response is at least this fraction of
    /// the image's largest.
    #[arg(long, default_value_t = 0.01)]
    pub threshold: f32,
    /// NCC window side in pixels (odd).
    #[arg(long, default_value_t = 9)]
    pub window: u32,
    /// Minimum NCC score of a match.
    #[arg(long, default_value_t = 0.8)]
    pub min_score: f32,
    /// Only match features at most this many pixels apart.
    #[arg(long)]
    pub search_radius: Option<f32>,
    /// Run the CPU reference instead of the GPU kernels.
    #[arg(long)]
    pub cpu: bool,
    /// Draw matches with A and B side by side (the default for images of
    /// different sizes) rather than as displacement arrows on B.
    #[arg(long)]
    pub side_by_side: bool,
}

/// The most pixels an input image or the picture drawn may have (64 Mpx:
/// 8192 x 8192; about 200 MB as RGB), so odd-shaped inputs cannot ask for
/// a canvas of tens of GB.
pub const MAX_PIXELS: u64 = 1 << 26;

fn load(path: &Path) -> anyhow::Result<(GreyImage, RgbImage)> {
    let reader = image::ImageReader::open(path)
        .with_context(|| format!("cannot open {}", path.display()))?
        .with_guessed_format()
        .with_context(|| format!("cannot read {}", path.display()))?;
    let (w, h) = reader
        .into_dimensions()
        .with_context(|| format!("cannot decode image {}", path.display()))?;
    ensure!(
        w as u64 * h as u64 <= MAX_PIXELS,
        "{}: {w} x {h} is more than {} Mpx",
        path.display(),
        MAX_PIXELS >> 20
    );
    let img = image::ImageReader::open(path)
        .with_context(|| format!("cannot open {}", path.display()))?
        .with_guessed_format()
        .with_context(|| format!("cannot read {}", path.display()))?
        .decode()
        .with_context(|| format!("cannot decode image {}", path.display()))?;
    let rgb = img.to_rgb8();
    Ok((GreyImage::from_rgb8(&rgb), rgb))
}

pub fn run(args: Args, target: &super::common::Target) -> anyhow::Result<()> {
    ensure!(
        args.images.len() <= 2,
        "--image: give one image (corners) or two (matches), not {}",
        args.images.len()
    );
    let inputs: Vec<&Path> = args.images.iter().map(PathBuf::as_path).collect();
    splattrack::io::guard::check_output(&args.out, "--out", &inputs)?;
    if let Some(csv) = &args.csv {
        splattrack::io::guard::check_output(csv, "--csv", &inputs)?;
    }
    ensure!(
        (1..=splattrack::app::MAX_CORNERS).contains(&args.max),
        "--max {}: must be 1..={}",
        args.max,
        splattrack::app::MAX_CORNERS
    );
    let ext = args
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    ensure!(
        matches!(ext.as_deref(), Some("png" | "jpg" | "jpeg")),
        "{}: the picture must be a .png or .jpg file",
        args.out.display()
    );
    let hcfg = HarrisConfig::default()
        .with_max_corners(args.max)
        .with_relative_threshold(args.threshold);
    let ncfg = NccConfig {
        patch: args.window,
        min_score: args.min_score,
        search_radius: args.search_radius,
        ..NccConfig::default()
    };
    hcfg.validate()?;
    ncfg.validate()?;
    let loaded: Vec<(GreyImage, RgbImage)> = args
        .images
        .iter()
        .map(|p| load(p))
        .collect::<anyhow::Result<_>>()?;

    let ctx = if args.cpu {
        None
    } else {
        Some(super::common::gpu(target, "features on the GPU")?)
    };
    let mut corners: Vec<Vec<Corner>> = Vec::new();
    match &ctx {
        Some(ctx) => {
            let mut harris = Harris::new(ctx, hcfg.clone())?;
            // Grey conversion on the GPU too; the host's grey image (same
            // formula) serves the NCC windows.
            for ((_, rgb), path) in loaded.iter().zip(&args.images) {
                corners.push(
                    harris
                        .detect_rgb8(rgb, None)
                        .with_context(|| format!("Harris corners of {}", path.display()))?,
                );
            }
        }
        None => {
            for (grey, _) in &loaded {
                corners.push(harris_cpu(grey, &hcfg, None)?);
            }
        }
    }
    for (c, path) in corners.iter().zip(&args.images) {
        println!("{}: {} corners", path.display(), c.len());
    }

    if loaded.len() == 1 {
        save(&draw::corners_picture(&loaded[0].1, &corners[0]), &args.out)?;
        if let Some(csv) = &args.csv {
            let rows = corners[0]
                .iter()
                .map(|c| format!("{},{},{}", c.x, c.y, c.score));
            write_csv(csv, "x,y,score", rows)?;
        }
        return Ok(());
    }

    let (ga, gb) = (&loaded[0].0, &loaded[1].0);
    let (ca, cb) = (&corners[0], &corners[1]);
    let matches: Vec<Match> = match &ctx {
        Some(ctx) => NccMatcher::new(ctx, ncfg)?.match_features(ga, ca, gb, cb)?,
        None => ncc_match_cpu(ga, ca, gb, cb, &ncfg)?,
    };
    println!("{} mutual matches", matches.len());
    let (ra, rb) = (&loaded[0].1, &loaded[1].1);
    let side_by_side = args.side_by_side || ra.dimensions() != rb.dimensions();
    let canvas = (ra.width() as u64 + rb.width() as u64) * ra.height().max(rb.height()) as u64;
    ensure!(
        !side_by_side || canvas <= MAX_PIXELS,
        "{} and {}: drawn side by side they need a {} x {} picture, more than {} Mpx; give images of similar shape",
        args.images[0].display(),
        args.images[1].display(),
        ra.width() as u64 + rb.width() as u64,
        ra.height().max(rb.height()),
        MAX_PIXELS >> 20
    );
    let pic = if side_by_side {
        draw::matches_side_by_side(ra, rb, ca, cb, &matches)
    } else {
        draw::match_arrows(rb, ca, cb, &matches)
    };
    save(&pic, &args.out)?;
    if let Some(csv) = &args.csv {
        let rows = matches.iter().map(|m| {
            let (a, b) = (ca[m.a], cb[m.b]);
            format!("{},{},{},{},{}", a.x, a.y, b.x, b.y, m.score)
        });
        write_csv(csv, "xa,ya,xb,yb,score", rows)?;
    }
    Ok(())
}

fn save(pic: &RgbImage, path: &Path) -> anyhow::Result<()> {
    pic.save(path)
        .with_context(|| format!("cannot write {}", path.display()))
}

fn write_csv(path: &Path, header: &str, rows: impl Iterator<Item = String>) -> anyhow::Result<()> {
    splattrack::io::write_atomic(path, |f| {
        writeln!(f, "{header}")?;
        for r in rows {
            writeln!(f, "{r}")?;
        }
        Ok(())
    })
    .with_context(|| format!("cannot write {}", path.display()))
}
