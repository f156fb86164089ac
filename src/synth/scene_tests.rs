//! The scenes of [`SynthScene`]: backgrounds, sizes, the exit slide and
//! occluders, checked against the rasteriser's own coverage.

use super::framing::{apparent_size_px, outside_fraction};
use super::*;
use crate::geometry::Intrinsics;

fn cam() -> Intrinsics {
    Intrinsics::new(320, 240, 300.0, 300.0, 159.5, 119.5)
}

fn config(object: &str, background: Background) -> SynthConfig {
    SynthConfig {
        object: object.into(),
        camera: cam(),
        frames: 40,
        noise: 0.0,
        background,
        ..Default::default()
    }
}

fn scene(cfg: &SynthConfig) -> SynthScene {
    SynthScene::new(cfg.clone(), SynthObject::by_name(&cfg.object).unwrap())
}

/// Colour bins (8 levels a channel) of a linear colour.
fn bin(c: [f32; 3]) -> usize {
    let q = |v: f32| ((v.clamp(0.0, 0.999) * 8.0) as usize).min(7);
    q(c[0]) * 64 + q(c[1]) * 8 + q(c[2])
}

#[test]
fn backgrounds_are_deterministic_by_seed() {
    for kind in [Background::Plain, Background::Shapes, Background::Clutter] {
        let cfg = config("blob", kind);
        assert_eq!(scene(&cfg).background, scene(&cfg).background, "{kind:?}");
        let other = SynthConfig {
            seed: 2,
            ..cfg.clone()
        };
        if kind != Background::Plain {
            assert_ne!(scene(&other).background, scene(&cfg).background, "{kind:?}");
        }
    }
    // And so are the frames rendered over them.
    let cfg = SynthConfig {
        noise: 0.01,
        occluders: 2,
        exit: 0.3,
        ..config("box", Background::Clutter)
    };
    assert_eq!(scene(&cfg).frame(7).image, scene(&cfg).frame(7).image);
}

#[test]
fn clutter_covers_the_whole_frame() {
    // The 16 x 16 blocks show structure: a grey-level spread well above
    // the sensor noise, where the smooth gradient shows none. Only an
    // untextured object's distractors (its own plain colour) may leave a
    // few blocks flat.
    let c = cam();
    let flat_blocks = |img: &[[f32; 3]]| {
        let (w, h) = (c.width as usize, c.height as usize);
        let mut flat = 0;
        for by in 0..h / 16 {
            for bx in 0..w / 16 {
                let l: Vec<f32> = (0..256)
                    .map(|k| {
                        let (x, y) = (bx * 16 + k % 16, by * 16 + k / 16);
                        background::luminance(img[y * w + x])
                    })
                    .collect();
                let m = l.iter().sum::<f32>() / 256.0;
                let sd = (l.iter().map(|v| (v - m).powi(2)).sum::<f32>() / 256.0).sqrt();
                flat += usize::from(sd < 0.015);
            }
        }
        flat as f64 / ((w / 16) * (h / 16)) as f64
    };
    for (object, most) in [("blob", 0.0), ("box", 0.0), ("plain", 0.05)] {
        let f = flat_blocks(&scene(&config(object, Background::Clutter)).background);
        assert!(f <= most, "{object}: {f:.3} of the blocks flat");
    }
    let f = flat_blocks(&scene(&config("blob", Background::Plain)).background);
    assert_eq!(f, 1.0, "the gradient");
}

#[test]
fn the_objects_pixels_are_the_objects_and_its_colours_are_everywhere() {
    for object in ["blob", "box", "plain"] {
        let cfg = config(object, Background::Clutter);
        let cluttered = scene(&cfg);
        let black = SynthScene::with_background(
            cfg.clone(),
            cluttered.object.clone(),
            vec![[0.0; 3]; cluttered.background.len()],
        );
        for i in [0, 13, 39] {
            let (a, b) = (cluttered.frame(i), black.frame(i));
            assert_eq!(a.coverage, b.coverage);
            let mut full = 0;
            for (k, &cov) in a.coverage.iter().enumerate() {
                let (x, y) = (k as u32 % cfg.camera.width, k as u32 / cfg.camera.width);
                if cov == 1.0 {
                    assert_eq!(a.image.get_pixel(x, y), b.image.get_pixel(x, y));
                    full += 1;
                }
            }
            assert!(full > 2000, "{object} frame {i}: {full} object pixels");
        }
        // Colour alone cannot find it: nearly every object pixel's colour
        // is common in the background too (its distractors and shapes).
        let f = black.frame(0);
        let mut bg_bins = vec![0usize; 512];
        for c in &cluttered.background {
            bg_bins[bin(*c)] += 1;
        }
        let shared = |bins: &[usize]| {
            let (mut n, mut common) = (0, 0);
            for (k, p) in f.image.pixels().enumerate() {
                if f.coverage[k] == 1.0 {
                    n += 1;
                    let c = p.0.map(|v| v as f32 / 255.0);
                    common += usize::from(bins[bin(c)] >= 20);
                }
            }
            common as f64 / n as f64
        };
        let s = shared(&bg_bins);
        assert!(
            s > 0.9,
            "{object}: {s:.2} of its pixels' colours in the clutter"
        );
        let mut plain_bins = vec![0usize; 512];
        for c in &scene(&config(object, Background::Plain)).background {
            plain_bins[bin(*c)] += 1;
        }
        let p = shared(&plain_bins);
        assert!(p < 0.5, "{object}: {p:.2} shared even with the gradient");
    }
}

