//! `splattrack track --model M.ply (--sequence DIR | --video FILE |
//! --device N|PATH --camera C) [--keyframes DIR|FILE] [--init init.csv]
//! [--mode kf+it|it|kf] --out poses.csv [--overlay DIR] [--profile]
//! [--bop FILE] [--start N|Ts] [--frames N]`: the flags, then
//! [`splattrack::app`] does the work.

use anyhow::{Context, bail};
use splattrack::Intrinsics;
use splattrack::app::{AppError, TrackInputs, TrackRun};
use splattrack::features::FeatureBackend;
use splattrack::io::guard::{check_output, check_output_dir};
use splattrack::io::live::LiveSource;
use splattrack::io::source::{FrameSource, Start};
use splattrack::io::video::VideoSource;
use splattrack::splat::Backend;
use splattrack::tracker::{ConfigError, Modalities, Mode, TrackerConfig};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The object's point model (PLY).
    #[arg(long)]
    pub model: PathBuf,
    /// The sequence directory (camera.json, frames/, init.csv, ...).
    #[arg(long, conflicts_with_all = ["video", "device", "camera"])]
    pub sequence: Option<PathBuf>,
    /// A video file (MP4, MOV, AVI, MKV, WebM, ...: whatever ffmpeg
    /// decodes), read through the ffmpeg program; needs --camera. Frames
    /// are numbered from 0 in decode order; the output gains time_s.
    #[arg(long, conflicts_with = "device")]
    pub video: Option<PathBuf>,
    /// A live camera: N for /dev/videoN, or a device path (V4L2, Linux),
    /// read through ffmpeg at the camera's size; needs --camera. Frames
    /// that arrive while one is tracked are dropped and counted; Ctrl-C
    /// ends the run after the current frame, every finished frame written.
    #[arg(long)]
    pub device: Option<String>,
    /// --video: read the video at its own frame rate, as a camera would
    /// deliver it, and track it as a live camera (frames that arrive while
    /// one is tracked are dropped and counted; Ctrl-C ends the run): how
    /// the tracker would fare live at this speed.
    #[arg(long, requires = "video")]
    pub realtime: bool,
    /// The camera of --video or --device (camera.json or an OpenCV yaml).
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// Where to start: a frame index (120), or seconds with an s suffix
    /// (4.5s: the first frame at or after 4.5 s; --video only). Frames keep
    /// their numbers in the whole video or sequence.
    #[arg(long)]
    pub start: Option<Start>,
    /// Keyframes: a directory with images and poses.csv, or a store built by
    /// `splattrack keyframes` (.stkf). Default: SEQUENCE/keyframes if present.
    #[arg(long)]
    pub keyframes: Option<PathBuf>,
    /// The pose of frame 0. Default: SEQUENCE/init.csv when present, else
    /// the object is searched for in the frames (automatic initialisation).
    #[arg(long)]
    pub init: Option<PathBuf>,
    /// kf+it (the paper's hybrid), it (frame to frame) or kf (keyframes only).
    #[arg(long, value_enum, default_value_t = Mode::KfIt, ignore_case = true)]
    pub mode: Mode,
    /// The cues tracked: texture (corners and NCC; the default), contour
    /// (the splatted silhouette against the frame's colours: for weakly
    /// textured objects), or both in one robust solve (texture,contour).
    #[arg(long, default_value = "texture")]
    pub modalities: Modalities,
    /// Output pose CSV (FORMATS.md "Tracker output").
    #[arg(long)]
    pub out: PathBuf,
    /// Write each frame with the model's outline at the tracked pose here.
    #[arg(long)]
    pub overlay: Option<PathBuf>,
    /// Print the time per stage and its parts, and the GPU time of every
    /// pass (timestamp queries, where the adapter has them).
    #[arg(long)]
    pub profile: bool,
    /// Also write a BOP-style results CSV (t in mm, assuming metre models).
    #[arg(long)]
    pub bop: Option<PathBuf>,
    /// BOP object id.
    #[arg(long, default_value_t = 1)]
    pub obj_id: u32,
    /// Track only N frames (from --start).
    #[arg(long)]
    pub frames: Option<usize>,
    /// The splatter: render (render pass), compute (compute shader with
    /// atomics) or auto ($SPLATTRACK_SPLATTER when set, else compute where
    /// the adapter supports it: the faster measured, BENCHMARKS.md).
    #[arg(long, default_value = "auto")]
    pub splatter: Backend,
    /// Where corners are detected and matched: gpu (compute shaders),
    /// host (the CPU references' arithmetic; Harris vectorised on every
    /// core) or auto (host on a CPU adapter such as lavapipe, where it
    /// measured faster, else gpu).
    #[arg(long, default_value = "auto")]
    pub feature_backend: FeatureBackend,
    /// Keep the frame loop's images on the GPU: on (each frame uploaded
    /// once; matching, the KF refinement and the pose check in the
    /// shaders; a few values per feature read back), off (host crops, the
    /// view read back) or auto (on with a GPU, off on a CPU adapter such
    /// as lavapipe, where off measured faster). With --feature-backend
    /// gpu, on runs a GPU's frame loop on any adapter, for profiling.
    #[arg(long, value_enum, default_value_t = OnOff::Auto)]
    pub resident: OnOff,
    /// Show each frame in a window as it is tracked: the model's outline
    /// at the tracked pose, tracking or lost (and why), inliers, residual
    /// and ms per frame. Esc, q or closing the window ends the run with
    /// every finished frame on disk. Needs a display (X11 or Wayland).
    #[arg(long)]
    pub view: bool,
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
    /// Keep the model's splat radii where they leave gaps between splats
    /// (default: those radii grow just enough to close the gaps).
    #[arg(long)]
    pub keep_radii: bool,
    /// Harris and NCC: the fraction of a window that must be valid where it
    /// has pinholes (default 0.8; 1: any invalid pixel voids the window).
    #[arg(long)]
    pub min_valid: Option<f32>,
    /// KF+IT: frames in a row that IT alone may track when the KF step
    /// fails (default 5).
    #[arg(long)]
    pub max_it_only: Option<usize>,
    /// IT: only corners whose surroundings at this distance (pixels) are on
    /// the object (default 0: outline corners too; 4 helps IT on the real
    /// cube, hurts it on the synthetic box).
    #[arg(long)]
    pub it_interior: Option<f32>,
    /// Contour: most rounds per frame (default 4; the first searches long
    /// then short lines, the others short lines at the newest estimate).
    #[arg(long)]
    pub contour_rounds: Option<usize>,
    /// Contour: from the second round on, a round that moved the outline
    /// less than this (mean, pixels) ends the frame's step (default 0.25;
    /// 0: always --contour-rounds rounds).
    #[arg(long)]
    pub contour_converged: Option<f64>,
    /// Contour: one contour point per cell of this side, pixels (default 4).
    #[arg(long)]
    pub contour_spacing: Option<u32>,
    /// Contour: Levenberg-Marquardt damping, fraction of the diagonal
    /// (default 0: the silhouette of a smooth body constrains some motions
    /// weakly, and damping holds them back; 0.001 steadies the real dragon).
    #[arg(long)]
    pub contour_damping: Option<f64>,
    /// Contour: splat depth and normals for the silhouette, as before the
    /// depth-only renders (for comparison; about 3x the contour's GPU time).
    #[arg(long)]
    pub contour_full_render: bool,
    /// Contour: a later round moves the last render's points instead of
    /// rendering when no point moved more than this since (pixels, along
    /// its normal; default 1; 0 renders every round).
    #[arg(long)]
    pub contour_reproject: Option<f64>,
    /// Contour: colour histograms per sector of directions around the
    /// object (default 8; 0: one pair for the whole object).
    #[arg(long)]
    pub contour_sectors: Option<usize>,
    /// Contour: the first round always renders, instead of moving the
    /// points of the render held from the KF step (or the last contour
    /// render) when they moved little (for comparison).
    #[arg(long)]
    pub contour_no_seed: bool,
    /// The frame loop before windows and reuse, for comparison: render,
    /// detect and match over the whole image every time instead of the
    /// object's projected region, and render the IT step's view anew
    /// instead of taking the previous check's (the same poses up to f32
    /// rounding, slower).
    #[arg(long)]
    pub full_frame: bool,
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
        if self.keep_radii {
            c.close_gaps = false;
        }
        if let Some(v) = self.min_valid {
            if !(v > 0.0 && v <= 1.0) {
                bail!("--min-valid {v}: must be in (0, 1]");
            }
            c.harris.min_valid_weight = v;
            c.ncc.min_valid = v;
        }
        set(&mut c.max_it_only_frames, self.max_it_only);
        set(&mut c.it_interior_px, self.it_interior);
        set(&mut c.contour.rounds, self.contour_rounds);
        set(&mut c.contour.converged_px, self.contour_converged);
        set(&mut c.contour.spacing_px, self.contour_spacing);
        set(&mut c.contour.damping, self.contour_damping);
        set(&mut c.contour.reproject_px, self.contour_reproject);
        set(&mut c.contour.sectors, self.contour_sectors);
        if self.contour_full_render {
            c.contour.depth_only = false;
        }
        if self.contour_no_seed {
            c.contour.seed_render = false;
        }
        if self.full_frame {
            c.windows = false;
        }
        if let Some(n) = self.max_corners {
            if !(1..=MAX_CORNERS).contains(&n) {
                bail!("--max-corners {n}: must be 1..={MAX_CORNERS}");
            }
        }
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

