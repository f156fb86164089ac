//! The flags of `splattrack track`, and the tracker settings they make.

use anyhow::bail;
use splattrack::features::FeatureBackend;
use splattrack::io::source::Start;
use splattrack::splat::Backend;
use splattrack::tracker::{ConfigError, Modalities, Mode, TrackerConfig};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The object's model: a point model (PLY), or a mesh (OBJ, STL, PLY
    /// with faces) sampled into 100000 points (`splattrack model` writes
    /// that sample out).
    #[arg(long)]
    pub model: PathBuf,
    /// The sequence directory (camera.json, frames/, init.csv, ...).
    #[arg(long, conflicts_with_all = ["video", "device", "camera"])]
    pub sequence: Option<PathBuf>,
    /// A video file (MP4, MOV, AVI, MKV, WebM, ...: whatever ffmpeg
    /// decodes), read through the ffmpeg program; needs --camera. Frames
    /// are numbered from 0 in decode order; the output gains time_s.
    #[arg(long, conflicts_with = "device")]
    pub video: Option<PathBuf>,
    /// A live camera: N for /dev/videoN, or a device path (V4L2, Linux),
    /// read through ffmpeg at the camera's size; needs --camera. Frames
    /// that arrive while one is tracked are dropped and counted; Ctrl-C
    /// ends the run after the current frame, every finished frame written.
    #[arg(long)]
    pub device: Option<String>,
    /// --video: read the video at its own frame rate, as a camera would
    /// deliver it, and track it as a live camera (frames that arrive while
    /// one is tracked are dropped and counted; Ctrl-C ends the run): how
    /// the tracker would fare live at this speed.
    #[arg(long, requires = "video")]
    pub realtime: bool,
    /// The camera of --video or --device (camera.json or an OpenCV yaml).
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// Where to start: a frame index (120), or seconds with an s suffix
    /// (4.5s: the first frame at or after 4.5 s; --video only). Frames keep
    /// their numbers in the whole video or sequence.
    #[arg(long)]
    pub start: Option<Start>,
    /// Keyframes: a directory with images and poses.csv, or a store built by
    /// `splattrack keyframes` (.stkf). Default: SEQUENCE/keyframes if present.
    #[arg(long)]
    pub keyframes: Option<PathBuf>,
    /// The pose of frame 0. Default: SEQUENCE/init.csv when present, else
    /// the object is searched for in the frames (automatic initialisation).
    #[arg(long)]
    pub init: Option<PathBuf>,
    /// kf+it (the paper's hybrid), it (frame to frame) or kf (keyframes
    /// only). Default: kf+it, or it when there are neither keyframes nor
    /// model colours to build the KF step's views from.
    #[arg(long, value_enum, ignore_case = true)]
    pub mode: Option<Mode>,
    /// The cues tracked: auto (the default: measured on the keyframes'
    /// views, texture for a textured object, texture,contour for a weakly
    /// textured one, contour for an untextured one and without keyframes
    /// or model colours), texture (corners and NCC), contour (the splatted
    /// silhouette against the frame's colours) or both in one robust solve
    /// (texture,contour).
    #[arg(long, default_value = "auto")]
    pub modalities: Cues,
    /// Output pose CSV (docs/formats.md "Tracker output").
    #[arg(long)]
    pub out: PathBuf,
    /// Write each frame with the model's outline at the tracked pose here.
    #[arg(long)]
    pub overlay: Option<PathBuf>,
    /// Print the time per stage and its parts, and the GPU time of every
    /// pass (timestamp queries, where the adapter has them).
    #[arg(long)]
    pub profile: bool,
    /// Also write a BOP-style results CSV (t in mm, assuming metre models).
    #[arg(long)]
    pub bop: Option<PathBuf>,
    /// Also write the refused estimates: for each lost frame with an
    /// estimate, the pose refused, its stage, the reason and the check's
    /// scores (docs/formats.md "Refused estimates").
    #[arg(long, value_name = "FILE.csv")]
    pub refused: Option<PathBuf>,
    /// BOP object id.
    #[arg(long, default_value_t = 1)]
    pub obj_id: u32,
    /// Track only N frames (from --start).
    #[arg(long)]
    pub frames: Option<usize>,
    /// The splatter: render (render pass), compute (compute shader with
    /// atomics) or auto ($SPLATTRACK_SPLATTER when set, else compute where
    /// the adapter supports it: the faster measured, docs/benchmarks.md).
    #[arg(long, default_value = "auto")]
    pub splatter: Backend,
    /// Where corners are detected and matched: gpu (compute shaders),
    /// host (the CPU references' arithmetic; Harris vectorised on every
    /// core) or auto (host on a CPU adapter such as lavapipe, where it
    /// measured faster, else gpu).
    #[arg(long, default_value = "auto")]
    pub feature_backend: FeatureBackend,
    /// Keep the frame loop's images on the GPU: on (each frame uploaded
    /// once; matching, the KF refinement and the pose check in the
    /// shaders; a few values per feature read back), off (host crops, the
    /// view read back) or auto (on with a GPU, off on a CPU adapter such
    /// as lavapipe, where off measured faster). With --feature-backend
    /// gpu, on runs a GPU's frame loop on any adapter, for profiling.
    #[arg(long, value_enum, default_value_t = OnOff::Auto)]
    pub resident: OnOff,
    /// Show each frame in a window as it is tracked: the model's outline
    /// at the tracked pose, tracking or lost (and why), inliers, residual
    /// and ms per frame. Esc, q or closing the window ends the run with
    /// every finished frame on disk. Needs a display (X11 or Wayland).
    #[arg(long)]
    pub view: bool,
    #[command(flatten)]
    pub tuning: Tuning,
}

