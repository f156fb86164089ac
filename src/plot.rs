//! Line charts as PNG images (error curves over time, like the paper's
//! Fig. 10), drawn with [`crate::draw`]: no plotting dependency, no fonts to
//! install.

use crate::draw::{self, Colour};
use image::RgbImage;

/// One curve.
#[derive(Debug, Clone)]
pub struct Series {
    /// Name shown in the legend.
    pub name: String,
    /// The (x, y) points, in drawing order.
    pub points: Vec<(f64, f64)>,
    /// Line colour.
    pub colour: Colour,
}

/// A chart: axes, title, curves. Non-finite points break a curve.
#[derive(Debug, Clone, Default)]
pub struct LineChart {
    /// Title drawn above the plot.
    pub title: String,
    /// Label of the x axis.
    pub x_label: String,
    /// Label of the y axis.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series>,
    /// Draw a dashed horizontal line at these y values (thresholds).
    pub guides: Vec<f64>,
    /// Fix the y range (else from the data, starting at 0 when all >= 0).
    pub y_max: Option<f64>,
}

/// A "nice" tick step giving about `n` ticks over `range`.
fn tick_step(range: f64, n: f64) -> f64 {
    let raw = (range / n).max(1e-12);
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let nice = if f < 1.5 {
        1.0
    } else if f < 3.5 {
        2.0
    } else if f < 7.5 {
        5.0
    } else {
        10.0
    };
    nice * mag
}

/// The multiples of `step` in `[lo, hi]`, at most 100 of them (counted,
/// not accumulated: adding a step that is tiny next to the values would
/// never reach `hi`).
fn ticks(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && step.is_finite() && step > 0.0) {
        return Vec::new();
    }
    let first = (lo / step).ceil();
    let n = ((hi / step + 1e-6).floor() - first + 1.0).clamp(0.0, 100.0) as usize;
    (0..n)
        .map(|k| (first + k as f64) * step)
        .filter(|v| *v <= hi + step * 1e-6)
        .collect()
}

fn fmt_tick(v: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    format!("{v:.decimals$}")
}

impl LineChart {
    /// An empty chart with the given title and axis labels.
    pub fn new(title: &str, x_label: &str, y_label: &str) -> Self {
        Self {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            ..Default::default()
        }
    }

    /// Adds a curve in the next palette colour.
    pub fn add(&mut self, name: &str, points: Vec<(f64, f64)>) -> &mut Self {
        let colour = draw::PALETTE[self.series.len() % draw::PALETTE.len()];
        self.series.push(Series {
            name: name.into(),
            points,
            colour,
        });
        self
    }

