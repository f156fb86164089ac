//! The keyframe store (`splattrack::keyframes`) against keyframes rendered
//! by the synth CPU triangle rasteriser: visibility checked against the
//! rasteriser's own depth (an independent z-buffer, not the splatter the
//! store uses), colours against the rendered images and the texture,
//! borrowed colours, keyframe selection, the file format and its errors.

mod tracking_common;

use nalgebra::{Vector2, Vector3};
use splattrack::geometry::{Intrinsics, Pose, rotation_exp};
use splattrack::gpu::shared_test_context;
use splattrack::keyframes::{KeyframeConfig, KeyframeError, KeyframeStore};
use splattrack::rng::Rng;
use splattrack::splat::Splatter;
use splattrack::synth::raster::Rendering;
use splattrack::synth::{Light, base_pose, keyframe_poses};
use std::sync::OnceLock;
use tracking_common::{Scene, TempDir, camera_320};

const DISTANCE: f64 = 0.55;

/// The torus (it hides parts of itself from every viewpoint), its 12 synth
/// keyframes rendered without noise, and the store built from them.
struct Fixture {
    scene: Scene,
    renderings: Vec<Rendering>,
    poses: Vec<Pose>,
    store: KeyframeStore,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let scene = Scene::new("torus", camera_320(), 20_000);
        let poses = keyframe_poses(DISTANCE);
        let renderings: Vec<Rendering> = poses
            .iter()
            .enumerate()
            .map(|(k, p)| scene.render(p, 0.3 * k as f64))
            .collect();
        let frames: Vec<(String, image::RgbImage, Pose)> = renderings
            .iter()
            .zip(&poses)
            .enumerate()
            .map(|(k, (r, p))| (format!("kf{k:02}"), scene.image(r, 0.0, 0), *p))
            .collect();
        let ctx = shared_test_context();
        let store = KeyframeStore::build(
            ctx,
            &Splatter::new(ctx).unwrap(),
            &scene.model,
            &scene.cam,
            &frames,
            &KeyframeConfig::default(),
        )
        .expect("build");
        Fixture {
            scene,
            renderings,
            poses,
            store,
        }
    })
}

fn point(model: &splattrack::PointModel, i: usize) -> Vector3<f64> {
    let p = model.positions[i];
    Vector3::new(p.x as f64, p.y as f64, p.z as f64)
}

fn normal(model: &splattrack::PointModel, i: usize) -> Vector3<f64> {
    let n = model.normals[i];
    Vector3::new(n.x as f64, n.y as f64, n.z as f64)
}

/// The rasterised depths of the four pixel centres around `uv` (NaN off the
/// object or outside the image) and the bilinear weights of `uv` among them.
fn depth_around(r: &Rendering, uv: &Vector2<f64>) -> ([f32; 4], [f64; 4]) {
    let (x0, y0) = (uv.x.floor() as i64, uv.y.floor() as i64);
    let (fx, fy) = (uv.x - x0 as f64, uv.y - y0 as f64);
    let mut out = [f32::NAN; 4];
    for (k, (dx, dy)) in [(0, 0), (1, 0), (0, 1), (1, 1)].iter().enumerate() {
        let (x, y) = (x0 + dx, y0 + dy);
        if x >= 0 && y >= 0 && x < r.width as i64 && y < r.height as i64 {
            out[k] = r.depth[(y * r.width as i64 + x) as usize];
        }
    }
    let w = [
        (1.0 - fx) * (1.0 - fy),
        fx * (1.0 - fy),
        (1.0 - fx) * fy,
        fx * fy,
    ];
    (out, w)
}

/// The largest rasterised depth within `radius` pixels of `uv`, or None
/// when any pixel there is off the object.
fn max_depth_near(r: &Rendering, uv: &Vector2<f64>, radius: i64) -> Option<f64> {
    let (px, py) = (uv.x.round() as i64, uv.y.round() as i64);
    let mut hi = f64::NEG_INFINITY;
    for y in py - radius..=py + radius {
        for x in px - radius..=px + radius {
            if x < 0 || y < 0 || x >= r.width as i64 || y >= r.height as i64 {
                return None;
            }
            let d = r.depth[(y * r.width as i64 + x) as usize];
            if d.is_nan() {
                return None;
            }
            hi = hi.max(d as f64);
        }
    }
    Some(hi)
}