/// A setting the adapter decides unless told.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnOff {
    Auto,
    On,
    Off,
}

impl OnOff {
    /// `None` for auto.
    pub fn choice(self) -> Option<bool> {
        match self {
            Self::Auto => None,
            Self::On => Some(true),
            Self::Off => Some(false),
        }
    }
}

/// The most corners per image the flags allow (a corner costs 16 bytes of
/// GPU memory and a share of every matching pass; a billion would ask for
/// a 16 GB buffer).
pub const MAX_CORNERS: usize = 100_000;

/// The flag of each [`TrackerConfig`] field that [`Tuning`] sets and
/// [`TrackerConfig::validate`] checks.
const FLAGS: [(&str, &str); 14] = [
    ("contour.rounds", "contour-rounds"),
    ("contour.sectors", "contour-sectors"),
    ("contour.converged_px", "contour-converged"),
    ("contour.reproject_px", "contour-reproject"),
    ("contour.spacing_px", "contour-spacing"),
    ("contour.damping", "contour-damping"),
    ("harris.relative_threshold", "harris-threshold"),
    ("it_search_px", "it-search"),
    ("kf_search_px", "kf-search"),
    ("recover_search_px", "recover-search"),
    ("roi_margin_px", "roi-margin"),
    ("max_residual_px", "max-residual"),
    ("min_splat_radius_px", "min-splat-px"),
    ("it_interior_px", "it-interior"),
];

