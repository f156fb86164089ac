//! NCC on GPU-resident images: `NccMatcher::match_resident`,
//! its mutual check and its sub-pixel refinement on the GPU, against the
//! host path it replaces (`match_features` on the same rows as host images,
//! then `refine_match` on the host, the CPU reference) on random images,
//! with invalid pixels and pinholes, and bands of rows; a known sub-pixel
//! shift; bad input.

use splattrack::features::patterns::{self, Warp};
use splattrack::features::{
    Corner, GpuGrey, GreyImage, NccConfig, NccMatcher, Refinement, ResidentImage, refine_match,
};
use splattrack::gpu::PassChain;
use splattrack::rng::Rng;

mod features_common;
use features_common::{ctx, random_points};

/// `img` with every row outside `rows` invalid (NaN): what matching on
/// those rows only sees, as a host image of the whole size.
fn band(img: &GreyImage, rows: std::ops::Range<usize>) -> GreyImage {
    let mut out = img.clone();
    for (y, row) in out.data.chunks_mut(img.width).enumerate() {
        if !rows.contains(&y) {
            row.fill(f32::NAN);
        }
    }
    out
}

/// The host path (the CPU reference of the refinement): matches on the
/// bands as host images, B's point refined by `refine_match`; (a, b,
/// score, refined point).
#[allow(clippy::type_complexity)]
fn host(
    m: &mut NccMatcher,
    (a, ra, pa): (&GreyImage, std::ops::Range<usize>, &[Corner]),
    (b, rb, pb): (&GreyImage, std::ops::Range<usize>, &[Corner]),
    refine: Option<Refinement>,
) -> Vec<(usize, usize, f32, Option<[f64; 2]>)> {
    let (ba, bb) = (band(a, ra), band(b, rb));
    m.match_features(&ba, pa, &bb, pb)
        .unwrap()
        .into_iter()
        .map(|x| {
            let (ca, cb) = (pa[x.a], pb[x.b]);
            let at = match refine {
                None => Some([cb.x as f64, cb.y as f64]),
                Some(r) => refine_match(
                    &ba,
                    [ca.x, ca.y],
                    &bb,
                    [cb.x, cb.y],
                    r.patch,
                    r.max_shift as i32,
                    r.min_score,
                )
                .map(|(p, _)| [p[0] as f64, p[1] as f64]),
            };
            (x.a, x.b, x.score, at)
        })
        .collect()
}

fn upload(img: &GreyImage) -> GpuGrey {
    let mut g = GpuGrey::new();
    g.upload(ctx(), img);
    g
}

