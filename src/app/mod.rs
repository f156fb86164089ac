//! The application layer: what `splattrack track`, `splattrack demo` and a
//! program embedding the crate share. Loading everything a tracking run
//! needs ([`TrackInputs`]), the keyframe store from a file or from
//! keyframe images ([`load_keyframes`], [`load_or_build_keyframes`]), and
//! the run over a sequence, a video or a camera ([`TrackRun`], frames from
//! any [`FrameSource`]): frames in order, undistorted, one pose row per
//! frame written as it is tracked (crash-safe), optional overlays and BOP
//! results, progress through a [`ProgressFn`], a callback per frame and a
//! [`FrameSink`] (the live view).

mod error;
pub mod refused;
mod stats;
mod tuning;

pub use error::AppError;
pub use stats::{FrameMs, RunStats};
pub use tuning::{MAX_CORNERS, Tuning, TuningError, run_mode};

use crate::device::{AsDevice, Device};
use crate::draw;
use crate::geometry::{Intrinsics, Pose, Undistorter};
use crate::io::bop::BopWriter;
use crate::io::poses::{PoseRow, PoseWriter, read_poses};
use crate::io::sequence::{Frame, Sequence};
use crate::io::source::{FrameSource, SequenceFrames};
use crate::keyframes::{KeyframeConfig, KeyframeStore, load_keyframe_images};
use crate::model::{LoadOptions, PointModel};
use crate::progress::{ProgressEvent, ProgressFn};
use crate::splat::Splatter;
use crate::tracker::{Status, TrackResult, Tracker, TrackerConfig};
use crate::view::{Flow, FrameSink, ViewFrame};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Loads the keyframe store `path` names: a store file saved by
/// [`KeyframeStore::save`] (refused when built for another model), or a
/// directory of keyframe images with `poses.csv`, built into a store here.
/// `cam` is the camera of the images as calibrated (distortion included).
pub fn load_keyframes(
    ctx: &impl AsDevice,
    model: &PointModel,
    cam: &Intrinsics,
    path: &Path,
) -> Result<KeyframeStore, AppError> {
    if path.is_file() {
        let store = KeyframeStore::load(path)?;
        store.check_model(model, path)?;
        return Ok(store);
    }
    build_keyframes(ctx, model, cam, path)
}

/// Builds a keyframe store from a directory of keyframe images and their
/// `poses.csv`, undistorting the images when `cam` has distortion.
pub fn build_keyframes(
    ctx: &impl AsDevice,
    model: &PointModel,
    cam: &Intrinsics,
    dir: &Path,
) -> Result<KeyframeStore, AppError> {
    let poses = dir.join("poses.csv");
    if !poses.is_file() {
        return Err(AppError::NotKeyframes(dir.to_owned()));
    }
    let rows = read_poses(&poses)?;
    let mut images = load_keyframe_images(dir, &rows, cam)?;
    if cam.has_distortion() {
        let und = Undistorter::new(cam);
        for (_, img, _) in &mut images {
            *img = und.apply(img).map_err(|reason| AppError::Undistort {
                path: dir.to_owned(),
                reason,
            })?;
        }
    }
    let splatter = Splatter::new(ctx)?;
    KeyframeStore::build(
        ctx,
        &splatter,
        model,
        &cam.undistorted(),
        &images,
        &KeyframeConfig::default(),
    )
    .map_err(|source| AppError::BuildKeyframes {
        path: dir.to_owned(),
        source,
    })
}

/// Where [`load_or_build_keyframes`] got its store.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeyframeOrigin {
    /// The cached store, which matched the model.
    Loaded,
    /// Built from the images (no cache, or a stale or unreadable one) and
    /// saved as the cache.
    Built,
}

/// The keyframe store cached at `cache` when it loads and was built for
/// `model`; otherwise built from the images in `dir` ([`build_keyframes`])
/// and saved to `cache`, so the next run skips the build.
pub fn load_or_build_keyframes(
    ctx: &impl AsDevice,
    model: &PointModel,
    cam: &Intrinsics,
    dir: &Path,
    cache: &Path,
) -> Result<(KeyframeStore, KeyframeOrigin), AppError> {
    if cache.is_file() {
        match KeyframeStore::load(cache).and_then(|s| s.check_model(model, cache).map(|_| s)) {
            Ok(store) => return Ok((store, KeyframeOrigin::Loaded)),
            Err(e) => log::info!("rebuilding the keyframe store: {e}"),
        }
    }
    let store = build_keyframes(ctx, model, cam, dir)?;
    store.save(cache)?;
    Ok((store, KeyframeOrigin::Built))
}

