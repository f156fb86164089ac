//! Where a tracking run's frames come from: one interface, [`FrameSource`],
//! over a sequence directory ([`SequenceFrames`]), a video file
//! ([`crate::io::video::VideoSource`]) and a live camera
//! ([`crate::io::live::LiveSource`]).
//!
//! Every source yields [`Frame`]s in order, numbered from 0 in the order
//! they were read or decoded (docs/formats.md), undistorted when the camera has
//! distortion, ready for a tracker on [`FrameSource::tracking_camera`].
//! Videos and cameras also give each frame its timestamp; a live camera
//! drops the frames that arrive while one is being tracked and counts them.

use crate::geometry::Intrinsics;
use crate::io::ffmpeg::VideoError;
use crate::io::sequence::{Frame, Sequence, SequenceError};
use crate::par::ChannelThread;
use std::path::Path;

/// Why a source could not give its next frame.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// A frame of a sequence directory is unusable.
    #[error(transparent)]
    Sequence(#[from] SequenceError),
    /// A video or camera could not be read.
    #[error(transparent)]
    Video(#[from] VideoError),
}

/// A stream of frames for a tracker.
pub trait FrameSource {
    /// The camera as calibrated (with its distortion, if any).
    fn camera(&self) -> &Intrinsics;

    /// The camera of the frames [`next_frame`](Self::next_frame) returns:
    /// the calibrated one without its distortion.
    fn tracking_camera(&self) -> Intrinsics {
        self.camera().undistorted()
    }

    /// What the frames come from (a directory, a video file, a device), for
    /// messages.
    fn name(&self) -> &Path;

    /// True when frames carry timestamps ([`Frame::time_s`]): videos and
    /// cameras. A run's pose file then gains a `time_s` column.
    fn has_timestamps(&self) -> bool;

    /// How many frames are left, when known (a sequence directory; not a
    /// video or a camera).
    fn remaining(&self) -> Option<usize> {
        None
    }

    /// About how many frames are left, for progress only (never a limit:
    /// a video's own count can be off): [`FrameSource::remaining`] where
    /// it is known, else an estimate (a video's container), else `None`.
    fn expected(&self) -> Option<usize> {
        self.remaining()
    }

    /// The next frame, `None` at the end of the stream (or, for a live
    /// source, once it was told to stop).
    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError>;

    /// Frames dropped so far: frames that arrived while the previous one
    /// was being tracked (live sources; 0 for files).
    fn dropped(&self) -> u64 {
        0
    }
}

/// A source borrowed for a run, so that the caller keeps it (and its
/// counts) afterwards.
impl<S: FrameSource + ?Sized> FrameSource for &mut S {
    fn camera(&self) -> &Intrinsics {
        (**self).camera()
    }
    fn tracking_camera(&self) -> Intrinsics {
        (**self).tracking_camera()
    }
    fn name(&self) -> &Path {
        (**self).name()
    }
    fn has_timestamps(&self) -> bool {
        (**self).has_timestamps()
    }
    fn remaining(&self) -> Option<usize> {
        (**self).remaining()
    }
    fn expected(&self) -> Option<usize> {
        (**self).expected()
    }
    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
        (**self).next_frame()
    }
    fn dropped(&self) -> u64 {
        (**self).dropped()
    }
}

/// Where to start in a stream (`--start`): a frame index (`120`), or a time
/// in seconds with an `s` suffix (`4.5s`: the first frame whose timestamp is
/// at least 4.5 s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Start {
    /// The first frame with this index (0: the first frame).
    Frame(usize),
    /// The first frame at or after this time, seconds.
    Seconds(f64),
}

impl Default for Start {
    fn default() -> Self {
        Start::Frame(0)
    }
}