#[test]
fn resident_matches_and_refinements_equal_the_host_path() {
    let mut rng = Rng::new(13);
    let a = patterns::smooth_noise(96, 80, 2.0, 31);
    let warp = Warp {
        shift: [1.3, -0.6],
        angle: 0.02,
        centre: [48.0, 40.0],
        gain: 0.9,
        bias: 0.05,
    };
    let mut b = warp.image(&a);
    // The pair without invalid pixels, for the widest windows (which the
    // holes below would void).
    let clean = (a.clone(), b.clone(), upload(&a), upload(&b));
    // Invalid pixels: a hole region in A, scattered pinholes in B.
    let mut a = a;
    for y in 30..40 {
        for x in 10..22 {
            a.data[y * 96 + x] = f32::NAN;
        }
    }
    // (Off the bands' first and last rows, where a pinhole of the whole
    // image is an invalid border pixel of the band.)
    for _ in 0..60 {
        let (x, y) = (rng.below(96) as usize, 22 + rng.below(36) as usize);
        b.data[y * 96 + x] = f32::NAN;
    }
    let holed = (upload(&a), upload(&b));
    let refine = Refinement {
        patch: 11,
        max_shift: 2,
        min_score: 0.5,
    };
    let cases = [
        (0..80, 0..80, None, NccConfig::default(), false),
        (0..80, 0..80, Some(refine), NccConfig::default(), false),
        (
            12..70,
            20..75,
            Some(refine),
            NccConfig::default()
                .with_search_radius(Some(6.0))
                .with_min_score(0.5),
            false,
        ),
        (
            5..60,
            5..60,
            Some(Refinement {
                patch: 7,
                max_shift: 3,
                min_score: 0.0,
            }),
            NccConfig::default().with_patch(7).with_min_score(-1.0),
            false,
        ),
        // More integer shifts than the workgroup's grid holds: each
        // thread samples its shifts' windows (mutual_refine).
        (
            0..80,
            0..80,
            Some(Refinement {
                patch: 9,
                max_shift: 5,
                min_score: 0.3,
            }),
            NccConfig::default(),
            false,
        ),
        // A window wider than the workgroup's memory holds:
        // mutual_refine_wide (on the pair without holes, which would void
        // most windows this wide).
        (
            0..80,
            0..80,
            Some(Refinement {
                patch: 23,
                max_shift: 2,
                min_score: 0.3,
            }),
            NccConfig::default(),
            true,
        ),
    ];
    let (mut total, mut refined) = (0, 0);
    for (ci, (ra, rb, r, cfg, whole)) in cases.into_iter().enumerate() {
        let (a, b, (ga, gb)) = if whole {
            (&clean.0, &clean.1, (&clean.2, &clean.3))
        } else {
            (&a, &b, (&holed.0, &holed.1))
        };
        let pa = random_points(&mut rng, 70, 96, 80);
        // B's features: A's moved by the warp plus noise, and strays.
        let mut pb: Vec<Corner> = pa
            .iter()
            .map(|c| Corner {
                x: c.x + 1.3 + rng.uniform(-0.4, 0.4) as f32,
                y: c.y - 0.6 + rng.uniform(-0.4, 0.4) as f32,
                score: 1.0,
            })
            .collect();
        pb.extend(random_points(&mut rng, 30, 96, 80));
        let mut m = NccMatcher::new(ctx(), cfg).unwrap();
        let want = host(&mut m, (a, ra.clone(), &pa), (b, rb.clone(), &pb), r);
        let refined_before = refined;
        // Both kernels: the refinement from workgroup memory (tiled, the
        // GPUs' default) and sampling the images (the CPU adapters').
        for tiled in [true, false] {
            m.set_options(splattrack::features::NccOptions {
                tiled: Some(tiled),
                ..m.options()
            });
            let got = m
                .match_resident(
                    ga.image().unwrap(),
                    ra.clone(),
                    &pa,
                    gb.image().unwrap(),
                    rb.clone(),
                    &pb,
                    [0, 0],
                    r,
                )
                .unwrap();
            assert_eq!(got.len(), want.len(), "case {ci}: match counts");
            for (g, w) in got.iter().zip(&want) {
                assert_eq!((g.a, g.b), (w.0, w.1), "case {ci}, tiled {tiled}");
                // The same scores as match_features (the same kernels).
                assert!((g.score - w.2).abs() <= 1e-6, "case {ci}: {g:?} {w:?}");
                // Refined points within 1e-3 px (f32 sums of up to 529 terms;
                // the GPU may fuse multiply-adds), failures the same.
                match (g.at, w.3) {
                    (Some(p), Some(q)) => {
                        let d = (p[0] - q[0]).abs().max((p[1] - q[1]).abs());
                        assert!(d <= 1e-3, "case {ci}, tiled {tiled}: {p:?} vs {q:?}");
                        refined += 1;
                    }
                    (None, None) => {}
                    other => panic!("case {ci}, tiled {tiled}: refinement {other:?}"),
                }
            }
        }
        // Every refining case refines some (each path of the kernels).
        assert!(
            r.is_none() || refined - refined_before >= 10,
            "case {ci}: {} refined",
            refined - refined_before
        );
        total += want.len();
    }
    assert!(
        total > 60 && refined > 20,
        "{total} matches, {refined} refined"
    );
}

#[test]
fn the_gpu_refinement_recovers_a_known_subpixel_shift() {
    let f = patterns::waves(3);
    let (w, h) = (72usize, 64usize);
    let a = GreyImage::from_fn(w, h, |x, y| f(x as f32, y as f32));
    let (sx, sy) = (0.37f32, -0.22f32);
    let b = GreyImage::from_fn(w, h, |x, y| f(x as f32 - sx, y as f32 - sy));
    let pa: Vec<Corner> = [(20.0, 20.0), (32.3, 40.7), (50.0, 25.5), (40.0, 30.0)]
        .iter()
        .map(|&(x, y)| Corner { x, y, score: 1.0 })
        .collect();
    // B's detected points half a pixel off the truth.
    let pb: Vec<Corner> = pa
        .iter()
        .map(|c| Corner {
            x: c.x + sx + 0.5,
            y: c.y + sy - 0.4,
            score: 1.0,
        })
        .collect();
    let mut m = NccMatcher::new(ctx(), NccConfig::default().with_min_score(0.5)).unwrap();
    let (ga, gb) = (upload(&a), upload(&b));
    let got = m
        .match_resident(
            ga.image().unwrap(),
            0..h,
            &pa,
            gb.image().unwrap(),
            8..h,
            &pb,
            [0, 0],
            Some(Refinement {
                patch: 11,
                max_shift: 3,
                min_score: 0.5,
            }),
        )
        .unwrap();
    assert_eq!(got.len(), 4, "{got:?}");
    for g in &got {
        assert_eq!(g.a, g.b);
        let p = g.at.expect("refined");
        let c = pa[g.a];
        let err = ((p[0] - (c.x + sx) as f64).powi(2) + (p[1] - (c.y + sy) as f64).powi(2)).sqrt();
        // Parabola fits to sampled scores: within 0.08 px (the host's
        // refine_match gives the same points, see the test above).
        assert!(err < 0.08, "feature {}: error {err} px", g.a);
    }
}