/// Everything a tracking run needs, loaded and checked.
pub struct TrackInputs {
    /// The object's point model (shared with each run's tracker, not
    /// copied, where the tracker keeps its radii: [`Tracker::builder`]).
    pub model: Arc<PointModel>,
    /// The sequence, its camera and frames, when the frames come from a
    /// sequence directory (`None`: from a video or a camera, given to the
    /// run by [`TrackRun::source`]).
    pub sequence: Option<Sequence>,
    /// The camera as calibrated (with its distortion, if any).
    pub camera: Intrinsics,
    /// The camera file.
    pub camera_path: PathBuf,
    /// The pose of the first frame; `None`: the tracker searches the
    /// frames for the object ([`crate::tracker::TrackerBuilder::initial_pose`]).
    pub init: Option<Pose>,
    /// The keyframe store, when there is one (shared with each run's
    /// tracker, not copied: [`crate::tracker::TrackerBuilder::keyframes`]).
    pub keyframes: Option<Arc<KeyframeStore>>,
}

impl TrackInputs {
    /// Loads the model (a mesh sampled into one:
    /// [`PointModel::load_any_with`]), opens the sequence, reads the initial pose (`init`,
    /// default `SEQUENCE/init.csv` when present: its first row; neither:
    /// none, the object is searched for) and loads or builds the
    /// keyframe store `keyframes` names ([`load_keyframes`]; default
    /// `SEQUENCE/keyframes` when present, else none). `model_options`
    /// says how the model is loaded (progress, estimation settings).
    pub fn load(
        ctx: &impl AsDevice,
        model: &Path,
        model_options: &LoadOptions,
        sequence: &Path,
        keyframes: Option<&Path>,
        init: Option<&Path>,
    ) -> Result<Self, AppError> {
        let model = PointModel::load_any_with(model, 0, model_options)?;
        let sequence = Sequence::open(sequence)?;
        let init_path = init.map(Path::to_owned).or_else(|| {
            let p = sequence.init_path();
            p.exists().then_some(p)
        });
        let init = match init_path {
            Some(p) => Some(read_poses(&p)?[0].pose),
            None => None,
        };
        let kf_path = keyframes
            .map(Path::to_owned)
            .or_else(|| sequence.keyframes_dir());
        let keyframes = match kf_path {
            Some(p) => Some(load_keyframes(ctx, &model, &sequence.camera, &p)?),
            None => None,
        };
        Ok(Self {
            model: Arc::new(model),
            camera: sequence.camera,
            camera_path: sequence.camera_path.clone(),
            sequence: Some(sequence),
            init,
            keyframes: keyframes.map(Arc::new),
        })
    }

    /// For frames from a video or a camera: loads the model (a mesh
    /// sampled into one), the camera
    /// file `camera` (camera.json or an OpenCV yaml), the initial pose
    /// (`init`: its first row is the pose of the first frame tracked;
    /// `None`: the object is searched for) and the keyframe store
    /// `keyframes` names, if any ([`load_keyframes`]).
    pub fn load_with_camera(
        ctx: &impl AsDevice,
        model: &Path,
        model_options: &LoadOptions,
        camera: &Path,
        keyframes: Option<&Path>,
        init: Option<&Path>,
    ) -> Result<Self, AppError> {
        let model = PointModel::load_any_with(model, 0, model_options)?;
        let cam = Intrinsics::load(camera)?;
        let init = match init {
            Some(p) => Some(read_poses(p)?[0].pose),
            None => None,
        };
        let keyframes = match keyframes {
            Some(p) => Some(load_keyframes(ctx, &model, &cam, p)?),
            None => None,
        };
        Ok(Self {
            model: Arc::new(model),
            sequence: None,
            camera: cam,
            camera_path: camera.to_owned(),
            init,
            keyframes: keyframes.map(Arc::new),
        })
    }

