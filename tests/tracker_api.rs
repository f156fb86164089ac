//! The tracker's entry points for callers that hand frames over or want
//! the novel view (the Python package uses both): `track_owned` with
//! `frame_buffer` gives `track`'s poses bit for bit, and `novel_view`
//! covers and places the object as the synth rasteriser (independent of
//! the splatter) draws it.

mod tracking_common;

use splattrack::gpu::shared_test_context;
use splattrack::tracker::Tracker;
use std::sync::Arc;
use tracking_common::Fig10;

#[test]
fn track_owned_gives_tracks_poses_bit_for_bit() {
    let fx = Fig10::blob(0..6);
    let store = Arc::new(fx.store);
    let model = Arc::new(fx.scene.model.clone());
    let build = || {
        Tracker::builder(shared_test_context(), model.clone(), fx.scene.cam)
            .keyframes(store.clone())
            .initial_pose(fx.frames[0].pose)
            .build()
            .expect("tracker")
    };
    let (mut borrowed, mut owned) = (build(), build());
    for (i, f) in fx.frames.iter().enumerate() {
        let a = borrowed.track(&f.image).expect("track");
        // The buffer handed back is a frame the tracker no longer needs
        // (stale bytes from the second frame on): every byte overwritten.
        let mut buf = owned.frame_buffer();
        assert_eq!(buf.dimensions(), f.image.dimensions());
        buf.copy_from_slice(&f.image);
        let b = owned.track_owned(buf).expect("track_owned");
        assert_eq!(a.status, b.status, "frame {i}");
        assert_eq!(a.inliers, b.inliers, "frame {i}");
        assert_eq!(a.pose, b.pose, "frame {i}: poses differ");
    }
}

#[test]
fn novel_view_covers_the_object_where_the_rasteriser_draws_it() {
    let fx = Fig10::blob([10]);
    let f = &fx.frames[0];
    let mut t = Tracker::builder(
        shared_test_context(),
        Arc::new(fx.scene.model.clone()),
        fx.scene.cam,
    )
    .keyframes(Arc::new(fx.store))
    .initial_pose(f.pose)
    .build()
    .expect("tracker");
    let v = t.novel_view(&f.pose).expect("novel view");
    let (w, h) = (fx.scene.cam.width, fx.scene.cam.height);
    assert_eq!((v.width, v.height), (w, h));
    let n = (w * h) as usize;
    assert_eq!((v.color.len(), v.depth.len(), v.mask.len()), (3 * n, n, n));
    // Coverage: intersection over union with the rasteriser's object
    // pixels (over half covered); the splats' soft rims cost a few %.
    let truth: Vec<bool> = f.coverage.iter().map(|c| *c > 0.5).collect();
    let inter = truth
        .iter()
        .zip(&v.mask)
        .filter(|(a, b)| **a && **b)
        .count();
    let union = truth
        .iter()
        .zip(&v.mask)
        .filter(|(a, b)| **a || **b)
        .count();
    let iou = inter as f64 / union as f64;
    assert!(iou > 0.9, "mask IoU {iou:.3} with the rasteriser's");
    // Depth: within 1% of the object's distance where both are inside
    // (the points lie on the mesh; splats are tangent discs).
    let mut errs: Vec<f64> = (0..n)
        .filter(|&i| f.coverage[i] > 0.99 && v.mask[i])
        .map(|i| (v.depth[i] as f64 - f.depth[i] as f64).abs() / f.depth[i] as f64)
        .collect();
    errs.sort_by(f64::total_cmp);
    assert!(errs.len() > 1000, "{} interior pixels", errs.len());
    let median = errs[errs.len() / 2];
    assert!(median < 0.01, "median relative depth error {median:.4}");
    // Empty pixels: no colour, NaN depth.
    for i in (0..n).filter(|&i| !v.mask[i]) {
        assert!(v.depth[i].is_nan(), "pixel {i}: depth off the object");
        assert_eq!(&v.color[3 * i..3 * i + 3], &[0, 0, 0]);
    }
}