#[test]
fn bad_rows_and_refinements_are_errors() {
    let img = patterns::smooth_noise(16, 12, 2.0, 1);
    let g = upload(&img);
    let c = [Corner {
        x: 8.0,
        y: 6.0,
        score: 1.0,
    }];
    let mut m = NccMatcher::new(ctx(), NccConfig::default()).unwrap();
    let im = g.image().unwrap();
    assert!(
        m.match_resident(im, 0..13, &c, im, 0..12, &c, [0, 0], None)
            .is_err()
    );
    let big = ResidentImage { height: 100, ..im };
    assert!(
        m.match_resident(big, 0..12, &c, im, 0..12, &c, [0, 0], None)
            .is_err()
    );
    let r = Refinement {
        patch: 65,
        max_shift: 2,
        min_score: 0.5,
    };
    assert!(
        m.match_resident(im, 0..12, &c, im, 0..12, &c, [0, 0], Some(r))
            .is_err()
    );
    assert!(
        m.match_resident(im, 3..3, &c, im, 0..12, &c, [0, 0], None)
            .unwrap()
            .is_empty()
    );
    assert!(GpuGrey::new().image().is_none());
}

#[test]
fn a_frame_taken_in_on_the_gpu_is_the_hosts_packed_grey_bit_for_bit() {
    // `FrameIntake` uploads a frame's RGB bytes and converts and packs
    // them on the GPU: the same bytes as `GpuGrey::upload` of the host's
    // grey (`GreyImage::from_rgb8`), for sizes whose byte count is not a
    // multiple of 4, after a larger frame in the same image, and into two
    // images in turn (as the tracker alternates them).
    use splattrack::features::FrameIntake;
    let c = ctx();
    let mut rng = Rng::new(17);
    let mut intake = FrameIntake::new(c).unwrap();
    let mut images = [GpuGrey::new(), GpuGrey::new()];
    let mut host = GpuGrey::new();
    for (k, (w, h)) in [(64, 48), (1, 1), (7, 5), (33, 17), (640, 480), (3, 2)]
        .into_iter()
        .enumerate()
    {
        let frame = image::RgbImage::from_fn(w, h, |_, _| {
            image::Rgb([0; 3].map(|_: u8| rng.uniform(0.0, 256.0) as u8))
        });
        let slot = &mut images[k % 2];
        intake.upload(&frame, slot).unwrap();
        host.upload(c, &GreyImage::from_rgb8(&frame));
        let (a, b) = (slot.image().unwrap(), host.image().unwrap());
        assert_eq!((a.width, a.height), (w as usize, h as usize));
        let n = 2 * (w * h) as usize;
        let got: Vec<u32> = c.read_buffer(a.pixels, n).unwrap();
        let want: Vec<u32> = c.read_buffer(b.pixels, n).unwrap();
        if let Some(i) = (0..n).find(|&i| got[i] != want[i]) {
            panic!(
                "{w}x{h}: pixel {} differs: {:#x} against {:#x}",
                i / 2,
                got[i],
                want[i]
            );
        }
    }
    // An empty frame leaves no image.
    intake
        .upload(&image::RgbImage::new(0, 0), &mut images[0])
        .unwrap();
    assert!(images[0].image().is_none());
}