    /// Whether the KF step's views have a texture: keyframes, or colours
    /// in the model ([`run_mode`]).
    pub fn textured(&self) -> bool {
        self.keyframes.is_some() || self.model.colors.is_some()
    }

    /// The camera of the frames the tracker sees: the calibrated one
    /// without its distortion.
    pub fn tracking_camera(&self) -> Intrinsics {
        self.camera.undistorted()
    }
}

/// The columns the tracker output adds after the pose (FORMATS.md
/// "Tracker output"; `cues`: [`cues_name`] of [`TrackResult::cues`]).
pub const RESULT_COLUMNS: [&str; 4] = ["inliers", "residual_px", "status", "cues"];

/// The column a run over a video or a camera adds after [`RESULT_COLUMNS`]:
/// the frame's timestamp in seconds (FORMATS.md, `track --video`).
pub const TIME_COLUMN: &str = "time_s";

/// The tracker output row of a frame.
pub fn result_row(label: &str, r: &TrackResult) -> PoseRow {
    let mut row = PoseRow::new(label, r.pose);
    let residual = if r.residual_px.is_finite() {
        format!("{:.3}", r.residual_px)
    } else {
        "nan".into()
    };
    row.extra = [
        r.inliers.to_string(),
        residual,
        r.status.name().into(),
        cues_name(r.cues),
    ]
    .into_iter()
    .zip(RESULT_COLUMNS)
    .map(|(v, k)| (k.to_string(), v))
    .collect();
    row
}

/// The cues of a frame as the `cues` column writes them: `texture`,
/// `contour`, `texture+contour` (no comma inside a CSV field) or `none`.
pub fn cues_name(m: crate::tracker::Modalities) -> String {
    m.name().replace(',', "+")
}

/// The progress stage a [`TrackRun`] reports, in frames.
pub const TRACKING_STAGE: &str = "tracking";

/// A tracking run over a sequence, a video or a camera: the tracker, its
/// settings, where the frames come from and where the results go. Built
/// with the setters, started by [`TrackRun::run`].
pub struct TrackRun<'a> {
    device: Device,
    inputs: &'a TrackInputs,
    config: TrackerConfig,
    source: Option<Box<dyn FrameSource + 'a>>,
    start: usize,
    stop: Option<Arc<AtomicBool>>,
    limit: Option<usize>,
    poses: Option<PathBuf>,
    overlays: Option<(PathBuf, usize)>,
    bop: Option<(PathBuf, u32)>,
    progress: Option<ProgressFn>,
    gpu_timing: bool,
    sink: Option<Box<dyn FrameSink + 'a>>,
}

impl<'a> TrackRun<'a> {
    /// A run of the tracker `config` describes over `inputs`' sequence
    /// (or the source [`TrackRun::source`] gives), writing nothing yet,
    /// on `device` (a [`Device`], or a `&GpuContext`).
    pub fn new(device: impl Into<Device>, inputs: &'a TrackInputs, config: TrackerConfig) -> Self {
        Self {
            device: device.into(),
            inputs,
            config,
            source: None,
            start: 0,
            stop: None,
            limit: None,
            poses: None,
            overlays: None,
            bop: None,
            progress: None,
            gpu_timing: false,
            sink: None,
        }
    }

    /// Times every GPU pass with timestamp queries
    /// ([`crate::tracker::Execution::gpu_timing`]; the means land in
    /// [`RunStats::mean_stages`]).
    pub fn gpu_timing(mut self, on: bool) -> Self {
        self.gpu_timing = on;
        self
    }

    /// Takes the frames from `source` (a video, a camera) instead of the
    /// inputs' sequence. Its camera is the one the tracker uses; it should
    /// be the inputs' camera, for which the keyframes were built.
    pub fn source(mut self, source: Box<dyn FrameSource + 'a>) -> Self {
        self.source = Some(source);
        self
    }

    /// Starts at frame `index` of the inputs' sequence (a [`Self::source`]
    /// has its own start, e.g. [`crate::io::video::VideoSource::open`]'s).
    pub fn start(mut self, index: usize) -> Self {
        self.start = index;
        self
    }

