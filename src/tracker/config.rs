//! Tracker settings: which tracker runs ([`Mode`]) and everything it is
//! tuned by ([`TrackerConfig`]), checked by [`TrackerConfig::validate`].

use super::error::ConfigError;
use crate::features::{HarrisConfig, NccConfig};
use crate::pose::IrlsConfig;
use std::fmt;

/// Which of the paper's trackers runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Mode {
    /// Frame to frame only: smooth, but drifts.
    #[cfg_attr(feature = "cli", value(name = "it"))]
    #[serde(rename = "it")]
    It,
    /// Against keyframe-textured novel views only: no drift, but jitter.
    #[cfg_attr(feature = "cli", value(name = "kf"))]
    #[serde(rename = "kf")]
    Kf,
    /// IT, then KF from the IT estimate (the paper's hybrid).
    #[default]
    #[cfg_attr(feature = "cli", value(name = "kf+it", aliases = ["kfit", "it+kf", "hybrid"]))]
    #[serde(rename = "kf+it", alias = "kfit", alias = "it+kf", alias = "hybrid")]
    KfIt,
}

impl Mode {
    /// The three modes, in the order the demo and the tables list them.
    pub const ALL: [Mode; 3] = [Mode::It, Mode::Kf, Mode::KfIt];

    /// The name used on the command line and in tables (`it`, `kf`,
    /// `kf+it`); [`str::parse`] accepts it back.
    pub fn name(&self) -> &'static str {
        match self {
            Mode::It => "it",
            Mode::Kf => "kf",
            Mode::KfIt => "kf+it",
        }
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Mode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "it" => Ok(Mode::It),
            "kf" => Ok(Mode::Kf),
            "kf+it" | "kfit" | "it+kf" | "hybrid" => Ok(Mode::KfIt),
            _ => Err(format!("unknown mode {s:?} (use kf+it, it or kf)")),
        }
    }
}

/// Which cues of the object the tracker uses: texture (Harris corners
/// matched by NCC: the IT and KF steps) and/or the contour (the splatted
/// silhouette searched for along its normals, [`super::contour`]). Written
/// `texture`, `contour` or `texture,contour` on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Modalities {
    /// Corners and NCC (the paper's IT and KF steps).
    pub texture: bool,
    /// The silhouette.
    pub contour: bool,
}

impl Modalities {
    /// Texture only (the paper's tracker).
    pub const TEXTURE: Self = Self {
        texture: true,
        contour: false,
    };
    /// Contour only.
    pub const CONTOUR: Self = Self {
        texture: false,
        contour: true,
    };
    /// Both, in one robust solve.
    pub const BOTH: Self = Self {
        texture: true,
        contour: true,
    };
    /// Neither (what held a lost frame: [`super::TrackResult::cues`]).
    pub const NONE: Self = Self {
        texture: false,
        contour: false,
    };

    /// `texture`, `contour` or `texture,contour`.
    pub fn name(&self) -> &'static str {
        match (self.texture, self.contour) {
            (true, false) => "texture",
            (false, true) => "contour",
            (true, true) => "texture,contour",
            (false, false) => "none",
        }
    }
}

impl Default for Modalities {
    /// Texture only: on the textured real cube the fused contour costs
    /// accuracy (0.50 against 0.35 degrees), while on the weakly textured
    /// objects texture alone loses the track (docs/contour.md: use
    /// `contour` or `texture,contour` there).
    fn default() -> Self {
        Self::TEXTURE
    }
}

impl fmt::Display for Modalities {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Modalities {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let mut m = Self {
            texture: false,
            contour: false,
        };
        for part in s.split([',', '+']) {
            match part.trim().to_ascii_lowercase().as_str() {
                "texture" => m.texture = true,
                "contour" => m.contour = true,
                other => {
                    return Err(format!(
                        "unknown modality {other:?} (use texture, contour or texture,contour)"
                    ));
                }
            }
        }
        Ok(m)
    }
}

/// What the automatic choice of cues measured and chose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CueChoice {
    /// The modalities chosen.
    pub modalities: Modalities,
    /// Whether there was a texture for the views (keyframes or model
    /// colours).
    pub textured_views: bool,
    /// The median texture of the views ([`super::Tracker::view_texture`]).
    pub view_texture: Option<f64>,
    /// The line between textured and weakly textured it was measured
    /// against ([`super::VerifyConfig::untextured_below`]).
    pub untextured_below: f64,
    /// The line under which views show shading only
    /// ([`super::cues::SHADING_ONLY_BELOW`]).
    pub shading_only_below: f64,
}

