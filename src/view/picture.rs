//! The picture the live view shows for a frame ([`compose`]): a status
//! band above the frame with the silhouette's outline.

use super::objects::status_colour;
use super::sink::ViewFrame;
use crate::draw::{self, Colour};
use crate::tracker::Status;
use image::{RgbImage, RgbaImage};

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
    if !frame.objects.is_empty() {
        return objects_lines(frame);
    }
    let r = frame.result;
    let first = frame_line(frame);
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

/// The first status line: mode, frame and its time.
fn frame_line(frame: &ViewFrame<'_>) -> String {
    let time = frame
        .time_s
        .map_or_else(String::new, |t| format!("  t {t:.3} s"));
    format!(
        "{}  frame {} ({}){time}",
        frame.mode.name(),
        frame.index,
        frame.label
    )
}

/// [`status_lines`] of several objects: mode, frame and time; how many
/// track, the frame's milliseconds and the frames per second; each lost
/// object's name and reason.
fn objects_lines(frame: &ViewFrame<'_>) -> [String; 3] {
    let first = frame_line(frame);
    let rate = frame
        .rate_hz
        .map_or_else(String::new, |f| format!("  {f:.1} frames/s"));
    let ms: f64 = frame
        .objects
        .iter()
        .map(|o| o.result.times.total.as_secs_f64() * 1e3)
        .sum();
    let second = format!(
        "{}  {ms:.0} ms{rate}",
        super::objects::objects_tracking(frame.objects)
    );
    let lost: Vec<String> = frame
        .objects
        .iter()
        .filter(|o| o.result.status == Status::Lost)
        .map(|o| match &o.result.reason {
            Some(why) => format!("{} lost: {why}", o.name),
            None => format!("{} lost", o.name),
        })
        .collect();
    [first, second, lost.join("; ")]
}

/// Frames per second over the last [`Rate::FRAMES`] frames, from the
/// times the frames were finished ([`ViewFrame::rate_hz`]).
#[derive(Debug, Clone, Default)]
pub struct Rate {
    times: std::collections::VecDeque<std::time::Instant>,
}

impl Rate {
    /// Frames the rate is measured over.
    pub const FRAMES: usize = 10;

    /// A frame finished now: the rate so far (`None` on the first).
    pub fn tick(&mut self) -> Option<f64> {
        self.tick_at(std::time::Instant::now())
    }

    /// A frame finished at `t` (not before the previous one).
    pub fn tick_at(&mut self, t: std::time::Instant) -> Option<f64> {
        self.times.push_back(t);
        if self.times.len() > Self::FRAMES + 1 {
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
/// lightly tinted ([`draw::silhouette`]); several objects each in its
/// colour, named ([`super::draw_objects`]), the status line red
/// when one is lost. A pure function: everything the display shows is
/// tested through it.
pub fn compose(frame: &ViewFrame<'_>) -> RgbaImage {
    let (w, h) = frame.image.dimensions();
    let layout = Layout::for_width(w);
    let status = if frame
        .objects
        .iter()
        .any(|o| o.result.status == Status::Lost)
    {
        Status::Lost
    } else {
        frame.result.status
    };
    let colour = status_colour(status);
    let mut picture = RgbImage::from_pixel(w, h + layout.band, image::Rgb(BAND_COLOUR));
    let mut shown = frame.image.clone();
    if !frame.objects.is_empty() {
        super::objects::draw_objects(&mut shown, frame.objects);
    } else if let Some(mask) = frame.mask {
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
    fn the_live_view_counts_the_objects_and_names_the_lost() {
        use crate::tracker::{LostReason, Mode, TrackResult};
        use crate::view::{ViewFrame, ViewObject, object_colour};
        let img = RgbImage::new(64, 48);
        let result = |status| TrackResult {
            pose: crate::geometry::Pose::identity(),
            inliers: 0,
            residual_px: f64::NAN,
            status,
            reason: None,
            keyframe: None,
            times: Default::default(),
            verify: None,
            texture_set_aside: false,
            cues: crate::tracker::Modalities::NONE,
            refused: None,
        };
        let a = result(Status::Tracking);
        let b = TrackResult {
            reason: Some(LostReason::NotFound),
            ..result(Status::Lost)
        };
        let mask: Vec<bool> = (0..64 * 48).map(|p| (p % 64) > 40 && p / 64 > 20).collect();
        let objects = [
            ViewObject {
                name: "a",
                result: &a,
                mask: None,
            },
            ViewObject {
                name: "b",
                result: &b,
                mask: Some(&mask),
            },
        ];
        let frame = ViewFrame {
            index: 3,
            label: "000003",
            image: &img,
            result: &a,
            mask: None,
            objects: &objects,
            time_s: None,
            rate_hz: None,
            mode: Mode::KfIt,
        };
        let lines = status_lines(&frame);
        assert!(lines[1].starts_with("1/2 tracking"), "{lines:?}");
        assert!(lines[2].starts_with("b lost: "), "{lines:?}");
        // b's outline in its lost colour, below the band.
        let picture = compose(&frame);
        let band = Layout::for_width(64).band;
        let c = object_colour(1, Status::Lost);
        let found = (band..picture.height())
            .flat_map(|y| (0..64).map(move |x| (x, y)))
            .any(|(x, y)| picture.get_pixel(x, y).0[..3] == c);
        assert!(found);
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