    /// Ends the run cleanly, after the frame being tracked, once `flag` is
    /// set (Ctrl-C on a live camera): every finished frame is written and
    /// the outputs are put in place as at the end of the frames.
    pub fn stop_on(mut self, flag: Arc<AtomicBool>) -> Self {
        self.stop = Some(flag);
        self
    }

    /// Tracks only the first `n` frames (`None`: all).
    pub fn limit(mut self, n: Option<usize>) -> Self {
        self.limit = n;
        self
    }

    /// Writes the tracker output CSV to `path`, row by row ([`PoseWriter`]).
    pub fn poses(mut self, path: &Path) -> Self {
        self.poses = Some(path.to_owned());
        self
    }

    /// Writes every `every`-th frame (1: all) with the model's outline at
    /// the tracked pose (green tracking, red lost) into `dir`, as
    /// `NNNNNN.png`.
    pub fn overlays(mut self, dir: &Path, every: usize) -> Self {
        self.overlays = Some((dir.to_owned(), every.max(1)));
        self
    }

    /// Writes BOP-style results for object `obj_id` to `path`.
    pub fn bop(mut self, path: &Path, obj_id: u32) -> Self {
        self.bop = Some((path.to_owned(), obj_id));
        self
    }

    /// Reports each tracked frame to `progress` (stage [`TRACKING_STAGE`]).
    pub fn progress(mut self, progress: Option<ProgressFn>) -> Self {
        self.progress = progress;
        self
    }

    /// Hands every finished frame to `sink` (the live view,
    /// [`crate::view`]), after the outputs are written: the frame, its
    /// result, the model's silhouette at the tracked pose when the sink
    /// wants it. When the sink answers [`Flow::Stop`] the run ends after
    /// that frame as at the end of the frames (outputs complete for the
    /// frames tracked, [`RunStats::stopped`] set).
    pub fn sink(mut self, sink: impl FrameSink + 'a) -> Self {
        self.sink = Some(Box::new(sink));
        self
    }

