//! The scenes of several objects ([`MultiScene`]): their occlusion and
//! the visibility ground truth, checked against each object rendered
//! alone by the rasteriser.

use super::multi::*;
use super::objects::Light;
use super::raster;
use crate::geometry::Intrinsics;

/// A small camera of the default field of view: the layouts are made in
/// fractions of the image, so they keep their occlusion at any size.
fn cam() -> Intrinsics {
    Intrinsics::new(160, 120, 150.0, 150.0, 79.5, 59.5)
}

fn scene(layout: Layout) -> MultiScene {
    MultiScene::new(MultiConfig {
        layout,
        camera: cam(),
        noise: 0.0,
        ..MultiConfig::default()
    })
    .unwrap()
}

/// Each object's visible fraction per frame, as the frames' ground truth
/// gives it (the rasteriser's object ids, at the scene's supersampling).
fn visibility(scene: &MultiScene) -> Vec<Vec<f64>> {
    let n = scene.config.frames;
    let mut v = vec![Vec::with_capacity(n); scene.objects.len()];
    for i in 0..n {
        let poses: Vec<_> = (0..scene.objects.len()).map(|k| scene.pose(k, i)).collect();
        let meshes: Vec<_> = scene
            .objects
            .iter()
            .map(|o| &o.object.mesh)
            .zip(&poses)
            .collect();
        let f = raster::visible_fractions(&meshes, &scene.config.camera, scene.config.samples);
        for (k, x) in f.into_iter().enumerate() {
            v[k].push(x);
        }
    }
    v
}

fn peak_hidden(v: &[f64]) -> f64 {
    v.iter().map(|x| 1.0 - x).fold(0.0, f64::max)
}

/// Every object wholly visible at the start and the end, and the nearest
/// never hidden.
fn starts_and_ends_apart(v: &[Vec<f64>]) {
    for (k, o) in v.iter().enumerate() {
        assert_eq!(o[0], 1.0, "object {k} at the start");
        assert_eq!(*o.last().unwrap(), 1.0, "object {k} at the end");
    }
    assert!(v.last().unwrap().iter().all(|&x| x == 1.0));
}

#[test]
fn cross_hides_about_half_of_the_farther_and_starts_and_ends_apart() {
    let s = scene(Layout::Cross);
    assert_eq!(s.names(), ["blob", "box"]);
    assert!(s.objects[0].distance() > s.objects[1].distance());
    let v = visibility(&s);
    starts_and_ends_apart(&v);
    let peak = peak_hidden(&v[0]);
    assert!((0.4..=0.6).contains(&peak), "{peak}");
    // Hidden only about the crossing, in the middle: apart for the first
    // and last fifth.
    let n = v[0].len();
    let hidden: Vec<usize> = (0..n).filter(|&i| v[0][i] < 1.0).collect();
    assert!(
        hidden[0] > n / 5 && *hidden.last().unwrap() < n - n / 5,
        "{hidden:?}"
    );
    assert!(hidden.contains(&(n / 2)), "{hidden:?}");
}

#[test]
fn hide_hides_the_farther_wholly_for_a_stretch_then_it_reappears() {
    let s = scene(Layout::Hide);
    let v = visibility(&s);
    starts_and_ends_apart(&v);
    let gone: Vec<usize> = (0..v[0].len()).filter(|&i| v[0][i] == 0.0).collect();
    assert!((8..=15).contains(&gone.len()), "{gone:?}");
    // One stretch, about the middle.
    assert_eq!(gone.last().unwrap() - gone[0] + 1, gone.len(), "{gone:?}");
    assert!(gone.contains(&(v[0].len() / 2)), "{gone:?}");
    // The farther moves slowly: less than a tenth of the image across.
    let cam = s.config.camera;
    let centre = |i| {
        let p = s.pose(0, i);
        cam.project(&p.translation).unwrap()
    };
    let moved = (centre(v[0].len() - 1) - centre(0)).norm();
    assert!(moved < 0.1 * cam.width as f64, "{moved}");
}

#[test]
fn mixed_hides_at_most_about_forty_percent_of_the_textured_object() {
    let s = scene(Layout::Mixed);
    assert_eq!(s.names(), ["blob", "plain"]);
    let v = visibility(&s);
    starts_and_ends_apart(&v);
    let peak = peak_hidden(&v[0]);
    assert!((0.2..=0.42).contains(&peak), "{peak}");
}

#[test]
fn cross3_hides_the_farther_ones_partly_and_never_wholly() {
    let s = scene(Layout::Cross3);
    assert_eq!(s.names(), ["blob", "torus", "box"]);
    let d: Vec<f64> = s.objects.iter().map(|o| o.distance()).collect();
    assert!(d[0] > d[1] && d[1] > d[2], "{d:?}");
    let v = visibility(&s);
    starts_and_ends_apart(&v);
    let peak = peak_hidden(&v[0]);
    assert!((0.3..=0.6).contains(&peak), "{peak}");
    assert!(v.iter().flatten().all(|&x| x > 0.0));
}

#[test]
fn objects_are_about_the_one_object_size() {
    for layout in [Layout::Cross, Layout::Hide, Layout::Mixed, Layout::Cross3] {
        let s = scene(layout);
        for k in 0..s.objects.len() {
            // The one-object default is about 0.3 of the width.
            let f = s.size_px(k) / cam().width as f64;
            assert!((0.15..=0.5).contains(&f), "{layout:?} object {k}: {f}");
            // Wholly in the image at the start and the end.
            let mesh = &s.objects[k].object.mesh;
            for i in [0, s.config.frames - 1] {
                let out = super::framing::outside_fraction(mesh, &s.pose(k, i), &cam());
                assert_eq!(out, 0.0, "{layout:?} object {k} frame {i}");
            }
        }
    }
}

