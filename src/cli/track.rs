//! `splattrack track --model M.ply --sequence DIR [--keyframes DIR|FILE]
//! [--init init.csv] [--mode kf+it|it|kf] --out poses.csv [--overlay DIR]
//! [--profile] [--bop FILE]`.

use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use splattrack::geometry::{Pose, Undistorter};
use splattrack::gpu::GpuContext;
use splattrack::io::{PoseRow, Sequence, poses};
use splattrack::keyframes::{KeyframeConfig, KeyframeStore};
use splattrack::splat::Splatter;
use splattrack::tracker::{Mode, Status, TrackResult, Tracker, TrackerConfig};
use splattrack::{Intrinsics, PointModel};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The object's point model (PLY).
    #[arg(long)]
    pub model: PathBuf,
    /// The sequence directory (camera.json, frames/, init.csv, ...).
    #[arg(long)]
    pub sequence: PathBuf,
    /// Keyframes: a directory with images and poses.csv, or a store built by
    /// `splattrack keyframes` (.stkf). Default: SEQUENCE/keyframes if present.
    #[arg(long)]
    pub keyframes: Option<PathBuf>,
    /// The pose of frame 0. Default: SEQUENCE/init.csv.
    #[arg(long)]
    pub init: Option<PathBuf>,
    /// kf+it (the paper's hybrid), it (frame to frame) or kf (keyframes only).
    #[arg(long, default_value = "kf+it")]
    pub mode: Mode,
    /// Output pose CSV (FORMATS.md "Tracker output").
    #[arg(long)]
    pub out: PathBuf,
    /// Write each frame with the model's outline at the tracked pose here.
    #[arg(long)]
    pub overlay: Option<PathBuf>,
    /// Print the time per stage.
    #[arg(long)]
    pub profile: bool,
    /// Also write a BOP-style results CSV (t in mm, assuming metre models).
    #[arg(long)]
    pub bop: Option<PathBuf>,
    /// BOP object id.
    #[arg(long, default_value_t = 1)]
    pub obj_id: u32,
    /// Track only the first N frames.
    #[arg(long)]
    pub frames: Option<usize>,
}

/// Loads (or builds) the keyframe store the options name.
pub fn keyframe_store(
    ctx: &GpuContext,
    model: &PointModel,
    cam: &Intrinsics,
    path: Option<&Path>,
) -> anyhow::Result<Option<KeyframeStore>> {
    let Some(path) = path else { return Ok(None) };
    if path.is_file() {
        let store = KeyframeStore::load(path)?;
        store.check_model(model, path)?;
        return Ok(Some(store));
    }
    if !path.join("poses.csv").is_file() {
        bail!(
            "{}: not a keyframe store file nor a directory with poses.csv",
            path.display()
        );
    }
    let splatter = Splatter::new(ctx)?;
    let rows = splattrack::io::read_poses(&path.join("poses.csv"))?;
    let mut frames = splattrack::keyframes::load_keyframe_images(path, &rows, cam)?;
    if cam.has_distortion() {
        let und = Undistorter::new(cam);
        for f in &mut frames {
            f.1 = und.apply(&f.1).map_err(anyhow::Error::msg)?;
        }
    }
    let store = KeyframeStore::build(
        ctx,
        &splatter,
        model,
        &cam.undistorted(),
        &frames,
        &KeyframeConfig::default(),
    )
    .with_context(|| format!("building keyframes from {}", path.display()))?;
    Ok(Some(store))
}

/// Reads the single pose of an init file (its first row).
pub fn read_init(path: &Path) -> anyhow::Result<Pose> {
    let rows = splattrack::io::read_poses(path)?;
    Ok(rows[0].pose)
}

/// Row-by-row pose writer: every finished frame is flushed to
/// `OUT.partial`, renamed to `OUT` only when the whole sequence is done, so
/// a crash never leaves a file that looks complete.
pub struct PoseWriter {
    file: std::io::BufWriter<std::fs::File>,
    partial: PathBuf,
    path: PathBuf,
}

impl PoseWriter {
    pub fn create(path: &Path, extra: &[&str]) -> anyhow::Result<Self> {
        let partial = path.with_extension("csv.partial");
        let f = std::fs::File::create(&partial)
            .with_context(|| format!("{}: cannot create", partial.display()))?;
        let mut file = std::io::BufWriter::new(f);
        writeln!(file, "{}", poses::header(extra))?;
        Ok(Self {
            file,
            partial,
            path: path.to_owned(),
        })
    }

    pub fn row(&mut self, row: &PoseRow) -> anyhow::Result<()> {
        writeln!(self.file, "{}", poses::format_row(row))
            .and_then(|_| self.file.flush())
            .with_context(|| format!("{}: cannot write", self.partial.display()))
    }

