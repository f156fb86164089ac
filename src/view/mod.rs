//! The live view: what `splattrack track --view` shows while it tracks.
//!
//! # How it works
//!
//! A tracking run ([`crate::app::TrackRun::sink`]) hands every finished
//! frame to a [`FrameSink`] as a [`ViewFrame`]: the frame as tracked
//! (undistorted), its [`TrackResult`](crate::tracker::TrackResult), the model's silhouette at the
//! tracked pose (one splatting of the model, the mask `--overlay` draws)
//! and the frame's timestamp when the source has one. The sink answers
//! [`Flow::Continue`] or [`Flow::Stop`]; `Stop` ends the run as the end of
//! the sequence would (every finished frame on disk).
//!
//! What the display shows is decided by one pure function, [`compose`]: a
//! status band above the frame (mode, frame number, time, `tracking` or
//! `lost` with inliers, residual and milliseconds, and on a lost frame the
//! tracker's reason) and the frame with the silhouette's outline in the
//! status colour ([`status_colour`]). With several objects each outline
//! has its object's colour ([`object_colour`]) and its name beside it,
//! and the band counts the objects tracking and names the lost ones. `display::DisplaySink` (the `view`
//! feature) shows that picture in an OS window (winit), drawn by the
//! tracker's own wgpu device ([`present`]: a letterboxing blit with a CPU
//! reference); tests feed [`compose`] and fake sinks directly, without a
//! display.
//!
//! The same window collects clicks for `splattrack init --click`
//! ([`DisplaySink::show`]); what the clicks mean and what the window shows
//! meanwhile are pure functions of the events ([`clicks`]).

pub mod clicks;
#[cfg(feature = "view")]
pub mod display;
mod objects;
mod picture;
pub mod present;
mod sink;

#[cfg(feature = "view")]
pub use display::{DisplaySink, DisplayStats};
pub use objects::{draw_objects, object_colour, objects_overlay, objects_tracking, status_colour};
pub use picture::{BAND_COLOUR, BAND_LINES, Layout, Rate, compose, status_lines};
pub use sink::{Flow, FrameSink, ViewError, ViewFrame, ViewObject};
