//! Where `splattrack track` reads its frames: a sequence directory, a
//! video file or a live camera, as the flags name it.

use super::args::Args;
use crate::cli::common::model_options;
use anyhow::bail;
use splattrack::Intrinsics;
use splattrack::app::TrackInputs;
use splattrack::io::live::LiveSource;
use splattrack::io::source::{FrameSource, Start};
use splattrack::io::video::VideoSource;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// Where the frames come from.
pub enum Input {
    Sequence(PathBuf),
    Video {
        file: PathBuf,
        camera: PathBuf,
        start: Start,
    },
    Device {
        device: String,
        camera: PathBuf,
    },
}

impl Input {
    /// The input as a user named it (the live view's title).
    pub fn describe(&self) -> String {
        match self {
            Input::Sequence(p) | Input::Video { file: p, .. } => p.display().to_string(),
            Input::Device { device, .. } => device.clone(),
        }
    }

    /// The one input the flags name, with the flags it needs.
    pub fn of(args: &Args) -> anyhow::Result<Self> {
        let camera = || {
            args.camera.clone().ok_or_else(|| {
                anyhow::anyhow!(
                    "--camera is needed with --video and --device (camera.json or an OpenCV yaml)"
                )
            })
        };
        Ok(match (&args.sequence, &args.video, &args.device) {
            (Some(dir), None, None) => {
                if let Some(Start::Seconds(t)) = args.start {
                    bail!(
                        "--start {t}s: a sequence's frames have no timestamps; give a frame index"
                    );
                }
                Input::Sequence(dir.clone())
            }
            (None, Some(file), None) => {
                if args.realtime && args.start.is_some() {
                    bail!("--start: not with --realtime (a replay starts at the beginning)");
                }
                Input::Video {
                    file: file.clone(),
                    camera: camera()?,
                    start: args.start.unwrap_or_default(),
                }
            }
            (None, None, Some(device)) => {
                if args.start.is_some() {
                    bail!("--start: a live camera starts now; not for --device");
                }
                Input::Device {
                    device: device.clone(),
                    camera: camera()?,
                }
            }
            (None, None, None) => {
                bail!("no frames: give --sequence DIR, --video FILE or --device N|PATH")
            }
            _ => bail!("give only one of --sequence, --video and --device"),
        })
    }

    /// A video or a camera, opened before the GPU and the model are set
    /// up: a missing ffmpeg, a file it cannot decode or frames of the wrong
    /// size fail first. `None` for a sequence, and for a `--realtime`
    /// video, checked now and replayed once the tracker is ready, so that
    /// no frame passes while the model loads.
    pub fn open(
        &self,
        realtime: bool,
        stop: &Arc<AtomicBool>,
    ) -> anyhow::Result<Option<Box<dyn FrameSource>>> {
        Ok(match self {
            Input::Sequence(_) => None,
            Input::Video {
                file,
                camera,
                start,
            } if !realtime => {
                let cam = Intrinsics::load(camera)?;
                Some(Box::new(VideoSource::open(file, &cam, camera, *start)?))
            }
            Input::Video { file, camera, .. } => {
                let cam = Intrinsics::load(camera)?;
                VideoSource::open(file, &cam, camera, Start::Frame(0))?;
                None
            }
            Input::Device { device, camera } => {
                let cam = Intrinsics::load(camera)?;
                Some(Box::new(
                    LiveSource::device(device, &cam, camera)?.stop_on(stop.clone()),
                ))
            }
        })
    }

    /// The model, camera, keyframes and first pose of a run of one
    /// object.
    pub fn load(
        &self,
        ctx: &splattrack::Device,
        model: &Path,
        keyframes: Option<&Path>,
        init: Option<&Path>,
    ) -> anyhow::Result<TrackInputs> {
        Ok(match self {
            Input::Sequence(dir) => {
                TrackInputs::load(ctx, model, &model_options(), dir, keyframes, init)?
            }
            Input::Video { camera, .. } | Input::Device { camera, .. } => {
                TrackInputs::load_with_camera(
                    ctx,
                    model,
                    &model_options(),
                    camera,
                    keyframes,
                    init,
                )?
            }
        })
    }
}
