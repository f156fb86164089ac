//! The tracker's tuning settings as `splattrack track` names them
//! ([`Tuning`], checked into a [`TrackerConfig`]), and the mode a run
//! takes when none is named ([`run_mode`]): shared by the command line
//! and the Python package, so that both track with the same settings.

use crate::tracker::{ConfigError, Mode, TrackerConfig};

/// Overrides of [`TrackerConfig`] defaults (unset: the default): the
/// tuning flags of `splattrack track`, each field named as its flag
/// (`harris_threshold` is `--harris-threshold`), and the keyword arguments
/// of the Python package under the same names.
#[derive(Debug, Clone, Default, PartialEq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct Tuning {
    /// Harris: keep corners whose response is at least this fraction of the
    /// largest one in the search region (default 0.003).
    #[cfg_attr(feature = "cli", arg(long))]
    pub harris_threshold: Option<f32>,
    /// Harris: at most this many corners per image (default 900).
    #[cfg_attr(feature = "cli", arg(long))]
    pub max_corners: Option<usize>,
    /// NCC: minimum score of a match (default 0.8).
    #[cfg_attr(feature = "cli", arg(long))]
    pub min_score: Option<f32>,
    /// NCC: window side, odd (default 9).
    #[cfg_attr(feature = "cli", arg(long))]
    pub ncc_window: Option<u32>,
    /// Frame-to-frame search radius, pixels (default 40).
    #[cfg_attr(feature = "cli", arg(long))]
    pub it_search: Option<f32>,
    /// Search radius against the novel view, pixels (default 24).
    #[cfg_attr(feature = "cli", arg(long))]
    pub kf_search: Option<f32>,
    /// Search radius when recovering a lost track, pixels (default 80).
    #[cfg_attr(feature = "cli", arg(long))]
    pub recover_search: Option<f32>,
    /// KF steps per frame (default 1).
    #[cfg_attr(feature = "cli", arg(long))]
    pub kf_iterations: Option<usize>,
    /// Gauss-Newton refinements after each linear solve (default 2).
    #[cfg_attr(feature = "cli", arg(long))]
    pub refine_iterations: Option<usize>,
    /// Margin around the object's projected bounding circle, pixels (default 24).
    #[cfg_attr(feature = "cli", arg(long))]
    pub roi_margin: Option<f64>,
    /// A step with fewer inliers than this is not trusted (default 8).
    #[cfg_attr(feature = "cli", arg(long))]
    pub min_inliers: Option<usize>,
    /// Inlier RMS residual above this: lost (default 3 px).
    #[cfg_attr(feature = "cli", arg(long))]
    pub max_residual: Option<f64>,
    /// Splat radii are raised to at least this many pixels (default 1; 0:
    /// the model's radii).
    #[cfg_attr(feature = "cli", arg(long))]
    pub min_splat_px: Option<f32>,
    /// Merge the model's points within cells of this many pixels at the
    /// initial pose's distance: faster on models denser than the camera
    /// resolves, at some cost in accuracy (default 0: every point; at most
    /// 16).
    #[cfg_attr(feature = "cli", arg(long))]
    pub detail_px: Option<f32>,
    /// Keep the model's splat radii where they leave gaps between splats
    /// (default: those radii grow just enough to close the gaps).
    #[cfg_attr(feature = "cli", arg(long))]
    pub keep_radii: bool,
    /// Harris and NCC: the fraction of a window that must be valid where it
    /// has pinholes (default 0.8; 1: any invalid pixel voids the window).
    #[cfg_attr(feature = "cli", arg(long))]
    pub min_valid: Option<f32>,
    /// KF+IT: frames in a row that IT alone may track when the KF step
    /// fails (default 5).
    #[cfg_attr(feature = "cli", arg(long))]
    pub max_it_only: Option<usize>,
    /// IT: only corners whose surroundings at this distance (pixels) are on
    /// the object (default 0: outline corners too; 4 helps IT on the real
    /// cube, hurts it on the synthetic box).
    #[cfg_attr(feature = "cli", arg(long))]
    pub it_interior: Option<f32>,
    /// Contour: most rounds per frame (default 4; the first searches long
    /// then short lines, the others short lines at the newest estimate).
    #[cfg_attr(feature = "cli", arg(long))]
    pub contour_rounds: Option<usize>,
    /// Contour: from the second round on, a round that moved the outline
    /// less than this (mean, pixels) ends the frame's step (default 0.25;
    /// 0: always --contour-rounds rounds).
    #[cfg_attr(feature = "cli", arg(long))]
    pub contour_converged: Option<f64>,
    /// Contour: one contour point per cell of this side, pixels (default 4).
    #[cfg_attr(feature = "cli", arg(long))]
    pub contour_spacing: Option<u32>,
    /// Contour: Levenberg-Marquardt damping, fraction of the diagonal
    /// (default 0: the silhouette of a smooth body constrains some motions
    /// weakly, and damping holds them back; 0.001 steadies the real dragon).
    #[cfg_attr(feature = "cli", arg(long))]
    pub contour_damping: Option<f64>,
    /// Contour: splat depth and normals for the silhouette, as before the
    /// depth-only renders (for comparison; about 3x the contour's GPU time).
    #[cfg_attr(feature = "cli", arg(long))]
    pub contour_full_render: bool,
    /// Contour: a later round moves the last render's points instead of
    /// rendering when no point moved more than this since (pixels, along
    /// its normal; default 1; 0 renders every round).
    #[cfg_attr(feature = "cli", arg(long))]
    pub contour_reproject: Option<f64>,
    /// Contour: colour histograms per sector of directions around the
    /// object (default 8; 0: one pair for the whole object).
    #[cfg_attr(feature = "cli", arg(long))]
    pub contour_sectors: Option<usize>,
    /// Contour: the first round always renders, instead of moving the
    /// points of the render held from the KF step (or the last contour
    /// render) when they moved little (for comparison).
    #[cfg_attr(feature = "cli", arg(long))]
    pub contour_no_seed: bool,
    /// The frame loop before windows and reuse, for comparison: render,
    /// detect and match over the whole image every time instead of the
    /// object's projected region, and render the IT step's view anew
    /// instead of taking the previous check's (the same poses up to f32
    /// rounding, slower).
    #[cfg_attr(feature = "cli", arg(long))]
    pub full_frame: bool,
}