pub fn run(args: Args, adapter: &Option<String>) -> anyhow::Result<()> {
    let config = TrackerConfig {
        mode: args.mode,
        modalities: args.modalities,
        splatter: args.splatter,
        feature_backend: args.feature_backend,
        resident: args.resident.choice(),
        ..args.tuning.apply(TrackerConfig::default())?
    };
    if args.frames == Some(0) {
        bail!("--frames 0: nothing to track");
    }
    let input = Input::of(&args)?;
    // Outputs that are this run's other inputs (the sequence's own files
    // are checked by the run).
    let mut inputs = vec![args.model.as_path()];
    inputs.extend(args.init.as_deref());
    inputs.extend(args.keyframes.as_deref());
    inputs.extend(args.video.as_deref());
    inputs.extend(args.camera.as_deref());
    check_output(&args.out, "--out", &inputs)?;
    if let Some(bop) = &args.bop {
        check_output(bop, "--bop", &inputs)?;
    }
    if let Some(dir) = &args.overlay {
        let protected: Vec<&std::path::Path> = args.keyframes.as_deref().into_iter().collect();
        check_output_dir(dir, "--overlay", &protected, &inputs)?;
    }
    // A video or a camera is opened first: a missing ffmpeg, a file it
    // cannot decode or frames of the wrong size fail before the GPU and
    // the model are set up.
    let stop = Arc::new(AtomicBool::new(false));
    let source: Option<Box<dyn FrameSource>> = match &input {
        Input::Sequence(_) => None,
        Input::Video {
            file,
            camera,
            start,
        } if !args.realtime => {
            let cam = Intrinsics::load(camera)?;
            Some(Box::new(VideoSource::open(file, &cam, camera, *start)?))
        }
        Input::Video { file, camera, .. } => {
            // Checked now; the replay starts once the tracker is ready
            // (below), so that no frame passes while the model loads.
            let cam = Intrinsics::load(camera)?;
            VideoSource::open(file, &cam, camera, Start::Frame(0))?;
            None
        }
        Input::Device { device, camera } => {
            let cam = Intrinsics::load(camera)?;
            Some(Box::new(
                LiveSource::device(device, &cam, camera)?.stop_on(stop.clone()),
            ))
        }
    };
    let ctx = super::gpu(adapter)?;
    // Before anything is loaded or written: no display, no run.
    let mut display = match args.view {
        true => Some(DisplaySink::open(
            &ctx,
            &format!("splattrack track {}", input.describe()),
        )?),
        false => None,
    };
    let inputs = match &input {
        Input::Sequence(dir) => TrackInputs::load(
            &ctx,
            &args.model,
            &super::model_options(),
            dir,
            args.keyframes.as_deref(),
            args.init.as_deref(),
        )?,
        Input::Video { camera, .. } | Input::Device { camera, .. } => {
            TrackInputs::load_with_camera(
                &ctx,
                &args.model,
                &super::model_options(),
                camera,
                args.keyframes.as_deref(),
                args.init.as_deref(),
            )?
        }
    };
    let live = matches!(input, Input::Device { .. }) || args.realtime;
    if live {
        // Ctrl-C: the run ends after the frame being tracked, its outputs
        // complete; a second Ctrl-C ends it at once (the rows so far stay
        // in OUT.partial).
        let flag = stop.clone();
        ctrlc::set_handler(move || {
            if flag.swap(true, Ordering::SeqCst) {
                eprintln!("stopped at once: the rows so far are in the .partial file");
                std::process::exit(130);
            }
            eprintln!("stopping after the current frame (Ctrl-C again to stop at once)");
        })
        .context("cannot catch Ctrl-C")?;
    }
    let mut run = TrackRun::new(&ctx, &inputs, config)
        .limit(args.frames)
        .poses(&args.out)
        .progress(Some(super::progress::bars(
            format!("{} ", args.mode.name()),
            1,
        )));
    if let Some(dir) = &args.overlay {
        run = run.overlays(dir, 1);
    }
    if let Some(path) = &args.bop {
        run = run.bop(path, args.obj_id);
    }
    if args.profile {
        run = run.gpu_timing(true);
    }
    match (source, &input) {
        (Some(src), _) => run = run.source(src).stop_on(stop.clone()),
        (None, Input::Sequence(_)) => {
            if let Some(Start::Frame(k)) = args.start {
                run = run.start(k);
            }
        }
        (None, Input::Video { file, camera, .. }) => {
            let replay = LiveSource::replay(file, &inputs.camera, camera)?;
            run = run
                .source(Box::new(replay.stop_on(stop.clone())))
                .stop_on(stop.clone());
        }
        (None, Input::Device { .. }) => {}
    }
    if let Some(w) = display.as_mut() {
        run = run.sink(w);
    }
    let wall = std::time::Instant::now();
    let stats = match run.run(|_, _| {}) {
        Err(AppError::NoFrames) if args.start.is_some() => {
            let what = input.describe();
            let start = match args.start {
                Some(Start::Seconds(t)) => format!("{t}s"),
                Some(Start::Frame(k)) => k.to_string(),
                None => String::new(),
            };
            bail!("{what}: no frame at or after --start {start}");
        }
        r => r?,
    };
    let wall = wall.elapsed().as_secs_f64();
    let aside = match stats.texture_set_aside {
        0 => String::new(),
        n => format!(" ({n} tracked by the contour alone, their texture set aside)"),
    };
    println!(
        "tracked {} frames ({} mode, {}): {} lost{aside}; {:.1} ms per frame (median {:.1}); poses in {}",
        stats.frames,
        args.mode.name(),
        ctx.describe(),
        stats.lost,
        stats.mean_ms[3],
        stats.median_ms,
        args.out.display()
    );
    let ctrl_c = stop.load(Ordering::SeqCst);
    if live {
        println!(
            "{} frames dropped (arrived while a frame was being tracked){}",
            stats.dropped,
            if ctrl_c { "; stopped by Ctrl-C" } else { "" }
        );
    }
    if stats.stopped && !ctrl_c {
        println!(
            "the live view was closed: stopped after {} frames",
            stats.frames
        );
    }
    if args.profile {
        println!(
            "frame source: {:.1} ms per frame (reading or decoding, waiting for it; outside the tracker's total)",
            stats.source_ms
        );
        print!(
            "{}",
            profile_table(&stats.mean_stages, ctx.is_cpu(), ctx.validates_indirect)
        );
        if let Some(m) = stats.gpu_memory {
            let mb = |b: u64| b as f64 / (1u64 << 20) as f64;
            println!(
                "GPU memory of the splatting: {:.1} MB (model {:.1}, keyframe colours {:.1}, render targets {:.1})",
                mb(m.total()),
                mb(m.model),
                mb(m.keyframe_colors),
                mb(m.targets)
            );
        }
        println!(
            "end to end (tracking, outputs{}): {:.1} ms per frame, {:.2} frames/s",
            if display.is_some() { ", live view" } else { "" },
            wall * 1e3 / stats.frames as f64,
            stats.frames as f64 / wall
        );
        if let Some(w) = &display {
            let v = w.stats();
            println!(
                "live view: {} frames shown, {} skipped (surface not ready); {:.1} ms per frame to compose, draw and present",
                v.shown,
                v.skipped,
                v.busy.as_secs_f64() * 1e3 / (v.shown + v.skipped).max(1) as f64
            );
        }
    }
    Ok(())
}

