//! Clicking known model points in a frame (`splattrack init --click`): what
//! each window event means and what the window shows, as pure functions of
//! the events, so that tests drive them without a display.
//!
//! The user is asked for each named point in turn: a left click places it,
//! a right click or `Esc` skips it (it is not visible), `Backspace` goes
//! back one point, `Enter` stops asking early (with at least four placed).
//! When every point is placed or skipped the session is in review: the
//! caller solves the pose and shows it; `Enter` accepts, `Backspace` goes
//! back to the last point, `Esc`, `q` or closing the window cancel.

use super::picture::{BAND_COLOUR, Layout};
use super::present::letterbox;
use crate::draw::{self, Colour};
use image::{RgbImage, RgbaImage};
use nalgebra::Vector2;

/// A window event, as far as clicking cares; positions are in window
/// pixels (the pointer's pixel).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RawEvent {
    /// Left mouse button pressed at this position.
    LeftClick(f64, f64),
    /// Right mouse button pressed.
    RightClick,
    /// A key pressed.
    Key(ClickKey),
    /// The window was closed.
    Close,
}

/// The keys that mean something while clicking.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClickKey {
    /// `Esc`.
    Escape,
    /// `Enter` or `Return`.
    Enter,
    /// `Backspace`.
    Backspace,
    /// `q`.
    Q,
}

/// What an event asks of the session.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Input {
    /// Place the current point at this frame pixel.
    Click(Vector2<f64>),
    /// The current point is not visible.
    Skip,
    /// Back one point.
    Undo,
    /// Stop asking (with enough points), or accept the pose in review.
    Accept,
    /// Give up; nothing is written.
    Cancel,
}

/// Where the session is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Asking for point `k`.
    Asking(usize),
    /// Every point answered: the pose is shown for confirmation.
    Review,
    /// The user accepted the pose.
    Accepted,
    /// The user cancelled.
    Cancelled,
}

/// Points placed fewer than this cannot end the asking early.
pub const MIN_CLICKS: usize = 4;

/// The state of a clicking session over named points.
#[derive(Debug, Clone, PartialEq)]
pub struct ClickSession {
    names: Vec<String>,
    pixels: Vec<Option<Vector2<f64>>>,
    phase: Phase,
}

impl ClickSession {
    /// A session asking for `names` in order (none: straight to review).
    pub fn new(names: Vec<String>) -> Self {
        let n = names.len();
        Self {
            names,
            pixels: vec![None; n],
            phase: if n == 0 {
                Phase::Review
            } else {
                Phase::Asking(0)
            },
        }
    }

