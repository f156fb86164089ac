//! The boundary along a line: the search along a contour point's normal
//! in the live frame ([`search_line`]).

use super::colour::ColourModel;
use super::histograms::Histograms;
use super::rows::Lifted;
use crate::pose::Observation;
use nalgebra::{Vector2, Vector3, Vector6};

/// The boundary along one line: from `position` along the outward `normal`,
/// samples every pixel within `half_len`; returns the offset `d` (pixels,
/// positive outward) where the object ends, the mean of its posterior
/// under a smooth step of width `slope` (the object's probability
/// `hf(o - d) = (1 - tanh((o - d) / slope)) / 2` at offset `o`), or `None`
/// when the line leaves the image, shows no boundary (a flat posterior) or
/// puts it at the line's ends. The colours are weighed with the whole
/// object's histograms ([`search_line_toward`]: a sector's).
pub fn search_line(
    frame: &image::RgbImage,
    colours: &ColourModel,
    position: Vector2<f64>,
    normal: Vector2<f64>,
    half_len: f32,
    slope: f32,
) -> Option<f64> {
    let h = colours.global();
    LINE_SCRATCH.with_borrow_mut(|s| {
        search_line_in(s, frame, colours, h, position, normal, half_len, slope)
    })
}

/// [`search_line`] with the histograms of the sector the line lies in,
/// `direction` from the object's centre
/// ([`ColourModel::histograms_toward`]).
#[allow(clippy::too_many_arguments)]
pub fn search_line_toward(
    frame: &image::RgbImage,
    colours: &ColourModel,
    direction: Vector2<f64>,
    position: Vector2<f64>,
    normal: Vector2<f64>,
    half_len: f32,
    slope: f32,
) -> Option<f64> {
    let h = colours.histograms_toward(direction);
    LINE_SCRATCH.with_borrow_mut(|s| {
        search_line_in(s, frame, colours, h, position, normal, half_len, slope)
    })
}

/// The buffers of [`search_line`], kept per thread between lines (a
/// frame searches hundreds of them).
#[derive(Default)]
struct LineScratch {
    /// The object probability of each sample.
    pf: Vec<f64>,
    /// Prefix sums of `ln pf` and `ln (1 - pf)`.
    inside: Vec<f64>,
    outside: Vec<f64>,
    /// The smooth step on the 1/8 px grid, for `steps_slope`.
    steps: Vec<f64>,
    steps_slope: f64,
    /// Log-likelihoods of the half-pixel candidates.
    ll: Vec<f64>,
}

thread_local! {
    static LINE_SCRATCH: std::cell::RefCell<LineScratch> = std::cell::RefCell::default();
}