/// Where the frames come from.
enum Input {
    Sequence(PathBuf),
    Video {
        file: PathBuf,
        camera: PathBuf,
        start: Start,
    },
    Device {
        device: String,
        camera: PathBuf,
    },
}

impl Input {
    /// The input as a user named it (the live view's title).
    fn describe(&self) -> String {
        match self {
            Input::Sequence(p) | Input::Video { file: p, .. } => p.display().to_string(),
            Input::Device { device, .. } => device.clone(),
        }
    }

    /// The one input the flags name, with the flags it needs.
    fn of(args: &Args) -> anyhow::Result<Self> {
        let camera = || {
            args.camera.clone().ok_or_else(|| {
                anyhow::anyhow!(
                    "--camera is needed with --video and --device (camera.json or an OpenCV yaml)"
                )
            })
        };
        Ok(match (&args.sequence, &args.video, &args.device) {
            (Some(dir), None, None) => {
                if let Some(Start::Seconds(t)) = args.start {
                    bail!(
                        "--start {t}s: a sequence's frames have no timestamps; give a frame index"
                    );
                }
                Input::Sequence(dir.clone())
            }
            (None, Some(file), None) => {
                if args.realtime && args.start.is_some() {
                    bail!("--start: not with --realtime (a replay starts at the beginning)");
                }
                Input::Video {
                    file: file.clone(),
                    camera: camera()?,
                    start: args.start.unwrap_or_default(),
                }
            }
            (None, None, Some(device)) => {
                if args.start.is_some() {
                    bail!("--start: a live camera starts now; not for --device");
                }
                Input::Device {
                    device: device.clone(),
                    camera: camera()?,
                }
            }
            (None, None, None) => {
                bail!("no frames: give --sequence DIR, --video FILE or --device N|PATH")
            }
            _ => bail!("give only one of --sequence, --video and --device"),
        })
    }
}

