//! The colour model's sectors seen through the line search: each side of
//! an object weighed against its own background.

use super::colour::ColourModel;
use super::line::{search_line, search_line_toward};
use nalgebra::Vector2;

/// An object whose halves swap colours with the background behind
/// them: yellow on the left against orange, orange on the right
/// against yellow (a disc of radius 40 at (64.3, 63.7) in 128x128).
fn swapped_halves(rng: &mut crate::rng::Rng) -> (image::RgbImage, Vec<bool>, Vector2<f64>) {
    let (w, h) = (128u32, 128u32);
    let c = Vector2::new(64.3, 63.7);
    let (yellow, orange) = ([220.0, 200.0, 40.0], [230.0, 120.0, 60.0]);
    let mut frame = image::RgbImage::new(w, h);
    let mut coverage = vec![false; (w * h) as usize];
    for (x, y, px) in frame.enumerate_pixels_mut() {
        let p = Vector2::new(x as f64, y as f64);
        let left = p.x < c.x;
        // The disc's share of the pixel, from 4x4 samples.
        let mut a = 0.0;
        for i in 0..4 {
            for j in 0..4 {
                let q = p + Vector2::new((i as f64 - 1.5) / 4.0, (j as f64 - 1.5) / 4.0);
                a += f64::from(u8::from((q - c).norm() < 40.0)) / 16.0;
            }
        }
        let (fg, bg) = if left {
            (yellow, orange)
        } else {
            (orange, yellow)
        };
        let mut v = [0u8; 3];
        for k in 0..3 {
            v[k] = (a * fg[k] + (1.0 - a) * bg[k] + 2.0 * rng.normal()).clamp(0.0, 255.0) as u8;
        }
        *px = image::Rgb(v);
        coverage[(y * w + x) as usize] = (p - c).norm() < 40.0;
    }
    (frame, coverage, c)
}

#[test]
fn sectors_weigh_each_side_against_its_own_background() {
    let mut rng = crate::rng::Rng::new(12);
    let (frame, coverage, c) = swapped_halves(&mut rng);
    let rect = (0, 0, 127, 127);
    let mut global = ColourModel::new(16);
    global.learn(&frame, &coverage, rect, 2, 1.0);
    let mut sectors = ColourModel::with_sectors(16, 8);
    sectors.learn_around(&frame, &coverage, rect, 2, 1.0, Some(c));
    assert!((0..8).all(|k| sectors.sector_learned(k)));
    // Lines within 40 degrees of the horizontal, left and right, from
    // up to 3 px off the outline: with sectors every one finds it to
    // within its pixel; with one pair of histograms (both colours are
    // object and background alike) none does.
    let (mut found, mut global_found) = (0, 0);
    for i in 0..40 {
        let side = if i % 2 == 0 {
            0.0
        } else {
            std::f64::consts::PI
        };
        let a = side + rng.uniform(-0.7, 0.7);
        let n = Vector2::new(a.cos(), a.sin());
        let off = rng.uniform(-3.0, 3.0);
        let at = c + n * (40.0 - off);
        let d = search_line_toward(&frame, &sectors, n, at, n, 8.0, 1.0)
            .unwrap_or_else(|| panic!("angle {a:.2}: no boundary"));
        assert!(
            (d - off).abs() < 0.5,
            "angle {a:.2}: {d:.3} against {off:.3}"
        );
        found += 1;
        if let Some(d) = search_line(&frame, &global, at, n, 8.0, 1.0)
            && (d - off).abs() < 1.0
        {
            global_found += 1;
        }
    }
    assert_eq!(found, 40);
    assert!(
        global_found <= 4,
        "one pair of histograms found {global_found} of 40"
    );
    // Without sectors, or before a sector learns, a line uses the
    // whole object's histograms.
    assert!(std::ptr::eq(
        global.histograms_toward(Vector2::x()),
        global.global()
    ));
    let fresh = ColourModel::with_sectors(16, 8);
    assert!(std::ptr::eq(
        fresh.histograms_toward(Vector2::x()),
        fresh.global()
    ));
    // Each direction's nearest sector: 8 sectors centred every 45
    // degrees from +x towards +y.
    assert_eq!(sectors.sector_toward(Vector2::new(1.0, 0.3)), Some(0));
    assert_eq!(sectors.sector_toward(Vector2::new(0.1, 1.0)), Some(2));
    assert_eq!(sectors.sector_toward(Vector2::new(-1.0, -0.2)), Some(4));
    assert_eq!(sectors.sector_toward(Vector2::new(1.0, -0.3)), Some(0));
    assert_eq!(global.sector_toward(Vector2::x()), None);
}

#[test]
fn a_sector_with_too_few_pixels_keeps_to_the_whole_objects_histograms() {
    // The object's centre far to the left of the window: every pixel
    // lies towards +x, so the sectors facing away see nothing.
    let mut rng = crate::rng::Rng::new(5);
    let (frame, coverage, _) = swapped_halves(&mut rng);
    let mut m = ColourModel::with_sectors(16, 8);
    m.learn_around(
        &frame,
        &coverage,
        (0, 0, 127, 127),
        2,
        1.0,
        Some(Vector2::new(-1e4, 63.7)),
    );
    assert!(m.is_learned());
    assert!(m.sector_learned(0));
    assert!(!m.sector_learned(4));
    assert!(std::ptr::eq(m.histograms_toward(-Vector2::x()), m.global()));
    // `learn` leaves the sectors alone.
    let mut g = ColourModel::with_sectors(16, 8);
    g.learn(&frame, &coverage, (0, 0, 127, 127), 2, 1.0);
    assert!(g.is_learned() && (0..8).all(|k| !g.sector_learned(k)));
}