    /// Tracks the frames in order, writing the outputs as it goes (each
    /// pose row flushed as it is written) and calling `on_frame` after each
    /// frame; the output files appear only when the run ends: at the end
    /// of the frames, after the limit, or on the stop flag. A video or a
    /// camera adds the column [`TIME_COLUMN`] to the pose file.
    pub fn run(
        mut self,
        mut on_frame: impl FnMut(&Frame, &TrackResult),
    ) -> Result<RunStats, AppError> {
        let inputs = self.inputs;
        let mut source: Box<dyn FrameSource + 'a> = match self.source.take() {
            Some(s) => s,
            None => match &inputs.sequence {
                Some(seq) => {
                    // Reading ahead takes a core: not where the tracker
                    // works on the host's.
                    let ahead = self.device.gpu().is_some_and(|c| !c.is_cpu());
                    Box::new(SequenceFrames::new(seq, self.start).read_ahead(ahead))
                }
                None => return Err(AppError::NoSource),
            },
        };
        // The frames to track, when known (a sequence; a limit).
        let n = match (source.remaining(), self.limit) {
            (Some(r), Some(l)) => Some(r.min(l)),
            (r, l) => r.or(l),
        };
        if n == Some(0) {
            return Err(AppError::NoFrames);
        }
        self.check_outputs()?;
        let mut sink = self.sink;
        if let Some((dir, _)) = &self.overlays {
            std::fs::create_dir_all(dir).map_err(|e| AppError::Overlay {
                path: dir.clone(),
                source: e.into(),
            })?;
        }
        let mode = self.config.mode;
        let (model, cam, store) = (
            self.inputs.model.clone(),
            source.tracking_camera(),
            self.inputs.keyframes.clone(),
        );
        let mut tracker = Tracker::builder(&self.device, model, cam)
            .maybe_keyframes(store)
            .config(self.config)
            .initial_pose(self.inputs.init)
            .execution(crate::tracker::Execution {
                gpu_timing: self.gpu_timing,
                ..Default::default()
            })
            .build()
            .map_err(|e| AppError::Start {
                sequence: source.name().to_owned(),
                source: Box::new(e),
            })?;
        let mut stats = RunStats {
            modalities: Some(tracker.config().modalities),
            cue_choice: tracker.cue_choice(),
            ..Default::default()
        };
        let timestamps = source.has_timestamps();
        let mut columns = RESULT_COLUMNS.to_vec();
        if timestamps {
            columns.push(TIME_COLUMN);
        }
        let mut poses = match &self.poses {
            Some(p) => Some(PoseWriter::create(p, &columns)?),
            None => None,
        };
        let mut bop = match &self.bop {
            Some((p, obj)) => Some(BopWriter::create(p, *obj)?),
            None => None,
        };
        // The progress total: the frames to track where known, else about
        // how many a video has left (0: unknown, a live camera).
        let total = n
            .or_else(|| source.expected())
            .map_or(0, |e| self.limit.map_or(e, |l| e.min(l)));
        let report = |done: usize| {
            if let Some(p) = &self.progress {
                p(ProgressEvent {
                    stage: TRACKING_STAGE,
                    done: done as u64,
                    total: total.max(done) as u64,
                });
            }
        };
        report(0);
        let mut sum_stages = crate::tracker::StageTimes::default();
        let mut source_time = Duration::ZERO;
        let mut totals = Vec::with_capacity(n.unwrap_or(0).min(1 << 16));
        let stop = self.stop.clone();
        let stopped = || stop.as_ref().is_some_and(|f| f.load(Ordering::SeqCst));
        let limit = n.unwrap_or(usize::MAX);
        let mut rate = crate::view::Rate::default();
        let mut sink_stopped = false;
        while totals.len() < limit {
            if stopped() {
                break;
            }
            let t0 = Instant::now();
            let Some(frame) = source.next_frame()? else {
                break;
            };
            source_time += t0.elapsed();
            let i = frame.index;
            let r = tracker
                .track(&frame.image)
                .map_err(|source| AppError::Track {
                    frame: frame_name(&frame),
                    source: Box::new(source),
                })?;
            if r.texture_set_aside {
                stats.texture_set_aside += 1;
                log::info!("frame {i}: texture set aside, the contour alone passed the check");
            }
            match (r.cues.texture, r.cues.contour) {
                (true, false) => stats.held_by[0] += 1,
                (false, true) => stats.held_by[1] += 1,
                (true, true) => stats.held_by[2] += 1,
                (false, false) => {}
            }
            if r.status == Status::Lost {
                stats.lost += 1;
                log::info!(
                    "frame {i}: lost ({})",
                    r.reason
                        .as_ref()
                        .map_or_else(|| "no reason".to_owned(), ToString::to_string)
                );
            }
            if let Some(w) = &mut poses {
                let mut row = result_row(&frame.label, &r);
                if timestamps {
                    let t = frame.time_s.unwrap_or(f64::NAN);
                    let t = if t.is_finite() {
                        format!("{t:.6}")
                    } else {
                        "nan".into()
                    };
                    row.extra.push((TIME_COLUMN.into(), t));
                }
                w.row(&row)?;
            }
            let t = &r.times;
            let m = &mut stats.mean;
            m.features += ms(t.features);
            m.it += ms(t.it);
            m.kf += ms(t.kf);
            m.total += ms(t.total);
            stats.contour_ms += ms(t.contour);
            sum_stages.add_scaled(t, 1.0);
            totals.push(ms(t.total));
            if let Some(w) = &mut bop {
                let score = if r.status == Status::Tracking {
                    1.0
                } else {
                    0.0
                };
                w.row(i, &r.pose, score, t.total.as_secs_f64())?;
            }
            let overlay = self.overlays.as_ref().filter(|(_, every)| i % every == 0);
            let mask = if overlay.is_some() || sink.as_ref().is_some_and(|s| s.wants_mask()) {
                Some(
                    tracker
                        .silhouette(&r.pose)
                        .map_err(|source| AppError::Track {
                            frame: frame_name(&frame),
                            source: Box::new(source),
                        })?,
                )
            } else {
                None
            };
            if let (Some((dir, _)), Some(mask)) = (overlay, &mask) {
                let colour = crate::view::status_colour(r.status);
                let label = format!(
                    "{} frame {i}  {}  {} inliers  {:.2} px",
                    mode.name(),
                    r.status.name(),
                    r.inliers,
                    r.residual_px
                );
                let path = dir.join(format!("{i:06}.png"));
                draw::silhouette_overlay(&frame.image, mask, colour, &label)
                    .save(&path)
                    .map_err(|source| AppError::Overlay { path, source })?;
            }
            on_frame(&frame, &r);
            report(totals.len());
            if let Some(s) = sink.as_mut() {
                let view = ViewFrame {
                    index: i,
                    label: &frame.label,
                    image: &frame.image,
                    result: &r,
                    mask: mask.as_deref().filter(|_| s.wants_mask()),
                    time_s: frame.time_s,
                    rate_hz: rate.tick(),
                    mode,
                };
                if s.frame(&view)? == Flow::Stop {
                    sink_stopped = true;
                    break;
                }
            }
        }
        stats.dropped = source.dropped();
        stats.stopped = stopped() || sink_stopped;
        let done = totals.len();
        if done == 0 {
            // Nothing tracked (an empty video, a stop before the first
            // frame): no output, not even a partial one.
            drop((poses, bop));
            for p in [
                self.poses.as_deref(),
                self.bop.as_ref().map(|b| b.0.as_path()),
            ]
            .into_iter()
            .flatten()
            {
                let _ = std::fs::remove_file(crate::io::atomic::partial_path(p));
            }
            return Err(AppError::NoFrames);
        }
        if let Some(w) = poses {
            w.finish()?;
        }
        if let Some(w) = bop {
            w.finish()?;
        }
        let k = 1.0 / done as f64;
        stats.frames = done;
        let m = &mut stats.mean;
        (m.features, m.it, m.kf, m.total) = (m.features * k, m.it * k, m.kf * k, m.total * k);
        stats.contour_ms *= k;
        stats.mean_stages.add_scaled(&sum_stages, k);
        stats.source_ms = ms(source_time) * k;
        totals.sort_by(f64::total_cmp);
        stats.median_ms = totals[totals.len() / 2];
        stats.gpu_memory = Some(tracker.gpu_memory());
        Ok(stats)
    }
}