#[test]
fn harris_on_a_window_packed_on_the_gpu_finds_the_host_crops_corners() {
    // `FrameIntake::pack_window` packs a window of the resident frame
    // into Harris's input with a rectangle allowed: the window's pixels
    // unchanged outside the rectangle, one more flag inside, and Harris
    // on it (`detect_packed`) finds exactly the corners of `detect` on the
    // host's crop with that rectangle as its mask.
    use splattrack::features::{FrameIntake, Harris, HarrisConfig};
    let c = ctx();
    let mut rng = Rng::new(23);
    let mut intake = FrameIntake::new(c).unwrap();
    let mut frame_img = GpuGrey::new();
    let mut harris = Harris::new(c, HarrisConfig::default()).unwrap();
    let mut found = 0;
    for k in 0..6 {
        let (w, h) = (160 + 16 * k, 120);
        let grey = patterns::smooth_noise(w as usize, h as usize, 1.5, 40 + k as u64);
        let frame = image::RgbImage::from_fn(w, h, |x, y| {
            let v = grey.get(x as usize, y as usize).clamp(0.0, 1.0);
            let b = (v * 255.0) as u8;
            image::Rgb([b, b.wrapping_add(rng.uniform(0.0, 9.0) as u8), b / 2])
        });
        intake.upload(&frame, &mut frame_img).unwrap();
        let host_grey = GreyImage::from_rgb8(&frame);
        let (ww, wh) = (
            rng.uniform(40.0, w as f64 - 20.0) as u32,
            rng.uniform(30.0, h as f64 - 20.0) as u32,
        );
        let (x0, y0) = (
            rng.uniform(0.0, (w - ww) as f64) as u32,
            rng.uniform(0.0, (h - wh) as f64) as u32,
        );
        let allowed = [3 + k, 2, ww - 4, wh - 1 - k];
        let target = harris.input_target(ww as usize, wh as usize).unwrap();
        intake
            .pack_window(
                frame_img.image().unwrap(),
                [x0, y0, ww, wh],
                allowed,
                &target,
            )
            .unwrap();
        // The bytes: the frame's outside the rectangle, one flag more inside.
        let n = (ww * wh) as usize;
        let packed: Vec<u32> = c.read_buffer(&target, 2 * n).unwrap();
        let whole: Vec<u32> = c
            .read_buffer(frame_img.image().unwrap().pixels, 2 * (w * h) as usize)
            .unwrap();
        let mut extra = None;
        for y in 0..wh {
            for x in 0..ww {
                let i = (y * ww + x) as usize;
                let j = ((y0 + y) * w + x0 + x) as usize;
                assert_eq!(packed[2 * i], whole[2 * j], "value at ({x}, {y})");
                let inside =
                    x >= allowed[0] && x <= allowed[2] && y >= allowed[1] && y <= allowed[3];
                if inside {
                    let e = packed[2 * i + 1] ^ whole[2 * j + 1];
                    assert!(
                        e != 0 && *extra.get_or_insert(e) == e,
                        "flags at ({x}, {y})"
                    );
                } else {
                    assert_eq!(packed[2 * i + 1], whole[2 * j + 1], "flags at ({x}, {y})");
                }
            }
        }
        // The corners.
        let got = harris.detect_packed(ww as usize, wh as usize).unwrap();
        let crop = GreyImage::from_fn(ww as usize, wh as usize, |x, y| {
            host_grey.get(x0 as usize + x, y0 as usize + y)
        });
        let mask: Vec<bool> = (0..n)
            .map(|i| {
                let (x, y) = ((i % ww as usize) as u32, (i / ww as usize) as u32);
                x >= allowed[0] && x <= allowed[2] && y >= allowed[1] && y <= allowed[3]
            })
            .collect();
        let want = harris.detect(&crop, Some(&mask)).unwrap();
        assert_eq!(got, want, "window {k}");
        found += got.len();
    }
    assert!(found > 50, "{found} corners");
    // A window beyond the frame, or a buffer too small, is refused.
    let small = harris.input_target(8, 8).unwrap();
    let img = frame_img.image().unwrap();
    let (w, h) = (img.width as u32, img.height as u32);
    assert!(
        intake
            .pack_window(img, [w - 10, 0, 20, 10], [0, 0, 1, 1], &small)
            .is_err()
    );
    let big = c.buffer("small", 64, splattrack::gpu::STORAGE_OUT);
    assert!(
        intake
            .pack_window(img, [0, 0, w, h], [0, 0, 1, 1], &big)
            .is_err()
    );
}

