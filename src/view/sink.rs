//! What a tracking run hands the live view: each finished frame
//! ([`ViewFrame`]) to a [`FrameSink`], which answers with a [`Flow`].

use crate::tracker::{Mode, TrackResult};
use image::RgbImage;

/// Why the live view failed.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// No display to open an OS window on (no `DISPLAY` / `WAYLAND_DISPLAY`,
    /// or the connection failed).
    #[error("--view needs a display: {0}")]
    NoDisplay(String),
    /// The OS window could not be opened.
    #[error("--view: cannot open a window: {0}")]
    Open(String),
    /// The tracker's GPU cannot present to the OS window.
    #[error("--view: {adapter} cannot draw into the window: {reason}")]
    Surface {
        /// The adapter.
        adapter: String,
        /// Why.
        reason: String,
    },
    /// Drawing a frame failed on the GPU.
    #[error("--view: {0}")]
    Gpu(#[from] crate::gpu::GpuError),
}

/// One finished frame, as a [`FrameSink`] gets it.
#[derive(Debug, Clone, Copy)]
pub struct ViewFrame<'a> {
    /// The frame's index in the run (0 for the first tracked frame).
    pub index: usize,
    /// The frame's label in the pose file (`frame` column).
    pub label: &'a str,
    /// The frame as tracked (undistorted when the camera has distortion).
    pub image: &'a RgbImage,
    /// What the tracker made of it.
    pub result: &'a TrackResult,
    /// The model's silhouette at `result.pose`, one flag per pixel of
    /// `image` (row-major), when the sink asked for it
    /// ([`FrameSink::wants_mask`]).
    pub mask: Option<&'a [bool]>,
    /// Every object of a run of several, in their order (the first is
    /// `result`'s and `mask`'s); empty with one object.
    pub objects: &'a [ViewObject<'a>],
    /// The frame's timestamp in seconds, when the source has one.
    pub time_s: Option<f64>,
    /// Frames per second of the whole run lately (reading, tracking,
    /// writing and showing: the rate a viewer sees), `None` on the first
    /// frame.
    pub rate_hz: Option<f64>,
    /// The tracker's mode.
    pub mode: Mode,
}

/// One object of a frame in a run of several ([`ViewFrame::objects`]).
#[derive(Debug, Clone, Copy)]
pub struct ViewObject<'a> {
    /// The object's name.
    pub name: &'a str,
    /// What the tracker made of it.
    pub result: &'a TrackResult,
    /// Its silhouette at `result.pose`, when the sink asked for it.
    pub mask: Option<&'a [bool]>,
}

/// What the run does after a sink has seen a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    /// Track the next frame.
    Continue,
    /// End the run here, as at the end of the sequence.
    Stop,
}

/// Receives every finished frame of a run, in order
/// ([`crate::app::TrackRun::sink`]).
pub trait FrameSink {
    /// Whether the frames should carry the model's silhouette at the
    /// tracked pose (it costs one splatting per frame).
    fn wants_mask(&self) -> bool {
        true
    }

    /// One finished frame; [`Flow::Stop`] ends the run after it.
    fn frame(&mut self, frame: &ViewFrame<'_>) -> Result<Flow, ViewError>;
}

impl<S: FrameSink + ?Sized> FrameSink for &mut S {
    fn wants_mask(&self) -> bool {
        (**self).wants_mask()
    }
    fn frame(&mut self, frame: &ViewFrame<'_>) -> Result<Flow, ViewError> {
        (**self).frame(frame)
    }
}
