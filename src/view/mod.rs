//! The live view: what `splattrack track --view` shows while it tracks.
//!
//! # How it works
//!
//! A tracking run ([`crate::app::TrackRun::sink`]) hands every finished
//! frame to a [`FrameSink`] as a [`ViewFrame`]: the frame as tracked
//! (undistorted), its [`TrackResult`], the model's silhouette at the
//! tracked pose (one splatting of the model, the mask `--overlay` draws)
//! and the frame's timestamp when the source has one. The sink answers
//! [`Flow::Continue`] or [`Flow::Stop`]; `Stop` ends the run as the end of
//! the sequence would (every finished frame on disk).
//!
//! What a window shows is decided by one pure function, [`compose`]: a
//! status band above the frame (mode, frame number, time, `tracking` or
//! `lost` with inliers, residual and milliseconds, and on a lost frame the
//! tracker's reason) and the frame with the silhouette's outline in the
//! status colour ([`status_colour`]). [`window::WindowSink`] shows that
//! picture in a winit window, drawn by the tracker's own wgpu device
//! ([`present`]: a letterboxing blit with a CPU reference); tests feed
//! [`compose`] and fake sinks directly, without a display.

pub mod present;
#[cfg(feature = "view")]
pub mod window;

use crate::draw::{self, Colour};
use crate::tracker::{Mode, Status, TrackResult};
use image::{RgbImage, RgbaImage};

#[cfg(feature = "view")]
pub use window::WindowSink;

/// Why the live view failed.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// No display to open a window on (no `DISPLAY` / `WAYLAND_DISPLAY`,
    /// or the connection failed).
    #[error("--view needs a display: {0}")]
    NoDisplay(String),
    /// The window could not be created.
    #[error("--view: cannot open a window: {0}")]
    Window(String),
    /// The tracker's GPU cannot present to the window.
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
    /// The frame's timestamp in seconds, when the source has one.
    pub time_s: Option<f64>,
    /// Frames per second of the whole run lately (reading, tracking,
    /// writing and showing: the rate a viewer sees), `None` on the first
    /// frame.
    pub rate_hz: Option<f64>,
    /// The tracker's mode.
    pub mode: Mode,
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

/// The colour of the outline and the status word: green tracking, red
/// lost (as `--overlay` draws them).
pub fn status_colour(status: Status) -> Colour {
    match status {
        Status::Tracking => [40, 230, 60],
        Status::Lost => [240, 40, 40],
    }
}

/// The colour of the status band behind the text.
pub const BAND_COLOUR: Colour = [16, 16, 16];

/// Lines of text in the status band.
pub const BAND_LINES: u32 = 3;

/// Where [`compose`] puts things, for a frame `width` pixels wide.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// Text scale: glyphs are `8 * scale` pixels square.
    pub scale: u32,
    /// Height of the status band above the frame, pixels.
    pub band: u32,
    /// Left margin and top margin of the text, pixels.
    pub margin: u32,
}

impl Layout {
    /// The layout for frames `width` pixels wide: text scale 1 up to 959
    /// pixels, 2 from 960 (full HD frames stay readable).
    pub fn for_width(width: u32) -> Self {
        let scale = if width >= 960 { 2 } else { 1 };
        let margin = 4 * scale;
        Self {
            scale,
            band: BAND_LINES * Self::line_height(scale) + 2 * margin,
            margin,
        }
    }

    fn line_height(scale: u32) -> u32 {
        8 * scale + 4 * scale
    }

    /// Top of text line `k` (0-based), pixels from the top of the picture.
    pub fn line_top(&self, k: u32) -> u32 {
        self.margin + k * Self::line_height(self.scale)
    }

    /// Characters that fit on a line of a picture `width` pixels wide.
    pub fn chars_per_line(&self, width: u32) -> usize {
        (width.saturating_sub(2 * self.margin) / (8 * self.scale)) as usize
    }
}

/// The text lines of the status band: mode, frame and time; status,
/// inliers, residual, the tracker's milliseconds and the run's frames per
/// second; on a lost frame, the reason, and on a frame whose texture was
/// set aside, that the contour alone tracked it.
pub fn status_lines(frame: &ViewFrame<'_>) -> [String; 3] {
    let r = frame.result;
    let time = frame
        .time_s
        .map_or_else(String::new, |t| format!("  t {t:.3} s"));
    let first = format!(
        "{}  frame {} ({}){time}",
        frame.mode.name(),
        frame.index,
        frame.label
    );
    let residual = if r.residual_px.is_finite() {
        format!("{:.2} px", r.residual_px)
    } else {
        "- px".into()
    };
    let rate = frame
        .rate_hz
        .map_or_else(String::new, |f| format!("  {f:.1} frames/s"));
    let second = format!(
        "{}  {} inliers  {residual}  {:.0} ms{rate}",
        r.status.name(),
        r.inliers,
        r.times.total.as_secs_f64() * 1e3
    );
    let third = match (r.status, &r.reason) {
        (Status::Lost, Some(why)) => format!("why: {why}"),
        (Status::Lost, None) => "why: not given".into(),
        (Status::Tracking, _) if r.texture_set_aside => {
            "contour alone: the texture's pose did not look like the frame".into()
        }
        (Status::Tracking, _) => String::new(),
    };
    [first, second, third]
}