/// Overrides of [`TrackerConfig`] defaults (unset: the default).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct Tuning {
    /// Harris: keep corners whose response is at least this fraction of the
    /// largest one in the search region (default 0.003).
    #[arg(long)]
    pub harris_threshold: Option<f32>,
    /// Harris: at most this many corners per image (default 900).
    #[arg(long)]
    pub max_corners: Option<usize>,
    /// NCC: minimum score of a match (default 0.8).
    #[arg(long)]
    pub min_score: Option<f32>,
    /// NCC: window side, odd (default 9).
    #[arg(long)]
    pub ncc_window: Option<u32>,
    /// Frame-to-frame search radius, pixels (default 40).
    #[arg(long)]
    pub it_search: Option<f32>,
    /// Search radius against the novel view, pixels (default 24).
    #[arg(long)]
    pub kf_search: Option<f32>,
    /// Search radius when recovering a lost track, pixels (default 80).
    #[arg(long)]
    pub recover_search: Option<f32>,
    /// KF steps per frame (default 1).
    #[arg(long)]
    pub kf_iterations: Option<usize>,
    /// Gauss-Newton refinements after each linear solve (default 2).
    #[arg(long)]
    pub refine_iterations: Option<usize>,
    /// Margin around the object's projected bounding circle, pixels (default 24).
    #[arg(long)]
    pub roi_margin: Option<f64>,
    /// A step with fewer inliers than this is not trusted (default 8).
    #[arg(long)]
    pub min_inliers: Option<usize>,
    /// Inlier RMS residual above this: lost (default 3 px).
    #[arg(long)]
    pub max_residual: Option<f64>,
    /// Splat radii are raised to at least this many pixels (default 1; 0:
    /// the model's radii).
    #[arg(long)]
    pub min_splat_px: Option<f32>,
    /// Keep the model's splat radii where they leave gaps between splats
    /// (default: those radii grow just enough to close the gaps).
    #[arg(long)]
    pub keep_radii: bool,
    /// Harris and NCC: the fraction of a window that must be valid where it
    /// has pinholes (default 0.8; 1: any invalid pixel voids the window).
    #[arg(long)]
    pub min_valid: Option<f32>,
    /// KF+IT: frames in a row that IT alone may track when the KF step
    /// fails (default 5).
    #[arg(long)]
    pub max_it_only: Option<usize>,
    /// IT: only corners whose surroundings at this distance (pixels) are on
    /// the object (default 0: outline corners too; 4 helps IT on the real
    /// cube, hurts it on the synthetic box).
    #[arg(long)]
    pub it_interior: Option<f32>,
    /// Contour: most rounds per frame (default 4; the first searches long
    /// then short lines, the others short lines at the newest estimate).
    #[arg(long)]
    pub contour_rounds: Option<usize>,
    /// Contour: from the second round on, a round that moved the outline
    /// less than this (mean, pixels) ends the frame's step (default 0.25;
    /// 0: always --contour-rounds rounds).
    #[arg(long)]
    pub contour_converged: Option<f64>,
    /// Contour: one contour point per cell of this side, pixels (default 4).
    #[arg(long)]
    pub contour_spacing: Option<u32>,
    /// Contour: Levenberg-Marquardt damping, fraction of the diagonal
    /// (default 0: the silhouette of a smooth body constrains some motions
    /// weakly, and damping holds them back; 0.001 steadies the real dragon).
    #[arg(long)]
    pub contour_damping: Option<f64>,
    /// Contour: splat depth and normals for the silhouette, as before the
    /// depth-only renders (for comparison; about 3x the contour's GPU time).
    #[arg(long)]
    pub contour_full_render: bool,
    /// Contour: a later round moves the last render's points instead of
    /// rendering when no point moved more than this since (pixels, along
    /// its normal; default 1; 0 renders every round).
    #[arg(long)]
    pub contour_reproject: Option<f64>,
    /// Contour: colour histograms per sector of directions around the
    /// object (default 8; 0: one pair for the whole object).
    #[arg(long)]
    pub contour_sectors: Option<usize>,
    /// Contour: the first round always renders, instead of moving the
    /// points of the render held from the KF step (or the last contour
    /// render) when they moved little (for comparison).
    #[arg(long)]
    pub contour_no_seed: bool,
    /// The frame loop before windows and reuse, for comparison: render,
    /// detect and match over the whole image every time instead of the
    /// object's projected region, and render the IT step's view anew
    /// instead of taking the previous check's (the same poses up to f32
    /// rounding, slower).
    #[arg(long)]
    pub full_frame: bool,
}

