//! Live sources: a camera (`--device`, V4L2 through ffmpeg, [`LiveSource::device`])
//! or any producer of frames ([`LiveSource::from_producer`], e.g. a fake in
//! tests), read on a thread that keeps only the newest frame.
//!
//! How it works: the reader thread fills a frame buffer and puts it in a
//! one-frame slot. A frame still in the slot when the next one arrives was
//! not wanted in time (the tracker was busy with an earlier one): it is
//! dropped, counted, and its buffer reused. The tracker takes the newest
//! frame from the slot when it is ready. Memory is bounded: at most three
//! frames exist at once (the one being read, the one in the slot, the one
//! being tracked), however fast the camera and however slow the tracker.
//! Frames replaced before the tracker asked for its first one (while the
//! model and keyframes were loading) are not counted as dropped but as
//! skipped at start-up.

use crate::geometry::{Intrinsics, Undistorter};
use crate::io::ffmpeg::{
    Ffmpeg, FfmpegKiller, VideoError, check_size, replay_args, undistort, v4l2_args,
};
use crate::io::sequence::Frame;
use crate::io::source::{FrameSource, SourceError};
use image::RgbImage;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// What a producer says about the frame it just wrote: its number in the
/// order produced (from 0; gaps allowed) and its timestamp in seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stamp {
    /// The frame's number.
    pub index: usize,
    /// Its timestamp, seconds.
    pub time_s: f64,
}

/// Fills the buffer with the next frame (of the camera's size) and says
/// which it was; `Ok(None)` at the end of the stream.
pub type Producer = Box<dyn FnMut(&mut RgbImage) -> Result<Option<Stamp>, VideoError> + Send>;

/// Counts of a live source.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LiveCounts {
    /// Frames the producer delivered.
    pub produced: u64,
    /// Frames handed to the tracker.
    pub taken: u64,
    /// Frames replaced unread after the first was taken.
    pub dropped: u64,
    /// Frames replaced unread before the first was taken.
    pub skipped: u64,
    /// Frame buffers allocated in all (the rest were reused).
    pub buffers: u64,
}

#[derive(Default)]
struct State {
    /// The consumer has asked for a frame (a lazy source starts then).
    requested: bool,
    slot: Option<(Stamp, RgbImage)>,
    free: Vec<RgbImage>,
    end: Option<Result<(), VideoError>>,
    closing: bool,
    counts: LiveCounts,
}

struct Shared {
    state: Mutex<State>,
    ready: Condvar,
}

impl Shared {
    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// A live stream of frames (see the module docs).
pub struct LiveSource {
    name: PathBuf,
    camera: Intrinsics,
    undistorter: Option<Undistorter>,
    shared: Arc<Shared>,
    reader: Option<JoinHandle<()>>,
    killer: Arc<Mutex<Option<FfmpegKiller>>>,
    stop: Option<Arc<AtomicBool>>,
}

impl LiveSource {
    /// A live source of frames from `producer` (frames of `camera`'s size,
    /// as calibrated), read on its own thread; `name` names it in messages.
    pub fn from_producer(name: &Path, camera: &Intrinsics, producer: Producer) -> Self {
        Self::start(name, camera, producer, Arc::default(), false)
    }

    /// Starts the reader thread on `producer`; with `lazy`, the producer
    /// is first called when a frame is first asked for. `killer` holds
    /// the ffmpeg to kill on drop, once there is one.
    fn start(
        name: &Path,
        camera: &Intrinsics,
        mut producer: Producer,
        killer: Arc<Mutex<Option<FfmpegKiller>>>,
        lazy: bool,
    ) -> Self {
        let shared = Arc::new(Shared {
            state: Mutex::new(State::default()),
            ready: Condvar::new(),
        });
        let (w, h) = (camera.width, camera.height);
        let s = shared.clone();
        let reader = std::thread::Builder::new()
            .name("splattrack-live".into())
            .spawn(move || {
                if lazy {
                    let mut st = s.lock();
                    while !st.requested && !st.closing {
                        st = s.ready.wait(st).unwrap_or_else(|p| p.into_inner());
                    }
                }
                loop {
                    let mut buf = {
                        let mut st = s.lock();
                        if st.closing {
                            break;
                        }
                        match st.free.pop() {
                            Some(b) => b,
                            None => {
                                st.counts.buffers += 1;
                                RgbImage::new(w, h)
                            }
                        }
                    };
                    let got = producer(&mut buf);
                    let mut st = s.lock();
                    match got {
                        Ok(Some(stamp)) => {
                            st.counts.produced += 1;
                            if let Some((_, old)) = st.slot.replace((stamp, buf)) {
                                if st.counts.taken > 0 {
                                    st.counts.dropped += 1;
                                } else {
                                    st.counts.skipped += 1;
                                }
                                st.free.push(old);
                            }
                            s.ready.notify_all();
                        }
                        Ok(None) => {
                            st.end = Some(Ok(()));
                            s.ready.notify_all();
                            break;
                        }
                        Err(e) => {
                            st.end = Some(Err(e));
                            s.ready.notify_all();
                            break;
                        }
                    }
                }
            });
        let reader = match reader {
            Ok(h) => Some(h),
            Err(e) => {
                shared.lock().end = Some(Err(VideoError::Spawn {
                    path: name.to_owned(),
                    source: e,
                }));
                None
            }
        };
        Self {
            name: name.to_owned(),
            camera: *camera,
            undistorter: camera.has_distortion().then(|| Undistorter::new(camera)),
            shared,
            reader,
            killer,
            stop: None,
        }
    }