#[allow(clippy::too_many_arguments)]
fn search_line_in(
    s: &mut LineScratch,
    frame: &image::RgbImage,
    colours: &ColourModel,
    hist: &Histograms,
    position: Vector2<f64>,
    normal: Vector2<f64>,
    half_len: f32,
    slope: f32,
) -> Option<f64> {
    let l = half_len.round().max(2.0) as i64;
    let n = (2 * l + 1) as usize;
    s.pf.clear();
    s.inside.clear();
    s.outside.clear();
    s.inside.push(0.0);
    s.outside.push(0.0);
    for k in -l..=l {
        let p = position + normal * k as f64;
        let c = crate::geometry::sample_bilinear_rgb(frame, p.x as f32, p.y as f32)?;
        let [p, ln_p, ln_q] = hist.terms(colours.bin(c.0));
        s.pf.push(p);
        let i = s.pf.len() - 1;
        s.inside.push(s.inside[i] + ln_p);
        s.outside.push(s.outside[i] + ln_q);
    }
    // Beyond 4 slopes the step is 0 or 1 to within 3e-4: those samples
    // count as plainly inside (ln pf) or outside (ln (1 - pf)), summed by
    // prefix sums; only the samples near `d` need the smooth step.
    let slope = slope as f64;
    let reach = (4.0 * slope).ceil() as i64;
    // The smooth step at every offset o - d the searches below meet: d
    // lies on a grid of 1/8 px and |o - d| <= reach, so the step is
    // tabulated once (per slope) at o - d = m / 8 (m / 8 is exact).
    if s.steps_slope != slope || s.steps.is_empty() {
        s.steps.clear();
        s.steps.extend(
            (-8 * reach..=8 * reach).map(|m| 0.5 * (1.0 - ((m as f64 / 8.0) / slope).tanh())),
        );
        s.steps_slope = slope;
    }
    let (pf, inside, outside, steps) = (&s.pf, &s.inside, &s.outside, &s.steps);
    let loglik = |d: f64| {
        // d in eighths of a pixel (exact: d lies on that grid).
        let d8 = (d * 8.0) as i64;
        debug_assert_eq!(d8 as f64, d * 8.0, "d off the 1/8 px grid");
        // Samples i with offset o = i - l: plainly inside when o < d - reach.
        let lo =
            ((d8 - 8 * reach).div_euclid(8) + i64::from((d8 - 8 * reach).rem_euclid(8) != 0) + l)
                .clamp(0, n as i64) as usize;
        let hi = ((d8 + 8 * reach).div_euclid(8) + l + 1).clamp(0, n as i64) as usize;
        // The samples near d: one logarithm of their likelihoods' product
        // (at least 0.02 each, at most 9 of them for a 1 px slope: no
        // underflow) instead of one per sample. Sample i is at o - d =
        // (8 (i - l) - d8) / 8, the step's entry m of that.
        let mut near = 1.0;
        let mut m = 8 * (lo as i64 - l) - d8 + 8 * reach;
        for p in &pf[lo..hi.max(lo)] {
            let hf = steps[m as usize];
            near *= hf * p + (1.0 - hf) * (1.0 - p);
            m += 8;
        }
        inside[lo] + (outside[n] - outside[hi]) + near.ln()
    };
    // Candidates every half pixel, away from the line's ends: d = h / 2.
    let candidate = |h: i64| h as f64 * 0.5;
    let (h0, h1) = (-(2 * l - 2), 2 * l - 2);
    s.ll.clear();
    s.ll.extend((h0..=h1).map(|h| loglik(candidate(h))));
    let ll = &s.ll;
    let (k, best) = ll
        .iter()
        .copied()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    // A boundary the line cannot place (a flat posterior: no transition,
    // or several alike) is no evidence.
    let (mut sw, mut sd, mut sdd) = (0.0, 0.0, 0.0);
    for (j, v) in ll.iter().enumerate() {
        let w = (v - best).exp();
        let d = candidate(h0 + j as i64);
        sw += w;
        sd += w * d;
        sdd += w * d * d;
    }
    let mean = sd / sw;
    let var = (sdd / sw - mean * mean).max(0.0);
    if var.sqrt() > (0.15 * l as f64).max(1.5) || k == 0 || k + 1 == ll.len() {
        return None;
    }
    // Sub-pixel, first to about half a pixel: the posterior mean on a
    // finer grid near the maximum (a boundary pixel of mixed colour, never
    // learnt, leaves the likelihood flat across it: its mean, not a
    // parabola's vertex, is unbiased); then within the pixels by their
    // colours ([`mixed_boundary`]).
    let dk = candidate(h0 + k as i64);
    let fine = (-12..=12)
        .map(|q| dk + q as f64 * 0.125)
        .filter(|d| d.abs() <= (l - 1) as f64);
    let fl: [Option<(f64, f64)>; 25] = {
        let mut a = [None; 25];
        for (slot, d) in a.iter_mut().zip(fine) {
            *slot = Some((d, loglik(d)));
        }
        a
    };
    let top = fl
        .iter()
        .flatten()
        .map(|p| p.1)
        .fold(f64::NEG_INFINITY, f64::max);
    let (mut sw, mut sd) = (0.0, 0.0);
    for (d, v) in fl.iter().flatten() {
        let w = (v - top).exp();
        sw += w;
        sd += w * d;
    }
    let d0 = sd / sw;
    Some(mixed_boundary(frame, position, normal, pf, l, d0).unwrap_or(d0))
}

/// Samples either side of the boundary that stand for the pure colours in
/// [`mixed_boundary`], pixels from the posterior's estimate.
const MIX_REACH: i64 = 2;

/// Spacing of [`mixed_boundary`]'s samples along the line, pixels.
const MIX_STEP: f64 = 0.25;

/// A sample farther than this fraction of the two colours' distance from
/// its mix of them (on the segment between them, or of the object's shade
/// and the background) shows a third colour: no mixed boundary.
const MIX_OFF_SEGMENT: f64 = 0.25;

/// A shade of the object's side is told from the background's share
/// when the background's colour lies at least this fraction of the two
/// colours' distance from every shade of the object's (else its share
/// would be noisier than on the segment between them).
const MIX_MIN_SHADE_DISTANCE: f64 = 0.5;

