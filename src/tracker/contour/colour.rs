//! The object's and the background's colours, learnt online
//! ([`ColourModel`]).

use super::histograms::Histograms;
use super::sectors::{SECTOR_LEAST_PX, turn_of, turns_of_row};
use nalgebra::Vector2;

/// Foreground (object) and background colour histograms, learnt online
/// from frames at their tracked poses: one pair over the whole object and,
/// where configured ([`super::ContourConfig::sectors`]), one pair per sector of
/// directions around the object's projected centre. What lies behind an
/// object changes along its outline (the real dragon's head stands
/// against an orange model, its tail against the white table): a line
/// then weighs its colours against the background seen on its side
/// (localised statistics, as RBOT's do around contour points).
#[derive(Debug, Clone, PartialEq)]
pub struct ColourModel {
    bins: u32,
    global: Histograms,
    sectors: Vec<Histograms>,
    scratch: LearnScratch,
}

/// The counts [`ColourModel::learn_around`] gathers from one frame, kept
/// between frames so that learning allocates nothing once the window and
/// sectors have been seen (the sectors' counts are 8 x 4096 bins a side).
/// Not part of the model: any two compare equal, and it prints as nothing.
#[derive(Clone, Default)]
struct LearnScratch {
    fg: Vec<f32>,
    bg: Vec<f32>,
    sectors_fg: Vec<f32>,
    sectors_bg: Vec<f32>,
    integral: Vec<u32>,
    /// A row's directions from the centre ([`turns_of_row`]).
    turns: Vec<f64>,
}

impl PartialEq for LearnScratch {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl std::fmt::Debug for LearnScratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("LearnScratch")
    }
}

/// `v` cleared and filled with `n` copies of `x` (its allocation kept).
fn refill<T: Copy>(v: &mut Vec<T>, n: usize, x: T) {
    v.clear();
    v.resize(n, x);
}

/// A run of pixels that [`ColourModel::learn_around`] counts into the same
/// bins: side (covered), bin and sector `k`; `near` and `far` are the
/// sums of sector `k`'s and sector `k + 1`'s bin (the same when there is
/// one sector), started from their values in memory.
#[derive(Default)]
struct Run {
    key: (bool, usize, usize),
    count: u32,
    near: f32,
    far: f32,
}

impl Run {
    /// Starts a run of `key`, reading its sector bins from `sides`.
    fn start(&mut self, key: (bool, usize, usize), sides: &[f32], nbins: usize, ns: usize) {
        let (_, b, k) = key;
        self.key = key;
        self.count = 0;
        if ns > 0 {
            self.near = sides[k * nbins + b];
            self.far = sides[(k + 1) % ns * nbins + b];
        }
    }

    /// Writes the run's sums back (a count of pixels is exact in f32 up to
    /// 2^24: adding it at once is adding 1 that many times).
    fn flush(
        &mut self,
        fg: &mut [f32],
        bg: &mut [f32],
        sfg: &mut [f32],
        sbg: &mut [f32],
        nbins: usize,
        ns: usize,
    ) {
        if self.count == 0 {
            return;
        }
        let (covered, b, k) = self.key;
        let (side, sides) = if covered { (fg, sfg) } else { (bg, sbg) };
        side[b] += self.count as f32;
        if ns > 0 {
            if ns > 1 {
                sides[(k + 1) % ns * nbins + b] = self.far;
            }
            sides[k * nbins + b] = self.near;
        }
        self.count = 0;
    }
}

impl ColourModel {
    /// Empty histograms of `bins` bins per channel, over the whole object
    /// only.
    pub fn new(bins: u32) -> Self {
        Self::with_sectors(bins, 0)
    }

    /// Empty histograms of `bins` bins per channel, over the whole object
    /// and for each of `sectors` sectors of directions around it (0: none;
    /// sector `k` centred on the direction `k / sectors` of a turn from
    /// +x, towards +y).
    pub fn with_sectors(bins: u32, sectors: usize) -> Self {
        let n = (bins * bins * bins) as usize;
        Self {
            bins,
            global: Histograms::new(n),
            sectors: vec![Histograms::new(n); sectors],
            scratch: LearnScratch::default(),
        }
    }

    /// The number of sectors.
    pub fn sectors(&self) -> usize {
        self.sectors.len()
    }

    /// Whether any frame has been learnt.
    pub fn is_learned(&self) -> bool {
        self.global.learned
    }

    /// Whether sector `k` has learnt from a frame.
    pub fn sector_learned(&self, k: usize) -> bool {
        self.sectors.get(k).is_some_and(|h| h.learned)
    }

    pub(super) fn bin(&self, c: [u8; 3]) -> usize {
        let q = |v: u8| (v as u32 * self.bins / 256) as usize;
        let b = self.bins as usize;
        (q(c[0]) * b + q(c[1])) * b + q(c[2])
    }

