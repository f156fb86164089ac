//! What both ways of giving points share: the fit and its refusal, the
//! report, and the overlay.

use anyhow::{Context, bail};
use image::RgbImage;
use splattrack::draw;
use splattrack::geometry::{Intrinsics, Undistorter};
use splattrack::io::correspondences::PointPair;
use splattrack::pose::{
    PnpRansacOptions, PnpSolution, reprojection_errors, solve_pnp, solve_pnp_ransac,
};
use splattrack::splat::{Attribute, GpuModel, Splatter};
use splattrack::{GpuContext, PointModel};

/// A solved and accepted pose, with what the report and overlay show.
pub struct Fit {
    pub solution: PnpSolution,
    /// Reprojection error of every pair, pixels.
    pub errors: Vec<f64>,
}

/// Solves the pose of `pairs` (from `source`, for messages): all points by
/// least squares up to 6, RANSAC beyond; refused with the reason when the
/// points are too few or degenerate, or the fit is worse than `max_rms`.
pub fn fit(
    pairs: &[PointPair],
    cam: &Intrinsics,
    max_rms: f64,
    threshold: f64,
    source: &str,
) -> anyhow::Result<Fit> {
    let points: Vec<_> = pairs.iter().map(|p| p.point).collect();
    let pixels: Vec<_> = pairs.iter().map(|p| p.pixel).collect();
    let solution = if pairs.len() > 6 {
        let opts = PnpRansacOptions {
            threshold_px: threshold,
            min_inliers: (pairs.len() / 2 + 1).max(5),
            iterations: 5000,
            ..Default::default()
        };
        solve_pnp_ransac(&points, &pixels, cam, &opts)
    } else {
        solve_pnp(&points, &pixels, cam)
    }
    .with_context(|| format!("{source}: no pose"))?;
    let errors = reprojection_errors(&solution.pose, &points, &pixels, cam);
    if solution.rms_px.is_nan() || solution.rms_px > max_rms {
        let worst = solution
            .inliers
            .iter()
            .copied()
            .max_by(|&a, &b| errors[a].total_cmp(&errors[b]))
            .unwrap_or(0);
        bail!(
            "{source}: the reprojection RMS is {:.2} px, more than --max-rms {max_rms} px \
             (worst: point {} at {:.2} px): the points and their pixels disagree",
            solution.rms_px,
            pairs[worst].name,
            errors[worst]
        );
    }
    Ok(Fit { solution, errors })
}

/// One line a point (name, pixel, reprojection error, outliers marked),
/// then the RMS.
pub fn report(pairs: &[PointPair], fit: &Fit) -> Vec<String> {
    let mut lines = vec![format!(
        "{:<16} {:>9} {:>9} {:>9} {:>9}",
        "point", "u", "v", "error_px", ""
    )];
    for (i, p) in pairs.iter().enumerate() {
        let outlier = !fit.solution.inliers.contains(&i);
        lines.push(format!(
            "{:<16} {:>9.2} {:>9.2} {:>9.2} {:>9}",
            p.name,
            p.pixel.x,
            p.pixel.y,
            fit.errors[i],
            if outlier { "outlier" } else { "" }
        ));
    }
    let outliers: Vec<&str> = (0..pairs.len())
        .filter(|i| !fit.solution.inliers.contains(i))
        .map(|i| pairs[i].name.as_str())
        .collect();
    lines.push(format!(
        "RMS {:.2} px over {} of {} points{}",
        fit.solution.rms_px,
        fit.solution.inliers.len(),
        pairs.len(),
        if outliers.is_empty() {
            String::new()
        } else {
            format!("; left out as outliers: {}", outliers.join(", "))
        }
    ));
    lines
}

/// What the overlay draws the model with: its silhouette at a pose
/// (splatted), or, without a GPU, its points projected.
pub struct ModelView<'a> {
    model: &'a PointModel,
    gpu: Option<(GpuContext, GpuModel, Splatter)>,
}