/// The `--profile` table: every stage of the step, its parts, and what
/// the stages leave over (grey conversion, decisions, bookkeeping).
/// `cpu_adapter`: the GPU passes ran on a CPU adapter, whose timestamps of
/// the feature passes are not to be trusted (said under them).
/// `validated`: wgpu checks indirect dispatches on the GPU (said beside
/// the submissions: a dispatch and two barriers more each).
fn profile_table(
    t: &splattrack::tracker::StageTimes,
    cpu_adapter: bool,
    validated: bool,
) -> String {
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    let rest = |whole: std::time::Duration, parts: &[std::time::Duration]| {
        ms(whole) - parts.iter().map(|d| ms(*d)).sum::<f64>()
    };
    let w = &t.waits;
    let mut rows = vec![
        ("features (frame Harris)", ms(t.features), Some(w.features)),
        ("IT", ms(t.it), Some(w.it)),
        ("  render + gather", ms(t.it_render), None),
        ("  NCC", ms(t.it_ncc), None),
        ("  solve", rest(t.it, &[t.it_render, t.it_ncc]), None),
        ("KF", ms(t.kf), Some(w.kf)),
        ("  render + read", ms(t.kf_render), None),
        ("  Harris", ms(t.kf_harris), None),
        ("  NCC + gather + refine", ms(t.kf_ncc), None),
        (
            "  solve",
            rest(t.kf, &[t.kf_render, t.kf_harris, t.kf_ncc]),
            None,
        ),
        ("contour", ms(t.contour), Some(w.contour)),
        ("pose check", ms(t.verify), Some(w.verify)),
        ("search", ms(t.search), Some(w.search)),
        (
            "other",
            rest(
                t.total,
                &[t.features, t.it, t.kf, t.contour, t.verify, t.search],
            ),
            None,
        ),
        ("total", ms(t.total), Some(t.gpu_wait)),
    ];
    if t.contour_rounds > 0.0 {
        let at = rows.iter().position(|(n, ..)| *n == "contour").unwrap_or(0) + 1;
        rows.insert(at, ("  waiting for its colours", ms(t.colour_wait), None));
    }
    let mut out = String::from("per frame (mean; in brackets the wait for the GPU):\n");
    for (name, v, wait) in rows {
        out += &format!("  {name:<26} {v:8.1} ms");
        if let Some(d) = wait.filter(|d| !d.is_zero()) {
            out += &format!("  ({:.1} waiting)", ms(d));
        }
        out += "\n";
    }
    out += &format!(
        "  {:<26} {:8.0} bytes in {:.1} readbacks\n",
        "read back from the GPU", t.readback_bytes, t.readbacks
    );
    out += &format!(
        "  {:<26} {:8.1} ms in those waits (the GPU's work and latency); the host's own work {:.1} ms, of which {:.1} finishing command buffers (wgpu encoding the passes) and {:.1} submitting{}\n",
        "waiting for the GPU",
        ms(t.gpu_wait),
        ms(t.total) - ms(t.gpu_wait),
        ms(t.gpu_finish),
        ms(t.gpu_submit),
        if cpu_adapter {
            " (a CPU adapter runs the GPU's work inside submissions too: the split says little there)"
        } else {
            ""
        }
    );
    out += &format!(
        "  {:<26} {:8.1} submissions, {:.1} command buffers, {:.1} uploads ({:.1} unchanged parameters skipped), {:.1} passes ({:.1} timed apart); indirect dispatches {}\n",
        "GPU work",
        t.submissions,
        t.command_buffers,
        t.uploads,
        t.uploads_skipped,
        t.passes_untimed,
        t.passes,
        if validated {
            "checked by wgpu first (WGPU_VALIDATION_INDIRECT_CALL or DX12)"
        } else {
            "as they are"
        }
    );
    if t.contour_rounds > 0.0 {
        out += &format!(
            "  {:<26} {:8.2} ({:.2} renders)\n",
            "contour rounds", t.contour_rounds, t.contour_renders
        );
    }
    if !t.colour_learning.is_zero() {
        out += &format!(
            "  {:<26} {:8.1} ms (on a thread of its own, beside the next frame's steps)\n",
            "contour colour learning",
            ms(t.colour_learning)
        );
    }
    if !t.gpu.is_empty() {
        let g = &t.gpu_timeline;
        out += &format!(
            "GPU timeline per frame (mean): {:.3} ms from the first pass to the last, {:.3} busy; idle {:.3} in {:.1} gaps of at most {} ms between passes, {:.3} in longer ones (the host's turns)\n",
            g.span,
            g.busy,
            g.short_gaps,
            g.short_gap_count,
            splattrack::gpu::GpuTimeline::SHORT_GAP_MS,
            g.long_gaps
        );
        out += "GPU passes per frame (mean, timestamp queries):\n";
        for (name, v) in &t.gpu {
            out += &format!("  {name:<26} {v:8.3} ms\n");
        }
        let features_timed = t
            .gpu
            .iter()
            .any(|(name, _)| name.contains(" harris ") || name.contains(" ncc "));
        if cpu_adapter && features_timed {
            out += "  (a CPU adapter: its timestamps of the Harris and NCC passes under-report, by 10-30x on lavapipe; the stage times above are the measure)\n";
        }
    }
    out
}