#[test]
fn a_window_of_the_resident_frame_is_the_host_crop_bit_for_bit() {
    // `FrameIntake::window_values`: the grey levels of a window of the
    // frame, NaN beyond it, as the pose check reads them, bit for bit the
    // host's crop of `GreyImage::from_rgb8` (inside, across the right and
    // bottom edges, and wholly outside).
    use splattrack::features::FrameIntake;
    let c = ctx();
    let mut rng = Rng::new(29);
    let mut intake = FrameIntake::new(c).unwrap();
    let mut img = GpuGrey::new();
    let (w, h) = (97u32, 61u32);
    let frame = image::RgbImage::from_fn(w, h, |_, _| {
        image::Rgb([0; 3].map(|_: u8| rng.uniform(0.0, 256.0) as u8))
    });
    let grey = GreyImage::from_rgb8(&frame);
    intake.upload(&frame, &mut img).unwrap();
    let out = c.buffer("values", 4 * 64 * 64, splattrack::gpu::STORAGE_OUT);
    for at in [
        [0, 0, 97, 61],
        [10, 7, 40, 30],
        [80, 50, 30, 20],
        [96, 60, 1, 1],
        [100, 70, 5, 4],
    ] {
        let done = intake.window_values(img.image().unwrap(), at, &out);
        if at[2] * at[3] > 64 * 64 {
            assert!(done.is_err(), "a window larger than its buffer");
            continue;
        }
        done.unwrap();
        let n = (at[2] * at[3]) as usize;
        let got: Vec<u32> = c.read_buffer(&out, n).unwrap();
        for (i, g) in got.iter().enumerate() {
            let (x, y) = (at[0] + i as u32 % at[2], at[1] + i as u32 / at[2]);
            let want = if x < w && y < h {
                grey.get(x as usize, y as usize)
            } else {
                f32::NAN
            };
            assert_eq!(*g, want.to_bits(), "window {at:?}, pixel ({x}, {y})");
        }
    }
}

