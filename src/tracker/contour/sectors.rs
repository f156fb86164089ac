//! The sectors of directions around the object's projected centre, each
//! with its own colour histograms.

use nalgebra::Vector2;

/// A sector learns from a frame only where each side of it holds at least
/// this many pixels (weights: a pixel counts towards its two nearest
/// sectors); until then its lines use the whole object's histograms.
pub const SECTOR_LEAST_PX: f32 = 200.0;

/// The direction of `d` as a fraction of a full turn, in [0, 1), from +x
/// towards +y (clockwise on the screen, whose y points down), to within
/// 6e-4 turns (0.22 degrees: a polynomial approximation of the
/// arctangent; the sectors' weights need no more, and it is several times
/// cheaper than `atan2` over a window's pixels). 0 for a zero vector and
/// for one with a component not finite (no histogram learns a NaN weight).
pub fn turn_of(d: Vector2<f64>) -> f64 {
    let (ax, ay) = (d.x.abs(), d.y.abs());
    if (ax == 0.0 && ay == 0.0) || !(ax.is_finite() && ay.is_finite()) {
        return 0.0;
    }
    // atan(t) / (2 pi) for t in [0, 1] (|error| < 6e-4 turns).
    let t = ax.min(ay) / ax.max(ay);
    let mut a = t * (0.25 * std::f64::consts::PI + 0.273 * (1.0 - t)) / std::f64::consts::TAU;
    if ay > ax {
        a = 0.25 - a;
    }
    if d.x < 0.0 {
        a = 0.5 - a;
    }
    if d.y < 0.0 {
        a = 1.0 - a;
    }
    if a >= 1.0 { 0.0 } else { a }
}

/// [`turn_of`]`((x0 + i - cx, dy))` into `out[i]`, bit for bit (the same
/// operations in the same order), for a row of pixels at once, with
/// selects instead of branches (the baseline x86-64 build keeps the
/// divisions scalar; a build for wider vectors may vectorise them).
/// `x0 + i` must fit an `i32`.
pub(super) fn turns_of_row(x0: i32, cx: f64, dy: f64, out: &mut [f64]) {
    let ay = dy.abs();
    let (quarter, turn) = (0.25 * std::f64::consts::PI, std::f64::consts::TAU);
    for (i, o) in out.iter_mut().enumerate() {
        let dx = (x0 + i as i32) as f64 - cx;
        let ax = dx.abs();
        // min and max: equal to f64's where neither is NaN (the result is
        // then 0 below).
        let (lo, hi) = if ax < ay { (ax, ay) } else { (ay, ax) };
        let t = lo / hi;
        let a = t * (quarter + 0.273 * (1.0 - t)) / turn;
        let a = if ay > ax { 0.25 - a } else { a };
        let a = if dx < 0.0 { 0.5 - a } else { a };
        let a = if dy < 0.0 { 1.0 - a } else { a };
        // Zero and non-finite vectors: hi is 0, infinite or NaN.
        let valid = hi > 0.0 && hi < f64::INFINITY;
        *o = if valid && a < 1.0 { a } else { 0.0 };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turn_of_is_the_direction_within_its_bound() {
        for (d, want) in [
            ((1.0, 0.0), 0.0),
            ((0.0, 1.0), 0.25),
            ((-1.0, 0.0), 0.5),
            ((0.0, -1.0), 0.75),
            ((1.0, 1.0), 0.125),
            ((-2.0, -2.0), 0.625),
            ((0.0, 0.0), 0.0),
            ((f64::NAN, 1.0), 0.0),
            ((f64::INFINITY, f64::NEG_INFINITY), 0.0),
        ] {
            assert!(
                (turn_of(Vector2::new(d.0, d.1)) - want).abs() < 1e-12,
                "{d:?}"
            );
        }
        let mut rng = crate::rng::Rng::new(3);
        let mut worst = 0.0f64;
        for _ in 0..100_000 {
            let d = Vector2::new(rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0));
            let t = turn_of(d);
            assert!((0.0..1.0).contains(&t), "{d:?}: {t}");
            let exact = (d.y.atan2(d.x) / std::f64::consts::TAU).rem_euclid(1.0);
            // The distance on the circle of turns.
            let e = (t - exact).abs();
            worst = worst.max(e.min(1.0 - e));
        }
        assert!(worst < 7e-4, "worst {worst} turns");
    }

    #[test]
    fn turns_of_a_row_are_turn_of_bit_for_bit() {
        let mut rng = crate::rng::Rng::new(22);
        let mut out = vec![0.0; 64];
        let rows = [0.0, -0.0, 3.0, -7.5, 1e-300, f64::NAN, f64::INFINITY];
        let randoms: Vec<f64> = (0..200).map(|_| rng.uniform(-300.0, 300.0)).collect();
        for (i, dy) in rows.into_iter().chain(randoms).enumerate() {
            let x0 = rng.below(400) as i32 - 200;
            let cx = match i % 4 {
                0 => rng.uniform(-300.0, 300.0),
                1 => (x0 + 10) as f64,
                2 => f64::NAN,
                _ => x0 as f64 + 0.5,
            };
            turns_of_row(x0, cx, dy, &mut out);
            for (k, t) in out.iter().enumerate() {
                let want = turn_of(Vector2::new((x0 + k as i32) as f64 - cx, dy));
                assert_eq!(
                    t.to_bits(),
                    want.to_bits(),
                    "x0 {x0}, cx {cx}, dy {dy}, k {k}"
                );
            }
        }
    }
}
