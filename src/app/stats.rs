//! What a tracking run measured ([`RunStats`]), and for each object of a
//! run of several ([`ObjectStats`]).

use crate::tracker::{StageTimes, Status, TrackResult};
use std::time::Duration;

/// Milliseconds per frame of the main stages ([`RunStats::mean`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameMs {
    /// The frame's Harris corners.
    pub features: f64,
    /// The frame-to-frame step.
    pub it: f64,
    /// The keyframe step(s).
    pub kf: f64,
    /// The whole frame ([`crate::tracker::StageTimes::total`]).
    pub total: f64,
}

/// What a run measured.
#[derive(Debug, Clone, Default)]
pub struct RunStats {
    /// Frames tracked.
    pub frames: usize,
    /// Of which lost (several objects: frames where one at least was
    /// lost).
    pub lost: usize,
    /// Frames whose texture steps were set aside for the contour alone
    /// ([`crate::tracker::TrackResult::texture_set_aside`]; several
    /// objects: summed over them).
    pub texture_set_aside: usize,
    /// Mean milliseconds per frame of the features, the IT and KF steps
    /// (several objects: summed over them), and the whole frame.
    pub mean: FrameMs,
    /// Mean milliseconds per frame of the contour step.
    pub contour_ms: f64,
    /// Median total milliseconds per frame.
    pub median_ms: f64,
    /// Mean time per frame of every stage and sub-stage (several
    /// objects: summed over them; each one's in [`Self::objects`]).
    pub mean_stages: crate::tracker::StageTimes,
    /// Mean milliseconds per frame spent getting the frame from its source
    /// (reading and decoding an image, or waiting for the video decoder or
    /// the camera, and undistorting it), outside the tracker's total.
    pub source_ms: f64,
    /// Frames the source dropped (a live camera: frames that arrived while
    /// one was being tracked).
    pub dropped: u64,
    /// True when the run ended before its last frame: on its stop flag
    /// ([`super::TrackRun::stop_on`], Ctrl-C) or because its
    /// [`crate::view::FrameSink`] said [`crate::view::Flow::Stop`] (the
    /// live view was closed); `frames` counts the frames tracked.
    pub stopped: bool,
    /// GPU memory of the tracker's splatting at the end of the run
    /// ([`crate::tracker::Tracker::gpu_memory`]; several objects: summed).
    pub gpu_memory: Option<crate::tracker::GpuMemoryUse>,
    /// The cues the run tracked with: as configured, or as the automatic
    /// choice set them ([`crate::tracker::TrackerConfig::auto_modalities`];
    /// `None` in a run of named objects: each one's in [`Self::objects`]).
    pub modalities: Option<crate::tracker::Modalities>,
    /// What the automatic choice measured, when it ran.
    pub cue_choice: Option<crate::tracker::CueChoice>,
    /// Frames tracked by each cue: `texture` alone, `contour` alone, and
    /// both ([`crate::tracker::TrackResult::cues`]; several objects:
    /// summed over them).
    pub held_by: [usize; 3],
    /// Each object's figures, in their order, in a run of named objects
    /// ([`super::TrackRun::objects`]); empty otherwise.
    pub objects: Vec<ObjectStats>,
}

/// What a run measured for one of its named objects.
#[derive(Debug, Clone, Default)]
pub struct ObjectStats {
    /// The object's name.
    pub name: String,
    /// Frames tracked.
    pub frames: usize,
    /// Of which the object was lost in.
    pub lost: usize,
    /// Frames whose texture steps were set aside for the contour alone.
    pub texture_set_aside: usize,
    /// Frames held by `texture` alone, `contour` alone, and both.
    pub held_by: [usize; 3],
    /// Mean milliseconds per frame of the object's features, IT and KF
    /// steps and its whole tracking.
    pub mean: FrameMs,
    /// Mean milliseconds per frame of its contour step.
    pub contour_ms: f64,
    /// Median milliseconds per frame of its tracking.
    pub median_ms: f64,
    /// Mean time per frame of its every stage and sub-stage.
    pub mean_stages: StageTimes,
    /// The cues it tracked with.
    pub modalities: Option<crate::tracker::Modalities>,
    /// What the automatic choice of its cues measured, when it ran.
    pub cue_choice: Option<crate::tracker::CueChoice>,
    /// Its tracker's GPU memory at the end of the run.
    pub gpu_memory: Option<crate::tracker::GpuMemoryUse>,
}

/// Sums a run's figures frame by frame, for an object or the whole run.
pub(super) struct Tally {
    stats: ObjectStats,
    sum: StageTimes,
    totals: Vec<f64>,
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

impl Tally {
    pub fn new(stats: ObjectStats) -> Self {
        Self {
            stats,
            sum: StageTimes::default(),
            totals: Vec::new(),
        }
    }

    /// Frames counted so far.
    pub fn frames(&self) -> usize {
        self.totals.len()
    }

    /// One object's result of a frame, `total` its time.
    pub fn add(&mut self, r: &TrackResult, total: Duration) {
        self.add_frame(std::slice::from_ref(r), total);
    }

    /// A frame's results, every object's (lost when one is), `total` the
    /// frame's time.
    pub fn add_frame(&mut self, results: &[TrackResult], total: Duration) {
        let s = &mut self.stats;
        if results.iter().any(|r| r.status == Status::Lost) {
            s.lost += 1;
        }
        for r in results {
            s.texture_set_aside += usize::from(r.texture_set_aside);
            match (r.cues.texture, r.cues.contour) {
                (true, false) => s.held_by[0] += 1,
                (false, true) => s.held_by[1] += 1,
                (true, true) => s.held_by[2] += 1,
                (false, false) => {}
            }
            let t = &r.times;
            s.mean.features += ms(t.features);
            s.mean.it += ms(t.it);
            s.mean.kf += ms(t.kf);
            s.contour_ms += ms(t.contour);
            self.sum.add_scaled(t, 1.0);
        }
        s.mean.total += ms(total);
        self.totals.push(ms(total));
    }

    /// The means over the frames counted (at least one).
    pub fn finish(mut self) -> ObjectStats {
        let done = self.totals.len().max(1);
        let k = 1.0 / done as f64;
        let s = &mut self.stats;
        s.frames = self.totals.len();
        let m = &mut s.mean;
        (m.features, m.it, m.kf, m.total) = (m.features * k, m.it * k, m.kf * k, m.total * k);
        s.contour_ms *= k;
        s.mean_stages.add_scaled(&self.sum, k);
        self.totals.sort_by(f64::total_cmp);
        s.median_ms = self
            .totals
            .get(self.totals.len() / 2)
            .copied()
            .unwrap_or(0.0);
        self.stats
    }

    /// The whole run's means into `stats`, with the frame source's
    /// milliseconds per frame.
    pub fn finish_into(self, stats: &mut RunStats, source_ms: f64) {
        let o = self.finish();
        stats.frames = o.frames;
        stats.lost = o.lost;
        stats.texture_set_aside = o.texture_set_aside;
        stats.held_by = o.held_by;
        stats.mean = o.mean;
        stats.contour_ms = o.contour_ms;
        stats.median_ms = o.median_ms;
        stats.mean_stages = o.mean_stages;
        stats.source_ms = source_ms;
    }
}