#[test]
fn corners_exported_on_the_gpu_match_as_the_hosts_corners_in_one_wait() {
    // The chained KF step: Harris on a resolved view leaves its
    // corners on the GPU (`detect_resolved_resident_later`), exports them
    // as NCC's A side and a gather's points (`export_corners`), and one
    // readback brings the corners and the matches. Against the detection
    // read back first and its corners matched from the host
    // (`match_resident`), on the same bands: the same corners, the same
    // matches and refined points bit for bit, the points the corners
    // (far away past them), and one wait instead of two.
    // Where the corners are not final on the GPU (the host selects: a
    // select limit of 0) or more come back than the readback's first
    // rows hold (a first detection), `exported` says so, and the export
    // wrote no corner. A context of its own, so that other tests'
    // readbacks are not counted.
    use splattrack::features::{ExportPlace, Harris, HarrisConfig};
    use splattrack::gpu::{STORAGE_OUT, own_test_context};
    let c = own_test_context();
    let mut rng = Rng::new(61);
    // The view: a window of 120x96 at (37, 22) of a 200x160 frame, empty
    // (NaN) in a corner, the frame the view moved by a warp, in noise.
    let (w, h, o) = (120usize, 96usize, [37usize, 22usize]);
    let mut view = patterns::smooth_noise(w, h, 1.6, 7);
    for y in 0..30 {
        for x in 0..(30 - y) {
            view.data[y * w + x] = f32::NAN;
        }
    }
    let warp = Warp {
        shift: [0.8, -1.1],
        angle: 0.015,
        centre: [60.0, 48.0],
        gain: 0.95,
        bias: 0.02,
    };
    let moved = warp.image(&view);
    let noise = patterns::smooth_noise(200, 160, 2.0, 8);
    let frame = GreyImage::from_fn(200, 160, |x, y| {
        let (vx, vy) = (x as i64 - o[0] as i64, y as i64 - o[1] as i64);
        if (0..w as i64).contains(&vx) && (0..h as i64).contains(&vy) {
            let v = moved.get(vx as usize, vy as usize);
            if v.is_finite() { v } else { noise.get(x, y) }
        } else {
            noise.get(x, y)
        }
    });
    let mut g = GpuGrey::new();
    g.upload(&c, &frame);
    let rgb: Vec<f32> = view.data.iter().flat_map(|&v| [v, v, v]).collect();
    let cfg = NccConfig::default()
        .with_search_radius(Some(6.0))
        .with_min_score(0.6);
    let refine = Some(Refinement {
        patch: 9,
        max_shift: 2,
        min_score: 0.5,
    });
    let origin = [o[0] as f32, o[1] as f32];
    // Bands as the tracker cuts them: A's rows from 5 on, B's from 20.
    let (a_rows, b_rows) = (5..h, 20..150);
    let (mut reference, mut chained) = (
        Harris::new(&c, HarrisConfig::default()).unwrap(),
        Harris::new(&c, HarrisConfig::default()).unwrap(),
    );
    let (mut m_ref, mut m) = (
        NccMatcher::new(&c, cfg.clone()).unwrap(),
        NccMatcher::new(&c, cfg).unwrap(),
    );
    let mut matched = 0;
    for (round, limit) in [(0, None), (1, None), (2, Some(0)), (3, None)] {
        let at = format!("round {round}");
        for harris in [&mut reference, &mut chained] {
            harris.set_options(splattrack::features::HarrisGpuOptions {
                select_limit: Some(limit.unwrap_or(splattrack::features::SELECT_MAX as usize)),
                ..harris.options()
            });
            let target = harris.colour_target(w, h).unwrap();
            c.queue.write_buffer(&target, 0, bytemuck::cast_slice(&rgb));
        }
        // The reference: corners read back, matched from the host.
        let want_corners = reference.detect_resolved_resident(w, h).unwrap();
        let a_own = want_corners.clone();
        // B: the corners moved by the warp (roughly), and strays.
        let mut b: Vec<Corner> = want_corners
            .iter()
            .map(|k| Corner {
                x: k.x + origin[0] + 0.8 + rng.uniform(-0.3, 0.3) as f32,
                y: k.y + origin[1] - 1.1 + rng.uniform(-0.3, 0.3) as f32,
                score: 1.0,
            })
            .filter(|k| b_rows.contains(&(k.y as usize)))
            .collect();
        b.extend(
            random_points(&mut rng, 40, 200, 160)
                .into_iter()
                .filter(|k| b_rows.contains(&(k.y as usize))),
        );
        let view_img = ResidentImage {
            pixels: &reference.resident_view(w, h).unwrap().pixels.clone(),
            width: w,
            height: h,
        };
        let b_img = g.image().unwrap();
        let shift = [-(o[0] as i32), -(o[1] as i32)];
        let want = m_ref
            .match_resident(
                view_img,
                a_rows.clone(),
                &a_own,
                b_img,
                b_rows.clone(),
                &b,
                shift,
                refine,
            )
            .unwrap();
        // Chained.
        let before = c.stats().readbacks;
        let pending = chained.detect_resolved_resident_later(w, h).unwrap();
        let slots = pending.slots();
        let rows = pending.rows();
        let points = c.buffer("points", (slots * 8) as u64, STORAGE_OUT);
        let view_pixels = chained.resident_view(w, h).unwrap().pixels.clone();
        let band_y0 = a_rows.start as f32;
        let pm = {
            let ch = &mut chained;
            let mut export = |passes: &mut PassChain, pos: &wgpu::Buffer| {
                ch.export_corners(
                    passes,
                    &pending,
                    ExportPlace::band(band_y0),
                    pos,
                    Some(&points),
                )
            };
            m.match_resident_exported(
                ResidentImage {
                    pixels: &view_pixels,
                    width: w,
                    height: h,
                },
                a_rows.clone(),
                slots,
                &mut export,
                g.image().unwrap(),
                b_rows.clone(),
                &b,
                shift,
                refine,
                rows,
            )
            .unwrap()
        };
        let detected = chained.finish_later(pending).unwrap();
        let waits = c.stats().readbacks - before;
        assert_eq!(detected.corners, want_corners, "{at}: corners");
        let n = want_corners.len();
        let pts: Vec<[f32; 2]> = c.read_buffer(&points, slots).unwrap();
        let expect_exported = round != 0 && limit.is_none();
        assert_eq!(
            detected.exported, expect_exported,
            "{at}: {n} corners, {rows} rows"
        );
        if !detected.exported {
            // Nothing usable was exported where the host finished.
            if limit.is_some() {
                assert!(pts.iter().all(|p| *p == [-1.0e9, -1.0e9]), "{at}");
            }
            continue;
        }
        assert_eq!(waits, 1, "{at}: waits");
        for (i, p) in pts.iter().enumerate() {
            let want_p = a_own.get(i).map_or([-1.0e9, -1.0e9], |k| [k.x, k.y]);
            assert_eq!(*p, want_p, "{at}: point {i}");
        }
        let got = m.finish_exported(pm, n).unwrap();
        assert_eq!(got, want, "{at}: matches");
        matched += got.len();
    }
    assert!(matched > 40, "{matched} matches");
    // A first detection of a view reads back 64 corners with its counters.
    let mut cold = Harris::new(&c, HarrisConfig::default()).unwrap();
    let target = cold.colour_target(w, h).unwrap();
    c.queue.write_buffer(&target, 0, bytemuck::cast_slice(&rgb));
    let pending = cold.detect_resolved_resident_later(w, h).unwrap();
    assert_eq!(pending.rows(), 64);
    // Bad calls are refused: an empty view, host mode, a small buffer.
    let d = cold.finish_later(pending).unwrap();
    assert!(d.corners.len() > 64 && !d.exported);
    assert!(cold.detect_resolved_resident_later(0, h).is_err());
    let pending = cold.detect_resolved_resident_later(w, h).unwrap();
    let small = c.buffer("small", 8, STORAGE_OUT);
    let mut enc = c.device.create_command_encoder(&Default::default());
    assert!(
        cold.export_corners(
            &mut PassChain::new(&c, &mut enc),
            &pending,
            ExportPlace::default(),
            &small,
            Some(&small)
        )
        .is_err()
    );
    cold.finish_later(pending).unwrap();
    cold.set_options(splattrack::features::HarrisGpuOptions {
        host: true,
        ..cold.options()
    });
    assert!(cold.detect_resolved_resident_later(w, h).is_err());
}