/// Bilinear sample of the rendering's linear RGB (None at the border).
fn rgb_at(r: &Rendering, uv: &Vector2<f64>) -> Option<[f32; 3]> {
    let (x0, y0) = (uv.x.floor(), uv.y.floor());
    if x0 < 0.0 || y0 < 0.0 || x0 + 1.0 >= r.width as f64 || y0 + 1.0 >= r.height as f64 {
        return None;
    }
    let (fx, fy) = ((uv.x - x0) as f32, (uv.y - y0) as f32);
    let at = |x: f64, y: f64| r.rgb[y as usize * r.width as usize + x as usize];
    let (a, b, c, d) = (
        at(x0, y0),
        at(x0 + 1.0, y0),
        at(x0, y0 + 1.0),
        at(x0 + 1.0, y0 + 1.0),
    );
    Some(std::array::from_fn(|k| {
        (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
    }))
}

fn percentile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

#[test]
fn visibility_follows_the_rasterised_depth() {
    let f = fixture();
    let (model, cam) = (&f.scene.model, &f.scene.cam);
    let diameter = f.scene.diameter;
    // A smooth patch: the four pixel centres around the projection within
    // 1% of the diameter in depth (occlusion boundaries jump by centimetres).
    // There, inverse depth interpolates bilinearly (exact on a plane), and
    // the points, sampled on the very triangles the rasteriser draws, must
    // lie on that surface when visible.
    let smooth_tol = 0.01 * diameter;
    let on_tol = 0.002 * diameter;
    // Behind the rasterised surface everywhere within 2 pixels of its
    // projection by more than 5% of the diameter (the torus tube is 27% of
    // it thick): hidden.
    let far = 0.05 * diameter;
    let mut visible = 0;
    let mut visible_off_object = 0;
    let mut smooth_errors = Vec::new();
    let mut far_behind = 0;
    let (mut clear, mut clear_seen) = (0, 0);
    for (k, kf) in f.store.keyframes.iter().enumerate() {
        let (pose, r) = (&f.poses[k], &f.renderings[k]);
        assert_eq!(kf.pose, *pose);
        for i in 0..model.len() {
            let x = pose.transform_point(&point(model, i));
            let uv = cam.project(&x).unwrap();
            let (d, w) = depth_around(r, &uv);
            let finite = d.iter().filter(|v| v.is_finite()).count();
            let lo = d.iter().fold(f32::INFINITY, |a, &b| a.min(b)) as f64;
            let hi = d.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b)) as f64;
            let smooth = finite == 4 && hi - lo < smooth_tol;
            let surface = 1.0 / (0..4).map(|j| w[j] / d[j] as f64).sum::<f64>();
            let err = (x.z - surface).abs();
            if max_depth_near(r, &uv, 2).is_some_and(|hi| x.z > hi + far) {
                far_behind += 1;
                assert!(
                    !kf.visible[i],
                    "keyframe {k} point {i}: {:.4} behind the surface, marked visible",
                    x.z - hi
                );
            }
            let cos = -(pose.rotation * normal(model, i)).dot(&x) / x.norm();
            if kf.visible[i] {
                visible += 1;
                visible_off_object += (finite == 0) as usize;
                if smooth {
                    smooth_errors.push(err / diameter);
                    assert!(
                        err < on_tol,
                        "keyframe {k} point {i}: visible, {:.3}% of the diameter off the \
                         rasterised surface (cos {cos:.2})",
                        100.0 * err / diameter
                    );
                }
            }
            // Clearly visible: on a smooth patch, on its surface, facing the
            // camera, away from the image border.
            let inside = uv.x > 4.0 && uv.y > 4.0 && uv.x < 315.0 && uv.y < 235.0;
            if smooth && err < on_tol && cos > 0.3 && inside {
                clear += 1;
                clear_seen += kf.visible[i] as usize;
            }
        }
    }
    let recall = clear_seen as f64 / clear as f64;
    let n_smooth = smooth_errors.len();
    let (p50, p99) = (
        percentile(&mut smooth_errors, 0.5),
        percentile(&mut smooth_errors, 0.99),
    );
    eprintln!(
        "{visible} visible point-keyframe pairs ({visible_off_object} with no rasterised depth \
         around): {n_smooth} on smooth patches, off the rasterised surface by a median \
         {:.4}% and a 99th percentile {:.4}% of the diameter; {far_behind} pairs far behind \
         the surface, none visible; {clear_seen} of {clear} clearly visible ones marked \
         visible ({:.2}%)",
        100.0 * p50,
        100.0 * p99,
        100.0 * recall
    );
    // The test must be able to fail: the torus hides much of itself, and
    // most visible points lie on smooth patches.
    assert!(far_behind > 10_000, "{far_behind}");
    assert!(n_smooth > visible / 2, "{n_smooth} of {visible}");
    assert!(visible_off_object < visible / 200, "{visible_off_object}");
    assert!(recall > 0.97, "{recall}");
}