    pub fn finish(mut self) -> anyhow::Result<()> {
        self.file.flush()?;
        std::fs::rename(&self.partial, &self.path)
            .with_context(|| format!("{}: cannot write", self.path.display()))
    }
}

/// The tracker output row of a frame.
pub fn result_row(i: usize, r: &TrackResult) -> PoseRow {
    let mut row = PoseRow::new(i.to_string(), r.pose);
    row.extra = vec![
        ("inliers".into(), r.inliers.to_string()),
        (
            "residual_px".into(),
            if r.residual_px.is_finite() {
                format!("{:.3}", r.residual_px)
            } else {
                "nan".into()
            },
        ),
        ("status".into(), r.status.name().into()),
    ];
    row
}

/// Everything a tracking run needs, loaded and checked.
pub struct Setup {
    pub model: PointModel,
    pub sequence: Sequence,
    pub cam: Intrinsics,
    pub undistorter: Option<Undistorter>,
    pub init: Pose,
    pub keyframes: Option<KeyframeStore>,
}

impl Setup {
    pub fn load(
        ctx: &GpuContext,
        model: &Path,
        sequence: &Path,
        keyframes: Option<&Path>,
        init: Option<&Path>,
    ) -> anyhow::Result<Self> {
        let model = PointModel::load(model)?;
        let sequence = Sequence::open(sequence)?;
        let raw_cam = sequence.camera;
        let undistorter = raw_cam.has_distortion().then(|| Undistorter::new(&raw_cam));
        let cam = raw_cam.undistorted();
        let init_path = init
            .map(Path::to_owned)
            .unwrap_or_else(|| sequence.init_path());
        let init = read_init(&init_path)?;
        let kf_dir = keyframes
            .map(Path::to_owned)
            .or_else(|| sequence.keyframes_dir());
        let keyframes = keyframe_store(ctx, &model, &raw_cam, kf_dir.as_deref())?;
        Ok(Self {
            model,
            sequence,
            cam,
            undistorter,
            init,
            keyframes,
        })
    }

    /// Frame `i`, undistorted.
    pub fn frame(&self, i: usize) -> anyhow::Result<image::RgbImage> {
        let path = &self.sequence.frames[i];
        let img = image::open(path)
            .with_context(|| format!("{}: cannot read frame", path.display()))?
            .to_rgb8();
        if img.width() != self.cam.width || img.height() != self.cam.height {
            bail!(
                "{}: frame is {}x{}, the camera ({}) is {}x{}",
                path.display(),
                img.width(),
                img.height(),
                self.sequence.camera_path.display(),
                self.cam.width,
                self.cam.height
            );
        }
        match &self.undistorter {
            Some(u) => u.apply(&img).map_err(anyhow::Error::msg),
            None => Ok(img),
        }
    }
}

/// Draws the tracked silhouette's outline (green when tracking, red when
/// lost) and a light tint over the object.
pub fn overlay(
    frame: &image::RgbImage,
    mask: &[bool],
    status: Status,
    label: &str,
) -> image::RgbImage {
    let mut img = frame.clone();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let colour = match status {
        Status::Tracking => [40, 230, 60],
        Status::Lost => [240, 40, 40],
    };
    for y in 0..h {
        for x in 0..w {
            if !mask[y * w + x] {
                continue;
            }
            let edge = [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)]
                .iter()
                .any(|(dx, dy)| {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    nx < 0
                        || ny < 0
                        || nx >= w as i64
                        || ny >= h as i64
                        || !mask[ny as usize * w + nx as usize]
                });
            if edge {
                for (dx, dy) in [(0, 0), (1, 0), (0, 1)] {
                    splattrack::draw::put(&mut img, x as i64 + dx, y as i64 + dy, colour);
                }
            } else {
                splattrack::draw::blend(&mut img, x as i64, y as i64, colour, 0.18);
            }
        }
    }
    splattrack::draw::label(&mut img, 6, 6, label, [255, 255, 255], [0, 0, 0], 1);
    img
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Options of one tracking run over a sequence.
pub struct RunOptions<'p> {
    pub mode: Mode,
    pub out: &'p Path,
    pub overlay: Option<&'p Path>,
    /// Write every k-th overlay (1: all).
    pub overlay_every: usize,
    pub bop: Option<&'p Path>,
    pub obj_id: u32,
    pub frames: Option<usize>,
    pub label: String,
}

/// What a run measured.
#[derive(Debug, Clone, Default)]
pub struct RunStats {
    pub frames: usize,
    pub lost: usize,
    /// Mean milliseconds per frame: features, IT, KF, total.
    pub mean_ms: [f64; 4],
    /// Median total milliseconds per frame.
    pub median_ms: f64,
}