#[test]
fn the_exit_slide_leaves_the_image_by_the_requested_fraction() {
    let c = cam();
    // A canvas three times as wide and high around the image, for the
    // whole silhouette (supersampled coverage, not the solver's count).
    let mut big = c;
    (big.width, big.height) = (3 * c.width, 3 * c.height);
    (big.cx, big.cy) = (c.cx + c.width as f64, c.cy + c.height as f64);
    for (object, fraction) in [("blob", 0.3), ("box", 0.5), ("plain", 0.15)] {
        let cfg = SynthConfig {
            exit: fraction,
            ..config(object, Background::Plain)
        };
        let s = scene(&cfg);
        let outside = |i: usize| {
            let f = s.frame(i);
            let whole = raster::render(
                &s.object,
                &f.pose,
                &big,
                &Light::moving(0.0),
                &vec![[0.0; 3]; (big.width * big.height) as usize],
                3,
            );
            let total: f32 = whole.coverage.iter().sum();
            1.0 - f.coverage.iter().sum::<f32>() as f64 / total as f64
        };
        let peak = (cfg.frames - 1) / 2;
        let at_peak = outside(peak);
        assert!(
            (at_peak - fraction).abs() < 0.02,
            "{object}: {at_peak:.3} outside, asked {fraction}"
        );
        assert!(outside(0) < 1e-6, "{object} starts in view");
        assert!(outside(peak / 2) < at_peak - 0.05, "{object} slides out");
        // The solver's own measure agrees.
        let o = outside_fraction(&s.object.mesh, &s.pose(peak), &c);
        assert!((o - fraction).abs() < 0.01, "{o}");
    }
}

#[test]
fn small_and_large_objects_have_the_requested_size() {
    for object in ["blob", "box", "plain"] {
        for px in [60.0, 200.0] {
            let o = SynthObject::by_name(object).unwrap();
            let cfg = config(object, Background::Clutter).with_object_px(&o, px);
            let s = scene(&cfg);
            let f = s.frame(0);
            // The coverage's bounding box (pixels at least half covered).
            let w = cfg.camera.width as usize;
            let (mut x0, mut x1, mut y0, mut y1) = (usize::MAX, 0, usize::MAX, 0);
            for (k, &cov) in f.coverage.iter().enumerate() {
                if cov >= 0.5 {
                    let (x, y) = (k % w, k / w);
                    (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
                }
            }
            let size = ((x1 - x0 + 1).max(y1 - y0 + 1)) as f64;
            assert!(
                (size - px).abs() < 0.1 * px,
                "{object}: {size} px across, asked {px}"
            );
            assert!((apparent_size_px(&o.mesh, &f.pose, &cfg.camera) - px).abs() < 0.1 * px);
        }
    }
}

#[test]
fn translations_scale_with_the_distance() {
    // The same motion in the image at twice the distance: twice the
    // translation, the same rotation.
    for i in [10, 25] {
        let a = trajectory_pose(Trajectory::Fig10, 0.55, i, 40);
        let b = trajectory_pose(Trajectory::Fig10, 1.1, i, 40);
        assert!((b.translation - 2.0 * a.translation).norm() < 1e-12);
        assert!(a.rotation_error_deg(&b) < 1e-9);
    }
}

#[test]
fn occluders_hide_part_of_the_object_in_front_of_it() {
    let cfg = SynthConfig {
        occluders: 3,
        ..config("blob", Background::Shapes)
    };
    let with = scene(&cfg);
    let without = scene(&SynthConfig {
        occluders: 0,
        ..cfg.clone()
    });
    let mut hidden = 0.0f32;
    let mut total = 0.0f32;
    for i in (0..cfg.frames).step_by(4) {
        let (a, b) = (with.frame(i), without.frame(i));
        assert_eq!(a.pose, b.pose);
        // Never more object than without them; hidden pixels lose depth.
        for k in 0..a.coverage.len() {
            assert!(a.coverage[k] <= b.coverage[k] + 1e-6);
            if a.depth[k].is_finite() {
                assert_eq!(a.depth[k], b.depth[k]);
            }
        }
        hidden += b.coverage.iter().sum::<f32>() - a.coverage.iter().sum::<f32>();
        total += b.coverage.iter().sum::<f32>();
    }
    let share = hidden / total;
    assert!(
        (0.02..0.6).contains(&share),
        "occluders hide {share:.3} of the object"
    );
}
