//! Known-answer tests of the PnP solvers: random poses and points, planar and
//! not, exact, noisy and with outliers, and every kind of bad input.

use super::*;
use crate::geometry::rotation_exp;

fn cam() -> Intrinsics {
    Intrinsics::new(640, 480, 600.0, 610.0, 320.0, 240.0)
}

/// A pose looking at the origin from 0.4-1.2 m, tilted by at most `max_angle`
/// radians (so that a plane z = 0 is never seen edge-on).
fn random_pose(rng: &mut Rng, max_angle: f64) -> Pose {
    let axis = rng.unit_vector();
    let r = rotation_exp(&(axis * rng.uniform(0.0, max_angle)));
    let t = Vector3::new(
        rng.uniform(-0.05, 0.05),
        rng.uniform(-0.05, 0.05),
        rng.uniform(0.4, 1.2),
    );
    Pose {
        rotation: r,
        translation: t,
    }
}

fn random_points(rng: &mut Rng, n: usize, planar: bool) -> Vec<Vector3<f64>> {
    (0..n)
        .map(|_| {
            let z = if planar { 0.0 } else { rng.uniform(-0.1, 0.1) };
            Vector3::new(rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), z)
        })
        .collect()
}

fn project(pose: &Pose, pts: &[Vector3<f64>], noise: f64, rng: &mut Rng) -> Vec<Vector2<f64>> {
    pts.iter()
        .map(|p| {
            cam().project(&pose.transform_point(p)).unwrap()
                + Vector2::new(rng.normal(), rng.normal()) * noise
        })
        .collect()
}

#[test]
fn exact_pixels_give_the_pose_planar_or_not() {
    let mut rng = Rng::new(1);
    for trial in 0..60 {
        let planar = trial % 2 == 1;
        let n = [4, 5, 6, 8, 12, 40][trial % 6];
        let gt = random_pose(&mut rng, if planar { 1.0 } else { 3.0 });
        let pts = random_points(&mut rng, n, planar);
        let pix = project(&gt, &pts, 0.0, &mut rng);
        let s = solve_pnp(&pts, &pix, &cam()).unwrap();
        let dr = (s.pose.rotation - gt.rotation).amax();
        let dt = (s.pose.translation - gt.translation).amax();
        assert!(
            dr < 1e-6 && dt < 1e-6,
            "trial {trial} n {n} planar {planar}: dR {dr:e} dt {dt:e}"
        );
        assert!(s.rms_px < 1e-6, "{}", s.rms_px);
        assert_eq!(s.inliers, (0..n).collect::<Vec<_>>());
    }
}

#[test]
fn one_pixel_of_noise_moves_the_pose_little() {
    let mut rng = Rng::new(2);
    let mut sum_dr = 0.0;
    for trial in 0..30 {
        let planar = trial % 2 == 0;
        let gt = random_pose(&mut rng, if planar { 1.0 } else { 3.0 });
        let pts = random_points(&mut rng, 30, planar);
        let pix = project(&gt, &pts, 1.0, &mut rng);
        let s = solve_pnp(&pts, &pix, &cam()).unwrap();
        let dr = s.pose.rotation_error_deg(&gt);
        let dt = s.pose.translation_error(&gt) / gt.translation.norm();
        // The solver finds the least-squares optimum: it fits at least as
        // well as the true pose (which a far, small planar target can leave
        // a few degrees away, inside the noise).
        let at_gt = reprojection_errors(&gt, &pts, &pix, &cam());
        let rms_gt = (at_gt.iter().map(|e| e * e).sum::<f64>() / 30.0).sqrt();
        assert!(s.rms_px <= rms_gt + 1e-9, "{} > {rms_gt}", s.rms_px);
        assert!(dr < 8.0 && dt < 0.03, "trial {trial}: {dr} deg, {dt}");
        sum_dr += dr;
        // 2-D noise of 1 px per axis: an RMS of sqrt(2 (60 - 6) / 60) px,
        // as the fit absorbs 6 of the 60 degrees of freedom.
        assert!(s.rms_px > 0.95 && s.rms_px < 1.75, "{}", s.rms_px);
    }
    assert!(sum_dr / 30.0 < 1.5, "mean {} deg", sum_dr / 30.0);
}