impl Tuning {
    /// `base` with these overrides applied, checked by
    /// [`TrackerConfig::validate`]; a value out of range is named by its flag.
    pub fn apply(&self, mut c: TrackerConfig) -> Result<TrackerConfig, TuningError> {
        fn set<T: Copy>(field: &mut T, v: Option<T>) {
            if let Some(v) = v {
                *field = v;
            }
        }
        set(&mut c.harris.relative_threshold, self.harris_threshold);
        set(&mut c.harris.max_corners, self.max_corners);
        set(&mut c.ncc.min_score, self.min_score);
        set(&mut c.ncc.patch, self.ncc_window);
        set(&mut c.it_search_px, self.it_search);
        set(&mut c.kf_search_px, self.kf_search);
        set(&mut c.recover_search_px, self.recover_search);
        set(&mut c.kf_iterations, self.kf_iterations);
        set(&mut c.refine_iterations, self.refine_iterations);
        set(&mut c.roi_margin_px, self.roi_margin);
        set(&mut c.min_inliers, self.min_inliers);
        set(&mut c.max_residual_px, self.max_residual);
        set(&mut c.min_splat_radius_px, self.min_splat_px);
        set(&mut c.detail_px, self.detail_px);
        if self.keep_radii {
            c.close_gaps = false;
        }
        if let Some(v) = self.min_valid {
            if !(v > 0.0 && v <= 1.0) {
                return Err(TuningError::out_of_range("min-valid", v, "in (0, 1]"));
            }
            c.harris.min_valid_weight = v;
            c.ncc.min_valid = v;
        }
        set(&mut c.max_it_only_frames, self.max_it_only);
        set(&mut c.it_interior_px, self.it_interior);
        set(&mut c.contour.rounds, self.contour_rounds);
        set(&mut c.contour.converged_px, self.contour_converged);
        set(&mut c.contour.spacing_px, self.contour_spacing);
        set(&mut c.contour.damping, self.contour_damping);
        set(&mut c.contour.reproject_px, self.contour_reproject);
        set(&mut c.contour.sectors, self.contour_sectors);
        if self.contour_full_render {
            c.contour.depth_only = false;
        }
        if self.contour_no_seed {
            c.contour.seed_render = false;
        }
        if self.full_frame {
            c.windows = false;
        }
        if let Some(n) = self.max_corners {
            if !(1..=MAX_CORNERS).contains(&n) {
                return Err(TuningError::out_of_range(
                    "max-corners",
                    n,
                    &format!("1..={MAX_CORNERS}"),
                ));
            }
        }
        match c.validate() {
            Ok(()) => Ok(c),
            Err(ConfigError::OutOfRange { field, value, rule }) => {
                match FLAGS.iter().find(|(f, _)| *f == field) {
                    Some((_, flag)) => Err(TuningError::out_of_range(flag, value, rule)),
                    None => Err(TuningError::Config(format!(
                        "{field} = {value}: must be {rule}"
                    ))),
                }
            }
            Err(e) => Err(TuningError::Config(e.to_string())),
        }
    }
}