/// A frame as errors name it: its image file, or the video or device and
/// the frame's number.
fn frame_name(frame: &Frame) -> PathBuf {
    match frame.time_s {
        None => frame.path.clone(),
        Some(_) => PathBuf::from(format!("{}, frame {}", frame.path.display(), frame.index)),
    }
}

impl TrackRun<'_> {
    /// Refuses, before anything is written, outputs that would overwrite
    /// the sequence's files (camera, init.csv, ground truth, keyframe
    /// poses, frames) or each other, and overlays aimed at the frames or
    /// keyframes folder.
    fn check_outputs(&self) -> Result<(), AppError> {
        use crate::io::guard::{check_output, check_output_dir};
        let Some(seq) = &self.inputs.sequence else {
            // A video or a camera: the outputs must not be the camera
            // file nor each other (the caller checks its other inputs).
            let inputs = [self.inputs.camera_path.as_path()];
            if let Some(p) = &self.poses {
                check_output(p, "pose output", &inputs)?;
            }
            if let Some((p, _)) = &self.bop {
                let mut with_poses = inputs.to_vec();
                with_poses.extend(self.poses.as_deref());
                check_output(p, "BOP output", &with_poses)?;
            }
            return Ok(());
        };
        let init = seq.init_path();
        let gt = seq.dir.join("poses.csv");
        let kf_dir = seq.dir.join("keyframes");
        let kf_poses = kf_dir.join("poses.csv");
        let frames_dir = seq.dir.join("frames");
        let mut inputs: Vec<&Path> = vec![&seq.camera_path, &init, &gt, &kf_poses];
        inputs.extend(seq.frames.iter().map(PathBuf::as_path));
        if let Some(p) = &self.poses {
            check_output(p, "pose output", &inputs)?;
        }
        if let Some((p, _)) = &self.bop {
            let mut with_poses = inputs.clone();
            with_poses.extend(self.poses.as_deref());
            check_output(p, "BOP output", &with_poses)?;
        }
        if let Some((dir, _)) = &self.overlays {
            check_output_dir(
                dir,
                "overlay folder",
                &[&frames_dir, &kf_dir, &seq.dir],
                &[],
            )?;
        }
        Ok(())
    }
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}