    /// Frames from `ffmpeg INPUT_ARGS` (the input options and `-i INPUT`),
    /// e.g. `-f v4l2 -i /dev/video0`, or `-re -i FILE` to replay a video at
    /// its own rate as a camera would deliver it. The first frame's size is
    /// checked against `camera` (from the file `camera_path`).
    pub fn ffmpeg(
        name: &Path,
        input_args: &[OsString],
        camera: &Intrinsics,
        camera_path: &Path,
    ) -> Result<Self, VideoError> {
        let mut ff = Ffmpeg::spawn(name, input_args)?;
        check_size(name, camera, camera_path, ff.size())?;
        let killer = Arc::new(Mutex::new(Some(ff.killer())));
        let producer: Producer = Box::new(move |buf: &mut RgbImage| {
            Ok(ff.read_frame(buf.as_mut())?.map(|i| Stamp {
                index: i.index,
                time_s: i.time_s,
            }))
        });
        Ok(Self::start(name, camera, producer, killer, false))
    }

    /// A video file replayed as a camera would deliver it: ffmpeg reads
    /// it at its own frame rate (`-re`), and frames that arrive while one
    /// is being tracked are dropped as a camera's would be. The replay
    /// starts when the first frame is asked for (not while the tracker
    /// is being set up); a file ffmpeg cannot read, or frames of another
    /// size than `camera`'s, are reported by that first request.
    pub fn replay(
        file: &Path,
        camera: &Intrinsics,
        camera_path: &Path,
    ) -> Result<Self, VideoError> {
        if !file.is_file() {
            return Err(VideoError::NotFound(file.to_owned()));
        }
        let args = replay_args(file);
        let killer: Arc<Mutex<Option<FfmpegKiller>>> = Arc::default();
        let slot = killer.clone();
        let (path, cam, cam_path) = (file.to_owned(), *camera, camera_path.to_owned());
        let mut ff: Option<Ffmpeg> = None;
        let producer: Producer = Box::new(move |buf: &mut RgbImage| {
            let f = match &mut ff {
                Some(f) => f,
                None => {
                    let f = Ffmpeg::spawn(&path, &args)?;
                    *slot.lock().unwrap_or_else(|p| p.into_inner()) = Some(f.killer());
                    check_size(&path, &cam, &cam_path, f.size())?;
                    ff.insert(f)
                }
            };
            Ok(f.read_frame(buf.as_mut())?.map(|i| Stamp {
                index: i.index,
                time_s: i.time_s,
            }))
        });
        Ok(Self::start(file, camera, producer, killer, true))
    }

    /// A camera: `device` is a number N (`/dev/videoN`) or a device path,
    /// read through V4L2 at the camera's size (Linux).
    pub fn device(
        device: &str,
        camera: &Intrinsics,
        camera_path: &Path,
    ) -> Result<Self, VideoError> {
        let path = device_path(device);
        if !cfg!(target_os = "linux") {
            return Err(VideoError::Unsupported {
                path,
                reason:
                    "cameras are read through V4L2, on Linux only; record a video and use --video"
                        .into(),
            });
        }
        if !path.exists() {
            return Err(VideoError::Unsupported {
                path,
                reason: "no such device (cameras are /dev/video0, /dev/video1, ...)".into(),
            });
        }
        let args = v4l2_args(&path, camera.width, camera.height);
        Self::ffmpeg(&path, &args, camera, camera_path)
    }

    /// Makes [`next_frame`](FrameSource::next_frame) return `None` (the end)
    /// once `flag` is set, also while it waits for a frame (Ctrl-C).
    pub fn stop_on(mut self, flag: Arc<AtomicBool>) -> Self {
        self.stop = Some(flag);
        self
    }

    /// The counts so far.
    pub fn counts(&self) -> LiveCounts {
        self.shared.lock().counts
    }
}

/// `/dev/videoN` for a number N, else the path as given.
pub fn device_path(device: &str) -> PathBuf {
    match device.trim().parse::<u32>() {
        Ok(n) => PathBuf::from(format!("/dev/video{n}")),
        Err(_) => PathBuf::from(device),
    }
}

impl FrameSource for LiveSource {
    fn camera(&self) -> &Intrinsics {
        &self.camera
    }

    fn name(&self) -> &Path {
        &self.name
    }

    fn has_timestamps(&self) -> bool {
        true
    }