    /// The sector whose centre is nearest the direction `d` from the
    /// object's centre (`None` without sectors).
    pub fn sector_toward(&self, d: Vector2<f64>) -> Option<usize> {
        let n = self.sectors.len();
        (n > 0).then(|| ((turn_of(d) * n as f64).round() as usize) % n)
    }

    /// The histograms a line in direction `d` from the object's centre
    /// weighs its colours with: its sector's where learnt, else the whole
    /// object's.
    pub fn histograms_toward(&self, d: Vector2<f64>) -> &Histograms {
        match self.sector_toward(d) {
            Some(k) if self.sectors[k].learned => &self.sectors[k],
            _ => &self.global,
        }
    }

    /// The whole object's histograms.
    pub fn global(&self) -> &Histograms {
        &self.global
    }

    /// Learns from `frame` with the object covering `coverage` (row-major,
    /// the frame's size): covered pixels are foreground, uncovered ones
    /// inside `rect` (x0, y0, x1, y1, inclusive) background, except those
    /// within `margin` pixels (a square window) of the other side: the
    /// pixels across the outline mix both colours (and the splatted
    /// coverage is a little wider than the object), and learnt as either
    /// they would pull every boundary found toward that side. The first call
    /// sets the histograms, later ones blend in with weight `rate`. The
    /// whole object's histograms only; [`Self::learn_around`] learns the
    /// sectors too.
    pub fn learn(
        &mut self,
        frame: &image::RgbImage,
        coverage: &[bool],
        rect: (usize, usize, usize, usize),
        margin: usize,
        rate: f32,
    ) {
        self.learn_around(frame, coverage, rect, margin, rate, None);
    }

    /// [`Self::learn`], and with `centre` (the object's projected centre)
    /// each sector from the pixels in its directions around it: a pixel
    /// counts towards its two nearest sectors, by how near (linearly in
    /// angle).
    pub fn learn_around(
        &mut self,
        frame: &image::RgbImage,
        coverage: &[bool],
        rect: (usize, usize, usize, usize),
        margin: usize,
        rate: f32,
        centre: Option<Vector2<f64>>,
    ) {
        let w = frame.width() as usize;
        let h = frame.height() as usize;
        let nbins = self.global.foreground.len();
        let ns = if centre.is_some() {
            self.sectors.len()
        } else {
            0
        };
        let mut scratch = std::mem::take(&mut self.scratch);
        let LearnScratch {
            fg,
            bg,
            sectors_fg: sfg,
            sectors_bg: sbg,
            integral,
            turns,
        } = &mut scratch;
        refill(fg, nbins, 0.0);
        refill(bg, nbins, 0.0);
        refill(sfg, nbins * ns, 0.0);
        refill(sbg, nbins * ns, 0.0);
        let (x0, y0) = (rect.0.min(w - 1), rect.1.min(h - 1));
        let (x1, y1) = (rect.2.min(w - 1).max(x0), rect.3.min(h - 1).max(y0));
        // Covered counts over the rectangle grown by the margin (clamped to
        // the image), as an integral image: a pixel is kept when its window
        // is all covered or all empty.
        let (gx0, gy0) = (x0.saturating_sub(margin), y0.saturating_sub(margin));
        let (gx1, gy1) = ((x1 + margin).min(w - 1), (y1 + margin).min(h - 1));
        let gw = gx1 - gx0 + 2;
        refill(integral, gw * (gy1 - gy0 + 2), 0);
        for y in gy0..=gy1 {
            let mut run = 0u32;
            for x in gx0..=gx1 {
                run += u32::from(coverage[y * w + x]);
                let k = (y - gy0 + 1) * gw + (x - gx0 + 1);
                integral[k] = integral[k - gw] + run;
            }
        }
        let window = |x: usize, y: usize| {
            let (a, b) = (
                x.saturating_sub(margin).max(gx0),
                y.saturating_sub(margin).max(gy0),
            );
            let (c, d) = ((x + margin).min(gx1), (y + margin).min(gy1));
            let at = |x: usize, y: usize| integral[(y - gy0) * gw + (x - gx0)];
            let n = ((c - a + 1) * (d - b + 1)) as u32;
            let sum = at(c + 1, d + 1) + at(a, b) - at(a, d + 1) - at(c + 1, b);
            (sum, n)
        };
        let centre = centre.unwrap_or_default();
        let raw = frame.as_raw();
        // Pixel coordinates as i32 for the row's directions; a frame
        // wider than that learns without sectors rather than wrongly.
        let ns = if x1 < i32::MAX as usize { ns } else { 0 };
        refill(turns, if ns > 0 { x1 - x0 + 1 } else { 0 }, 0.0);
        // A run of pixels on one side in one bin (and sector) keeps its
        // sums in registers: the same additions in the same order as bin
        // by bin through memory (so the same sums bit for bit), without
        // waiting on each store when neighbours share a colour.
        let mut run = Run::default();
        for y in y0..=y1 {
            if ns > 0 {
                turns_of_row(x0 as i32, centre.x, y as f64 - centre.y, turns);
            }
            for x in x0..=x1 {
                let (sum, n) = window(x, y);
                let covered = coverage[y * w + x];
                if (covered && sum != n) || (!covered && sum != 0) {
                    continue;
                }
                let p = (y * w + x) * 3;
                let b = self.bin([raw[p], raw[p + 1], raw[p + 2]]);
                let (k, f) = if ns > 0 {
                    let t = turns[x - x0] * ns as f64;
                    let k = (t as usize).min(ns - 1);
                    (k, (t - k as f64) as f32)
                } else {
                    (0, 0.0)
                };
                if run.count == 0 || run.key != (covered, b, k) {
                    run.flush(fg, bg, sfg, sbg, nbins, ns);
                    run.start(
                        (covered, b, k),
                        if covered { &*sfg } else { &*sbg },
                        nbins,
                        ns,
                    );
                }
                run.count += 1;
                if ns > 0 {
                    run.near += 1.0 - f;
                    if ns == 1 {
                        run.near += f;
                    } else {
                        run.far += f;
                    }
                }
            }
        }
        run.flush(fg, bg, sfg, sbg, nbins, ns);
        self.global.blend(fg, bg, 1.0, rate);
        for (k, hist) in self.sectors.iter_mut().enumerate().take(ns) {
            let r = k * nbins..(k + 1) * nbins;
            hist.blend(&sfg[r.clone()], &sbg[r], SECTOR_LEAST_PX, rate);
        }
        self.scratch = scratch;
    }