impl Tuning {
    /// `base` with these overrides applied, checked by
    /// [`TrackerConfig::validate`]; a value out of range is named by its flag.
    pub fn apply(&self, mut c: TrackerConfig) -> anyhow::Result<TrackerConfig> {
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
        if self.keep_radii {
            c.close_gaps = false;
        }
        if let Some(v) = self.min_valid {
            if !(v > 0.0 && v <= 1.0) {
                bail!("--min-valid {v}: must be in (0, 1]");
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
                bail!("--max-corners {n}: must be 1..={MAX_CORNERS}");
            }
        }
        match c.validate() {
            Ok(()) => Ok(c),
            Err(ConfigError::OutOfRange { field, value, rule }) => {
                match FLAGS.iter().find(|(f, _)| *f == field) {
                    Some((_, flag)) => bail!("--{flag} {value}: must be {rule}"),
                    None => bail!("tracker settings: {field} = {value}: must be {rule}"),
                }
            }
            Err(e) => bail!("tracker settings: {e}"),
        }
    }
}

/// `--modalities`: `auto`, or the cues named.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cues {
    /// Chosen per object ([`TrackerConfig::auto_modalities`]).
    Auto,
    /// As named.
    Named(Modalities),
}

impl std::str::FromStr for Cues {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s.trim().eq_ignore_ascii_case("auto") {
            return Ok(Self::Auto);
        }
        s.parse()
            .map(Self::Named)
            .map_err(|e: String| e.replace("(use ", "(use auto, "))
    }
}

/// A setting the adapter decides unless told.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnOff {
    Auto,
    On,
    Off,
}

impl OnOff {
    /// `None` for auto.
    pub fn choice(self) -> Option<bool> {
        match self {
            Self::Auto => None,
            Self::On => Some(true),
            Self::Off => Some(false),
        }
    }
}

/// The most corners per image the flags allow (a corner costs 16 bytes of
/// GPU memory and a share of every matching pass; a billion would ask for
/// a 16 GB buffer).
pub const MAX_CORNERS: usize = 100_000;

/// The flag of each [`TrackerConfig`] field that [`Tuning`] sets and
/// [`TrackerConfig::validate`] checks.
const FLAGS: [(&str, &str); 14] = [
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
    ("it_interior_px", "it-interior"),
];

impl Args {
    /// The tracker's settings: the defaults with the tuning flags' overrides, and
    /// the mode, cues and backends named.
    pub fn config(&self) -> anyhow::Result<TrackerConfig> {
        let (modalities, auto_modalities) = match self.modalities {
            Cues::Auto => (Modalities::default(), true),
            Cues::Named(m) => (m, false),
        };
        Ok(TrackerConfig {
            mode: self.mode.unwrap_or_default(),
            modalities,
            auto_modalities,
            splatter: self.splatter,
            feature_backend: self.feature_backend,
            resident: self.resident.choice(),
            ..self.tuning.apply(TrackerConfig::default())?
        })
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