impl std::str::FromStr for Start {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let t = s.trim();
        if let Some(secs) = t.strip_suffix('s') {
            return match secs.trim().parse::<f64>() {
                Ok(v) if v.is_finite() && v >= 0.0 => Ok(Start::Seconds(v)),
                _ => Err(format!(
                    "{s:?}: expected a frame index (120) or seconds (4.5s), not negative"
                )),
            };
        }
        t.parse::<usize>().map(Start::Frame).map_err(|_| {
            format!("{s:?}: expected a frame index (120) or seconds with an s suffix (4.5s)")
        })
    }
}

impl Start {
    /// True when the frame `index` at `time_s` comes before this start.
    pub fn skips(&self, index: usize, time_s: f64) -> bool {
        match *self {
            Start::Frame(k) => index < k,
            // Timestamps are exact multiples of the stream's time base; the
            // tolerance keeps a frame at 2.0 s for `2s` despite rounding.
            Start::Seconds(s) => time_s < s - 1e-7,
        }
    }
}

/// The frames of a [`Sequence`] from a start index on ([`Sequence::frame`]);
/// no timestamps. Read one at a time when asked for, or
/// ([`SequenceFrames::read_ahead`]), from the first frame asked for, by a
/// thread of their own that reads and decodes the next frames ahead (one
/// waiting, one being decoded), so that decoding overlaps the tracking of
/// the frame before: on an H200 the real cube's PNG frames took 4.5 ms
/// each to decode against 6.4 ms to track. Frames and errors come in
/// order either way; an error ends the reading ahead. The thread ends when
/// the source is dropped.
pub struct SequenceFrames<'a> {
    seq: &'a Sequence,
    next: usize,
    read_ahead: bool,
    ahead: Option<Ahead>,
}

/// The frames decoded ahead: the receiving end of the thread decoding
/// them (dropped, it ends the thread after the frame it is decoding).
type Ahead = ChannelThread<std::sync::mpsc::Receiver<Result<Frame, SequenceError>>>;

/// Reads frames `start..` of a copy of `seq` (its paths and camera: the
/// undistortion maps are shared) on a new thread; `None` when no thread
/// can be made (the frames are then read in the caller's).
fn read_ahead_from(seq: &Sequence, start: usize) -> Option<Ahead> {
    let seq = seq.clone();
    let (tx, rx) = std::sync::mpsc::sync_channel(1);
    ChannelThread::spawn("frames ahead", rx, move || {
        for i in start..seq.frames.len() {
            let frame = seq.frame(i);
            let failed = frame.is_err();
            // A closed channel: the source was dropped.
            if tx.send(frame).is_err() || failed {
                break;
            }
        }
    })
    .ok()
}

impl<'a> SequenceFrames<'a> {
    /// Frames `start`, `start + 1`, ... of `seq` (none when `start` is past
    /// the end).
    pub fn new(seq: &'a Sequence, start: usize) -> Self {
        Self {
            seq,
            next: start,
            read_ahead: false,
            ahead: None,
        }
    }

    /// Reads and decodes the frames ahead on a thread of their own (`on`),
    /// or one at a time when asked for. Worth it where the tracker leaves
    /// a core idle: with a GPU (`TrackRun` turns it on there), not on a CPU
    /// adapter such as lavapipe, whose "GPU" work takes every core (the
    /// real cube on 2 cores: 102 ms end to end a frame without, 117 with,
    /// medians of 5 alternated runs).
    pub fn read_ahead(mut self, on: bool) -> Self {
        self.read_ahead = on;
        self
    }
}