/// Colours closer than this (RGB distance, 0..255 units) do not place the
/// boundary within a pixel: image noise would.
const MIX_MIN_CONTRAST: f64 = 30.0;

/// The boundary within its pixels. The colour models place it to about half
/// a pixel only (a sample's colour is object or background by the
/// histograms; the samples across the boundary mix both and are in
/// neither). But a mixed sample shows the boundary's place: camera pixels
/// (and anti-aliased renders) average the colours of the two sides over
/// their area, so its colour lies between the object's and the
/// background's in proportion to the object's share `alpha`. With the
/// samples [`MIX_REACH`] pixels either side of `d0` (the posterior's
/// estimate, offsets along the line from `position`) standing for the
/// pure colours, each sample between is split into its shares of them
/// (the object's side scaled by a free shade where the background lies
/// away from its shades: a limb darkens towards the outline; else on the
/// segment between them),
/// and the boundary is where a sharp step of the same area lies:
/// for samples every `h` from `a` to `b`, `alpha(a) = 1`, `alpha(b) = 0`,
/// a step at `e` covers `h sum alpha = e - a + h / 2`. (Fine steps make
/// this hold for any blur across the boundary, a pixel's footprint seen
/// along a slanted line included; at one pixel it would not.) `pf`: the
/// object probabilities of the line's samples at offsets `-l..=l`. `None`
/// (keep `d0`) where the line is too short, the two colours are too alike,
/// the colour model does not put them on their sides, a sample between is
/// no mix of them, or the result leaves `d0`'s pixel.
fn mixed_boundary(
    frame: &image::RgbImage,
    position: Vector2<f64>,
    normal: Vector2<f64>,
    pf: &[f64],
    l: i64,
    d0: f64,
) -> Option<f64> {
    let c = d0.round() as i64;
    let (a, b) = (c - MIX_REACH, c + MIX_REACH);
    if a < -l || b > l {
        return None;
    }
    if !(pf[(a + l) as usize] > 0.5 && pf[(b + l) as usize] < 0.5) {
        return None;
    }
    let colour = |o: f64| {
        let p = position + normal * o;
        crate::geometry::sample_bilinear_rgb(frame, p.x as f32, p.y as f32)
            .map(|v| Vector3::new(v.0[0] as f64, v.0[1] as f64, v.0[2] as f64))
    };
    let (inside, outside) = (colour(a as f64)?, colour(b as f64)?);
    let span = inside - outside;
    let len2 = span.norm_squared();
    if len2 < MIX_MIN_CONTRAST * MIX_MIN_CONTRAST {
        return None;
    }
    // The object's side darkens towards a limb (its surface turns away
    // from the light): a mixed sample is then `s inside` and the
    // background over their shares, with an unknown shade `s`. Where the
    // background's colour lies away from every shade of the object's (the
    // ray through `inside`), `v = p inside + q outside` is solved for
    // (p, q) by least squares and the object's share is `1 - q` (the
    // background's share is what the shade cannot change). The standard
    // deviation of `q` is the noise over that distance, against the noise
    // over the colours' distance on the segment: nearer than
    // [`MIX_MIN_SHADE_DISTANCE`] of it (colours apart in brightness
    // more than in hue), the shade and the share are told apart too
    // poorly, and the sample is placed on the segment between them.
    let gram = nalgebra::Matrix2::new(
        inside.norm_squared(),
        inside.dot(&outside),
        inside.dot(&outside),
        outside.norm_squared(),
    );
    let off_shades2 = gram.determinant() / gram[(0, 0)].max(1e-9);
    let shaded = (off_shades2 >= MIX_MIN_SHADE_DISTANCE * MIX_MIN_SHADE_DISTANCE * len2)
        .then(|| gram.try_inverse())
        .flatten();
    let steps = ((b - a) as f64 / MIX_STEP).round() as i64;
    let mut area = 1.0; // alpha(a)
    for j in 1..steps {
        let o = a as f64 + j as f64 * MIX_STEP;
        let c = colour(o)?;
        let (t, off) = match &shaded {
            Some(inv) => {
                let pq = inv * nalgebra::Vector2::new(inside.dot(&c), outside.dot(&c));
                let (p, q) = (pq[0].max(0.0), pq[1].clamp(0.0, 1.0));
                (1.0 - q, c - inside * p - outside * q)
            }
            None => {
                let v = c - outside;
                let t = v.dot(&span) / len2;
                (t, v - span * t)
            }
        };
        // A third colour (texture, clutter) is not a mix of the two.
        if off.norm_squared() > MIX_OFF_SEGMENT * MIX_OFF_SEGMENT * len2 {
            return None;
        }
        area += t.clamp(0.0, 1.0);
    }
    let e = a as f64 - 0.5 * MIX_STEP + MIX_STEP * area;
    ((e - d0).abs() <= 1.0).then_some(e)
}

