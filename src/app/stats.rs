//! What a tracking run measured ([`RunStats`]).

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
    /// Of which lost.
    pub lost: usize,
    /// Frames whose texture steps were set aside for the contour alone
    /// ([`crate::tracker::TrackResult::texture_set_aside`]).
    pub texture_set_aside: usize,
    /// Mean milliseconds per frame of the features, the IT and KF steps,
    /// and the whole frame.
    pub mean: FrameMs,
    /// Mean milliseconds per frame of the contour step.
    pub contour_ms: f64,
    /// Median total milliseconds per frame.
    pub median_ms: f64,
    /// Mean time per frame of every stage and sub-stage.
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
    /// ([`crate::tracker::Tracker::gpu_memory`]).
    pub gpu_memory: Option<crate::tracker::GpuMemoryUse>,
    /// The cues the run tracked with: as configured, or as the automatic
    /// choice set them ([`crate::tracker::TrackerConfig::auto_modalities`]).
    pub modalities: Option<crate::tracker::Modalities>,
    /// What the automatic choice measured, when it ran.
    pub cue_choice: Option<crate::tracker::CueChoice>,
    /// Frames tracked by each cue: `texture` alone, `contour` alone, and
    /// both ([`crate::tracker::TrackResult::cues`]).
    pub held_by: [usize; 3],
}
