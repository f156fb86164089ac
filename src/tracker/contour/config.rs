//! Settings of the contour modality.

use crate::tracker::error::ConfigError;

/// Settings of the contour modality.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct ContourConfig {
    /// Half-length of the search lines, pixels, one entry per iteration
    /// (coarse to fine).
    pub search_px: Vec<f32>,
    /// Lines are this many times longer when the contour starts without a
    /// trusted texture estimate (contour alone, a failed texture step, or
    /// recovering).
    pub long_factor: f32,
    /// One contour point per cell of this side, pixels.
    pub spacing_px: u32,
    /// Colour histogram bins per channel.
    pub bins: u32,
    /// Weight of the newest frame in the online colour histograms.
    pub learning_rate: f32,
    /// Pixels this close to the outline (either side) are not learnt.
    pub learn_margin_px: usize,
    /// The splatted silhouette is this much wider than the object, pixels
    /// (the splatter's 0.75 px low-pass disc around each splat): contour
    /// points are moved this far inward. On limbs (a surface seen edge-on
    /// at the outline) and where the surface normal is unknown; on creases
    /// (a face that ends at the outline) the inset follows from the
    /// splats' size there ([`super::crease_inset`]).
    pub inset_px: f64,
    /// Drop the contour points whose window is not one straight edge (a
    /// corner of the outline, which the covered fraction places inside
    /// it: [`super::straight_edges`]). Off by default: on the untextured
    /// box it moved the depth by 0.14 mm (of a 0.64 mm bias), but on the
    /// real dragon's detailed outline it dropped points the fit needed
    /// (2.51 against 1.89 degrees mean, fused with texture).
    pub drop_corners: bool,
    /// Width of the smooth step of the line model, pixels.
    pub slope_px: f32,
    /// Fewer usable contour points than this: the step fails.
    pub min_points: usize,
    /// Most rounds per frame, each a render (or the last render's points
    /// moved, [`Self::reproject_px`]), line searches and a solve: the
    /// first searches every line length of `search_px`, later ones (at the
    /// newest estimate) the finest only.
    pub rounds: usize,
    /// From the second round on, a round whose correction moved the
    /// contour points less than this along their normals (mean, pixels)
    /// ends the step: a frame whose pose has converged stops, one that
    /// moved far (the first estimate linearised too far from it) searches
    /// again, up to [`Self::rounds`]. 0: always `rounds` rounds.
    pub converged_px: f64,
    /// Levenberg-Marquardt damping of each solve, as a fraction of the
    /// normal matrix's diagonal: it keeps a motion the silhouette hardly
    /// sees (a rotation of a nearly symmetric outline) from jumping, but
    /// holds it back where the object really makes it (0 by default: 0.01
    /// left the synthetic `plain` object 26 degrees behind its tilt).
    pub damping: f64,
    /// [`Self::damping`] when the step refines a trusted KF estimate, fused
    /// with its matches: it holds the fused solve near that estimate, so that the
    /// outline refines a textured object's pose instead of pulling it
    /// (the real cube fused: 1.01 degrees undamped, 0.50 at 0.1, against
    /// 0.35 with texture alone; 1 spoils the real dragon).
    pub fused_damping: f64,
    /// Damping of a second contour step, from the previous pose, on a
    /// frame whose undamped contour pose failed the check while no texture
    /// step was trusted (0: no second step). A box's silhouette leaves a
    /// turn about the vertical and a move along the ray nearly unseen: the
    /// real cube's CAD mesh, partly hidden by a hand, drifted along it by
    /// 5 to 48 degrees undamped (37 of 99 frames lost), and at 0.003 is
    /// tracked throughout. Only frames that would be lost take it, so an
    /// object whose undamped steps pass keeps following motions the
    /// silhouette hardly sees (the `plain` object's tilt).
    pub retry_damping: f64,
    /// Whether a trusted KF step is refined by the contour (fused with its
    /// matches); else the contour runs only where the KF step fails. Off,
    /// the real cube keeps texture's 0.34 degrees but the real dragon,
    /// whose few trusted KF steps are wrong, goes from 3.3 to 10.7.
    pub refine_texture: bool,
    /// Fewer contour inliers than this fraction of the usable points: the
    /// step fails (the silhouette does not fit the frame).
    pub min_inlier_fraction: f64,
    /// Whether the contour's renders are depth-only
    /// ([`crate::splat::Splatter::render_depth`]: the visibility pass
    /// alone, a third of a depth and normal render), the limb normals then
    /// taken from the model's points ([`super::ModelNormals`]); else depth and
    /// normals are splatted (the former way, for comparison).
    pub depth_only: bool,
    /// A later round moves the last render's contour points to the newest
    /// estimate (lifted to 3-D at their depth, projected again) instead of
    /// rendering, when no point's normal motion since that render exceeds
    /// this many pixels (0: always render). After a small correction the
    /// outline is nearly the same points of the surface; keeping them also
    /// keeps the points' sampling of the frame (a new render picks other
    /// pixels of the outline, whose line noise moves the weakly seen
    /// rotations; docs/contour.md: the real dragon fused 98.8% to 100%).
    pub reproject_px: f64,
    /// Sectors of directions around the object's projected centre, each
    /// with its own colour histograms (learnt from the pixels in its
    /// directions, its lines weighed with them): what lies behind an object
    /// changes along its outline. 0: one pair of histograms for the whole
    /// object (docs/contour.md: measured 0, 4, 6, 8, 12).
    pub sectors: usize,
    /// Whether a render the targets already hold near the step's start
    /// (the KF step's novel view, whose depth comes from its predictors;
    /// or the last contour render) stands for the first round's render:
    /// its points are moved to the start as a later round's are (same
    /// [`Self::reproject_px`] test), and the round renders only when they
    /// moved too far. Off: the first round always renders.
    pub seed_render: bool,
}