#[test]
fn ransac_recovers_pose_and_inliers_with_half_outliers() {
    let mut rng = Rng::new(3);
    for trial in 0..10 {
        let planar = trial % 2 == 0;
        let gt = random_pose(&mut rng, if planar { 1.0 } else { 3.0 });
        let n = 60;
        let pts = random_points(&mut rng, n, planar);
        let mut pix = project(&gt, &pts, 0.5, &mut rng);
        let mut truth = Vec::new();
        for (i, q) in pix.iter_mut().enumerate() {
            if i % 2 == 0 {
                // An outlier far from its true projection.
                loop {
                    let r = Vector2::new(rng.uniform(0.0, 640.0), rng.uniform(0.0, 480.0));
                    if (r - *q).norm() > 20.0 {
                        *q = r;
                        break;
                    }
                }
            } else {
                truth.push(i);
            }
        }
        let opts = PnpRansacOptions {
            seed: trial as u64,
            ..Default::default()
        };
        let s = solve_pnp_ransac(&pts, &pix, &cam(), &opts).unwrap();
        assert_eq!(s.inliers, truth, "trial {trial}");
        let dr = s.pose.rotation_error_deg(&gt);
        let dt = s.pose.translation_error(&gt) / gt.translation.norm();
        assert!(dr < 2.0 && dt < 0.03, "trial {trial}: {dr} deg, {dt}");
        assert!(s.rms_px < 1.0, "{}", s.rms_px);
        // The refinement reaches the least-squares pose of the true inliers.
        let pts_in: Vec<_> = truth.iter().map(|&i| pts[i]).collect();
        let pix_in: Vec<_> = truth.iter().map(|&i| pix[i]).collect();
        let ls = solve_pnp(&pts_in, &pix_in, &cam()).unwrap();
        assert!((ls.pose.rotation - s.pose.rotation).amax() < 1e-6);
        assert!((ls.pose.translation - s.pose.translation).amax() < 1e-6);
        assert!((ls.rms_px - s.rms_px).abs() < 1e-6);
        // Exact inliers: the pose to rounding.
        let exact = project(&gt, &pts, 0.0, &mut rng);
        let mut pix2 = pix.clone();
        for &i in &truth {
            pix2[i] = exact[i];
        }
        let s = solve_pnp_ransac(&pts, &pix2, &cam(), &opts).unwrap();
        assert!((s.pose.rotation - gt.rotation).amax() < 1e-6);
        assert!((s.pose.translation - gt.translation).amax() < 1e-6);
    }
}

#[test]
fn ransac_without_consensus_is_an_error() {
    let mut rng = Rng::new(4);
    let pts = random_points(&mut rng, 30, false);
    let pix: Vec<Vector2<f64>> = (0..30)
        .map(|_| Vector2::new(rng.uniform(0.0, 640.0), rng.uniform(0.0, 480.0)))
        .collect();
    let opts = PnpRansacOptions {
        min_inliers: 10,
        threshold_px: 2.0,
        ..Default::default()
    };
    match solve_pnp_ransac(&pts, &pix, &cam(), &opts) {
        Err(PnpError::NoConsensus { best, total, .. }) => assert!(best < 10 && total == 30),
        other => panic!("{other:?}"),
    }
}

#[test]
fn distorted_pixels_are_undistorted_first() {
    let mut rng = Rng::new(5);
    let mut c = cam();
    c.distortion = [-0.2, 0.05, 0.001, -0.001, 0.0];
    let gt = random_pose(&mut rng, 2.0);
    let pts = random_points(&mut rng, 10, false);
    let pix: Vec<Vector2<f64>> = project(&gt, &pts, 0.0, &mut rng)
        .into_iter()
        .map(|q| c.distort_pixel(q))
        .collect();
    let s = solve_pnp(&pts, &pix, &c).unwrap();
    assert!((s.pose.rotation - gt.rotation).amax() < 1e-6);
    assert!(
        reprojection_errors(&s.pose, &pts, &pix, &c)
            .iter()
            .all(|&e| e < 1e-6)
    );
}

