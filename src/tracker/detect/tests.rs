//! The keyframes' features on the GPU: corners lifted to model points.

use crate::geometry::Intrinsics;
use crate::gpu::shared_test_context;
use crate::keyframes::{KeyframeConfig, KeyframeStore};
use crate::rng::Rng;
use crate::splat::Splatter;
use crate::synth::sequence::sample_model;
use crate::synth::{Light, SynthObject, background, keyframe_poses, raster, to_image};
use crate::tracker::{Tracker, TrackerConfig};

#[test]
fn keyframe_corners_lift_onto_the_model_where_the_keyframe_saw_them() {
    let ctx = shared_test_context();
    let cam = Intrinsics::new(640, 480, 600.0, 600.0, 319.5, 239.5);
    let object = SynthObject::by_name("box").unwrap();
    let model = sample_model(&object, 60_000, 3).unwrap();
    let bg = background(&cam, 7);
    let poses = &keyframe_poses(0.55)[..3];
    let images: Vec<_> = poses
        .iter()
        .enumerate()
        .map(|(k, pose)| {
            let r = raster::render(&object, pose, &cam, &Light::moving(0.0), &bg, 3);
            let img = to_image(&r.rgb, &cam, 0.01, &mut Rng::new(k as u64));
            (format!("kf{k}"), img, *pose)
        })
        .collect();
    let splatter = Splatter::new(ctx).unwrap();
    let cfg = KeyframeConfig::default();
    let store = KeyframeStore::build(ctx, &splatter, &model, &cam, &images, &cfg).unwrap();
    // Searching: the detector is made with the tracker.
    let t = Tracker::builder(ctx, model, cam)
        .keyframes(store)
        .config(TrackerConfig::default())
        .build()
        .unwrap();
    let det = t.detector.as_ref().expect("detector made for the search");
    let diameter = object.mesh.diameter();
    for (k, (kf, pose)) in det.keyframes.iter().zip(poses).enumerate() {
        // The mesh's depth at each pixel centre (the rasteriser's).
        let r = raster::render(&object, pose, &cam, &Light::moving(0.0), &bg, 1);
        let mut errs = Vec::new();
        for (p, px) in kf.points.iter().zip(&kf.pixels) {
            let x = pose.transform_point(p);
            let uv = cam.project(&x).unwrap();
            let off = (uv.x - px[0] as f64).hypot(uv.y - px[1] as f64);
            assert!(off < 0.5, "keyframe {k}: reprojected {off:.2} px off");
            let (u, v) = (px[0].round() as usize, px[1].round() as usize);
            let z = r.depth[v * cam.width as usize + u] as f64;
            if z.is_finite() {
                errs.push((x.z - z).abs() / diameter);
            }
        }
        errs.sort_by(f64::total_cmp);
        let median = errs[errs.len() / 2];
        let p90 = errs[errs.len() * 9 / 10];
        eprintln!(
            "keyframe {k}: {} points, depth off the mesh: median {:.4}, 90% {:.4} of the diameter",
            kf.points.len(),
            median,
            p90
        );
        assert!(kf.points.len() >= 20, "keyframe {k}: {}", kf.points.len());
        assert!(errs.len() * 10 >= kf.points.len() * 9);
        assert!(median < 0.003 && p90 < 0.01, "{median:.4} {p90:.4}");
    }
}