#[test]
fn each_pixel_shows_the_object_its_id_names_and_visibility_counts_them() {
    let s = scene(Layout::Cross);
    let cam = s.config.camera;
    let i = s.config.frames / 2;
    let poses = [s.pose(0, i), s.pose(1, i)];
    let light = Light::moving(0.3);
    let black = vec![[0.0f32; 3]; (cam.width * cam.height) as usize];
    let objects = [
        (&s.objects[0].object, &poses[0]),
        (&s.objects[1].object, &poses[1]),
    ];
    let joint = raster::render_many(&objects, &cam, &light, &black, 3);
    let alone: Vec<_> = objects
        .iter()
        .map(|(o, p)| raster::render(o, p, &cam, &light, &black, 3))
        .collect();
    let (mut own, mut hidden) = (0, 0);
    for px in 0..black.len() {
        for k in 0..2 {
            if joint.coverage[k][px] == 1.0 {
                // Wholly this object's: its own colour, as rendered alone.
                assert_eq!(joint.rgb[px], alone[k].rgb[px], "pixel {px}");
                assert_eq!(joint.id[px], k as u8);
                own += 1;
                if alone[0].coverage[px] == 1.0 && k == 1 {
                    hidden += 1;
                }
            }
        }
        if alone[0].coverage[px] == 0.0 && alone[1].coverage[px] == 0.0 {
            assert_eq!(joint.id[px], raster::NO_OBJECT);
        }
    }
    assert!(own > 1000 && hidden > 100, "{own} {hidden}");
    // The visible fraction: the samples the object shows over those it
    // covers alone.
    for (k, a) in alone.iter().enumerate() {
        let seen: f32 = joint.coverage[k].iter().sum();
        let all: f32 = a.coverage.iter().sum();
        let want = seen as f64 / all as f64;
        assert!((joint.visible_fraction(k) - want).abs() < 1e-4, "{k}");
    }
    assert!(joint.visible_fraction(0) < 0.8 && joint.visible_fraction(1) == 1.0);
    // The frame's ground truth is this.
    let f = s.frame(i);
    assert_eq!(f.poses, poses);
    assert!((f.visibility[0] - joint.visible_fraction(0)).abs() < 1e-12);
    assert_eq!(f.id, joint.id);
}

#[test]
fn frames_are_deterministic_by_seed() {
    let cfg = MultiConfig {
        camera: cam(),
        frames: 10,
        ..MultiConfig::default()
    };
    let a = MultiScene::new(cfg.clone()).unwrap().frame(3);
    let b = MultiScene::new(cfg.clone()).unwrap().frame(3);
    assert_eq!(a.image, b.image);
    let other = MultiScene::new(MultiConfig { seed: 2, ..cfg })
        .unwrap()
        .frame(3);
    assert_ne!(a.image, other.image);
    assert_eq!(a.poses, other.poses);
}

#[test]
fn repeated_objects_are_numbered_and_bad_lists_refused() {
    let names = object_names(&["blob".into(), "box".into(), "blob".into()]);
    assert_eq!(names, ["blob", "box", "blob-2"]);
    let names = object_names(&["box".into(), "box".into(), "box".into()]);
    assert_eq!(names, ["box", "box-2", "box-3"]);
    let with = |objects: &[&str], layout| {
        MultiScene::new(MultiConfig {
            layout,
            objects: objects.iter().map(|s| s.to_string()).collect(),
            camera: cam(),
            ..MultiConfig::default()
        })
    };
    let e = with(&["blob"], Layout::Cross).err().unwrap().to_string();
    assert!(e.contains("cross takes 2 objects, got 1"), "{e}");
    let e = with(&["blob", "box"], Layout::Cross3)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("cross3 takes 3 objects, got 2"), "{e}");
    let e = with(&["blob", "cube"], Layout::Cross)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("\"cube\""), "{e}");
    let s = with(&["blob", "blob"], Layout::Cross).unwrap();
    assert_eq!(s.names(), ["blob", "blob-2"]);
}

#[test]
fn visibility_files_are_read_back_and_bad_ones_named() {
    use super::sequence::read_visibility;
    let dir = std::env::temp_dir().join(format!("splattrack-vis-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("visibility.csv");
    let read = |text: &str| {
        std::fs::write(&path, text).unwrap();
        read_visibility(&path)
    };
    let rows = read("object,frame,visible\nblob,000000,1.000000\nbox,000000,0.25\n").unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(
        (rows[1].object.as_str(), rows[1].frame.as_str()),
        ("box", "000000")
    );
    assert_eq!(rows[1].visible, 0.25);
    for (text, needle) in [
        ("frame,visible\n", "line 1: the header"),
        ("object,frame,visible\nblob,0\n", "line 2: 2 fields"),
        (
            "object,frame,visible\nblob,0,1\nblob,1,1.5\n",
            "line 3: visible \"1.5\"",
        ),
        ("object,frame,visible\nblob,0,x\n", "visible \"x\""),
        ("object,frame,visible\n,0,1\n", "an empty object"),
    ] {
        let e = read(text).unwrap_err().to_string();
        assert!(e.contains(needle) && e.contains("visibility.csv"), "{e}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