#[cfg(not(feature = "view"))]
use no_view::DisplaySink;
#[cfg(feature = "view")]
use splattrack::view::DisplaySink;

/// Stands in for the live view in a build without it (the `view` feature
/// off): `--view` is refused before anything runs.
#[cfg(not(feature = "view"))]
mod no_view {
    use splattrack::GpuContext;
    use splattrack::view::{Flow, FrameSink, ViewError, ViewFrame};

    /// What the live view did; never anything here.
    pub struct Stats {
        pub shown: usize,
        pub skipped: usize,
        pub busy: std::time::Duration,
    }

    /// Never made: [`DisplaySink::open`] always fails.
    pub enum DisplaySink {}

    impl DisplaySink {
        pub fn open(_: &GpuContext, _: &str) -> anyhow::Result<Self> {
            anyhow::bail!(
                "--view: this splattrack was built without the live view (cargo feature `view`)"
            )
        }
        pub fn stats(&self) -> Stats {
            match *self {}
        }
    }

    impl FrameSink for DisplaySink {
        fn frame(&mut self, _: &ViewFrame<'_>) -> Result<Flow, ViewError> {
            match *self {}
        }
    }
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
            keep_radii: true,
            min_valid: Some(0.8),
            ..Default::default()
        };
        assert!(same.close_gaps);
        let c = t.apply(base).unwrap();
        assert!(!c.close_gaps);
        assert_eq!((c.ncc.min_valid, c.harris.min_valid_weight), (0.8, 0.8));
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
            Tuning {
                min_valid: Some(0.0),
                ..Default::default()
            },
            Tuning {
                min_valid: Some(f32::NAN),
                ..Default::default()
            },
        ];
        for t in bad {
            assert!(t.apply(TrackerConfig::default()).is_err(), "{t:?}");
        }
    }
}