#[test]
fn colours_are_the_keyframe_images_at_the_projections() {
    let f = fixture();
    let (model, cam) = (&f.scene.model, &f.scene.cam);
    let mut image_diff = Vec::new();
    let mut texture_diff = Vec::new();
    let mut control_diff = Vec::new();
    for (k, kf) in f.store.keyframes.iter().enumerate() {
        let (pose, r) = (&f.poses[k], &f.renderings[k]);
        let light = Light::moving(0.3 * k as f64);
        // Independent of the image: the texture's albedo, shaded as the
        // rasteriser shades it, with the torus's smooth normal (the one its
        // vertex normals sample: away from the nearest point of the ring of
        // radius 0.08 through the tube's centre).
        let shaded = |i: usize| {
            let p = point(model, i);
            let ring = Vector3::new(p.x, p.y, 0.0).normalize() * 0.08;
            let n = (p - ring).normalize();
            let albedo = f.scene.object.texture.albedo(&p, &n);
            let shade = light.shade(&(pose.rotation * n)) as f32;
            albedo.map(|a| a * shade)
        };
        let dist =
            |a: [f32; 3], b: [f32; 3]| (0..3).map(|j| (a[j] - b[j]).abs()).fold(0.0, f32::max);
        let seen: Vec<usize> = (0..model.len()).filter(|&i| kf.visible[i]).collect();
        for (n, &i) in seen.iter().enumerate() {
            let x = pose.transform_point(&point(model, i));
            let uv = cam.project(&x).unwrap();
            let c = kf.colors[i];
            if let Some(want) = rgb_at(r, &uv) {
                image_diff.push(dist(c, want) as f64);
            }
            // Away from the texture's cell walls (18 mm cells; walls blur
            // over a pixel or two), where the albedo is constant.
            let q = point(model, i) / 0.018;
            if q.iter().all(|v| (v - v.floor() - 0.5).abs() < 0.22) {
                texture_diff.push(dist(c, shaded(i)) as f64);
            }
            // Control: another visible point's expected colour.
            let other = seen[(n * 7919 + 13) % seen.len()];
            control_diff.push(dist(c, shaded(other)) as f64);
        }
    }
    let img50 = percentile(&mut image_diff, 0.5);
    let img99 = percentile(&mut image_diff, 0.99);
    let tex50 = percentile(&mut texture_diff, 0.5);
    let tex90 = percentile(&mut texture_diff, 0.9);
    let control50 = percentile(&mut control_diff, 0.5);
    eprintln!(
        "keyframe colour vs the rendered image at the projection: median {img50:.4}, 99th \
         percentile {img99:.4}; vs the shaded albedo inside texture cells: median {tex50:.4}, \
         90th percentile {tex90:.4} (another point's: median {control50:.4})"
    );
    // The images have no noise: 8-bit quantisation only.
    assert!(
        img50 <= 1.0 / 255.0 && img99 <= 2.0 / 255.0,
        "{img50} {img99}"
    );
    // Percentiles, not a maximum: near silhouettes and slanted cell walls
    // the bilinear footprint still mixes colours.
    assert!(tex50 < 0.01 && tex90 < 0.04, "{tex50} {tex90}");
    assert!(control50 > 0.15, "{control50}");
}