#[test]
fn frame_corners_exported_as_b_match_as_the_hosts_with_the_gate_in_one_wait() {
    // The chained IT step: Harris on a packed window of the
    // resident frame leaves its corners on the GPU (`detect_packed_later`)
    // and exports them as NCC's B side (`export_corners` with an origin, a
    // clip rectangle and a first slot), A's features (the previous
    // frame's, from the host) are gated by a gather's samples at them
    // (those empty left out), and one readback brings the corners and the
    // matches. Against the detection read back first, B cut to the crop
    // on the host and A to its features with a valid sample
    // (`match_resident`): the same corners, the same matches and points
    // bit for bit, one wait instead of two. A context of its own, so that
    // other tests' readbacks are not counted.
    use splattrack::features::{ExportPlace, FrameIntake, Harris, HarrisConfig};
    use splattrack::gpu::{STORAGE_IN, own_test_context};
    use splattrack::splat::GATHER_STRIDE;
    let c = own_test_context();
    let mut rng = Rng::new(71);
    let (w, h) = (220u32, 170u32);
    let mut intake = FrameIntake::new(&c).unwrap();
    let (mut before, mut now) = (GpuGrey::new(), GpuGrey::new());
    let cfg = NccConfig::default()
        .with_search_radius(Some(7.0))
        .with_min_score(0.6);
    let (mut reference, mut chained) = (
        Harris::new(&c, HarrisConfig::default()).unwrap(),
        Harris::new(&c, HarrisConfig::default()).unwrap(),
    );
    let (mut m_ref, mut m) = (
        NccMatcher::new(&c, cfg.clone()).unwrap(),
        NccMatcher::new(&c, cfg).unwrap(),
    );
    let (mut matched, mut gated_out, mut clipped) = (0, 0, 0);
    for round in 0..4u64 {
        let at = format!("round {round}");
        let grey = patterns::smooth_noise(w as usize, h as usize, 1.5, 90 + round);
        let warp = Warp {
            shift: [1.3, -0.7],
            angle: 0.01,
            centre: [110.0, 85.0],
            gain: 1.02,
            bias: -0.01,
        };
        let moved = warp.image(&grey);
        let rgb = |g: &GreyImage| {
            image::RgbImage::from_fn(w, h, |x, y| {
                let v = g.get(x as usize, y as usize);
                let b = (if v.is_finite() { v } else { 0.5 }.clamp(0.0, 1.0) * 255.0) as u8;
                image::Rgb([b, b, b])
            })
        };
        intake.upload(&rgb(&grey), &mut before).unwrap();
        intake.upload(&rgb(&moved), &mut now).unwrap();
        // The frame's window for Harris, its region of interest, and the
        // matching's crop (rows, and x for B) within the frame.
        let (ww, wh) = (150 + 5 * round as u32, 110u32);
        let (x0, y0) = (20 + 7 * round as u32, 30 - 5 * round as u32);
        let allowed = [4, 4, ww - 5, wh - 5];
        let crop = [30.0f32, 25.0, 30.0 + 150.0, 25.0 + 120.0];
        let rows = 25..145usize;
        for harris in [&mut reference, &mut chained] {
            let target = harris.input_target(ww as usize, wh as usize).unwrap();
            intake
                .pack_window(now.image().unwrap(), [x0, y0, ww, wh], allowed, &target)
                .unwrap();
        }
        let o = [x0 as f32, y0 as f32];
        // A: the previous frame's corners (in the frame), each with a
        // sample, a quarter of them empty.
        let a: Vec<Corner> = {
            let t = reference.input_target(w as usize, h as usize).unwrap();
            intake
                .pack_window(
                    before.image().unwrap(),
                    [0, 0, w, h],
                    [0, 0, w - 1, h - 1],
                    &t,
                )
                .unwrap();
            reference.detect_packed(w as usize, h as usize).unwrap()
        };
        let valid: Vec<bool> = (0..a.len()).map(|_| rng.uniform(0.0, 1.0) > 0.25).collect();
        let samples: Vec<f32> = valid
            .iter()
            .flat_map(|&v| {
                let mut s = [f32::NAN; GATHER_STRIDE];
                s[GATHER_STRIDE - 1] = if v { 1.0 } else { 0.0 };
                s
            })
            .collect();
        let gate = c.buffer("gate", (samples.len() * 4) as u64, STORAGE_IN);
        c.queue
            .write_buffer(&gate, 0, bytemuck::cast_slice(&samples));
        // The reference: the corners read back and placed in the frame,
        // B cut to the crop and A to its valid features on the host.
        let target = reference.input_target(ww as usize, wh as usize).unwrap();
        intake
            .pack_window(now.image().unwrap(), [x0, y0, ww, wh], allowed, &target)
            .unwrap();
        let want_corners: Vec<Corner> = reference
            .detect_packed(ww as usize, wh as usize)
            .unwrap()
            .iter()
            .map(|k| Corner {
                x: k.x + o[0],
                y: k.y + o[1],
                score: k.score,
            })
            .collect();
        let inside =
            |k: &Corner| k.x >= crop[0] && k.y >= crop[1] && k.x < crop[2] && k.y < crop[3];
        let b_idx: Vec<usize> = (0..want_corners.len())
            .filter(|&i| inside(&want_corners[i]))
            .collect();
        clipped += want_corners.len() - b_idx.len();
        let b_in: Vec<Corner> = b_idx.iter().map(|&i| want_corners[i]).collect();
        let a_idx: Vec<usize> = (0..a.len()).filter(|&i| valid[i]).collect();
        gated_out += a.len() - a_idx.len();
        let a_in: Vec<Corner> = a_idx.iter().map(|&i| a[i]).collect();
        let want: Vec<_> = m_ref
            .match_resident(
                before.image().unwrap(),
                rows.clone(),
                &a_in,
                now.image().unwrap(),
                rows.clone(),
                &b_in,
                [0, 0],
                None,
            )
            .unwrap()
            .into_iter()
            .map(|r| (a_idx[r.a], b_idx[r.b], r.score, r.at))
            .collect();
        // Chained.
        let waits = c.stats().readbacks;
        let pending = chained
            .detect_packed_later(ww as usize, wh as usize)
            .unwrap();
        let slots = pending.slots();
        let place = ExportPlace {
            origin: o,
            clip: Some(crop),
            band_y0: rows.start as f32,
            first: a.len(),
        };
        let pm = {
            let ch = &mut chained;
            let mut export = |passes: &mut PassChain, pos: &wgpu::Buffer| {
                ch.export_corners(passes, &pending, place, pos, None)
            };
            m.match_resident_exported_b(
                before.image().unwrap(),
                rows.clone(),
                &a,
                Some(&gate),
                now.image().unwrap(),
                rows.clone(),
                slots,
                &mut export,
                [0, 0],
                None,
            )
            .unwrap()
        };
        let detected = chained.finish_later(pending).unwrap();
        let got: Vec<_> = m
            .finish_exported(pm, a.len())
            .unwrap()
            .into_iter()
            .map(|r| (r.a, r.b, r.score, r.at))
            .collect();
        let waits = c.stats().readbacks - waits;
        let got_corners: Vec<Corner> = detected
            .corners
            .iter()
            .map(|k| Corner {
                x: k.x + o[0],
                y: k.y + o[1],
                score: k.score,
            })
            .collect();
        assert_eq!(got_corners, want_corners, "{at}: corners");
        if round == 0 {
            // A first detection reads back fewer rows than it keeps:
            // nothing exported, the matching to be done again.
            assert!(!detected.exported, "{at}");
            continue;
        }
        assert!(detected.exported, "{at}");
        assert_eq!(waits, 1, "{at}: waits");
        assert_eq!(got, want, "{at}: matches");
        matched += got.len();
    }
    assert!(matched > 60, "{matched} matches");
    assert!(
        gated_out > 10 && clipped > 10,
        "{gated_out} gated, {clipped} clipped"
    );
    // A gate smaller than A's samples is refused.
    let small = c.buffer("small", 16, STORAGE_IN);
    let pending = chained.detect_packed_later(50, 40).unwrap();
    let mut export = |_: &mut PassChain, _: &wgpu::Buffer| Ok(());
    let a = [Corner {
        x: 10.0,
        y: 10.0,
        score: 1.0,
    }; 3];
    let img = now.image().unwrap();
    assert!(
        m.match_resident_exported_b(
            img,
            0..40,
            &a,
            Some(&small),
            img,
            0..40,
            4,
            &mut export,
            [0, 0],
            None
        )
        .is_err()
    );
    chained.finish_later(pending).unwrap();
}