#[test]
fn bad_input_is_a_typed_error() {
    let mut rng = Rng::new(6);
    let gt = random_pose(&mut rng, 1.0);
    let pts = random_points(&mut rng, 8, false);
    let pix = project(&gt, &pts, 0.0, &mut rng);
    let opts = PnpRansacOptions::default();
    let both = |p: &[Vector3<f64>], q: &[Vector2<f64>]| {
        [
            solve_pnp(p, q, &cam()).err(),
            solve_pnp_ransac(p, q, &cam(), &opts).err(),
        ]
    };
    for e in both(&pts[..3], &pix[..3]) {
        assert_eq!(e, Some(PnpError::TooFewPoints { got: 3, need: 4 }));
    }
    for e in both(&pts, &pix[..7]) {
        assert!(matches!(e, Some(PnpError::LengthMismatch { .. })));
    }
    let mut nan = pix.clone();
    nan[5].x = f64::NAN;
    for e in both(&pts, &nan) {
        assert_eq!(e, Some(PnpError::NonFinite { index: 5 }));
    }
    let mut inf = pts.clone();
    inf[2].z = f64::INFINITY;
    for e in both(&inf, &pix) {
        assert_eq!(e, Some(PnpError::NonFinite { index: 2 }));
    }
    let line: Vec<Vector3<f64>> = (0..8)
        .map(|i| Vector3::new(0.1, -0.2, 0.3) * (i as f64 * 0.1))
        .collect();
    let line_pix = project(&gt, &line, 0.0, &mut rng);
    for e in both(&line, &line_pix) {
        assert_eq!(e, Some(PnpError::Degenerate("collinear model points")));
    }
    let same = vec![Vector3::new(0.01, 0.02, 0.03); 8];
    for e in both(&same, &pix) {
        assert_eq!(e, Some(PnpError::Degenerate("coincident model points")));
    }
    let mut bad_cam = cam();
    bad_cam.fx = 0.0;
    assert!(matches!(
        solve_pnp(&pts, &pix, &bad_cam),
        Err(PnpError::Camera(_))
    ));
    // Pixels in one place or on one line fix no pose.
    let one = vec![Vector2::new(100.0, 100.0); 8];
    for e in both(&pts, &one) {
        assert_eq!(e, Some(PnpError::Degenerate("coincident pixels")));
    }
    let row: Vec<Vector2<f64>> = (0..8)
        .map(|i| Vector2::new(50.0 * i as f64, 200.0))
        .collect();
    for e in both(&pts, &row) {
        assert_eq!(e, Some(PnpError::Degenerate("collinear pixels")));
    }
}

#[test]
fn arbitrary_input_never_panics() {
    let mut rng = Rng::new(7);
    let opts = PnpRansacOptions {
        iterations: 200,
        ..Default::default()
    };
    for trial in 0..150 {
        let n = 4 + rng.below(12) as usize;
        let scale = [1e-9, 1e-3, 1.0, 1e6][trial % 4];
        let pts: Vec<Vector3<f64>> = (0..n)
            .map(|_| {
                let v = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * scale;
                // Some points repeated, some on a line.
                if rng.below(4) == 0 {
                    Vector3::zeros()
                } else {
                    v
                }
            })
            .collect();
        let pix: Vec<Vector2<f64>> = (0..n)
            .map(|_| Vector2::new(rng.uniform(-1e4, 1e4), rng.uniform(-10.0, 500.0)))
            .collect();
        let results = [
            solve_pnp(&pts, &pix, &cam()),
            solve_pnp_ransac(&pts, &pix, &cam(), &opts),
        ];
        // Errors are fine; a solution must be a real pose.
        for s in results.into_iter().flatten() {
            assert!(s.pose.validate().is_ok() && s.rms_px.is_finite());
            assert!(s.inliers.len() >= 4 && s.inliers.iter().all(|&i| i < n));
        }
    }
}
