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
use splattrack::tracker::{ConfigError, Mode, Status, TrackResult, Tracker, TrackerConfig};
use splattrack::{Intrinsics, PointModel};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
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
    #[arg(long, value_enum, default_value_t = Mode::KfIt, ignore_case = true)]
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
    #[command(flatten)]
    pub tuning: Tuning,
}

/// Overrides of [`TrackerConfig`] defaults (unset: the default).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct Tuning {
    /// Harris: keep corners whose response is at least this fraction of the
    /// largest one in the search region (default 0.003).
    #[arg(long)]
    pub harris_threshold: Option<f32>,
    /// Harris: at most this many corners per image (default 900).
    #[arg(long)]
    pub max_corners: Option<usize>,
    /// NCC: minimum score of a match (default 0.8).
    #[arg(long)]
    pub min_score: Option<f32>,
    /// NCC: window side, odd (default 9).
    #[arg(long)]
    pub ncc_window: Option<u32>,
    /// Frame-to-frame search radius, pixels (default 40).
    #[arg(long)]
    pub it_search: Option<f32>,
    /// Search radius against the novel view, pixels (default 24).
    #[arg(long)]
    pub kf_search: Option<f32>,
    /// Search radius when recovering a lost track, pixels (default 80).
    #[arg(long)]
    pub recover_search: Option<f32>,
    /// KF steps per frame (default 1).
    #[arg(long)]
    pub kf_iterations: Option<usize>,
    /// Gauss-Newton refinements after each linear solve (default 2).
    #[arg(long)]
    pub refine_iterations: Option<usize>,
    /// Margin around the object's projected bounding circle, pixels (default 24).
    #[arg(long)]
    pub roi_margin: Option<f64>,
    /// A step with fewer inliers than this is not trusted (default 8).
    #[arg(long)]
    pub min_inliers: Option<usize>,
    /// Inlier RMS residual above this: lost (default 3 px).
    #[arg(long)]
    pub max_residual: Option<f64>,
    /// Splat radii are raised to at least this many pixels (default 1; 0:
    /// the model's radii).
    #[arg(long)]
    pub min_splat_px: Option<f32>,
    /// KF+IT: frames in a row that IT alone may track when the KF step
    /// fails (default 5).
    #[arg(long)]
    pub max_it_only: Option<usize>,
    /// IT: only corners whose surroundings at this distance (pixels) are on
    /// the object (default 0: outline corners too; 4 helps IT on the real
    /// cube, hurts it on the synthetic box).
    #[arg(long)]
    pub it_interior: Option<f32>,
}

impl Tuning {
    /// `base` with these overrides applied, checked by
    /// [`TrackerConfig::validate`]; a value out of range is named by its flag.
    pub fn apply(&self, mut c: TrackerConfig) -> anyhow::Result<TrackerConfig> {
        fn set<T: Copy>(field: &mut T, v: Option<T>) {
            if let Some(v) = v {
                *field = v;
            }
        }
        set(&mut c.harris.relative_threshold, self.harris_threshold);
        set(&mut c.harris.max_corners, self.max_corners);
        set(&mut c.ncc.min_score, self.min_score);
        set(&mut c.ncc.window, self.ncc_window);
        set(&mut c.it_search_px, self.it_search);
        set(&mut c.kf_search_px, self.kf_search);
        set(&mut c.recover_search_px, self.recover_search);
        set(&mut c.kf_iterations, self.kf_iterations);
        set(&mut c.refine_iterations, self.refine_iterations);
        set(&mut c.roi_margin_px, self.roi_margin);
        set(&mut c.min_inliers, self.min_inliers);
        set(&mut c.max_residual_px, self.max_residual);
        set(&mut c.min_splat_radius_px, self.min_splat_px);
        set(&mut c.max_it_only_frames, self.max_it_only);
        set(&mut c.it_interior_px, self.it_interior);
        match c.validate() {
            Ok(()) => Ok(c),
            Err(ConfigError::OutOfRange { field, value, rule }) => {
                match FLAGS.iter().find(|(f, _)| *f == field) {
                    Some((_, flag)) => bail!("--{flag} {value}: must be {rule}"),
                    None => bail!("tracker settings: {field} = {value}: must be {rule}"),
                }
            }
            Err(e) => bail!("tracker settings: {e}"),
        }
    }
}