impl Default for ContourConfig {
    fn default() -> Self {
        Self {
            search_px: vec![16.0, 8.0, 5.0],
            long_factor: 2.0,
            spacing_px: 4,
            bins: 16,
            learning_rate: 0.2,
            learn_margin_px: 2,
            inset_px: 0.65,
            drop_corners: false,
            slope_px: 1.0,
            min_points: 24,
            rounds: 4,
            converged_px: 0.25,
            damping: 0.0,
            fused_damping: 0.1,
            retry_damping: 0.003,
            refine_texture: true,
            min_inlier_fraction: 0.5,
            depth_only: true,
            reproject_px: 1.0,
            seed_render: true,
            sectors: 8,
        }
    }
}

impl ContourConfig {
    /// Checks the ranges (part of [`crate::tracker::TrackerConfig::validate`]).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |field, value: String, rule| Err(ConfigError::OutOfRange { field, value, rule });
        if self.search_px.is_empty()
            || self
                .search_px
                .iter()
                .any(|v| !(v.is_finite() && *v >= 2.0 && *v <= 200.0))
        {
            return bad(
                "contour.search_px",
                format!("{:?}", self.search_px),
                "a non-empty list of half-lengths in [2, 200]",
            );
        }
        if !(self.long_factor.is_finite() && (1.0..=10.0).contains(&self.long_factor)) {
            return bad(
                "contour.long_factor",
                self.long_factor.to_string(),
                "in [1, 10]",
            );
        }
        if !(1..=256).contains(&self.spacing_px) {
            return bad(
                "contour.spacing_px",
                self.spacing_px.to_string(),
                "in [1, 256]",
            );
        }
        if !(2..=64).contains(&self.bins) {
            return bad("contour.bins", self.bins.to_string(), "in [2, 64]");
        }
        if !(self.learning_rate > 0.0 && self.learning_rate <= 1.0) {
            return bad(
                "contour.learning_rate",
                self.learning_rate.to_string(),
                "in (0, 1]",
            );
        }
        if !(self.inset_px.is_finite() && (-2.0..=2.0).contains(&self.inset_px)) {
            return bad("contour.inset_px", self.inset_px.to_string(), "in [-2, 2]");
        }
        if self.learn_margin_px > 32 {
            return bad(
                "contour.learn_margin_px",
                self.learn_margin_px.to_string(),
                "in [0, 32]",
            );
        }
        if !(self.slope_px.is_finite() && self.slope_px > 0.0) {
            return bad("contour.slope_px", self.slope_px.to_string(), "> 0");
        }
        if self.sectors > 64 {
            return bad("contour.sectors", self.sectors.to_string(), "in [0, 64]");
        }
        if !(1..=10).contains(&self.rounds) {
            return bad("contour.rounds", self.rounds.to_string(), "in [1, 10]");
        }
        if !(self.converged_px.is_finite() && self.converged_px >= 0.0) {
            return bad(
                "contour.converged_px",
                self.converged_px.to_string(),
                ">= 0",
            );
        }
        if !(self.damping.is_finite() && self.damping >= 0.0) {
            return bad("contour.damping", self.damping.to_string(), ">= 0");
        }
        if !(self.fused_damping.is_finite() && self.fused_damping >= 0.0) {
            return bad(
                "contour.fused_damping",
                self.fused_damping.to_string(),
                ">= 0",
            );
        }
        if !(self.retry_damping.is_finite() && self.retry_damping >= 0.0) {
            return bad(
                "contour.retry_damping",
                self.retry_damping.to_string(),
                ">= 0",
            );
        }
        if !(self.reproject_px.is_finite() && (0.0..=100.0).contains(&self.reproject_px)) {
            return bad(
                "contour.reproject_px",
                self.reproject_px.to_string(),
                "in [0, 100]",
            );
        }
        if !(0.0..=1.0).contains(&self.min_inlier_fraction) {
            return bad(
                "contour.min_inlier_fraction",
                self.min_inlier_fraction.to_string(),
                "in [0, 1]",
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_rules_name_their_field() {
        ContourConfig::default().validate().unwrap();
        let c = ContourConfig {
            search_px: vec![],
            ..Default::default()
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("contour.search_px")
        );
        for (c, field) in [
            (
                ContourConfig {
                    inset_px: f64::NAN,
                    ..Default::default()
                },
                "contour.inset_px",
            ),
            (
                ContourConfig {
                    fused_damping: -1.0,
                    ..Default::default()
                },
                "contour.fused_damping",
            ),
            (
                ContourConfig {
                    learn_margin_px: 100,
                    ..Default::default()
                },
                "contour.learn_margin_px",
            ),
            (
                ContourConfig {
                    reproject_px: f64::NAN,
                    ..Default::default()
                },
                "contour.reproject_px",
            ),
            (
                ContourConfig {
                    sectors: 65,
                    ..Default::default()
                },
                "contour.sectors",
            ),
        ] {
            assert!(c.validate().unwrap_err().to_string().contains(field));
        }
        let c = ContourConfig {
            bins: 1,
            ..Default::default()
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("contour.bins")
        );
    }
}