impl FrameSource for SequenceFrames<'_> {
    fn camera(&self) -> &Intrinsics {
        &self.seq.camera
    }

    fn tracking_camera(&self) -> Intrinsics {
        self.seq.tracking_camera()
    }

    fn name(&self) -> &Path {
        &self.seq.dir
    }

    fn has_timestamps(&self) -> bool {
        false
    }

    fn remaining(&self) -> Option<usize> {
        Some(self.seq.frames.len().saturating_sub(self.next))
    }

    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
        if self.next >= self.seq.frames.len() {
            return Ok(None);
        }
        if self.read_ahead && self.ahead.is_none() {
            self.ahead = read_ahead_from(self.seq, self.next);
        }
        let received = self.ahead.as_ref().and_then(|a| a.end().recv().ok());
        // Without a thread (or after one that died), in this one.
        let f = match received {
            Some(f) => f,
            None => self.seq.frame(self.next),
        }?;
        self.next += 1;
        Ok(Some(f))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn start_parses_frames_and_seconds() {
        assert_eq!("0".parse::<Start>(), Ok(Start::Frame(0)));
        assert_eq!(" 120 ".parse::<Start>(), Ok(Start::Frame(120)));
        assert_eq!("4.5s".parse::<Start>(), Ok(Start::Seconds(4.5)));
        assert_eq!("2s".parse::<Start>(), Ok(Start::Seconds(2.0)));
        for bad in ["", "-1", "1.5", "x", "-2s", "nans", "infs", "s"] {
            assert!(bad.parse::<Start>().is_err(), "{bad}");
        }
        assert!(Start::Frame(3).skips(2, 100.0) && !Start::Frame(3).skips(3, 0.0));
        let s = Start::Seconds(2.0);
        assert!(s.skips(0, 1.9666667) && !s.skips(0, 2.0) && !s.skips(0, 1.99999999));
    }

    /// Frames read ahead on their thread are the sequence's, in order, bit
    /// for bit; a source dropped after one frame returns at once (its
    /// thread joined); a frame that cannot be read gives its error in its
    /// turn, after the frames before it, and again when asked again.
    #[test]
    fn frames_read_ahead_are_the_sequences_in_order_with_errors_in_their_turn() {
        let Some(root) = crate::io::testing::real_data("visp_rbt_cube") else {
            return;
        };
        let seq = Sequence::open(&root).unwrap();
        let mut src = SequenceFrames::new(&seq, 92).read_ahead(true);
        for i in 92..99 {
            let f = src.next_frame().unwrap().unwrap();
            assert_eq!(f.index, i);
            assert_eq!(f.image, seq.frame(i).unwrap().image, "frame {i}");
        }
        assert!(src.next_frame().unwrap().is_none());
        let mut early = SequenceFrames::new(&seq, 0).read_ahead(true);
        assert_eq!(early.next_frame().unwrap().unwrap().index, 0);
        drop(early);

        let dir = std::env::temp_dir().join(format!("splattrack_ahead_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("frames")).unwrap();
        std::fs::copy(root.join("camera.json"), dir.join("camera.json")).unwrap();
        for (i, from) in [0, 1, 2, 3].iter().enumerate() {
            let to = dir.join(format!("frames/{i:06}.png"));
            std::fs::copy(&seq.frames[*from], &to).unwrap();
        }
        std::fs::write(dir.join("frames/000002.png"), b"not a png").unwrap();
        let bad = Sequence::open(&dir).unwrap();
        let mut src = SequenceFrames::new(&bad, 0).read_ahead(true);
        assert_eq!(src.next_frame().unwrap().unwrap().index, 0);
        assert_eq!(src.next_frame().unwrap().unwrap().index, 1);
        for _ in 0..2 {
            let e = src.next_frame().unwrap_err().to_string();
            assert!(e.contains("000002.png"), "{e}");
        }
        assert_eq!(src.remaining(), Some(2));
        drop(src);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn sequence_frames_start_where_asked() {
        let Some(root) = crate::io::testing::real_data("visp_rbt_cube") else {
            return;
        };
        let seq = Sequence::open(&root).unwrap();
        let mut src = SequenceFrames::new(&seq, 97);
        assert_eq!(src.remaining(), Some(2));
        assert!(!src.has_timestamps());
        let f = src.next_frame().unwrap().unwrap();
        assert_eq!((f.index, f.label.as_str(), f.time_s), (97, "97", None));
        assert_eq!(src.next_frame().unwrap().unwrap().index, 98);
        assert!(src.next_frame().unwrap().is_none());
        assert_eq!(src.remaining(), Some(0));
        assert!(
            SequenceFrames::new(&seq, 500)
                .next_frame()
                .unwrap()
                .is_none()
        );
    }
}