/// The flag of each [`TrackerConfig`] field that [`Tuning`] sets and
/// [`TrackerConfig::validate`] checks.
const FLAGS: [(&str, &str); 8] = [
    ("harris.relative_threshold", "harris-threshold"),
    ("it_search_px", "it-search"),
    ("kf_search_px", "kf-search"),
    ("recover_search_px", "recover-search"),
    ("roi_margin_px", "roi-margin"),
    ("max_residual_px", "max-residual"),
    ("min_splat_radius_px", "min-splat-px"),
    ("it_interior_px", "it-interior"),
];

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
    ctx: &Arc<GpuContext>,
    setup: &Setup,
    opts: &RunOptions,
) -> anyhow::Result<RunStats> {
    let config = TrackerConfig {
        mode: opts.mode,
        ..Default::default()
    };
    track_sequence_with(ctx, setup, opts, config)
}

/// [`track_sequence`] with explicit tracker settings (`opts.mode` wins over
/// `config.mode`).
pub fn track_sequence_with(
    ctx: &Arc<GpuContext>,
    setup: &Setup,
    opts: &RunOptions,
    config: TrackerConfig,
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
        ..config
    };
    let mut tracker = Tracker::new(
        ctx.clone(),
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
                r.reason
                    .as_ref()
                    .map_or_else(|| "no reason".into(), ToString::to_string)
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
    let config = args.tuning.apply(TrackerConfig::default())?;
    let ctx = Arc::new(super::gpu(adapter)?);
    let setup = Setup::load(
        &ctx,
        &args.model,
        &args.sequence,
        args.keyframes.as_deref(),
        args.init.as_deref(),
    )?;
    let stats = track_sequence_with(
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
        config,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tuning_overrides_only_what_is_given() {
        let base = TrackerConfig::default();
        let same = Tuning::default().apply(base.clone()).unwrap();
        assert_eq!(same.kf_search_px, base.kf_search_px);
        assert_eq!(
            same.harris.relative_threshold,
            base.harris.relative_threshold
        );
        let t = Tuning {
            harris_threshold: Some(0.001),
            kf_search: Some(16.0),
            kf_iterations: Some(2),
            min_splat_px: Some(0.0),
            max_it_only: Some(0),
            it_interior: Some(4.0),
            ..Default::default()
        };
        let c = t.apply(base).unwrap();
        assert_eq!(c.harris.relative_threshold, 0.001);
        assert_eq!(c.kf_search_px, 16.0);
        assert_eq!(c.kf_iterations, 2);
        assert_eq!(c.min_splat_radius_px, 0.0);
        assert_eq!(c.max_it_only_frames, 0);
        assert_eq!(c.it_interior_px, 4.0);
    }

    #[test]
    fn tuning_refuses_impossible_values() {
        let bad = [
            Tuning {
                harris_threshold: Some(0.0),
                ..Default::default()
            },
            Tuning {
                kf_search: Some(f32::NAN),
                ..Default::default()
            },
            Tuning {
                min_score: Some(1.5),
                ..Default::default()
            },
            Tuning {
                ncc_window: Some(8),
                ..Default::default()
            },
            Tuning {
                max_residual: Some(-1.0),
                ..Default::default()
            },
            Tuning {
                min_splat_px: Some(f32::INFINITY),
                ..Default::default()
            },
        ];
        for t in bad {
            assert!(t.apply(TrackerConfig::default()).is_err(), "{t:?}");
        }
    }
}