    /// Where the session is.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// The points placed so far: (index into the names, frame pixel).
    pub fn clicked(&self) -> Vec<(usize, Vector2<f64>)> {
        self.pixels
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.map(|p| (i, p)))
            .collect()
    }

    /// What `event` asks, in the current phase. `to_frame` maps a window
    /// position to a frame pixel (`None` outside the frame: the click is
    /// ignored).
    pub fn translate(
        &self,
        event: RawEvent,
        to_frame: impl Fn(f64, f64) -> Option<Vector2<f64>>,
    ) -> Option<Input> {
        let asking = matches!(self.phase, Phase::Asking(_));
        match event {
            RawEvent::Close | RawEvent::Key(ClickKey::Q) => Some(Input::Cancel),
            RawEvent::LeftClick(x, y) if asking => to_frame(x, y).map(Input::Click),
            RawEvent::RightClick if asking => Some(Input::Skip),
            RawEvent::Key(ClickKey::Escape) if asking => Some(Input::Skip),
            RawEvent::Key(ClickKey::Escape) => Some(Input::Cancel),
            RawEvent::Key(ClickKey::Enter) => Some(Input::Accept),
            RawEvent::Key(ClickKey::Backspace) => Some(Input::Undo),
            RawEvent::LeftClick(..) | RawEvent::RightClick => None,
        }
    }

    /// Applies `input`; returns the new phase.
    pub fn apply(&mut self, input: Input) -> Phase {
        let n = self.names.len();
        self.phase = match (self.phase, input) {
            (Phase::Accepted | Phase::Cancelled, _) => self.phase,
            (_, Input::Cancel) => Phase::Cancelled,
            (Phase::Asking(k), Input::Click(p)) => {
                self.pixels[k] = Some(p);
                next(k, n)
            }
            (Phase::Asking(k), Input::Skip) => {
                self.pixels[k] = None;
                next(k, n)
            }
            (Phase::Asking(k), Input::Undo) => {
                let back = k.saturating_sub(1);
                self.pixels[back] = None;
                Phase::Asking(back)
            }
            (Phase::Asking(k), Input::Accept) => {
                if self.clicked().len() >= MIN_CLICKS {
                    for p in &mut self.pixels[k..] {
                        *p = None;
                    }
                    Phase::Review
                } else {
                    Phase::Asking(k)
                }
            }
            (Phase::Review, Input::Accept) => Phase::Accepted,
            (Phase::Review, Input::Undo) if n > 0 => {
                let last = self.clicked().last().map_or(n - 1, |(i, _)| *i);
                self.pixels[last] = None;
                Phase::Asking(last)
            }
            (Phase::Review, _) => Phase::Review,
        };
        self.phase
    }

    /// The three lines of the band above the frame while asking.
    pub fn prompt(&self) -> [String; 3] {
        let placed = self.clicked().len();
        match self.phase {
            Phase::Asking(k) => [
                format!(
                    "click point {} of {}: {}",
                    k + 1,
                    self.names.len(),
                    self.names[k]
                ),
                format!("right click or Esc: not visible   Backspace: back   {placed} placed"),
                if placed >= MIN_CLICKS {
                    "Enter: solve with these   q: cancel".into()
                } else {
                    format!("at least {MIN_CLICKS} points are needed   q: cancel")
                },
            ],
            Phase::Review => [
                format!("{placed} points placed"),
                "Enter: accept and write   Backspace: back   Esc or q: cancel".into(),
                String::new(),
            ],
            Phase::Accepted => ["accepted".into(), String::new(), String::new()],
            Phase::Cancelled => ["cancelled".into(), String::new(), String::new()],
        }
    }

    /// The picture the window shows while asking: [`compose_band`] of the
    /// frame with the placed points marked and named.
    pub fn picture(&self, frame: &RgbImage) -> RgbaImage {
        let mut shown = frame.clone();
        for (i, p) in self.clicked() {
            mark(&mut shown, p, CLICK_COLOUR, &self.names[i]);
        }
        compose_band(&shown, &self.prompt(), draw::WHITE)
    }
}

fn next(k: usize, n: usize) -> Phase {
    if k + 1 < n {
        Phase::Asking(k + 1)
    } else {
        Phase::Review
    }
}

/// The colour of placed points.
pub const CLICK_COLOUR: Colour = [255, 220, 0];

/// A placed point: a cross with its name beside it.
pub fn mark(img: &mut RgbImage, p: Vector2<f64>, colour: Colour, name: &str) {
    draw::cross(img, p.x, p.y, 6.0, draw::BLACK);
    draw::cross(img, p.x, p.y, 5.0, colour);
    draw::label(
        img,
        p.x.round() as i64 + 7,
        p.y.round() as i64 + 4,
        name,
        colour,
        draw::BLACK,
        1,
    );
}

/// `frame` below a band ([`Layout::band`] pixels) holding `lines`, the
/// first in `first_colour`, the others white.
pub fn compose_band(frame: &RgbImage, lines: &[String; 3], first_colour: Colour) -> RgbaImage {
    let (w, h) = frame.dimensions();
    let layout = Layout::for_width(w);
    let mut picture = RgbImage::from_pixel(w, h + layout.band, image::Rgb(BAND_COLOUR));
    image::imageops::replace(&mut picture, frame, 0, layout.band as i64);
    for (k, line) in lines.iter().enumerate() {
        let c = if k == 0 { first_colour } else { draw::WHITE };
        let n = layout.chars_per_line(w);
        let text: String = line.chars().take(n).collect();
        draw::text(
            &mut picture,
            layout.margin as i64,
            layout.line_top(k as u32) as i64,
            &text,
            c,
            layout.scale,
        );
    }
    image::DynamicImage::ImageRgb8(picture).into_rgba8()
}

