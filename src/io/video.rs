//! Video files through an `ffmpeg` child process ([`VideoSource`]; the
//! process, and how and why it is run, in [`crate::io::ffmpeg`]): every
//! frame as decoded, from a [`Start`] on. One frame buffer is reused: the
//! video is never held in memory. The first frame's size is checked
//! against the camera before anything else is read.

use crate::geometry::{Intrinsics, Undistorter};
use crate::io::ffmpeg::{Ffmpeg, check_size, file_args, probe_frame_count, undistort};
use crate::io::sequence::Frame;
use crate::io::source::{FrameSource, SourceError, Start};
use std::path::{Path, PathBuf};

pub use crate::io::ffmpeg::VideoError;

/// The frames of a video file, decoded one at a time by ffmpeg (see the
/// module docs), from a [`Start`] on; each frame keeps its index in the
/// whole video and its timestamp.
pub struct VideoSource {
    ffmpeg: Ffmpeg,
    path: PathBuf,
    camera: Intrinsics,
    undistorter: Option<Undistorter>,
    start: Start,
    buf: Vec<u8>,
    /// Frames the container says the video has (for progress).
    frames: Option<usize>,
    /// Frames read so far, the skipped ones before the start included.
    read: usize,
}

impl VideoSource {
    /// Opens `path` for frames of `camera` (calibrated, from the file
    /// `camera_path`, named in errors): ffmpeg is started and the first
    /// frame's size checked against the camera.
    pub fn open(
        path: &Path,
        camera: &Intrinsics,
        camera_path: &Path,
        start: Start,
    ) -> Result<Self, VideoError> {
        if !path.is_file() {
            return Err(VideoError::NotFound(path.to_owned()));
        }
        let ffmpeg = Ffmpeg::spawn(path, &file_args(path))?;
        check_size(path, camera, camera_path, ffmpeg.size())?;
        Ok(Self {
            ffmpeg,
            path: path.to_owned(),
            camera: *camera,
            undistorter: camera.has_distortion().then(|| Undistorter::new(camera)),
            start,
            buf: Vec::new(),
            frames: probe_frame_count(path),
            read: 0,
        })
    }
}

impl FrameSource for VideoSource {
    fn camera(&self) -> &Intrinsics {
        &self.camera
    }

    fn name(&self) -> &Path {
        &self.path
    }

    fn has_timestamps(&self) -> bool {
        true
    }

    fn expected(&self) -> Option<usize> {
        let skipped = match self.start {
            Start::Frame(k) => k,
            Start::Seconds(_) => 0,
        };
        self.frames
            .map(|n| n.saturating_sub(self.read.max(skipped)))
            .filter(|n| *n > 0)
    }

    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
        let (w, h) = self.ffmpeg.size();
        let bytes = w as usize * h as usize * 3;
        loop {
            // Frames before the start are read into one reused buffer; a
            // frame returned takes the buffer with it.
            self.buf.resize(bytes, 0);
            let Some(info) = self.ffmpeg.read_frame(&mut self.buf)? else {
                return Ok(None);
            };
            self.read += 1;
            if self.start.skips(info.index, info.time_s) {
                continue;
            }
            let buf = std::mem::take(&mut self.buf);
            let image = image::RgbImage::from_raw(w, h, buf).ok_or_else(|| VideoError::Died {
                path: self.path.clone(),
                frame: info.index,
                reason: "short frame".into(),
            })?;
            let image = undistort(self.undistorter.as_ref(), image, &self.path)?;
            return Ok(Some(Frame {
                index: info.index,
                label: info.index.to_string(),
                path: self.path.clone(),
                image,
                time_s: Some(info.time_s),
            }));
        }
    }
}