    /// The probability that a pixel of colour `c` shows the object (equal
    /// priors), kept within [0.02, 0.98] so that one pixel cannot veto a
    /// boundary position; 0.5 for a colour never seen. The whole object's
    /// histograms.
    pub fn foreground_probability(&self, c: [u8; 3]) -> f32 {
        self.global.probability_of_bin(self.bin(c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_are_not_learnt_near_the_outline() {
        // Object red on the left half, background blue, and a mixed purple
        // column on the boundary that belongs to neither.
        let (w, h) = (20u32, 10u32);
        let frame = image::RgbImage::from_fn(w, h, |x, _| match x {
            0..=9 => image::Rgb([250, 10, 10]),
            10 => image::Rgb([130, 10, 130]),
            _ => image::Rgb([10, 10, 250]),
        });
        let coverage: Vec<bool> = (0..w * h).map(|i| i % w <= 10).collect();
        let rect = (0, 0, w as usize - 1, h as usize - 1);
        let mut near = ColourModel::new(8);
        near.learn(&frame, &coverage, rect, 0, 1.0);
        assert!(near.foreground_probability([130, 10, 130]) > 0.9);
        let mut away = ColourModel::new(8);
        away.learn(&frame, &coverage, rect, 2, 1.0);
        assert_eq!(away.foreground_probability([130, 10, 130]), 0.5);
        assert!(away.foreground_probability([250, 10, 10]) > 0.9);
        assert!(away.foreground_probability([10, 10, 250]) < 0.1);
    }

    /// [`ColourModel::learn_around`] as first written: pixel by pixel,
    /// each count added to its bins in memory, [`turn_of`] per pixel.
    fn learn_around_reference(
        m: &mut ColourModel,
        frame: &image::RgbImage,
        coverage: &[bool],
        rect: (usize, usize, usize, usize),
        margin: usize,
        rate: f32,
        centre: Option<Vector2<f64>>,
    ) {
        let (w, h) = (frame.width() as usize, frame.height() as usize);
        let nbins = m.global.foreground.len();
        let ns = if centre.is_some() { m.sectors.len() } else { 0 };
        let (mut fg, mut bg) = (vec![0f32; nbins], vec![0f32; nbins]);
        let (mut sfg, mut sbg) = (vec![0f32; nbins * ns], vec![0f32; nbins * ns]);
        let (x0, y0) = (rect.0.min(w - 1), rect.1.min(h - 1));
        let (x1, y1) = (rect.2.min(w - 1).max(x0), rect.3.min(h - 1).max(y0));
        let centre = centre.unwrap_or_default();
        for y in y0..=y1 {
            for x in x0..=x1 {
                let covered = coverage[y * w + x];
                let (a, b) = (x.saturating_sub(margin), y.saturating_sub(margin));
                let (c, d) = ((x + margin).min(w - 1), (y + margin).min(h - 1));
                let mixed = (b..=d).any(|v| (a..=c).any(|u| coverage[v * w + u] != covered));
                if mixed {
                    continue;
                }
                let bin = m.bin(frame.get_pixel(x as u32, y as u32).0);
                let (side, sides) = if covered {
                    (&mut fg, &mut sfg)
                } else {
                    (&mut bg, &mut sbg)
                };
                side[bin] += 1.0;
                if ns > 0 {
                    let t = turn_of(Vector2::new(x as f64, y as f64) - centre) * ns as f64;
                    let k = (t as usize).min(ns - 1);
                    let f = (t - k as f64) as f32;
                    sides[k * nbins + bin] += 1.0 - f;
                    sides[(k + 1) % ns * nbins + bin] += f;
                }
            }
        }
        m.global.blend(&fg, &bg, 1.0, rate);
        for (k, hist) in m.sectors.iter_mut().enumerate().take(ns) {
            let r = k * nbins..(k + 1) * nbins;
            hist.blend(&sfg[r.clone()], &sbg[r], SECTOR_LEAST_PX, rate);
        }
    }

    #[test]
    fn learning_gives_the_pixel_by_pixel_sums_bit_for_bit() {
        // learn_around sums a run of pixels in the same bins in registers
        // and takes a row's directions at once (turns_of_row): the
        // histograms must be those of the plain loop exactly. Frames of
        // blocks of one colour (long runs) and of noise (short ones), blobs of
        // coverage, rectangles cut by the frame's edges, margins 0-3,
        // 0, 1, 2 and 8 sectors, centres inside and outside the frame
        // (and on a pixel: a zero direction), a second frame blended in.
        let mut rng = crate::rng::Rng::new(21);
        for case in 0..60 {
            let (w, h) = (8 + rng.below(90) as u32, 8 + rng.below(70) as u32);
            // Blocks of one colour (runs up to 12 pixels long), or noise.
            let blocks = case % 2 == 0;
            let frame = |rng: &mut crate::rng::Rng| {
                let palette: Vec<[u8; 3]> = (0..4)
                    .map(|_| [0; 3].map(|_| rng.below(256) as u8))
                    .collect();
                let mut f = image::RgbImage::new(w, h);
                for (x, y, px) in f.enumerate_pixels_mut() {
                    let v = if blocks {
                        palette[((x / 12 + y / 3) % 4) as usize]
                    } else {
                        [0; 3].map(|_| rng.below(256) as u8)
                    };
                    *px = image::Rgb(v);
                }
                f
            };
            let blobs: Vec<(f64, f64, f64)> = (0..3)
                .map(|_| {
                    let r = rng.uniform(2.0, 20.0);
                    (rng.uniform(0.0, w as f64), rng.uniform(0.0, h as f64), r)
                })
                .collect();
            let coverage: Vec<bool> = (0..(w * h) as usize)
                .map(|i| {
                    let (x, y) = ((i % w as usize) as f64, (i / w as usize) as f64);
                    blobs.iter().any(|(cx, cy, r)| (x - cx).hypot(y - cy) < *r)
                })
                .collect();
            let rect = (
                rng.below(w as u64 / 2) as usize,
                rng.below(h as u64 / 2) as usize,
                (w as u64 / 2 + rng.below(w as u64)) as usize,
                (h as u64 / 2 + rng.below(h as u64)) as usize,
            );
            let margin = rng.below(4) as usize;
            let sectors = [0, 1, 2, 8][case % 4];
            let centre = match case % 3 {
                0 => Some(Vector2::new(
                    rng.uniform(0.0, w as f64),
                    rng.uniform(0.0, h as f64),
                )),
                1 => Some(Vector2::new(
                    rng.below(w as u64) as f64,
                    rng.below(h as u64) as f64,
                )),
                _ => Some(Vector2::new(
                    rng.uniform(-200.0, 300.0),
                    rng.uniform(-200.0, 300.0),
                )),
            };
            let centre = if case % 5 == 4 { None } else { centre };
            let mut fast = ColourModel::with_sectors(4 + (case % 3) as u32 * 6, sectors);
            let mut plain = fast.clone();
            for rate in [1.0, 0.3] {
                let f = frame(&mut rng);
                fast.learn_around(&f, &coverage, rect, margin, rate, centre);
                learn_around_reference(&mut plain, &f, &coverage, rect, margin, rate, centre);
                assert!(
                    fast.global == plain.global && fast.sectors == plain.sectors,
                    "case {case}: {w}x{h}, rect {rect:?}, margin {margin}, {sectors} sectors, \
                     centre {centre:?}, rate {rate}"
                );
            }
        }
    }
}