/// The frame pixel (OpenCV convention) under the window pixel `(x, y)`,
/// for a picture of `picture` size (a [`compose_band`] of a frame `frame`
/// size) letterboxed into a window of `window` size; `None` outside the
/// frame.
pub fn frame_pixel(
    (x, y): (f64, f64),
    window: (u32, u32),
    picture: (u32, u32),
    frame: (u32, u32),
) -> Option<Vector2<f64>> {
    let [x0, y0, x1, _] = letterbox(picture, window);
    let s = (x1 - x0) as f64 / picture.0.max(1) as f64;
    if s <= 0.0 {
        return None;
    }
    // The window pixel's centre, in picture pixels, OpenCV convention.
    let u = (x + 0.5 - x0 as f64) / s - 0.5;
    let v = (y + 0.5 - y0 as f64) / s - 0.5 - (picture.1 - frame.1) as f64;
    let inside =
        (-0.5..frame.0 as f64 - 0.5).contains(&u) && (-0.5..frame.1 as f64 - 0.5).contains(&v);
    inside.then(|| Vector2::new(u, v))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn session() -> ClickSession {
        ClickSession::new(["a", "b", "c", "d", "e"].map(String::from).to_vec())
    }

    fn px(x: f64) -> Vector2<f64> {
        Vector2::new(x, 2.0 * x)
    }

    #[test]
    fn clicks_skips_and_undo_walk_through_the_points() {
        let mut s = session();
        assert_eq!(s.apply(Input::Click(px(1.0))), Phase::Asking(1));
        assert_eq!(s.apply(Input::Skip), Phase::Asking(2));
        assert_eq!(s.apply(Input::Click(px(3.0))), Phase::Asking(3));
        assert_eq!(s.apply(Input::Undo), Phase::Asking(2));
        assert_eq!(s.clicked(), vec![(0, px(1.0))]);
        assert_eq!(s.apply(Input::Click(px(3.5))), Phase::Asking(3));
        // Too few to stop early.
        assert_eq!(s.apply(Input::Accept), Phase::Asking(3));
        assert_eq!(s.apply(Input::Click(px(4.0))), Phase::Asking(4));
        assert_eq!(s.apply(Input::Click(px(5.0))), Phase::Review);
        assert_eq!(
            s.clicked(),
            vec![(0, px(1.0)), (2, px(3.5)), (3, px(4.0)), (4, px(5.0))]
        );
        // Back from review to the last point, then accept.
        assert_eq!(s.apply(Input::Undo), Phase::Asking(4));
        assert_eq!(s.clicked().len(), 3);
        assert_eq!(s.apply(Input::Click(px(6.0))), Phase::Review);
        assert_eq!(s.apply(Input::Click(px(9.0))), Phase::Review);
        assert_eq!(s.apply(Input::Accept), Phase::Accepted);
        assert_eq!(s.apply(Input::Cancel), Phase::Accepted);
        assert_eq!(s.clicked()[3], (4, px(6.0)));
    }

    #[test]
    fn enter_stops_early_with_four_points() {
        let mut s = ClickSession::new((0..8).map(|i| format!("p{i}")).collect());
        for i in 0..4 {
            s.apply(Input::Click(px(i as f64)));
        }
        assert_eq!(s.phase(), Phase::Asking(4));
        assert_eq!(s.apply(Input::Accept), Phase::Review);
        assert_eq!(s.clicked().len(), 4);
        let mut s = session();
        assert_eq!(s.apply(Input::Cancel), Phase::Cancelled);
        assert_eq!(s.apply(Input::Click(px(1.0))), Phase::Cancelled);
    }

    #[test]
    fn events_mean_what_the_phase_says() {
        let mut s = session();
        let map = |x: f64, y: f64| (x >= 0.0).then(|| Vector2::new(x, y));
        let t = |s: &ClickSession, e| s.translate(e, map);
        assert_eq!(
            t(&s, RawEvent::LeftClick(3.0, 4.0)),
            Some(Input::Click(Vector2::new(3.0, 4.0)))
        );
        assert_eq!(t(&s, RawEvent::LeftClick(-1.0, 4.0)), None);
        assert_eq!(t(&s, RawEvent::RightClick), Some(Input::Skip));
        assert_eq!(t(&s, RawEvent::Key(ClickKey::Escape)), Some(Input::Skip));
        assert_eq!(t(&s, RawEvent::Key(ClickKey::Q)), Some(Input::Cancel));
        assert_eq!(t(&s, RawEvent::Close), Some(Input::Cancel));
        // A whole session from synthetic events.
        let events = [
            RawEvent::LeftClick(10.0, 10.0),
            RawEvent::RightClick,
            RawEvent::LeftClick(-5.0, 0.0), // outside: ignored
            RawEvent::LeftClick(30.0, 10.0),
            RawEvent::LeftClick(30.0, 40.0),
            RawEvent::Key(ClickKey::Escape), // skips the last point: review
            RawEvent::Key(ClickKey::Backspace), // back to the last placed one
            RawEvent::LeftClick(50.0, 50.0),
            RawEvent::LeftClick(60.0, 70.0),
        ];
        for e in events {
            if let Some(i) = t(&s, e) {
                s.apply(i);
            }
        }
        assert_eq!(s.phase(), Phase::Review);
        assert_eq!(
            s.clicked(),
            vec![
                (0, Vector2::new(10.0, 10.0)),
                (2, Vector2::new(30.0, 10.0)),
                (3, Vector2::new(50.0, 50.0)),
                (4, Vector2::new(60.0, 70.0)),
            ]
        );
        // In review a click means nothing and Esc cancels.
        assert_eq!(t(&s, RawEvent::LeftClick(1.0, 1.0)), None);
        assert_eq!(t(&s, RawEvent::Key(ClickKey::Escape)), Some(Input::Cancel));
        assert_eq!(t(&s, RawEvent::Key(ClickKey::Enter)), Some(Input::Accept));
    }

    #[test]
    fn window_pixels_map_to_frame_pixels() {
        let frame = (640, 480);
        let band = Layout::for_width(640).band;
        let picture = (640, 480 + band);
        // One to one: the window pixel is the picture pixel.
        let p = frame_pixel((100.0, 200.0 + band as f64), picture, picture, frame).unwrap();
        assert!((p - Vector2::new(100.0, 200.0)).norm() < 1e-12, "{p}");
        assert_eq!(frame_pixel((100.0, 2.0), picture, picture, frame), None);
        // Twice the size: two window pixels a frame pixel.
        let window = (picture.0 * 2, picture.1 * 2);
        let p = frame_pixel((201.0, 2.0 * band as f64 + 401.0), window, picture, frame).unwrap();
        assert!((p - Vector2::new(100.25, 200.25)).norm() < 1e-12, "{p}");
        // Letterboxed: a wide window puts bars left and right.
        let window = (picture.0 * 2 + 100, picture.1 * 2);
        let p = frame_pixel((251.0, 2.0 * band as f64 + 401.0), window, picture, frame).unwrap();
        assert!((p - Vector2::new(100.25, 200.25)).norm() < 1e-12, "{p}");
        assert_eq!(frame_pixel((10.0, 600.0), window, picture, frame), None);
    }

    #[test]
    fn the_picture_shows_the_prompt_and_the_marks() {
        let frame = RgbImage::from_pixel(200, 100, image::Rgb([40, 40, 40]));
        let mut s = session();
        let empty = s.picture(&frame);
        let band = Layout::for_width(200).band;
        assert_eq!(empty.dimensions(), (200, 100 + band));
        s.apply(Input::Click(Vector2::new(50.0, 50.0)));
        let marked = s.picture(&frame);
        let p = marked.get_pixel(50, 50 + band);
        assert_eq!([p[0], p[1], p[2]], CLICK_COLOUR);
        assert_eq!(empty.get_pixel(50, 50 + band)[0], 40);
        assert!(
            s.prompt()[0].contains("point 2 of 5: b"),
            "{:?}",
            s.prompt()
        );
    }
}
