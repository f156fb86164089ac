//! `splattrack features --image A.png [--image B.png] [--max N] --out viz.png
//! [--csv F.csv]`: Harris corners of A, or mutual NCC matches A -> B.

use anyhow::{Context, ensure};
use image::{Rgb, RgbImage};
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

fn load(path: &Path) -> anyhow::Result<(GreyImage, RgbImage)> {
    let img = image::ImageReader::open(path)
        .with_context(|| format!("cannot open {}", path.display()))?
        .with_guessed_format()
        .with_context(|| format!("cannot read {}", path.display()))?
        .decode()
        .with_context(|| format!("cannot decode image {}", path.display()))?;
    let rgb = img.to_rgb8();
    Ok((GreyImage::from_rgb8(&rgb), rgb))
}

pub fn run(args: Args, adapter: &Option<String>) -> anyhow::Result<()> {
    ensure!(
        args.images.len() <= 2,
        "--image: give one image (corners) or two (matches), not {}",
        args.images.len()
    );
    ensure!(args.max > 0, "--max must be at least 1");
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
        window: args.window,
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
        Some(super::gpu(adapter)?)
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
        let mut pic = loaded[0].1.clone();
        for c in &corners[0] {
            cross(&mut pic, c.x, c.y, 3, Rgb([0, 255, 0]));
        }
        save(&pic, &args.out)?;
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
    let pic = if args.side_by_side || ra.dimensions() != rb.dimensions() {
        side_by_side(ra, rb, ca, cb, &matches)
    } else {
        arrows(rb, ca, cb, &matches)
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
    let ctx = || format!("cannot write {}", path.display());
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).with_context(ctx)?);
    writeln!(f, "{header}").with_context(ctx)?;
    for r in rows {
        writeln!(f, "{r}").with_context(ctx)?;
    }
    f.flush().with_context(ctx)
}

/// A and B side by side (B to the right), a line from each matched corner
/// of A to its match in B, unmatched corners as small grey crosses.
fn side_by_side(
    a: &RgbImage,
    b: &RgbImage,
    ca: &[Corner],
    cb: &[Corner],
    matches: &[Match],
) -> RgbImage {
    let (wa, ha) = a.dimensions();
    let (wb, hb) = b.dimensions();
    let mut pic = RgbImage::from_pixel(wa + wb, ha.max(hb), Rgb([0, 0, 0]));
    image::imageops::replace(&mut pic, a, 0, 0);
    image::imageops::replace(&mut pic, b, wa as i64, 0);
    let grey = Rgb([150, 150, 150]);
    for c in ca {
        cross(&mut pic, c.x, c.y, 2, grey);
    }
    for c in cb {
        cross(&mut pic, c.x + wa as f32, c.y, 2, grey);
    }
    for (k, m) in matches.iter().enumerate() {
        let col = palette(k);
        let (p, q) = (ca[m.a], cb[m.b]);
        line(&mut pic, p.x, p.y, q.x + wa as f32, q.y, col);
        cross(&mut pic, p.x, p.y, 3, col);
        cross(&mut pic, q.x + wa as f32, q.y, 3, col);
    }
    pic
}

/// B, dimmed, with an arrow per match from the corner's position in A to
/// its match in B (the image motion), coloured by direction.
fn arrows(b: &RgbImage, ca: &[Corner], cb: &[Corner], matches: &[Match]) -> RgbImage {
    let mut pic = b.clone();
    for p in pic.pixels_mut() {
        p.0 = p.0.map(|v| (v as f32 * 0.55) as u8);
    }
    for m in matches {
        let (p, q) = (ca[m.a], cb[m.b]);
        let angle = (q.y - p.y).atan2(q.x - p.x);
        let col = palette_at((angle / std::f32::consts::TAU).rem_euclid(1.0));
        line(&mut pic, p.x, p.y, q.x, q.y, col);
        cross(&mut pic, q.x, q.y, 2, col);
    }
    pic
}

/// Well-separated saturated colours.
fn palette(k: usize) -> Rgb<u8> {
    palette_at((k as f32 * 0.618_034).fract())
}

/// A saturated colour of hue `t` in [0, 1).
fn palette_at(t: f32) -> Rgb<u8> {
    let h = t * 6.0;
    let x = (1.0 - (h % 2.0 - 1.0).abs()) * 255.0;
    let (r, g, b) = match h as u32 {
        0 => (255.0, x, 0.0),
        1 => (x, 255.0, 0.0),
        2 => (0.0, 255.0, x),
        3 => (0.0, x, 255.0),
        4 => (x, 0.0, 255.0),
        _ => (255.0, 0.0, x),
    };
    Rgb([r as u8, g as u8, b as u8])
}

fn put(pic: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && (x as u32) < pic.width() && (y as u32) < pic.height() {
        pic.put_pixel(x as u32, y as u32, c);
    }
}

fn cross(pic: &mut RgbImage, x: f32, y: f32, r: i64, c: Rgb<u8>) {
    if !(x.is_finite() && y.is_finite()) {
        return;
    }
    let (x, y) = (x.round() as i64, y.round() as i64);
    for d in -r..=r {
        put(pic, x + d, y, c);
        put(pic, x, y + d, c);
    }
}

fn line(pic: &mut RgbImage, x0: f32, y0: f32, x1: f32, y1: f32, c: Rgb<u8>) {
    let n = (x1 - x0).abs().max((y1 - y0).abs()).ceil();
    if !n.is_finite() || n > 1e5 {
        return;
    }
    let n = n as i64;
    for i in 0..=n {
        let t = if n == 0 { 0.0 } else { i as f32 / n as f32 };
        put(
            pic,
            (x0 + t * (x1 - x0)).round() as i64,
            (y0 + t * (y1 - y0)).round() as i64,
            c,
        );
    }
}
