//! The application layer: what `splattrack track`, `splattrack demo` and a
//! program embedding the crate share. Loading everything a tracking run
//! needs ([`TrackInputs`]), the keyframe store from a file or from
//! keyframe images ([`load_keyframes`], [`load_or_build_keyframes`]), and
//! the run over a sequence ([`TrackRun`]): frames in order, undistorted,
//! one pose row per frame written as it is tracked (crash-safe), optional
//! overlays and BOP results, progress through a [`ProgressFn`], a
//! callback per frame and a [`FrameSink`] (the live view).

use crate::draw;
use crate::geometry::{Intrinsics, Pose, Undistorter};
use crate::gpu::GpuContext;
use crate::io::atomic::WriteError;
use crate::io::bop::BopWriter;
use crate::io::poses::{PoseFileError, PoseRow, PoseWriter, read_poses};
use crate::io::sequence::{Frame, Sequence, SequenceError};
use crate::keyframes::{KeyframeConfig, KeyframeError, KeyframeStore, load_keyframe_images};
use crate::model::{LoadOptions, ModelError, PointModel};
use crate::progress::{ProgressEvent, ProgressFn};
use crate::splat::{SplatError, Splatter};
use crate::tracker::{Status, TrackError, TrackResult, Tracker, TrackerConfig};
use crate::view::{Flow, FrameSink, ViewError, ViewFrame};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Why a tracking run could not be set up or finished (a lost frame is not
/// an error).
#[derive(Debug, thiserror::Error)]
pub enum AppError {
    /// The point model could not be loaded.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The sequence directory or one of its frames is unusable.
    #[error(transparent)]
    Sequence(#[from] SequenceError),
    /// A pose file could not be read or written.
    #[error(transparent)]
    Poses(#[from] PoseFileError),
    /// An output file (BOP results) could not be written.
    #[error(transparent)]
    Write(#[from] WriteError),
    /// A keyframe store could not be loaded or saved, or is for another model.
    #[error(transparent)]
    Keyframes(#[from] KeyframeError),
    /// The splatter could not be created.
    #[error(transparent)]
    Splat(#[from] SplatError),
    /// A keyframe path that is neither a store nor a keyframe directory.
    #[error("{0}: not a keyframe store file nor a directory with poses.csv")]
    NotKeyframes(PathBuf),
    /// Building a keyframe store from images failed.
    #[error("building keyframes from {path}: {source}")]
    BuildKeyframes {
        /// The keyframe directory.
        path: PathBuf,
        /// Why.
        #[source]
        source: KeyframeError,
    },
    /// A keyframe image could not be undistorted.
    #[error("{path}: cannot undistort: {reason}")]
    Undistort {
        /// The keyframe directory.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The tracker refused its inputs.
    #[error("starting the tracker on {sequence}: {source}")]
    Start {
        /// The sequence directory.
        sequence: PathBuf,
        /// Why.
        #[source]
        source: Box<TrackError>,
    },
    /// Tracking stopped at a frame (bad frame, GPU failure).
    #[error("{frame}: {source}")]
    Track {
        /// The frame's image file.
        frame: PathBuf,
        /// Why.
        #[source]
        source: Box<TrackError>,
    },
    /// An overlay picture could not be written.
    #[error("{path}: cannot write: {source}")]
    Overlay {
        /// The picture or its directory.
        path: PathBuf,
        /// Why.
        #[source]
        source: image::ImageError,
    },
    /// No frame to track (an empty range).
    #[error("no frames to track")]
    NoFrames,
    /// An output would overwrite one of the run's inputs.
    #[error(transparent)]
    Clobber(#[from] crate::io::guard::ClobberError),
    /// The live view failed.
    #[error(transparent)]
    View(#[from] ViewError),
}

/// Loads the keyframe store `path` names: a store file saved by
/// [`KeyframeStore::save`] (refused when built for another model), or a
/// directory of keyframe images with `poses.csv`, built into a store here.
/// `cam` is the camera of the images as calibrated (distortion included).
pub fn load_keyframes(
    ctx: &GpuContext,
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
    ctx: &GpuContext,
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
    ctx: &GpuContext,
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
    /// The object's point model.
    pub model: PointModel,
    /// The sequence, its camera and frames.
    pub sequence: Sequence,
    /// The pose of the first frame; `None`: the tracker searches the
    /// frames for the object ([`Tracker::new_searching`]).
    pub init: Option<Pose>,
    /// The keyframe store, when there is one.
    pub keyframes: Option<KeyframeStore>,
}

impl TrackInputs {
    /// Loads the model, opens the sequence, reads the initial pose (`init`,
    /// default `SEQUENCE/init.csv` when present: its first row; neither:
    /// none, the object is searched for) and loads or builds the
    /// keyframe store `keyframes` names ([`load_keyframes`]; default
    /// `SEQUENCE/keyframes` when present, else none). `model_options`
    /// says how the model is loaded (progress, estimation settings).
    pub fn load(
        ctx: &GpuContext,
        model: &Path,
        model_options: &LoadOptions,
        sequence: &Path,
        keyframes: Option<&Path>,
        init: Option<&Path>,
    ) -> Result<Self, AppError> {
        let model = PointModel::load_with(model, model_options)?;
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
            model,
            sequence,
            init,
            keyframes,
        })
    }
}

/// The columns the tracker output adds after the pose (FORMATS.md
/// "Tracker output").
pub const RESULT_COLUMNS: [&str; 3] = ["inliers", "residual_px", "status"];

/// The tracker output row of a frame.
pub fn result_row(label: &str, r: &TrackResult) -> PoseRow {
    let mut row = PoseRow::new(label, r.pose);
    let residual = if r.residual_px.is_finite() {
        format!("{:.3}", r.residual_px)
    } else {
        "nan".into()
    };
    row.extra = [r.inliers.to_string(), residual, r.status.name().into()]
        .into_iter()
        .zip(RESULT_COLUMNS)
        .map(|(v, k)| (k.to_string(), v))
        .collect();
    row
}

/// What a run measured.
#[derive(Debug, Clone, Default)]
pub struct RunStats {
    /// Frames tracked.
    pub frames: usize,
    /// Of which lost.
    pub lost: usize,
    /// Mean milliseconds per frame: features, IT, KF, total.
    pub mean_ms: [f64; 4],
    /// Mean milliseconds per frame of the contour step.
    pub contour_ms: f64,
    /// Median total milliseconds per frame.
    pub median_ms: f64,
    /// Mean time per frame of every stage and sub-stage.
    pub mean_stages: crate::tracker::StageTimes,
    /// The run ended before its last frame because its [`FrameSink`] said
    /// [`Flow::Stop`] (the live view was closed); `frames` counts the
    /// frames tracked.
    pub stopped: bool,
}

/// The progress stage a [`TrackRun`] reports, in frames.
pub const TRACKING_STAGE: &str = "tracking";

/// A tracking run over a sequence: the tracker, its settings and where the
/// results go. Built with the setters, started by [`TrackRun::run`].
pub struct TrackRun<'a> {
    ctx: &'a GpuContext,
    inputs: &'a TrackInputs,
    config: TrackerConfig,
    limit: Option<usize>,
    poses: Option<PathBuf>,
    overlays: Option<(PathBuf, usize)>,
    bop: Option<(PathBuf, u32)>,
    progress: Option<ProgressFn>,
    gpu_timing: bool,
    sink: Option<Box<dyn FrameSink + 'a>>,
}

impl<'a> TrackRun<'a> {
    /// A run of the tracker `config` describes over `inputs`' sequence,
    /// writing nothing yet.
    pub fn new(ctx: &'a GpuContext, inputs: &'a TrackInputs, config: TrackerConfig) -> Self {
        Self {
            ctx,
            inputs,
            config,
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
    /// ([`Tracker::enable_gpu_timing`]; the means land in
    /// [`RunStats::mean_stages`]).
    pub fn gpu_timing(mut self, on: bool) -> Self {
        self.gpu_timing = on;
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
    /// that frame as at the end of the sequence (outputs complete for the
    /// frames tracked, [`RunStats::stopped`] set).
    pub fn sink(mut self, sink: impl FrameSink + 'a) -> Self {
        self.sink = Some(Box::new(sink));
        self
    }

    /// Tracks the frames in order, writing the outputs as it goes and
    /// calling `on_frame` after each frame; the output files appear only
    /// when every frame is done.
    pub fn run(self, mut on_frame: impl FnMut(&Frame, &TrackResult)) -> Result<RunStats, AppError> {
        let seq = &self.inputs.sequence;
        let n = self.limit.unwrap_or(seq.frames.len()).min(seq.frames.len());
        if n == 0 {
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
            seq.tracking_camera(),
            self.inputs.keyframes.clone(),
        );
        let mut tracker = match self.inputs.init {
            Some(init) => Tracker::new(self.ctx, model, cam, store, self.config, init),
            None => Tracker::new_searching(self.ctx, model, cam, store, self.config),
        }
        .map_err(|source| AppError::Start {
            sequence: seq.dir.clone(),
            source: Box::new(source),
        })?;
        if self.gpu_timing {
            tracker.enable_gpu_timing();
        }
        let mut poses = match &self.poses {
            Some(p) => Some(PoseWriter::create(p, &RESULT_COLUMNS)?),
            None => None,
        };
        let mut bop = match &self.bop {
            Some((p, obj)) => Some(BopWriter::create(p, *obj)?),
            None => None,
        };
        let report = |done: usize| {
            if let Some(p) = &self.progress {
                p(ProgressEvent {
                    stage: TRACKING_STAGE,
                    done: done as u64,
                    total: n as u64,
                });
            }
        };
        report(0);
        let mut stats = RunStats {
            frames: n,
            ..Default::default()
        };
        let mut totals = Vec::with_capacity(n);
        let mut done = 0;
        let mut rate = crate::view::Rate::default();
        for frame in seq.iter_frames().take(n) {
            let frame = frame?;
            let i = frame.index;
            let r = tracker
                .track(&frame.image)
                .map_err(|source| AppError::Track {
                    frame: frame.path.clone(),
                    source: Box::new(source),
                })?;
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
                w.row(&result_row(&frame.label, &r))?;
            }
            let t = &r.times;
            for (acc, d) in stats
                .mean_ms
                .iter_mut()
                .zip([t.features, t.it, t.kf, t.total])
            {
                *acc += ms(d) / n as f64;
            }
            stats.contour_ms += ms(t.contour) / n as f64;
            stats.mean_stages.add_scaled(t, 1.0 / n as f64);
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
                            frame: frame.path.clone(),
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
            report(i + 1);
            done += 1;
            if let Some(s) = sink.as_mut() {
                let view = ViewFrame {
                    index: i,
                    label: &frame.label,
                    image: &frame.image,
                    result: &r,
                    mask: mask.as_deref().filter(|_| s.wants_mask()),
                    // Image folders have no timestamps; a video's go here.
                    time_s: None,
                    rate_hz: rate.tick(),
                    mode,
                };
                if s.frame(&view)? == Flow::Stop {
                    break;
                }
            }
        }
        if done < n {
            // Stopped by the sink: the means were taken over n frames.
            stats.stopped = true;
            stats.frames = done;
            let k = n as f64 / done as f64;
            stats.mean_ms.iter_mut().for_each(|v| *v *= k);
            stats.contour_ms *= k;
            let stages = std::mem::take(&mut stats.mean_stages);
            stats.mean_stages.add_scaled(&stages, k);
        }
        if let Some(w) = poses {
            w.finish()?;
        }
        if let Some(w) = bop {
            w.finish()?;
        }
        totals.sort_by(f64::total_cmp);
        stats.median_ms = totals[totals.len() / 2];
        Ok(stats)
    }
}

impl TrackRun<'_> {
    /// Refuses, before anything is written, outputs that would overwrite
    /// the sequence's files (camera, init.csv, ground truth, keyframe
    /// poses, frames) or each other, and overlays aimed at the frames or
    /// keyframes folder.
    fn check_outputs(&self) -> Result<(), AppError> {
        use crate::io::guard::{check_output, check_output_dir};
        let seq = &self.inputs.sequence;
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
