//! The run over the frames ([`TrackRun`]): one object, or several
//! ([`TrackRun::objects`]), each frame's outputs written as it is tracked.

use super::inputs::{ObjectInputs, TrackInputs};
use super::objects::Trackers;
use super::stats::{ObjectStats, RunStats, Tally};
use super::{AppError, RESULT_COLUMNS, TIME_COLUMN, result_row};
use crate::device::Device;
use crate::draw;
use crate::io::bop::{BopWriter, bop_obj_id};
use crate::io::poses::PoseWriter;
use crate::io::sequence::Frame;
use crate::io::source::{FrameSource, SequenceFrames};
use crate::progress::{ProgressEvent, ProgressFn};
use crate::tracker::{MultiTracker, Status, TrackResult, Tracker, TrackerConfig};
use crate::view::{Flow, FrameSink, ViewFrame, ViewObject};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

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
    objects: Option<Vec<ObjectInputs>>,
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
            objects: None,
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

    /// Tracks these objects, each with its own model, first pose,
    /// keyframes and settings, instead of the inputs' object (whose model,
    /// first pose and keyframes, and the run's settings, are then unused;
    /// the inputs give the camera and the frames). Each frame's rows are
    /// written in the objects' order, each with its name in the `object`
    /// column; two objects or more are tracked together by a
    /// [`MultiTracker`], one alone by its [`Tracker`] (the same poses).
    pub fn objects(mut self, objects: Vec<ObjectInputs>) -> Self {
        self.objects = Some(objects);
        self
    }

    /// Writes BOP-style results for object `obj_id` to `path` (in a run
    /// of [`Self::objects`], each object's id comes from its name:
    /// [`bop_obj_id`]).
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
    /// frame with the first object's result; the output files appear only
    /// when the run ends: at the end of the frames, after the limit, or on
    /// the stop flag. A video or a camera adds the column [`TIME_COLUMN`]
    /// to the pose file.
    pub fn run(self, mut on_frame: impl FnMut(&Frame, &TrackResult)) -> Result<RunStats, AppError> {
        self.run_objects(|frame, results| on_frame(frame, &results[0]))
    }

    /// [`Self::run`], calling `on_frame` with every object's result, in
    /// the objects' order.
    pub fn run_objects(
        mut self,
        mut on_frame: impl FnMut(&Frame, &[TrackResult]),
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
        let mut sink = self.sink.take();
        if let Some((dir, _)) = &self.overlays {
            std::fs::create_dir_all(dir).map_err(|e| AppError::Overlay {
                path: dir.clone(),
                source: e.into(),
            })?;
        }
        let cam = source.tracking_camera();
        let (mut trackers, names) = self.trackers(&cam, source.name())?;
        let named = !names.is_empty();
        let mode = match &self.objects {
            Some(objects) => objects[0].config.mode,
            None => self.config.mode,
        };
        let mut stats = RunStats::default();
        if !named {
            stats.modalities = Some(trackers.tracker(0).config().modalities);
            stats.cue_choice = trackers.tracker(0).cue_choice();
        }
        let mut per_object: Vec<Tally> = names
            .iter()
            .enumerate()
            .map(|(k, name)| {
                Tally::new(ObjectStats {
                    name: name.clone(),
                    modalities: Some(trackers.tracker(k).config().modalities),
                    cue_choice: trackers.tracker(k).cue_choice(),
                    ..Default::default()
                })
            })
            .collect();
        let timestamps = source.has_timestamps();
        let mut columns = RESULT_COLUMNS.to_vec();
        if timestamps {
            columns.push(TIME_COLUMN);
        }
        let mut poses = match (&self.poses, named) {
            (Some(p), false) => Some(PoseWriter::create(p, &columns)?),
            (Some(p), true) => Some(PoseWriter::create_objects(p, &columns)?),
            (None, _) => None,
        };
        let mut bop = match &self.bop {
            Some((p, obj)) => Some(BopWriter::create(p, *obj)?),
            None => None,
        };
        let obj_ids: Vec<u32> = names
            .iter()
            .enumerate()
            .map(|(k, name)| bop_obj_id(name, k + 1))
            .collect();
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
        let mut whole = Tally::new(ObjectStats::default());
        let mut source_time = Duration::ZERO;
        let stop = self.stop.clone();
        let stopped = || stop.as_ref().is_some_and(|f| f.load(Ordering::SeqCst));
        let limit = n.unwrap_or(usize::MAX);
        let mut rate = crate::view::Rate::default();
        let mut sink_stopped = false;
        while whole.frames() < limit {
            if stopped() {
                break;
            }
            let t0 = Instant::now();
            let Some(frame) = source.next_frame()? else {
                break;
            };
            source_time += t0.elapsed();
            let i = frame.index;
            let t1 = Instant::now();
            let results = trackers
                .track(&frame.image)
                .map_err(|source| AppError::Track {
                    frame: frame_name(&frame),
                    source: Box::new(source),
                })?;
            // One object: its own total, as the tracker measured it;
            // several: the whole frame's.
            let frame_total = match &trackers {
                Trackers::One(_) => results[0].times.total,
                Trackers::Many { .. } => t1.elapsed(),
            };
            if named {
                for ((tally, r), name) in per_object.iter_mut().zip(&results).zip(&names) {
                    tally.add(r, r.times.total);
                    if r.status == Status::Lost {
                        log::info!("frame {i}: {name} lost ({})", why(r));
                    }
                }
                if names.len() > 1 {
                    let tracking = results
                        .iter()
                        .filter(|r| r.status == Status::Tracking)
                        .count();
                    log::info!("frame {i}: {tracking} of {} objects tracking", names.len());
                }
            } else {
                let r = &results[0];
                if r.texture_set_aside {
                    log::info!("frame {i}: texture set aside, the contour alone passed the check");
                }
                if r.status == Status::Lost {
                    log::info!("frame {i}: lost ({})", why(r));
                }
            }
            whole.add_frame(&results, frame_total);
            let time = timestamps.then(|| {
                let t = frame.time_s.unwrap_or(f64::NAN);
                if t.is_finite() {
                    format!("{t:.6}")
                } else {
                    "nan".into()
                }
            });
            for (k, r) in results.iter().enumerate() {
                if let Some(w) = &mut poses {
                    let mut row = result_row(&frame.label, r);
                    if let Some(t) = &time {
                        row.extra.push((TIME_COLUMN.into(), t.clone()));
                    }
                    if named {
                        row = row.of_object(names[k].as_str());
                    }
                    w.row(&row)?;
                }
                if let Some(w) = &mut bop {
                    let score = if r.status == Status::Tracking {
                        1.0
                    } else {
                        0.0
                    };
                    let seconds = r.times.total.as_secs_f64();
                    match obj_ids.get(k) {
                        Some(id) => w.object_row(i, *id, &r.pose, score, seconds)?,
                        None => w.row(i, &r.pose, score, seconds)?,
                    }
                }
            }
            let overlay = self.overlays.as_ref().filter(|(_, every)| i % every == 0);
            let masks = if overlay.is_some() || sink.as_ref().is_some_and(|s| s.wants_mask()) {
                Some(
                    trackers
                        .silhouettes(&self.device, &cam, &results)
                        .map_err(|source| AppError::Track {
                            frame: frame_name(&frame),
                            source: Box::new(source),
                        })?,
                )
            } else {
                None
            };
            // Several objects: each drawn in its own colour, named.
            let objects: Vec<ViewObject<'_>> = if trackers.len() > 1 {
                results
                    .iter()
                    .zip(&names)
                    .enumerate()
                    .map(|(k, (r, name))| ViewObject {
                        name,
                        result: r,
                        mask: masks.as_ref().map(|m| m[k].as_slice()),
                    })
                    .collect()
            } else {
                Vec::new()
            };
            if let (Some((dir, _)), Some(masks)) = (overlay, &masks) {
                let r = &results[0];
                let picture = if objects.is_empty() {
                    let label = format!(
                        "{} frame {i}  {}  {} inliers  {:.2} px",
                        mode.name(),
                        r.status.name(),
                        r.inliers,
                        r.residual_px
                    );
                    let colour = crate::view::status_colour(r.status);
                    draw::silhouette_overlay(&frame.image, &masks[0], colour, &label)
                } else {
                    let label = format!(
                        "{} frame {i}  {}",
                        mode.name(),
                        crate::view::objects_tracking(&objects)
                    );
                    crate::view::objects_overlay(&frame.image, &objects, &label)
                };
                let path = dir.join(format!("{i:06}.png"));
                picture
                    .save(&path)
                    .map_err(|source| AppError::Overlay { path, source })?;
            }
            on_frame(&frame, &results);
            report(whole.frames());
            if let Some(s) = sink.as_mut() {
                let view = ViewFrame {
                    index: i,
                    label: &frame.label,
                    image: &frame.image,
                    result: &results[0],
                    mask: masks
                        .as_ref()
                        .map(|m| m[0].as_slice())
                        .filter(|_| s.wants_mask()),
                    objects: &objects,
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
        let done = whole.frames();
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
        whole.finish_into(&mut stats, ms(source_time) / done as f64);
        stats.objects = per_object
            .into_iter()
            .enumerate()
            .map(|(k, t)| {
                let mut o = t.finish();
                o.gpu_memory = Some(trackers.tracker(k).gpu_memory());
                o
            })
            .collect();
        stats.gpu_memory = Some(if named {
            let none = crate::tracker::GpuMemoryUse {
                model: 0,
                keyframe_colors: 0,
                targets: 0,
            };
            stats
                .objects
                .iter()
                .filter_map(|o| o.gpu_memory)
                .fold(none, |a, m| crate::tracker::GpuMemoryUse {
                    model: a.model + m.model,
                    keyframe_colors: a.keyframe_colors + m.keyframe_colors,
                    targets: a.targets + m.targets,
                })
        } else {
            trackers.tracker(0).gpu_memory()
        });
        Ok(stats)
    }

    /// The run's trackers, and the objects' names (none: the inputs'
    /// object, unnamed).
    fn trackers(
        &self,
        cam: &crate::geometry::Intrinsics,
        sequence: &Path,
    ) -> Result<(Trackers, Vec<String>), AppError> {
        let execution = crate::tracker::Execution {
            gpu_timing: self.gpu_timing,
            ..Default::default()
        };
        let start = |e: crate::tracker::TrackError| AppError::Start {
            sequence: sequence.to_owned(),
            source: Box::new(e),
        };
        let Some(objects) = &self.objects else {
            let tracker = Tracker::builder(&self.device, self.inputs.model.clone(), *cam)
                .maybe_keyframes(self.inputs.keyframes.clone())
                .config(self.config.clone())
                .initial_pose(self.inputs.init)
                .execution(execution)
                .build()
                .map_err(start)?;
            return Ok((Trackers::One(Box::new(tracker)), Vec::new()));
        };
        if objects.is_empty() {
            return Err(AppError::Objects(crate::tracker::MultiError::Empty));
        }
        let mut named = Vec::with_capacity(objects.len());
        for o in objects {
            let tracker = Tracker::builder(&self.device, o.model.clone(), *cam)
                .maybe_keyframes(o.keyframes.clone())
                .config(o.config.clone())
                .initial_pose(o.init)
                .execution(execution)
                .build()
                .map_err(start)?;
            named.push((o.name.clone(), tracker));
        }
        let multi = MultiTracker::new(named)?;
        let names: Vec<String> = multi.names().map(str::to_owned).collect();
        let trackers = if multi.len() == 1 {
            let (_, tracker) = multi.into_trackers().pop().expect("one object");
            Trackers::One(Box::new(tracker))
        } else {
            Trackers::Many {
                multi: Box::new(multi),
                masks: None,
            }
        };
        Ok((trackers, names))
    }
}

/// A lost frame's reason, as the log says it.
fn why(r: &TrackResult) -> String {
    r.reason
        .as_ref()
        .map_or_else(|| "no reason".to_owned(), ToString::to_string)
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