impl CueChoice {
    /// The modalities and why, in one line.
    pub fn describe(&self) -> String {
        let m = self.modalities.name();
        let (line, shading) = (self.untextured_below, self.shading_only_below);
        match (self.textured_views, self.view_texture) {
            (false, _) => format!("{m} (no keyframes and no model colours: the outline only)"),
            (true, Some(t)) if t >= line => {
                format!("{m} (a textured object: its views' texture {t:.3} >= {line})")
            }
            (true, Some(t)) if t < shading => format!(
                "{m} (an untextured object: its views' texture {t:.3} < {shading}, shading only)"
            ),
            (true, Some(t)) => format!(
                "{m} (a weakly textured object: its views' texture {t:.3} between {shading} and {line})"
            ),
            (true, None) => format!("{m} (the views' texture could not be measured)"),
        }
    }
}

/// Tracker settings. Defaults follow the paper (900 corners, 9x9 NCC
/// windows) and were tuned on the synthetic sequences. Serialised field by
/// field; fields missing when read take their default.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct TrackerConfig {
    /// Which tracker runs (default: KF+IT).
    pub mode: Mode,
    /// Harris corner detection on every frame and novel view.
    pub harris: HarrisConfig,
    /// NCC matching (window, minimum score); the search radius is set per
    /// step from the fields below.
    pub ncc: NccConfig,
    /// The robust solver of every pose update.
    pub irls: IrlsConfig,
    /// NCC search radius of frame-to-frame matching, pixels.
    pub it_search_px: f32,
    /// NCC search radius against the novel view, pixels.
    pub kf_search_px: f32,
    /// Search radius when recovering a lost track, pixels.
    pub recover_search_px: f32,
    /// Gauss-Newton refinements after each linear solve.
    pub refine_iterations: usize,
    /// KF steps per frame (each re-renders the novel view at the newest
    /// estimate).
    pub kf_iterations: usize,
    /// Margin around the object's projected bounding circle where corners
    /// are detected, pixels.
    pub roi_margin_px: f64,
    /// A step with fewer inliers than this is not trusted; when neither
    /// the KF nor the IT step of a frame is, the frame is `lost` (8: the box
    /// on the fast trajectory has frames with 8-11 good KF matches).
    pub min_inliers: usize,
    /// Inlier RMS residual above this: `lost`.
    pub max_residual_px: f64,
    /// In KF+IT, refine the KF correction jointly with the IT step's inlier
    /// matches (frame-to-frame constraints damp the KF jitter, the keyframe
    /// matches bound the drift) instead of the paper's plain sequence.
    pub fuse: bool,
    /// Weight of the IT matches relative to the KF matches when fusing.
    pub fuse_weight: f64,
    /// Refine each KF match to the sub-pixel NCC peak (a correlation patch
    /// of this many pixels a side) rather than trusting the two detected
    /// corners; 0: off. The novel view is blurrier than the frame, which
    /// biases independently detected corners (see `features::refine`).
    #[serde(rename = "refine_window")]
    pub refine_patch: u32,
    /// Splat radii are raised to at least this many pixels (at the initial
    /// pose's distance). Models sampled at about one point per pixel leave
    /// scattered empty pixels in the splatted views, and each one voids every
    /// Harris corner and NCC window that touches it. 0: the radii as given.
    pub min_splat_radius_px: f32,
    /// The finest detail the tracker renders, in pixels at the initial
    /// pose's distance; 0 (the default): every point as given. Above 0,
    /// the model's points (and a keyframe store's colours of them) are
    /// first merged within cubic cells of this size
    /// ([`PointModel::merged`](crate::model::PointModel::merged)), so
    /// that a model sampled finer than the camera resolves it costs about
    /// what its visible detail costs: at 1 the real cube's 100,000 points
    /// become 57,000 and its frame on the CPU device takes 0.7 times as
    /// long, its errors within the spread that resampling the model gives
    /// either way, while sharp synthetic textures lose 2-25% of their
    /// accuracy (docs/performance.md, "A coarser model"). At most 16.
    pub detail_px: f32,
    /// Grow the splat radii that leave gaps between splats, and only those
    /// ([`PointModel::close_gaps`](crate::model::PointModel::close_gaps)),
    /// after the pixel floor, when at least
    /// [`GAP_MODEL_FRACTION`](crate::model::GAP_MODEL_FRACTION) of them
    /// need it: novel views and predictor images without holes whatever
    /// radii the model came with. Default true.
    pub close_gaps: bool,
    /// KF+IT: consecutive frames whose KF step may fail while a sound IT
    /// estimate stands in for it (IT alone drifts); beyond that the frame
    /// is `lost`.
    pub max_it_only_frames: usize,
    /// IT uses only corners of the previous frame whose surroundings (8
    /// points at this distance, pixels; 4 = the NCC window's corners and
    /// edge midpoints) are on the object too. 0 (default): every corner on
    /// the object, outline included. Outline corners mix the background's
    /// motion in: with 4, IT's mean rotation error on the real ViSP cube
    /// drops from 2.7 to 0.75 degrees, but on the synthetic box (fast
    /// trajectory) it rises from 1.0 to 2.9 degrees (half the matches gone),
    /// so it is off by default.
    pub it_interior_px: f32,
    /// The check of every reported pose against the image
    /// ([`crate::tracker::VerifyConfig`]).
    pub verify: super::verify::VerifyConfig,
    /// Automatic initialisation and re-detection
    /// ([`crate::tracker::InitConfig`]).
    pub init: super::init::InitConfig,
    /// The cues used (default: texture only; with
    /// [`TrackerConfig::auto_modalities`], set when the tracker is built).
    pub modalities: Modalities,
    /// Choose [`TrackerConfig::modalities`] per object when the tracker is
    /// built, from how textured its keyframes' views are (`cues` module
    /// docs, [`super::Tracker::choose_modalities`]): `contour` without
    /// keyframes or model colours and for an untextured object, `texture`
    /// for a textured one, `texture,contour` for a weakly textured one
    /// (the real dragon). Default false in the
    /// library (the modalities as given); `splattrack track`'s default
    /// `--modalities auto` sets it.
    #[serde(default)]
    pub auto_modalities: bool,
    /// The contour modality's settings.
    pub contour: super::contour::ContourConfig,
    /// Confine renders, reads, corner detection and NCC matching to the
    /// object's projected region, and let the check's render serve the
    /// next frame's IT step (the same results up to f32
    /// rounding, tests/tracker.rs). Off: the loop as it was before, the
    /// whole image every time and every render made anew (for comparison).
    pub windows: bool,
    /// A render made earlier in the frame (the KF step's novel view, with
    /// colour and predictors, textured by the keyframe the check's render
    /// would use) stands for the pose check's render, and for the next
    /// frame's IT step's, when no corner of the model's bounding box moves
    /// more than this many pixels from its pose to the pose checked (0,
    /// the default: the check always renders). With windows only. At 1 px
    /// the real cube's KF+IT frame renders 1.2 times instead of 2, but its
    /// mean rotation error rises from 0.349 to 0.380 degrees (the IT step
    /// linearised on a render up to 1 px off; docs/performance.md).
    pub reuse_render_px: f32,
    /// Which splatter renders ([`crate::splat::Backend`]; `Auto`:
    /// `$SPLATTRACK_SPLATTER`, else the compute splatter where supported).
    pub splatter: crate::splat::Backend,
    /// Where corners are detected and host images matched
    /// ([`crate::features::FeatureBackend`]; `Auto`: the host on a CPU
    /// adapter, else the GPU).
    #[serde(default)]
    pub feature_backend: crate::features::FeatureBackend,
    /// Keep the frame loop's images on the GPU: each frame's
    /// bytes uploaded once and converted there
    /// ([`crate::features::FrameIntake`]), NCC, the mutual check and the KF step's
    /// sub-pixel refinement on the frame and the novel view where they
    /// lie, the pose check scored there, a few values per feature read
    /// back (`Some(true)`); or match host crops and score the check from
    /// a readback of the view (`Some(false)`). `None`: on with a GPU,
    /// off on a CPU adapter (lavapipe), where the host path measured
    /// faster ([`super::Execution::resident_matching`]). The same poses
    /// within f32 rounding (tests/tracker.rs).
    #[serde(default)]
    pub resident: Option<bool>,
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self {
            mode: Mode::KfIt,
            // 0.003 rather than the detector's 0.01: the threshold is
            // relative to the strongest corner in the region of interest,
            // often in the background on real frames (on the ViSP cube the
            // object kept too few corners at 0.01).
            //
            // Harris and NCC void any window with an invalid pixel (their
            // tolerance of pinholes, min_valid 0.8, measured no better on
            // the real cube: 0.381 against 0.349 deg with the 1 px floor's
            // radii, 0.364 against 0.368 with closed radii;
            // docs/accuracy.md). `track --min-valid 0.8` turns it on.
            harris: HarrisConfig {
                min_valid_weight: 1.0,
                ..HarrisConfig::default().with_relative_threshold(0.003)
            },
            ncc: NccConfig {
                min_valid: 1.0,
                ..NccConfig::default()
            },
            irls: IrlsConfig::default(),
            it_search_px: 40.0,
            kf_search_px: 24.0,
            recover_search_px: 80.0,
            refine_iterations: 2,
            kf_iterations: 1,
            roi_margin_px: 24.0,
            min_inliers: 8,
            max_residual_px: 3.0,
            fuse: false,
            fuse_weight: 0.5,
            refine_patch: 15,
            min_splat_radius_px: 1.0,
            detail_px: 0.0,
            close_gaps: true,
            max_it_only_frames: 5,
            it_interior_px: 0.0,
            verify: Default::default(),
            init: Default::default(),
            modalities: Modalities::default(),
            auto_modalities: false,
            contour: super::contour::ContourConfig::default(),
            windows: true,
            reuse_render_px: 0.0,
            splatter: crate::splat::Backend::Auto,
            feature_backend: crate::features::FeatureBackend::Auto,
            resident: None,
        }
    }
}