impl<'a> ModelView<'a> {
    /// Uses the GPU when one opens; warns and projects points otherwise.
    pub fn new(model: &'a PointModel, target: &crate::cli::common::Target) -> Self {
        let gpu = (|| -> anyhow::Result<_> {
            let ctx = crate::cli::common::gpu(target, "init's views")?;
            let splatter = Splatter::new(&ctx)?;
            let gm = GpuModel::new(&ctx, model)?;
            Ok((ctx, gm, splatter))
        })();
        let gpu = match gpu {
            Ok(g) => Some(g),
            Err(e) => {
                log::warn!("no GPU for the overlay's silhouette ({e:#}); drawing points instead");
                None
            }
        };
        Self { model, gpu }
    }

    /// The context, for the click window.
    #[cfg(feature = "view")]
    pub fn context(&self) -> Option<&GpuContext> {
        self.gpu.as_ref().map(|g| &g.0)
    }

    /// The overlay of `fit` on `frame` (as the camera took it: undistorted
    /// here, with the pixels).
    pub fn overlay(
        &self,
        frame: &RgbImage,
        cam: &Intrinsics,
        pairs: &[PointPair],
        fit: &Fit,
    ) -> anyhow::Result<RgbImage> {
        let ideal = cam.undistorted();
        let pose = &fit.solution.pose;
        let mut img = if cam.has_distortion() {
            Undistorter::new(cam)
                .apply(frame)
                .map_err(|e| anyhow::anyhow!("undistorting the frame: {e}"))?
        } else {
            frame.clone()
        };
        const MODEL: draw::Colour = [40, 230, 60];
        match &self.gpu {
            Some((ctx, gm, splatter)) => {
                // Covered pixels, as the tracker's silhouette counts them.
                let weight = splatter
                    .render_image(ctx, gm, &ideal, pose, Attribute::Weight)
                    .context("splatting the model for the overlay")?;
                let mut mask: Vec<bool> = weight.data.iter().map(|&w| w > 0.0).collect();
                fill_pinholes(&mut mask, ideal.width as usize);
                draw::silhouette(&mut img, &mask, MODEL);
            }
            None => {
                let step = (self.model.len() / 20_000).max(1);
                for p in self.model.positions.iter().step_by(step) {
                    let x = nalgebra::Vector3::new(p.x as f64, p.y as f64, p.z as f64);
                    if let Some(q) = ideal.project(&pose.transform_point(&x)) {
                        draw::blend(&mut img, q.x.round() as i64, q.y.round() as i64, MODEL, 0.6);
                    }
                }
            }
        }
        for (i, p) in pairs.iter().enumerate() {
            let given = if cam.has_distortion() {
                cam.undistort_pixel(p.pixel)
            } else {
                p.pixel
            };
            let inlier = fit.solution.inliers.contains(&i);
            let colour = if inlier {
                splattrack::view::clicks::CLICK_COLOUR
            } else {
                [240, 40, 40]
            };
            if let Some(r) = ideal.project(&pose.transform_point(&p.point)) {
                draw::line(&mut img, given.x, given.y, r.x, r.y, colour, 1.0);
                draw::circle(&mut img, r.x, r.y, 4.0, [0, 200, 255]);
            }
            let name = format!("{} {:.1}px", p.name, fit.errors[i]);
            splattrack::view::clicks::mark(&mut img, given, colour, &name);
        }
        let text = format!(
            "init: RMS {:.2} px, {} of {} points",
            fit.solution.rms_px,
            fit.solution.inliers.len(),
            pairs.len()
        );
        draw::label(&mut img, 6, 6, &text, draw::WHITE, draw::BLACK, 1);
        Ok(img)
    }
}

/// Covers the uncovered pixels that at least three of their four
/// neighbours cover: the splatting's pinholes would each draw as a bit of
/// outline inside the silhouette.
fn fill_pinholes(mask: &mut [bool], w: usize) {
    let h = mask.len() / w.max(1);
    let src = mask.to_vec();
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let i = y * w + x;
            let around = [i - 1, i + 1, i - w, i + w]
                .iter()
                .filter(|&&j| src[j])
                .count();
            if !src[i] && around >= 3 {
                mask[i] = true;
            }
        }
    }
}