#[test]
fn hidden_points_borrow_from_the_nearest_keyframe_that_sees_them() {
    let f = fixture();
    let store = &f.store;
    let model = &f.scene.model;
    // Viewing directions, computed here: camera centre minus the store's
    // pivot, in the object frame.
    let dirs: Vec<Vector3<f64>> = store
        .keyframes
        .iter()
        .map(|k| (-(k.pose.rotation.transpose() * k.pose.translation) - store.center).normalize())
        .collect();
    let (mut borrowed, mut from_model) = (0, 0);
    for (k, kf) in store.keyframes.iter().enumerate() {
        for i in (0..model.len()).filter(|&i| !kf.visible[i]) {
            let donor = (0..store.keyframes.len())
                .filter(|&j| j != k && store.keyframes[j].visible[i])
                // The most similar direction; on a tie, the lower index.
                .min_by(|&a, &b| dirs[k].dot(&dirs[b]).total_cmp(&dirs[k].dot(&dirs[a])));
            match donor {
                Some(j) => {
                    assert_eq!(
                        kf.colors[i], store.keyframes[j].colors[i],
                        "kf {k} point {i}"
                    );
                    borrowed += 1;
                }
                None => {
                    assert_eq!(kf.colors[i], model.colors.as_ref().unwrap()[i]);
                    from_model += 1;
                }
            }
        }
    }
    eprintln!("{borrowed} borrowed colours, {from_model} from the model");
    assert!(borrowed > 10_000, "{borrowed}");
}

#[test]
fn closest_picks_the_nearest_viewing_direction() {
    let f = fixture();
    let store = &f.store;
    // The synth viewpoints: 8 around at 25 degrees elevation, 4 at 60.
    let views: Vec<(f64, f64)> = (0..8)
        .map(|k| (30.0 + 45.0 * k as f64, 25.0))
        .chain((0..4).map(|k| (75.0 + 90.0 * k as f64, 60.0)))
        .collect();
    assert_eq!(views.len(), store.keyframes.len());
    let mut rng = Rng::new(5);
    for (k, &(az, el)) in views.iter().enumerate() {
        assert!(
            base_pose(DISTANCE, az, el).rotation_error_deg(&store.keyframes[k].pose) < 1e-4,
            "keyframe {k} is not at ({az}, {el}): {}",
            base_pose(DISTANCE, az, el).rotation_error_deg(&store.keyframes[k].pose)
        );
        for _ in 0..8 {
            // Up to 12 degrees off the keyframe's direction (neighbours
            // are 35 to 45 degrees apart), 0.8x to 1.25x as far, and rolled
            // about the optical axis (which must not matter).
            let p = base_pose(
                DISTANCE * rng.uniform(0.8, 1.25),
                az + rng.uniform(-12.0, 12.0),
                el + rng.uniform(-8.0, 8.0),
            );
            let roll = rotation_exp(&Vector3::new(0.0, 0.0, rng.uniform(-3.0, 3.0)));
            let p = Pose {
                rotation: roll * p.rotation,
                translation: roll * p.translation,
            };
            assert_eq!(store.closest(&p), k, "near keyframe {k} ({az}, {el})");
        }
    }
    // Straight above: nearest are the four 60-degree views, 30 degrees off.
    let above = base_pose(DISTANCE, 80.0, 89.0);
    assert!(store.closest(&above) >= 8);
}