    fn dropped(&self) -> u64 {
        self.counts().dropped
    }

    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
        let stopped = || self.stop.as_ref().is_some_and(|f| f.load(Ordering::SeqCst));
        let mut st = self.shared.lock();
        if !st.requested {
            st.requested = true;
            self.shared.ready.notify_all();
        }
        loop {
            if stopped() {
                return Ok(None);
            }
            if let Some((stamp, image)) = st.slot.take() {
                st.counts.taken += 1;
                drop(st);
                let image = undistort(self.undistorter.as_ref(), image, &self.name)?;
                return Ok(Some(Frame {
                    index: stamp.index,
                    label: stamp.index.to_string(),
                    path: self.name.clone(),
                    image,
                    time_s: Some(stamp.time_s),
                }));
            }
            if let Some(end) = st.end.take() {
                st.end = Some(Ok(()));
                return end.map(|()| None).map_err(SourceError::from);
            }
            st = self
                .shared
                .ready
                .wait_timeout(st, Duration::from_millis(50))
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }
}

impl Drop for LiveSource {
    fn drop(&mut self) {
        {
            let mut st = self.shared.lock();
            st.closing = true;
            st.slot = None;
            st.free.clear();
            self.shared.ready.notify_all();
        }
        // The reader may be blocked on ffmpeg's pipe: killing ffmpeg ends
        // the read; the reader then reaps it.
        if let Some(k) = &*self.killer.lock().unwrap_or_else(|p| p.into_inner()) {
            k.kill();
        }
        if let Some(h) = self.reader.take() {
            let _ = h.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Intrinsics {
        Intrinsics::new(8, 6, 10.0, 10.0, 3.5, 2.5)
    }

    /// A producer of `n` frames, one every 0.1 ms, each filled with its
    /// number.
    fn counting(n: usize) -> Producer {
        let mut k = 0;
        Box::new(move |buf: &mut RgbImage| {
            if k == n {
                return Ok(None);
            }
            std::thread::sleep(Duration::from_micros(100));
            buf.pixels_mut().for_each(|p| p.0 = [k as u8; 3]);
            k += 1;
            Ok(Some(Stamp {
                index: k - 1,
                time_s: (k - 1) as f64 / 30.0,
            }))
        })
    }

    #[test]
    fn a_slow_consumer_gets_the_newest_frames_and_the_rest_are_counted() {
        let mut src = LiveSource::from_producer(Path::new("fake"), &camera(), counting(2000));
        let mut seen = Vec::new();
        while let Some(f) = src.next_frame().unwrap() {
            // Each frame's pixels are the frame it says it is.
            assert_eq!(f.image.get_pixel(0, 0).0, [f.index as u8; 3]);
            assert_eq!(f.time_s, Some(f.index as f64 / 30.0));
            seen.push(f.index);
            std::thread::sleep(Duration::from_millis(2));
        }
        let c = src.counts();
        assert!(seen.windows(2).all(|w| w[0] < w[1]), "{seen:?}");
        assert_eq!(c.produced, 2000);
        assert_eq!(c.taken as usize, seen.len());
        assert_eq!(c.produced, c.taken + c.dropped + c.skipped);
        // Every frame after the first that was not taken was dropped: the
        // gaps in the numbers.
        let gaps: usize = seen.windows(2).map(|w| w[1] - w[0] - 1).sum();
        assert_eq!(gaps as u64, c.dropped);
        assert!(c.dropped > 0, "{c:?}");
        // Bounded memory: a buffer per frame taken (it leaves with the
        // frame) and at most two more, never one per frame produced.
        assert!(c.buffers <= c.taken + 2, "{c:?}");
        assert_eq!(*seen.last().unwrap(), 1999);
    }

    #[test]
    fn stop_ends_a_wait_and_errors_come_through() {
        let flag = Arc::new(AtomicBool::new(false));
        let mut k = 0;
        // The first frame at once, the next a second later.
        let slow: Producer = Box::new(move |_| {
            if k > 0 {
                std::thread::sleep(Duration::from_secs(1));
            }
            k += 1;
            Ok(Some(Stamp {
                index: k,
                time_s: 0.0,
            }))
        });
        let mut src =
            LiveSource::from_producer(Path::new("fake"), &camera(), slow).stop_on(flag.clone());
        assert!(src.next_frame().unwrap().is_some());
        let f2 = flag.clone();
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(30));
            f2.store(true, Ordering::SeqCst);
        });
        assert!(src.next_frame().unwrap().is_none());
        drop(src);

        let failing: Producer = Box::new(|_| {
            Err(VideoError::Died {
                path: "cam".into(),
                frame: 0,
                reason: "unplugged".into(),
            })
        });
        let mut src = LiveSource::from_producer(Path::new("cam"), &camera(), failing);
        let e = src.next_frame().unwrap_err().to_string();
        assert!(e.contains("cam") && e.contains("unplugged"), "{e}");
        assert!(src.next_frame().unwrap().is_none());
    }

    #[test]
    fn device_numbers_name_dev_video() {
        assert_eq!(device_path("0"), PathBuf::from("/dev/video0"));
        assert_eq!(device_path("/dev/video2"), PathBuf::from("/dev/video2"));
        let e = LiveSource::device("97", &camera(), Path::new("camera.json"))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("/dev/video97"), "{e}");
    }
}