/// Tracks the sequence of `setup`, writing the pose CSV (and overlays, BOP
/// results) as it goes, with a progress bar.
pub fn track_sequence(
    ctx: &GpuContext,
    setup: &Setup,
    opts: &RunOptions,
) -> anyhow::Result<RunStats> {
    let n = opts
        .frames
        .unwrap_or(setup.sequence.frames.len())
        .min(setup.sequence.frames.len());
    if n == 0 {
        bail!("--frames 0: nothing to track");
    }
    if let Some(dir) = opts.overlay {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
    }
    let config = TrackerConfig {
        mode: opts.mode,
        ..Default::default()
    };
    let mut tracker = Tracker::new(
        ctx,
        setup.model.clone(),
        setup.cam,
        setup.keyframes.clone(),
        config,
        setup.init,
    )
    .with_context(|| format!("starting the tracker on {}", setup.sequence.dir.display()))?;
    let mut out = PoseWriter::create(opts.out, &["inliers", "residual_px", "status"])?;
    let mut bop = String::from("scene_id,im_id,obj_id,score,R,t,time\n");
    let bar = ProgressBar::new(n as u64);
    bar.set_style(
        ProgressStyle::with_template(
            "{prefix} {bar:40} {pos}/{len} frames {msg} [{elapsed} < {eta}]",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_prefix(opts.label.clone());
    let mut stats = RunStats {
        frames: n,
        ..Default::default()
    };
    let mut totals = Vec::with_capacity(n);
    for i in 0..n {
        let frame = setup.frame(i)?;
        let r = tracker
            .track(&frame)
            .with_context(|| format!("{}", setup.sequence.frames[i].display()))?;
        if r.status == Status::Lost {
            stats.lost += 1;
            log::info!(
                "frame {i}: lost ({})",
                r.reason.as_deref().unwrap_or("no reason")
            );
        }
        out.row(&result_row(i, &r))?;
        let t = &r.times;
        for (acc, d) in stats
            .mean_ms
            .iter_mut()
            .zip([t.features, t.it, t.kf, t.total])
        {
            *acc += ms(d) / n as f64;
        }
        totals.push(ms(t.total));
        if opts.bop.is_some() {
            let p = r.pose.to_row_major();
            let rot: Vec<String> = p[..9].iter().map(|v| format!("{v:.9}")).collect();
            let tr: Vec<String> = p[9..]
                .iter()
                .map(|v| format!("{:.6}", v * 1000.0))
                .collect();
            bop.push_str(&format!(
                "0,{i},{},{:.4},{},{},{:.4}\n",
                opts.obj_id,
                if r.status == Status::Tracking {
                    1.0
                } else {
                    0.0
                },
                rot.join(" "),
                tr.join(" "),
                t.total.as_secs_f64()
            ));
        }
        if let Some(dir) = opts.overlay.filter(|_| i % opts.overlay_every.max(1) == 0) {
            let mask = tracker.silhouette(&r.pose)?;
            let label = format!(
                "{} frame {i}  {}  {} inliers  {:.2} px",
                opts.mode.name(),
                r.status.name(),
                r.inliers,
                r.residual_px
            );
            let path = dir.join(format!("{i:06}.png"));
            overlay(&frame, &mask, r.status, &label)
                .save(&path)
                .with_context(|| format!("{}: cannot write", path.display()))?;
        }
        bar.set_message(format!(
            "{:.0} ms/frame",
            totals.iter().sum::<f64>() / totals.len() as f64
        ));
        bar.inc(1);
    }
    bar.finish_and_clear();
    out.finish()?;
    if let Some(path) = opts.bop {
        std::fs::write(path, bop).with_context(|| format!("{}: cannot write", path.display()))?;
    }
    totals.sort_by(f64::total_cmp);
    stats.median_ms = totals[totals.len() / 2];
    Ok(stats)
}

pub fn run(args: Args, adapter: &Option<String>) -> anyhow::Result<()> {
    let ctx = super::gpu(adapter)?;
    let setup = Setup::load(
        &ctx,
        &args.model,
        &args.sequence,
        args.keyframes.as_deref(),
        args.init.as_deref(),
    )?;
    let stats = track_sequence(
        &ctx,
        &setup,
        &RunOptions {
            mode: args.mode,
            out: &args.out,
            overlay: args.overlay.as_deref(),
            overlay_every: 1,
            bop: args.bop.as_deref(),
            obj_id: args.obj_id,
            frames: args.frames,
            label: args.mode.name().to_string(),
        },
    )?;
    println!(
        "tracked {} frames ({} mode, {}): {} lost; {:.1} ms per frame (median {:.1}); poses in {}",
        stats.frames,
        args.mode.name(),
        ctx.describe(),
        stats.lost,
        stats.mean_ms[3],
        stats.median_ms,
        args.out.display()
    );
    if args.profile {
        let m = stats.mean_ms;
        println!(
            "per frame (mean): features {:.1} ms, IT {:.1} ms, KF {:.1} ms, total {:.1} ms",
            m[0], m[1], m[2], m[3]
        );
    }
    Ok(())
}