/// A tuning value out of its range, or impossible settings.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TuningError {
    /// The setting (named as its flag, without the dashes:
    /// `max-corners`) breaks its rule.
    #[error("--{setting} {value}: must be {rule}")]
    OutOfRange {
        /// The flag's name, e.g. `kf-search`.
        setting: &'static str,
        /// The value given, as its type prints it.
        value: String,
        /// What it must be, e.g. `>= 0`.
        rule: String,
    },
    /// Settings that [`TrackerConfig::validate`] refuses otherwise.
    #[error("tracker settings: {0}")]
    Config(String),
}

impl TuningError {
    fn out_of_range(setting: &'static str, value: impl ToString, rule: &str) -> Self {
        Self::OutOfRange {
            setting,
            value: value.to_string(),
            rule: rule.to_owned(),
        }
    }
}

/// The most corners per image the settings allow (a corner costs 16 bytes of
/// GPU memory and a share of every matching pass; a billion would ask for
/// a 16 GB buffer).
pub const MAX_CORNERS: usize = 100_000;

/// The flag of each [`TrackerConfig`] field that [`Tuning`] sets and
/// [`TrackerConfig::validate`] checks.
const FLAGS: [(&str, &str); 15] = [
    ("contour.rounds", "contour-rounds"),
    ("contour.sectors", "contour-sectors"),
    ("contour.converged_px", "contour-converged"),
    ("contour.reproject_px", "contour-reproject"),
    ("contour.spacing_px", "contour-spacing"),
    ("contour.damping", "contour-damping"),
    ("harris.relative_threshold", "harris-threshold"),
    ("it_search_px", "it-search"),
    ("kf_search_px", "kf-search"),
    ("recover_search_px", "recover-search"),
    ("roi_margin_px", "roi-margin"),
    ("max_residual_px", "max-residual"),
    ("min_splat_radius_px", "min-splat-px"),
    ("detail_px", "detail-px"),
    ("it_interior_px", "it-interior"),
];

/// The mode of a run: `asked`, else kf+it where there is a texture for
/// the KF step's views (`textured`: keyframes or model colours) and it
/// (frame to frame) where there is none. `Err` with the mode asked for
/// when it is a KF mode without a texture.
pub fn run_mode(asked: Option<Mode>, textured: bool) -> Result<Mode, Mode> {
    match asked {
        Some(m) if m != Mode::It && !textured => Err(m),
        Some(m) => Ok(m),
        None if textured => Ok(Mode::KfIt),
        None => Ok(Mode::It),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tuning_overrides_only_what_is_given() {
        let base = TrackerConfig::default();
        let same = Tuning::default().apply(base.clone()).unwrap();
        assert_eq!(same.kf_search_px, base.kf_search_px);
        assert_eq!(
            same.harris.relative_threshold,
            base.harris.relative_threshold
        );
        let t = Tuning {
            harris_threshold: Some(0.001),
            kf_search: Some(16.0),
            kf_iterations: Some(2),
            min_splat_px: Some(0.0),
            max_it_only: Some(0),
            it_interior: Some(4.0),
            keep_radii: true,
            min_valid: Some(0.8),
            ..Default::default()
        };
        assert!(same.close_gaps);
        let c = t.apply(base).unwrap();
        assert!(!c.close_gaps);
        assert_eq!((c.ncc.min_valid, c.harris.min_valid_weight), (0.8, 0.8));
        assert_eq!(c.harris.relative_threshold, 0.001);
        assert_eq!(c.kf_search_px, 16.0);
        assert_eq!(c.kf_iterations, 2);
        assert_eq!(c.min_splat_radius_px, 0.0);
        assert_eq!(c.max_it_only_frames, 0);
        assert_eq!(c.it_interior_px, 4.0);
    }

    #[test]
    fn tuning_refuses_impossible_values() {
        let bad = [
            Tuning {
                harris_threshold: Some(0.0),
                ..Default::default()
            },
            Tuning {
                kf_search: Some(f32::NAN),
                ..Default::default()
            },
            Tuning {
                min_score: Some(1.5),
                ..Default::default()
            },
            Tuning {
                ncc_window: Some(8),
                ..Default::default()
            },
            Tuning {
                max_residual: Some(-1.0),
                ..Default::default()
            },
            Tuning {
                min_splat_px: Some(f32::INFINITY),
                ..Default::default()
            },
            Tuning {
                min_valid: Some(0.0),
                ..Default::default()
            },
            Tuning {
                min_valid: Some(f32::NAN),
                ..Default::default()
            },
        ];
        for t in bad {
            assert!(t.apply(TrackerConfig::default()).is_err(), "{t:?}");
        }
    }
}