/// Frames per second over the last [`Rate::WINDOW`] frames, from the
/// times the frames were finished ([`ViewFrame::rate_hz`]).
#[derive(Debug, Clone, Default)]
pub struct Rate {
    times: std::collections::VecDeque<std::time::Instant>,
}

impl Rate {
    /// Frames the rate is measured over.
    pub const WINDOW: usize = 10;

    /// A frame finished now: the rate so far (`None` on the first).
    pub fn tick(&mut self) -> Option<f64> {
        self.tick_at(std::time::Instant::now())
    }

    /// A frame finished at `t` (not before the previous one).
    pub fn tick_at(&mut self, t: std::time::Instant) -> Option<f64> {
        self.times.push_back(t);
        if self.times.len() > Self::WINDOW + 1 {
            self.times.pop_front();
        }
        let (first, last) = (self.times.front()?, self.times.back()?);
        let span = last.duration_since(*first).as_secs_f64();
        (self.times.len() > 1 && span > 0.0).then(|| (self.times.len() - 1) as f64 / span)
    }
}

/// `text` cut to `n` characters, ending in `...` when cut.
fn fit(text: &str, n: usize) -> String {
    if text.chars().count() <= n {
        return text.to_owned();
    }
    let keep = n.saturating_sub(3);
    text.chars()
        .take(keep)
        .chain("...".chars())
        .take(n)
        .collect()
}

/// The picture the live view shows for `frame`: a status band
/// ([`Layout::band`] pixels, [`BAND_COLOUR`]) with [`status_lines`] in it
/// (the status line in [`status_colour`], the others white), above the
/// frame with the silhouette's outline in the status colour and its inside
/// lightly tinted ([`draw::silhouette`]). A pure function: everything the
/// window shows is tested through it.
pub fn compose(frame: &ViewFrame<'_>) -> RgbaImage {
    let (w, h) = frame.image.dimensions();
    let layout = Layout::for_width(w);
    let colour = status_colour(frame.result.status);
    let mut picture = RgbImage::from_pixel(w, h + layout.band, image::Rgb(BAND_COLOUR));
    let mut shown = frame.image.clone();
    if let Some(mask) = frame.mask {
        draw::silhouette(&mut shown, mask, colour);
    }
    image::imageops::replace(&mut picture, &shown, 0, layout.band as i64);
    let n = layout.chars_per_line(w);
    let lines = status_lines(frame);
    let colours = [draw::WHITE, colour, draw::WHITE];
    for (k, (line, c)) in lines.iter().zip(colours).enumerate() {
        draw::text(
            &mut picture,
            layout.margin as i64,
            layout.line_top(k as u32) as i64,
            &fit(line, n),
            c,
            layout.scale,
        );
    }
    image::DynamicImage::ImageRgb8(picture).into_rgba8()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rate_is_frames_over_the_recent_span() {
        use std::time::{Duration, Instant};
        let t0 = Instant::now();
        let at = |s: f64| t0 + Duration::from_secs_f64(s);
        let mut r = Rate::default();
        assert_eq!(r.tick_at(at(0.0)), None);
        assert_eq!(r.tick_at(at(0.5)), Some(2.0));
        assert_eq!(r.tick_at(at(1.0)), Some(2.0));
        // Ten frames at 2 per second, then ten at 10: only the last ten
        // intervals count.
        let mut r = Rate::default();
        let mut last = None;
        for k in 0..=10 {
            last = r.tick_at(at(k as f64 * 0.5));
        }
        assert!((last.unwrap() - 2.0).abs() < 1e-9);
        for k in 1..=10 {
            last = r.tick_at(at(5.0 + k as f64 * 0.1));
        }
        assert!((last.unwrap() - 10.0).abs() < 1e-6, "{last:?}");
    }

    #[test]
    fn long_lines_are_cut_with_an_ellipsis() {
        assert_eq!(fit("abcdef", 6), "abcdef");
        assert_eq!(fit("abcdefg", 6), "abc...");
        assert_eq!(fit("abcdefg", 2), "..");
    }

    #[test]
    fn the_band_holds_its_lines() {
        for w in [64, 640, 959, 960, 1920] {
            let l = Layout::for_width(w);
            assert!(l.line_top(BAND_LINES - 1) + 8 * l.scale <= l.band, "{w}");
        }
        assert_eq!(Layout::for_width(640).chars_per_line(640), 79);
    }
}
