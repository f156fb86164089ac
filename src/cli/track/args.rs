//! The flags of `splattrack track`, and the tracker settings they make.

use splattrack::app::Tuning;
use splattrack::features::FeatureBackend;
use splattrack::io::source::Start;
use splattrack::splat::Backend;
use splattrack::tracker::{Modalities, Mode, TrackerConfig};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The object's model: a point model (PLY), or a mesh (OBJ, STL, PLY
    /// with faces) sampled into 100000 points (`splattrack model` writes
    /// that sample out). Repeat for several objects, each NAME=PATH or
    /// PATH (named by the file's stem). Default with --sequence DIR: every
    /// DIR/objects/NAME/model.ply.
    #[arg(long, value_name = "[NAME=]PATH")]
    pub model: Vec<String>,
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
    /// `splattrack keyframes` (.stkf); once per --model, in their order.
    /// Default: SEQUENCE/objects/NAME/keyframes, else (one model)
    /// SEQUENCE/keyframes, if present.
    #[arg(long)]
    pub keyframes: Vec<PathBuf>,
    /// The pose of frame 0: a pose file's first row, or in a file with an
    /// object column each object's first row; once, or once per --model.
    /// Default: SEQUENCE/init.csv when present, else the object is
    /// searched for in the frames (automatic initialisation).
    #[arg(long)]
    pub init: Vec<PathBuf>,
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
    /// (texture,contour). Once for every object, or once per --model.
    #[arg(long)]
    pub modalities: Vec<Cues>,
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
    /// BOP object id of the one model (default 1; several models: each
    /// object's from its name, obj_000005 -> 5, else its position).
    #[arg(long)]
    pub obj_id: Option<u32>,
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

impl Args {
    /// The tracker's settings with the cues `cues`: the defaults with the
    /// tuning flags' overrides, and the mode and backends named.
    pub fn config(&self, cues: Cues) -> anyhow::Result<TrackerConfig> {
        let (modalities, auto_modalities) = match cues {
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