#[test]
fn save_load_round_trip() {
    let f = fixture();
    let dir = TempDir::new("kf-roundtrip");
    let path = dir.0.join("store.stkf");
    f.store.save(&path).unwrap();
    assert!(!splattrack::io::atomic::partial_path(&path).exists());
    let back = KeyframeStore::load(&path).unwrap();
    assert_eq!(back.points, f.store.points);
    assert_eq!(back.fingerprint, f.store.fingerprint);
    assert_eq!(back.center, f.store.center);
    assert_eq!(back.keyframes.len(), f.store.keyframes.len());
    for (a, b) in f.store.keyframes.iter().zip(&back.keyframes) {
        assert_eq!(a.name, b.name);
        assert_eq!(a.pose, b.pose);
        assert_eq!(a.visible, b.visible);
        for (ca, cb) in a.colors.iter().zip(&b.colors) {
            for j in 0..3 {
                // Stored as 8 bits, rounded: within half a step.
                assert!((ca[j] - cb[j]).abs() <= 0.5 / 255.0 + 1e-6, "{ca:?} {cb:?}");
            }
        }
    }
    back.check_model(&f.scene.model, &path).unwrap();
    // Saving what was loaded gives the same bytes.
    let again = dir.0.join("again.stkf");
    back.save(&again).unwrap();
    assert_eq!(
        std::fs::read(&path).unwrap(),
        std::fs::read(&again).unwrap()
    );
}