/// The contour rows of `found` at `twist`: each line searched where the
/// twist moved its point (to first order, `n^T L twist` along the normal),
/// in order, the lines without a boundary left out. The lines are
/// independent: long lists are split over the CPU's cores (the results
/// are the same as in one thread, in the same order).
pub(super) fn search_lines(
    frame: &image::RgbImage,
    colours: &ColourModel,
    centre: Vector2<f64>,
    found: &[Lifted],
    twist: &Vector6<f64>,
    half: f32,
    slope: f32,
) -> Vec<Observation> {
    let one = |l: &Lifted| {
        let (p, row) = (&l.point, &l.row);
        let moved = (row.predictors * twist)[0];
        search_line_toward(
            frame,
            colours,
            p.position - centre,
            p.position + p.normal * moved,
            p.normal,
            half,
            slope,
        )
        .map(|d| Observation {
            displacement: Vector2::new(moved + d, 0.0),
            ..*row
        })
    };
    crate::par::flat_map_split(found, 64, |part| part.iter().filter_map(one).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::contour::outline::ContourPoint;
    use crate::tracker::contour::rows::contour_row;

    /// A frame whose object is the half-plane `n . (p - p0) < 0`, each pixel
    /// the area average of the object's and the background's colours (as a
    /// camera integrates them), plus noise; and its coverage at the pixel
    /// centres.
    fn half_plane(
        n: Vector2<f64>,
        p0: Vector2<f64>,
        rng: &mut crate::rng::Rng,
    ) -> (image::RgbImage, Vec<bool>) {
        half_plane_shaded(n, p0, 0.0, rng)
    }

    /// [`half_plane`] with the object's colour darkened towards its edge,
    /// as a limb is: by `darken` at the edge, `darken / e` a pixel inside.
    fn half_plane_shaded(
        n: Vector2<f64>,
        p0: Vector2<f64>,
        darken: f64,
        rng: &mut crate::rng::Rng,
    ) -> (image::RgbImage, Vec<bool>) {
        let (w, h) = (64u32, 64u32);
        let (fg, bg) = ([200.0, 160.0, 40.0], [60.0, 40.0, 120.0]);
        let depth = |x: f64, y: f64| -n.dot(&(Vector2::new(x, y) - p0));
        let inside = |x: f64, y: f64| depth(x, y) > 0.0;
        let mut frame = image::RgbImage::new(w, h);
        for (x, y, px) in frame.enumerate_pixels_mut() {
            let s = 16;
            let mut sum = [0.0; 3];
            for i in 0..s {
                for j in 0..s {
                    let u = x as f64 - 0.5 + (i as f64 + 0.5) / s as f64;
                    let v = y as f64 - 0.5 + (j as f64 + 0.5) / s as f64;
                    let d = depth(u, v);
                    for k in 0..3 {
                        sum[k] += if d > 0.0 {
                            fg[k] * (1.0 - darken * (-d).exp())
                        } else {
                            bg[k]
                        };
                    }
                }
            }
            let mut c =
                |k: usize| (sum[k] / (s * s) as f64 + 2.0 * rng.normal()).clamp(0.0, 255.0) as u8;
            *px = image::Rgb([c(0), c(1), c(2)]);
        }
        let coverage = (0..w * h)
            .map(|i| inside((i % w) as f64, (i / w) as f64))
            .collect();
        (frame, coverage)
    }

    /// Straight edges at random angles and sub-pixel places (darkened by
    /// `darken` towards the edge, [`half_plane_shaded`]), searched from a
    /// point a known distance off: every offset found is within `most` px
    /// of that distance; returns their rms error.
    fn edge_search_rms(seed: u64, darken: f64, most: f64) -> f64 {
        let mut rng = crate::rng::Rng::new(seed);
        let mut sq = 0.0;
        let trials = 40;
        for _ in 0..trials {
            let a = rng.uniform(0.0, std::f64::consts::TAU);
            let n = Vector2::new(a.cos(), a.sin());
            let p0 = Vector2::new(rng.uniform(30.0, 34.0), rng.uniform(30.0, 34.0));
            let (frame, coverage) = half_plane_shaded(n, p0, darken, &mut rng);
            let mut colours = ColourModel::new(16);
            colours.learn(&frame, &coverage, (0, 0, 63, 63), 2, 1.0);
            let off = rng.uniform(-2.0, 2.0);
            let d = search_line(&frame, &colours, p0 - n * off, n, 8.0, 1.0).unwrap();
            let err = d - off;
            assert!(
                err.abs() < most,
                "angle {a:.2}, offset {off:.2}: found {d:.3}"
            );
            sq += err * err;
        }
        (sq / trials as f64).sqrt()
    }

    /// [`search_line`]'s model in its plainest arithmetic: each
    /// candidate's log-likelihood a sum of one logarithm per sample (the
    /// step taken as 0 or 1 beyond 4 slopes, as there), the probabilities
    /// from [`ColourModel::foreground_probability`], fresh buffers.
    fn search_line_reference(
        frame: &image::RgbImage,
        colours: &ColourModel,
        position: Vector2<f64>,
        normal: Vector2<f64>,
        half_len: f32,
        slope: f32,
    ) -> Option<f64> {
        let l = half_len.round().max(2.0) as i64;
        let mut pf = Vec::new();
        for k in -l..=l {
            let p = position + normal * k as f64;
            let c = crate::geometry::sample_bilinear_rgb(frame, p.x as f32, p.y as f32)?;
            pf.push(colours.foreground_probability(c.0) as f64);
        }
        let slope = slope as f64;
        let reach = (4.0 * slope).ceil();
        let loglik = |d: f64| {
            let mut v = 0.0;
            for (i, p) in pf.iter().enumerate() {
                let o = (i as i64 - l) as f64;
                v += if o < d - reach {
                    p.ln()
                } else if o > d + reach {
                    (1.0 - p).ln()
                } else {
                    let hf = 0.5 * (1.0 - ((o - d) / slope).tanh());
                    (hf * p + (1.0 - hf) * (1.0 - p)).ln()
                };
            }
            v
        };
        let candidates: Vec<f64> = (-(2 * l - 2)..=(2 * l - 2))
            .map(|h| h as f64 * 0.5)
            .collect();
        let ll: Vec<f64> = candidates.iter().map(|&d| loglik(d)).collect();
        let (k, best) = ll
            .iter()
            .copied()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))?;
        let w: Vec<f64> = ll.iter().map(|v| (v - best).exp()).collect();
        let sw: f64 = w.iter().sum();
        let mean = w.iter().zip(&candidates).map(|(w, d)| w * d).sum::<f64>() / sw;
        let var = w
            .iter()
            .zip(&candidates)
            .map(|(w, d)| w * (d - mean).powi(2))
            .sum::<f64>()
            / sw;
        if var.sqrt() > (0.15 * l as f64).max(1.5) || k == 0 || k + 1 == ll.len() {
            return None;
        }
        let fine: Vec<f64> = (-12..=12)
            .map(|q| candidates[k] + q as f64 * 0.125)
            .filter(|d| d.abs() <= (l - 1) as f64)
            .collect();
        let fl: Vec<f64> = fine.iter().map(|&d| loglik(d)).collect();
        let top = fl.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let w: Vec<f64> = fl.iter().map(|v| (v - top).exp()).collect();
        let d0 = w.iter().zip(&fine).map(|(w, d)| w * d).sum::<f64>() / w.iter().sum::<f64>();
        Some(mixed_boundary(frame, position, normal, &pf, l, d0).unwrap_or(d0))
    }

    #[test]
    fn the_line_search_is_its_plainest_arithmetic() {
        // Edges at random angles, places and shading; lines of every
        // length the contour uses (long ones cross the image's border and
        // find nothing), from random points near the edge and far from
        // it, with slopes of 0.5 to 2 px; one thread's buffers shared by
        // them all, as in the tracker. The fast search keeps the same
        // arithmetic except the order of its sums (a product per
        // candidate, prefix sums, a tabulated step): equal to 1e-9 px.
        let mut rng = crate::rng::Rng::new(41);
        let (mut found, mut none) = (0, 0);
        for _ in 0..24 {
            let a = rng.uniform(0.0, std::f64::consts::TAU);
            let n = Vector2::new(a.cos(), a.sin());
            let p0 = Vector2::new(rng.uniform(28.0, 36.0), rng.uniform(28.0, 36.0));
            let (frame, coverage) = half_plane_shaded(n, p0, rng.uniform(0.0, 0.5), &mut rng);
            let mut colours = ColourModel::new(16);
            colours.learn(&frame, &coverage, (0, 0, 63, 63), 2, 1.0);
            for _ in 0..12 {
                let half = [5.0f32, 8.0, 10.0, 16.0, 32.0][rng.below(5) as usize];
                let slope = [0.5f32, 1.0, 2.0][rng.below(3) as usize];
                let off = rng.uniform(-12.0, 12.0);
                let turn = rng.uniform(-0.3, 0.3);
                let dir = Vector2::new(
                    n.x * turn.cos() - n.y * turn.sin(),
                    n.x * turn.sin() + n.y * turn.cos(),
                );
                let at = p0 - n * off;
                let fast = search_line(&frame, &colours, at, dir, half, slope);
                let plain = search_line_reference(&frame, &colours, at, dir, half, slope);
                match (fast, plain) {
                    (Some(f), Some(p)) => {
                        assert!(
                            (f - p).abs() < 1e-9,
                            "half {half}, slope {slope}: {f} vs {p}"
                        );
                        found += 1;
                    }
                    (None, None) => none += 1,
                    other => panic!("half {half}, slope {slope}, offset {off:.2}: {other:?}"),
                }
            }
        }
        assert!(found > 150 && none > 20, "found {found}, none {none}");
    }

    #[test]
    fn the_boundary_is_found_within_its_pixel() {
        // Without the mixed colours (the posterior alone) the errors reach
        // a quarter of a pixel.
        let rms = edge_search_rms(5, 0.0, 0.1);
        assert!(rms < 0.05, "rms {rms:.3} px");
    }

    #[test]
    fn a_limb_darkening_towards_the_edge_does_not_pull_the_boundary_in() {
        // The object's side darkens towards its outline (half as bright at
        // the edge, as the synthetic `plain` object's limbs are under its
        // light): its shade is not a share of the background. Placed on
        // the segment between the two colours, as before, the darker
        // mixed samples read as background (the first of these edges was
        // found 0.30 px inside the true one).
        let rms = edge_search_rms(7, 0.5, 0.12);
        assert!(rms < 0.06, "rms {rms:.3} px");
    }

    #[test]
    fn lines_searched_on_several_cores_give_one_threads_rows_in_order() {
        let mut rng = crate::rng::Rng::new(9);
        let n = Vector2::new(0.6, 0.8);
        let (frame, coverage) = half_plane(n, Vector2::new(32.0, 32.0), &mut rng);
        let mut colours = ColourModel::new(16);
        colours.learn(&frame, &coverage, (0, 0, 63, 63), 2, 1.0);
        let cam = crate::geometry::Intrinsics::new(64, 64, 60.0, 60.0, 31.5, 31.5);
        // 150 lines across the edge, some off the image (no row).
        let found: Vec<Lifted> = (0..150)
            .map(|i| {
                let t = i as f64 * 0.6 - 45.0;
                let pos = Vector2::new(32.0, 32.0) + Vector2::new(-n.y, n.x) * t
                    - n * rng.uniform(-2.0, 2.0);
                let xc = cam.unproject(&pos, 1.0);
                Lifted {
                    point: ContourPoint {
                        pixel: [pos.x.max(0.0) as u32, pos.y.max(0.0) as u32],
                        position: pos,
                        normal: n,
                    },
                    xc,
                    row: contour_row(&cam.motion_predictors(&xc), &n, 0.0),
                }
            })
            .collect();
        let twist = Vector6::new(0.001, -0.002, 0.0, 0.0, 0.0, 0.01);
        let rows = search_lines(&frame, &colours, Vector2::zeros(), &found, &twist, 5.0, 1.0);
        let one: Vec<Observation> = found
            .iter()
            .filter_map(|l| {
                let moved = (l.row.predictors * twist)[0];
                let p = &l.point;
                search_line(
                    &frame,
                    &colours,
                    p.position + p.normal * moved,
                    p.normal,
                    5.0,
                    1.0,
                )
                .map(|d| Observation {
                    displacement: Vector2::new(moved + d, 0.0),
                    ..l.row
                })
            })
            .collect();
        assert!(
            one.len() > 64 && one.len() < found.len(),
            "{} rows",
            one.len()
        );
        assert_eq!(rows, one);
    }
}