    /// Draws the chart into `img` inside the rectangle (x0, y0, w, h).
    pub fn draw(&self, img: &mut RgbImage, x0: i64, y0: i64, w: i64, h: i64) {
        draw::fill_rect(img, x0, y0, x0 + w - 1, y0 + h - 1, draw::WHITE);
        let finite = self
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|(x, y)| x.is_finite() && y.is_finite());
        let (mut xmin, mut xmax, mut ymin, mut ymax) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for &(x, y) in finite {
            xmin = xmin.min(x);
            xmax = xmax.max(x);
            ymin = ymin.min(y);
            ymax = ymax.max(y);
        }
        if !xmin.is_finite() {
            (xmin, xmax, ymin, ymax) = (0.0, 1.0, 0.0, 1.0);
        }
        if ymin >= 0.0 {
            ymin = 0.0;
        }
        for g in &self.guides {
            ymax = ymax.max(*g * 1.1);
        }
        if let Some(m) = self.y_max {
            ymax = m;
        }
        // A range too narrow for f64 to step through at the values' size
        // (one frame labelled 1.6e15, a timestamp in microseconds) is
        // widened, so a tick step always moves.
        let min_range = (xmin.abs().max(xmax.abs()) * 1e-9).max(1.0);
        if xmax - xmin < min_range {
            xmax = xmin + min_range;
        }
        if ymax <= ymin {
            ymax = ymin + 1.0;
        }
        let ystep = tick_step(ymax - ymin, 5.0);
        ymax = (ymax / ystep).ceil() * ystep;
        let xstep = tick_step(xmax - xmin, 8.0);
        // Plot area, leaving room for labels.
        let (left, right, top, bottom) = (x0 + 70, x0 + w - 16, y0 + 44, y0 + h - 44);
        let sx = |x: f64| left as f64 + (x - xmin) / (xmax - xmin) * (right - left) as f64;
        let sy = |y: f64| bottom as f64 - (y - ymin) / (ymax - ymin) * (bottom - top) as f64;
        draw::text(img, left, y0 + 6, &self.title, draw::BLACK, 2);
        // Grid and ticks.
        for y in ticks(ymin, ymax, ystep) {
            let py = sy(y);
            draw::line(
                img,
                left as f64,
                py,
                right as f64,
                py,
                draw::LIGHT_GREY,
                1.0,
            );
            let t = fmt_tick(y, ystep);
            draw::text(
                img,
                left - 6 - draw::text_width(&t, 1),
                py as i64 - 4,
                &t,
                draw::BLACK,
                1,
            );
        }
        for x in ticks(xmin, xmax, xstep) {
            let px = sx(x);
            draw::line(
                img,
                px,
                bottom as f64,
                px,
                bottom as f64 + 4.0,
                draw::BLACK,
                1.0,
            );
            let t = fmt_tick(x, xstep);
            draw::text(
                img,
                px as i64 - draw::text_width(&t, 1) / 2,
                bottom + 8,
                &t,
                draw::BLACK,
                1,
            );
        }
        for g in &self.guides {
            let py = sy(*g);
            let mut px = left as f64;
            while px < right as f64 {
                draw::line(
                    img,
                    px,
                    py,
                    (px + 6.0).min(right as f64),
                    py,
                    draw::GREY,
                    1.0,
                );
                px += 12.0;
            }
        }
        draw::line(
            img,
            left as f64,
            top as f64,
            left as f64,
            bottom as f64,
            draw::BLACK,
            1.0,
        );
        draw::line(
            img,
            left as f64,
            bottom as f64,
            right as f64,
            bottom as f64,
            draw::BLACK,
            1.0,
        );
        draw::text(
            img,
            (left + right) / 2 - draw::text_width(&self.x_label, 1) / 2,
            bottom + 24,
            &self.x_label,
            draw::BLACK,
            1,
        );
        draw::text(img, x0 + 4, y0 + 28, &self.y_label, draw::BLACK, 1);
        // Curves, clipped to the plot area.
        for s in &self.series {
            let mut prev: Option<(f64, f64)> = None;
            for &(x, y) in &s.points {
                if !(x.is_finite() && y.is_finite()) {
                    prev = None;
                    continue;
                }
                let p = (sx(x), sy(y.min(ymax)));
                if let Some(q) = prev {
                    draw::line(img, q.0, q.1, p.0, p.1, s.colour, 2.0);
                }
                prev = Some(p);
            }
        }
        // Legend, top right.
        let mut ly = top + 4;
        for s in &self.series {
            let tw = draw::text_width(&s.name, 1);
            let lx = right - tw - 30;
            draw::fill_rect(img, lx - 4, ly - 3, right - 2, ly + 10, draw::WHITE);
            draw::line(
                img,
                lx as f64,
                ly as f64 + 4.0,
                lx as f64 + 18.0,
                ly as f64 + 4.0,
                s.colour,
                3.0,
            );
            draw::text(img, lx + 24, ly, &s.name, draw::BLACK, 1);
            ly += 14;
        }
    }

    /// The chart alone as an image.
    pub fn render(&self, width: u32, height: u32) -> RgbImage {
        let mut img = RgbImage::new(width, height);
        self.draw(&mut img, 0, 0, width as i64, height as i64);
        img
    }
}

/// Charts stacked vertically in one image, each `height` pixels high.
pub fn stack(charts: &[LineChart], width: u32, height: u32) -> RgbImage {
    let mut img = RgbImage::new(width, height * charts.len().max(1) as u32);
    for (i, c) in charts.iter().enumerate() {
        c.draw(
            &mut img,
            0,
            (i as u32 * height) as i64,
            width as i64,
            height as i64,
        );
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_labels_plot_without_hanging() {
        // Frame labels that are microsecond timestamps, one or many frames.
        for pts in [
            vec![(1.6e15, 0.5)],
            vec![
                (1.6e15, 0.5),
                (1.6e15 + 33_333.0, 0.7),
                (1.6e15 + 66_666.0, 0.2),
            ],
            vec![(f64::MAX / 4.0, 1e300), (-f64::MAX / 4.0, -1e300)],
        ] {
            let mut c = LineChart::new("t", "frame", "deg");
            c.add("a", pts);
            let img = c.render(320, 200);
            assert_eq!(img.dimensions(), (320, 200));
        }
        assert!(ticks(0.0, 1e300, 1e-300).len() <= 100);
        assert_eq!(ticks(0.0, 10.0, 2.0), vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
    }

    #[test]
    fn ticks_are_round_numbers() {
        assert_eq!(tick_step(10.0, 5.0), 2.0);
        assert_eq!(tick_step(0.7, 5.0), 0.1);
        assert_eq!(tick_step(1234.0, 8.0), 200.0);
        assert_eq!(fmt_tick(0.30000000000000004, 0.1), "0.3");
    }

    #[test]
    fn curves_land_where_their_values_say() {
        let mut c = LineChart::new("t", "frame", "deg");
        c.add("a", (0..=10).map(|i| (i as f64, 1.0)).collect());
        c.y_max = Some(2.0);
        let img = c.render(400, 200);
        // The curve at y = 1 of 0..2 sits halfway up the plot area
        // (top 44, bottom 156): row 100; its colour must be there.
        let col = draw::PALETTE[0];
        let hits = (80..380)
            .filter(|&x| (98..=102).any(|y| img.get_pixel(x, y).0 == col))
            .count();
        assert!(hits > 200, "{hits}");
        // Empty and non-finite inputs draw without panicking.
        let mut e = LineChart::new("", "", "");
        e.add("nan", vec![(f64::NAN, 1.0), (1.0, f64::INFINITY)]);
        let _ = stack(&[e, LineChart::default()], 300, 150);
    }
}