/// The largest [`TrackerConfig::detail_px`] a configuration may ask for.
const MAX_DETAIL_PX: f32 = 16.0;

impl TrackerConfig {
    /// Checks every setting's range (the ones the detectors check too);
    /// [`crate::tracker::TrackerBuilder::build`] refuses a configuration that fails.
    pub fn validate(&self) -> Result<(), ConfigError> {
        fn check<T: fmt::Display + Copy>(
            field: &'static str,
            value: T,
            ok: impl Fn(T) -> bool,
            rule: &'static str,
        ) -> Result<(), ConfigError> {
            if ok(value) {
                Ok(())
            } else {
                Err(ConfigError::OutOfRange {
                    field,
                    value: value.to_string(),
                    rule,
                })
            }
        }
        let radius = |v: f32| v >= 0.0 && v.is_finite();
        check(
            "harris.relative_threshold",
            self.harris.relative_threshold,
            |v| v > 0.0 && v <= 1.0,
            "in (0, 1]",
        )?;
        let search = "a finite radius >= 0";
        check("it_search_px", self.it_search_px, radius, search)?;
        check("kf_search_px", self.kf_search_px, radius, search)?;
        check("recover_search_px", self.recover_search_px, radius, search)?;
        check(
            "roi_margin_px",
            self.roi_margin_px,
            |v| v >= 0.0 && v.is_finite(),
            ">= 0",
        )?;
        check(
            "max_residual_px",
            self.max_residual_px,
            |v| v > 0.0 && v.is_finite(),
            "> 0",
        )?;
        check(
            "min_splat_radius_px",
            self.min_splat_radius_px,
            radius,
            ">= 0",
        )?;
        // Cells of more than 16 pixels leave too little of an object to
        // track: a typo, not a level of detail.
        let detail = |v: f32| (0.0..=MAX_DETAIL_PX).contains(&v);
        check("detail_px", self.detail_px, detail, "in [0, 16]")?;
        check("it_interior_px", self.it_interior_px, radius, ">= 0")?;
        check("reuse_render_px", self.reuse_render_px, radius, ">= 0")?;
        check(
            "modalities",
            self.modalities,
            |m| m.texture || m.contour,
            "at least one of texture and contour",
        )?;
        check(
            "init.template_px",
            self.init.template_px,
            |v| v >= 4.0 && v.is_finite(),
            "a finite size >= 4",
        )?;
        check(
            "init.confirm_max_turn_deg",
            self.init.confirm_max_turn_deg,
            |v| (0.0..=180.0).contains(&v),
            "in [0, 180]",
        )?;
        check(
            "init.keyframe_tilt_deg",
            self.init.keyframe_tilt_deg,
            |v| (0.0..=90.0).contains(&v),
            "in [0, 90]",
        )?;
        self.contour.validate()?;
        self.harris.validate()?;
        self.ncc.validate()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_each_rule_names_its_field() {
        TrackerConfig::default().validate().unwrap();
        type Change = fn(&mut TrackerConfig);
        let bad: [(Change, &str); 9] = [
            (|c| c.detail_px = 17.0, "detail_px = 17: must be in [0, 16]"),
            (
                |c| c.harris.relative_threshold = 0.0,
                "harris.relative_threshold = 0: must be in (0, 1]",
            ),
            (
                |c| c.kf_search_px = f32::NAN,
                "kf_search_px = NaN: must be a finite radius >= 0",
            ),
            (
                |c| c.max_residual_px = -1.0,
                "max_residual_px = -1: must be > 0",
            ),
            (
                |c| c.min_splat_radius_px = f32::INFINITY,
                "min_splat_radius_px = inf: must be >= 0",
            ),
            (|c| c.ncc.patch = 8, "patch = 8"),
            (
                |c| c.roi_margin_px = -2.5,
                "roi_margin_px = -2.5: must be >= 0",
            ),
            (
                |c| c.init.keyframe_tilt_deg = f64::NAN,
                "init.keyframe_tilt_deg = NaN: must be in [0, 90]",
            ),
            (
                |c| c.init.template_px = 0.0,
                "init.template_px = 0: must be a finite size >= 4",
            ),
        ];
        for (change, want) in bad {
            let mut c = TrackerConfig::default();
            change(&mut c);
            let e = c.validate().unwrap_err().to_string();
            assert!(e.contains(want), "{e:?} lacks {want:?}");
        }
    }

    #[test]
    #[cfg(feature = "cli")]
    fn mode_names_parse_display_and_serialise_alike() {
        use clap::ValueEnum;
        for m in Mode::ALL {
            assert_eq!(m.to_string(), m.name());
            assert_eq!(m.name().parse::<Mode>(), Ok(m));
            assert_eq!(Mode::from_str(m.name(), true), Ok(m));
            let json = serde_json::to_string(&m).unwrap();
            assert_eq!(json, format!("\"{}\"", m.name()));
            assert_eq!(serde_json::from_str::<Mode>(&json).unwrap(), m);
        }
        for alias in ["kfit", "it+kf", "hybrid"] {
            assert_eq!(Mode::from_str(alias, true), Ok(Mode::KfIt));
            assert_eq!(alias.parse::<Mode>(), Ok(Mode::KfIt));
        }
    }

    #[test]
    fn modalities_parse_and_refuse_nonsense() {
        for m in [Modalities::TEXTURE, Modalities::CONTOUR, Modalities::BOTH] {
            assert_eq!(m.name().parse::<Modalities>(), Ok(m));
        }
        assert_eq!(
            "Contour+texture".parse::<Modalities>(),
            Ok(Modalities::BOTH)
        );
        assert!(
            "edges"
                .parse::<Modalities>()
                .unwrap_err()
                .contains("\"edges\"")
        );
        assert!("".parse::<Modalities>().is_err());
        let none = TrackerConfig {
            modalities: Modalities {
                texture: false,
                contour: false,
            },
            ..Default::default()
        };
        assert!(
            none.validate()
                .unwrap_err()
                .to_string()
                .contains("modalities")
        );
    }

    #[test]
    fn config_serde_roundtrip_and_partial_input() {
        let c = TrackerConfig {
            mode: Mode::It,
            kf_search_px: 16.0,
            fuse: true,
            ..Default::default()
        };
        let text = serde_json::to_string(&c).unwrap();
        assert_eq!(serde_json::from_str::<TrackerConfig>(&text).unwrap(), c);
        let partial: TrackerConfig =
            serde_json::from_str(r#"{"mode": "kf", "min_inliers": 12}"#).unwrap();
        assert_eq!(
            partial,
            TrackerConfig {
                mode: Mode::Kf,
                min_inliers: 12,
                ..Default::default()
            }
        );
    }
}