#[test]
fn check_model_refuses_another_model() {
    let f = fixture();
    let path = std::path::Path::new("torus.stkf");
    // Another object.
    let blob = tracking_common::Scene::new("blob", camera_320(), 20_000).model;
    let e = f.store.check_model(&blob, path).unwrap_err();
    assert!(matches!(e, KeyframeError::WrongModel { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("torus.stkf") && msg.contains("another model"),
        "{msg}"
    );
    // The same number of points, one of them moved by a hair.
    let mut moved = f.scene.model.clone();
    moved.positions[123].x += 1e-6;
    assert!(matches!(
        f.store.check_model(&moved, path),
        Err(KeyframeError::WrongModel { .. })
    ));
    // A subset.
    let mut fewer = f.scene.model.clone();
    fewer.positions.pop();
    assert!(f.store.check_model(&fewer, path).is_err());
}

#[test]
fn corrupt_files_are_format_errors_naming_the_file() {
    let f = fixture();
    let dir = TempDir::new("kf-corrupt");
    // A small store (3 keyframes) keeps the fuzzing cheap.
    let mut small = f.store.clone();
    small.keyframes.truncate(3);
    let good_path = dir.0.join("good.stkf");
    small.save(&good_path).unwrap();
    let good = std::fs::read(&good_path).unwrap();
    let bad_path = dir.0.join("bad.stkf");
    let name = bad_path.display().to_string();
    let expect_format = |bytes: &[u8], what: &str| {
        std::fs::write(&bad_path, bytes).unwrap();
        match KeyframeStore::load(&bad_path) {
            Err(e @ KeyframeError::Format { .. }) => {
                assert!(e.to_string().contains(&name), "{what}: {e}");
            }
            Err(e) => panic!("{what}: not a Format error: {e}"),
            Ok(_) => panic!("{what}: loaded"),
        }
    };
    let mut rng = Rng::new(11);
    // Truncations: the empty file, inside the header, inside names, poses
    // and colours, one byte short.
    let mut cuts = vec![0, 1, 7, 8, 15, 31, 40, 55, 56, 60, good.len() - 1];
    cuts.extend((0..25).map(|_| rng.below(good.len() as u64) as usize));
    for cut in cuts {
        expect_format(&good[..cut], &format!("truncated to {cut} bytes"));
    }
    // Extra bytes and a wrong magic.
    let mut longer = good.clone();
    longer.push(0);
    expect_format(&longer, "one trailing byte");
    let mut magic = good.clone();
    magic[3] ^= 0x20;
    expect_format(&magic, "wrong magic");
    // Bit flips anywhere in the header, names and poses (the first 260
    // bytes cover the header and the first keyframe's name and pose): a
    // flip may leave a loadable store (a different fingerprint, say), but
    // never a panic, and an error is a Format error naming the file. Flips
    // in the counts and the pose are always errors.
    let mut errors = 0;
    for _ in 0..60 {
        let mut b = good.clone();
        let at = rng.below(260.min(b.len() as u64)) as usize;
        b[at] ^= 1 << rng.below(8);
        std::fs::write(&bad_path, &b).unwrap();
        match KeyframeStore::load(&bad_path) {
            Ok(s) => assert_eq!(s.keyframes.len(), 3, "flip at {at}"),
            Err(e @ KeyframeError::Format { .. }) => {
                assert!(e.to_string().contains(&name), "{e}");
                errors += 1;
            }
            Err(e) => panic!("flip at byte {at}: not a Format error: {e}"),
        }
    }
    assert!(errors > 10, "{errors}");
    // The exact high bit of the point count: sizes no longer add up.
    let mut b = good.clone();
    b[8 + 7] ^= 0x80;
    expect_format(&b, "point count");
    // A rotation element of the first pose set to 2.0.
    let name_len = u32::from_le_bytes(good[56..60].try_into().unwrap()) as usize;
    let mut b = good.clone();
    let r11 = 60 + name_len;
    b[r11..r11 + 8].copy_from_slice(&2.0f64.to_le_bytes());
    expect_format(&b, "non-rotation pose");
    // A NaN centre.
    let mut b = good.clone();
    b[32..40].copy_from_slice(&f64::NAN.to_le_bytes());
    expect_format(&b, "NaN centre");
    // A missing file is an I/O error naming it.
    let missing = dir.0.join("missing.stkf");
    let e = KeyframeStore::load(&missing).unwrap_err();
    assert!(matches!(e, KeyframeError::Io { .. }) && e.to_string().contains("missing.stkf"));
}

#[test]
fn from_model_colors_is_one_all_visible_keyframe() {
    let f = fixture();
    let model = &f.scene.model;
    let pose = f.poses[2];
    let s = KeyframeStore::from_model_colors(model, &pose).unwrap();
    assert_eq!(s.keyframes.len(), 1);
    let k = &s.keyframes[0];
    assert_eq!(k.pose, pose);
    assert_eq!(k.visible_count(), model.len());
    assert_eq!(&k.colors, model.colors.as_ref().unwrap());
    assert_eq!(s.points, model.len() as u64);
    s.check_model(model, std::path::Path::new("m")).unwrap();
    assert_eq!(s.closest(&f.poses[7]), 0);
    // The textured model carries those colours.
    assert_eq!(s.textured(model, 0).colors, model.colors);
    // Without colours there is nothing to make a texture from.
    let mut bare = model.clone();
    bare.colors = None;
    assert!(KeyframeStore::from_model_colors(&bare, &pose).is_none());
}

#[test]
fn keyframe_that_does_not_see_the_object_is_refused() {
    let f = fixture();
    let ctx = shared_test_context();
    let cam: Intrinsics = f.scene.cam;
    let splatter = Splatter::new(ctx).unwrap();
    let build = |name: &str, pose: Pose| {
        let frames = vec![(
            name.to_string(),
            image::RgbImage::new(cam.width, cam.height),
            pose,
        )];
        KeyframeStore::build(
            ctx,
            &splatter,
            &f.scene.model,
            &cam,
            &frames,
            &KeyframeConfig::default(),
        )
    };
    // The object far off to the side: nothing projects into the image.
    let mut aside = f.poses[0];
    aside.translation.x += 2.0;
    let e = build("aside", aside).unwrap_err();
    assert!(matches!(e, KeyframeError::NothingVisible { .. }), "{e}");
    assert!(e.to_string().contains("aside"), "{e}");
    // Behind the camera: the splatter refuses (an error, not a panic).
    let mut behind = f.poses[0];
    behind.translation.z = -behind.translation.z;
    let e = build("behind", behind).unwrap_err();
    assert!(e.to_string().contains("behind the camera"), "{e}");
}

#[test]
fn the_textured_cache_stays_within_its_budget_and_renders_the_same() {
    use splattrack::keyframes::TexturedCache;
    use splattrack::splat::{Attribute, Attributes, GpuModel, SplatTargets};
    let f = fixture();
    let ctx = shared_test_context();
    let model = &f.scene.model;
    // Room for the colours of two keyframes (4 bytes a point; the
    // geometry is shared and not counted).
    let budget = 2 * 4 * model.len() as u64 + 100;
    let mut cache = TexturedCache::new(f.store.keyframes.len(), model.len(), budget);
    assert_eq!(cache.max_resident(), 2);
    let splatter = Splatter::new(ctx).unwrap();
    let cam = &f.scene.cam;
    let mut targets = SplatTargets::new(ctx, cam.width, cam.height);
    let mut colour = |gm: &GpuModel, pose: &Pose| {
        splatter
            .render(ctx, gm, cam, pose, Attributes::ALL, &mut targets)
            .unwrap();
        splatter.read(ctx, &targets, Attribute::Color).unwrap().data
    };
    let geometry = GpuModel::new(ctx, model).unwrap();
    let mut uploads = Vec::new();
    for k in [0, 1, 0, 2, 1, 1, 3] {
        let pose = f.poses[k];
        let got = colour(cache.get(ctx, &f.store, &geometry, k).unwrap(), &pose);
        // Only the colours are per keyframe.
        let cached = cache.get(ctx, &f.store, &geometry, k).unwrap();
        assert_eq!(cached.color_bytes(), 4 * model.len() as u64);
        assert_eq!(cached.geometry_bytes(), 32 * model.len() as u64);
        assert!(cache.resident() <= 2, "{} resident", cache.resident());
        uploads.push(cache.uploads());
        // The cached model is keyframe k's texture: the same picture as a
        // fresh upload of it.
        // (Additive blending may sum in another order on the GPU: equal
        // within float rounding, far below an 8-bit step.)
        let fresh = GpuModel::new(ctx, &f.store.textured(model, k)).unwrap();
        let want = colour(&fresh, &pose);
        let diff = got
            .iter()
            .zip(&want)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(diff < 1e-4, "keyframe {k}: max difference {diff}");
    }
    // 0, 1 uploaded; 0 hit; 2 evicts 1; 1 evicts 0; 1 hit; 3 evicts 2.
    assert_eq!(uploads, [1, 2, 2, 3, 4, 4, 5]);
    // A budget below one model still keeps one.
    assert_eq!(TexturedCache::new(12, model.len(), 1).max_resident(), 1);
}

#[test]
fn a_merged_store_averages_the_colours_its_merged_points_are_seen_with() {
    let f = fixture();
    let model = &f.scene.model;
    let (merged, group) = model.merged(0.01);
    assert!(
        merged.len() < model.len() / 2,
        "{} of {}",
        merged.len(),
        model.len()
    );
    let store = f.store.merged(&merged, &group).expect("the groups fit");
    store
        .check_model(&merged, std::path::Path::new("merged"))
        .expect("the store is the merged model's");
    assert_eq!(store.keyframes.len(), f.store.keyframes.len());
    for (k, (a, b)) in f.store.keyframes.iter().zip(&store.keyframes).enumerate() {
        assert_eq!((a.name.as_str(), a.pose), (b.name.as_str(), b.pose));
        // Each merged point against its members, summed here in f64.
        let mut sums = vec![([0.0f64; 3], 0usize, [0.0f64; 3], 0usize); merged.len()];
        for (i, &g) in group.iter().enumerate() {
            let s = &mut sums[g as usize];
            for c in 0..3 {
                s.2[c] += a.colors[i][c] as f64;
                if a.visible[i] {
                    s.0[c] += a.colors[i][c] as f64;
                }
            }
            s.3 += 1;
            s.1 += usize::from(a.visible[i]);
        }
        for (j, (seen, n_seen, all, n_all)) in sums.iter().enumerate() {
            assert_eq!(b.visible[j], *n_seen > 0, "keyframe {k}, point {j}");
            let (sum, n) = if *n_seen > 0 {
                (seen, n_seen)
            } else {
                (all, n_all)
            };
            for (got, sum) in b.colors[j].iter().zip(sum) {
                let want = sum / *n as f64;
                assert!((*got as f64 - want).abs() < 1e-6, "keyframe {k}, point {j}");
            }
        }
    }
    // Groups that do not fit the store or the model: none.
    assert!(f.store.merged(&merged, &group[1..]).is_none());
    let mut past = group.clone();
    past[0] = merged.len() as u32;
    assert!(f.store.merged(&merged, &past).is_none());
}
