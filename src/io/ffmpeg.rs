//! The `ffmpeg` and `ffprobe` programs: a child `ffmpeg` that decodes a
//! video file or a camera into RGB frames on a pipe ([`Ffmpeg`]), read by
//! [`crate::io::video`] and [`crate::io::live`]; the arguments that name
//! their inputs; the frame count `ffprobe` reads from a container; and
//! the checks of the frames they deliver.
//!
//! How it works: `ffmpeg -i FILE -map 0:v:0 -vf showinfo -vsync passthrough
//! -f rawvideo -pix_fmt rgb24 pipe:1` decodes the first video stream and
//! writes every frame, as decoded (no frame duplicated or dropped to make a
//! constant rate), as `width * height * 3` bytes of RGB on its standard
//! output; the `showinfo` filter logs each frame's number, size and
//! presentation timestamp on standard error, where a thread reads them in
//! order (the log line of a frame is written before its pixels).
//!
//! Why a child process rather than FFmpeg's libraries or a Rust decoder:
//! the user needs only the `ffmpeg` program (every package manager has
//! one; tested with 5.1), the crate builds with no C headers or
//! libraries, every container and codec that ffmpeg reads works (MP4/H.264
//! and H.265, MOV, AVI, MKV, WebM/VP8/VP9/AV1, MJPEG), and the same route
//! reads V4L2 cameras. The cost is one copy of each frame through a pipe,
//! measured as small beside tracking (docs/performance.md).
//!
//! The child runs in its own process group (so the terminal's Ctrl-C
//! reaches only splattrack, which then stops it), is killed and reaped on
//! every path (end, error, drop): no zombie, no orphan left decoding.

use crate::geometry::{Intrinsics, Undistorter};
use std::ffi::OsString;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, ExitStatus, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// The program run to decode (looked up on `PATH`).
pub const FFMPEG: &str = "ffmpeg";

/// How long [`Ffmpeg::spawn`] waits for the first frame (a camera that
/// opens but sends nothing).
pub const FIRST_FRAME_TIMEOUT: Duration = Duration::from_secs(30);

/// Why a video or camera could not be read.
#[derive(Debug, thiserror::Error)]
pub enum VideoError {
    /// The `ffmpeg` program is not installed.
    #[error(
        "ffmpeg not found on PATH: install it (apt install ffmpeg, dnf install ffmpeg, brew install ffmpeg, or https://ffmpeg.org/download.html)"
    )]
    NoFfmpeg,
    /// The video file does not exist.
    #[error("{0}: no such file")]
    NotFound(PathBuf),
    /// `ffmpeg` could not be started.
    #[error("{path}: cannot start ffmpeg: {source}")]
    Spawn {
        /// The video or device.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// `ffmpeg` could not open or decode it (not a video, an unsupported
    /// codec, a missing device).
    #[error("{path}: cannot decode: {reason}")]
    Open {
        /// The video or device.
        path: PathBuf,
        /// ffmpeg's own message.
        reason: String,
    },
    /// It holds no video frame.
    #[error("{0}: no video frames")]
    Empty(PathBuf),
    /// Its frames are not the camera's size.
    #[error("{path}: frames are {got_w}x{got_h}, the camera ({camera}) is {want_w}x{want_h}")]
    FrameSize {
        /// The video or device.
        path: PathBuf,
        /// The camera file.
        camera: PathBuf,
        /// The frames' width.
        got_w: u32,
        /// The frames' height.
        got_h: u32,
        /// The camera's width.
        want_w: u32,
        /// The camera's height.
        want_h: u32,
    },
    /// Decoding stopped part way (a corrupt file, ffmpeg killed, a camera
    /// unplugged).
    #[error("{path}: decoding stopped at frame {frame}: {reason}")]
    Died {
        /// The video or device.
        path: PathBuf,
        /// The frame that could not be read.
        frame: usize,
        /// ffmpeg's message, or its exit status.
        reason: String,
    },
    /// A frame could not be undistorted.
    #[error("{path}: cannot undistort: {reason}")]
    Undistort {
        /// The video or device.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// Not available on this platform or not a valid device.
    #[error("{path}: {reason}")]
    Unsupported {
        /// The device.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

/// What `showinfo` says about one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameInfo {
    /// Its number in decode order, from 0.
    pub index: usize,
    /// Its presentation time, seconds (NaN when the stream has none).
    pub time_s: f64,
    /// Its size.
    pub width: u32,
    /// Its size.
    pub height: u32,
}

/// A running `ffmpeg` that writes RGB frames to a pipe.
pub struct Ffmpeg {
    path: PathBuf,
    child: Arc<Mutex<Child>>,
    stdout: ChildStdout,
    infos: Receiver<FrameInfo>,
    stderr: Option<JoinHandle<Vec<String>>>,
    first: Option<FrameInfo>,
    width: u32,
    height: u32,
    next: usize,
    done: bool,
}

/// Kills a running [`Ffmpeg`] from another thread (its reader may be blocked
/// on the pipe).
#[derive(Clone)]
pub struct FfmpegKiller(Arc<Mutex<Child>>);

impl FfmpegKiller {
    /// Kills the process (a no-op once it has exited).
    pub fn kill(&self) {
        let _ = self.0.lock().unwrap_or_else(|p| p.into_inner()).kill();
    }
}

impl Ffmpeg {
    /// Starts `ffmpeg INPUT_ARGS ...` (the input options and `-i INPUT`) for
    /// `path` and waits for the first frame's size. A missing program, an
    /// input ffmpeg cannot open and an input without video frames fail
    /// here, named by `path`.
    pub fn spawn(path: &Path, input_args: &[OsString]) -> Result<Self, VideoError> {
        let mut cmd = Command::new(FFMPEG);
        cmd.args(["-hide_banner", "-nostdin", "-nostats"])
            // "level": each line says [info], [warning], [error] or [fatal].
            .args(["-loglevel", "level+info"])
            .args(input_args)
            .args(["-map", "0:v:0", "-vf", "showinfo", "-vsync", "passthrough"])
            .args(["-f", "rawvideo", "-pix_fmt", "rgb24", "pipe:1"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        #[cfg(unix)]
        {
            use std::os::unix::process::CommandExt;
            cmd.process_group(0);
        }
        let mut child = cmd.spawn().map_err(|source| match source.kind() {
            std::io::ErrorKind::NotFound => VideoError::NoFfmpeg,
            _ => VideoError::Spawn {
                path: path.to_owned(),
                source,
            },
        })?;
        let (stdout, stderr) = (child.stdout.take(), child.stderr.take());
        let child = Arc::new(Mutex::new(child));
        let (Some(stdout), Some(stderr)) = (stdout, stderr) else {
            kill_and_reap(&child);
            return Err(VideoError::Spawn {
                path: path.to_owned(),
                source: std::io::Error::other("no pipes to the child"),
            });
        };
        let (tx, infos) = channel();
        let stderr = std::thread::Builder::new()
            .name("ffmpeg-stderr".into())
            .spawn(move || read_log(stderr, |info| tx.send(info).is_ok()))
            .map_err(|source| {
                kill_and_reap(&child);
                VideoError::Spawn {
                    path: path.to_owned(),
                    source,
                }
            })?;
        let mut ff = Self {
            path: path.to_owned(),
            child,
            stdout,
            infos,
            stderr: Some(stderr),
            first: None,
            width: 0,
            height: 0,
            next: 0,
            done: false,
        };
        match ff.infos.recv_timeout(FIRST_FRAME_TIMEOUT) {
            Ok(info) => {
                ff.width = info.width;
                ff.height = info.height;
                ff.first = Some(info);
                Ok(ff)
            }
            Err(RecvTimeoutError::Timeout) => {
                ff.reap(true);
                Err(VideoError::Open {
                    path: path.to_owned(),
                    reason: format!("no frame within {} s", FIRST_FRAME_TIMEOUT.as_secs()),
                })
            }
            Err(RecvTimeoutError::Disconnected) => {
                // The log ended without a frame: ffmpeg exited.
                let (status, errors) = ff.reap(false);
                Err(match errors.last() {
                    Some(e) => VideoError::Open {
                        path: path.to_owned(),
                        reason: e.clone(),
                    },
                    None if status.is_some_and(|s| s.success()) => {
                        VideoError::Empty(path.to_owned())
                    }
                    None => VideoError::Open {
                        path: path.to_owned(),
                        reason: describe_status(status),
                    },
                })
            }
        }
    }

    /// The frames' size.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// A handle that kills the process from another thread.
    pub fn killer(&self) -> FfmpegKiller {
        FfmpegKiller(self.child.clone())
    }

    /// Reads the next frame into `rgb` (`width * height * 3` bytes); `None`
    /// at the end of the stream, after which the process has been reaped.
    pub fn read_frame(&mut self, rgb: &mut [u8]) -> Result<Option<FrameInfo>, VideoError> {
        if self.done {
            return Ok(None);
        }
        let info = match self.first.take() {
            Some(i) => i,
            None => match self.infos.recv() {
                Ok(i) => i,
                Err(_) => return self.end(),
            },
        };
        if (info.width, info.height) != (self.width, self.height) {
            return Err(self.fail(format!(
                "the frame size changed from {}x{} to {}x{}",
                self.width, self.height, info.width, info.height
            )));
        }
        if rgb.len() != self.width as usize * self.height as usize * 3 {
            return Err(self.fail(format!(
                "a buffer of {} bytes for {}x{} RGB frames",
                rgb.len(),
                self.width,
                self.height
            )));
        }
        if let Err(e) = self.stdout.read_exact(rgb) {
            let (status, errors) = self.reap(false);
            return Err(VideoError::Died {
                path: self.path.clone(),
                frame: self.next,
                reason: errors
                    .last()
                    .cloned()
                    .unwrap_or_else(|| format!("{e} ({})", describe_status(status))),
            });
        }
        let info = FrameInfo {
            index: self.next,
            ..info
        };
        self.next += 1;
        Ok(Some(info))
    }

    /// The end of the log: the process exits; a failure is reported.
    fn end(&mut self) -> Result<Option<FrameInfo>, VideoError> {
        // Whatever is left on the pipe is not a whole logged frame.
        let mut rest = [0u8; 1];
        let trailing = matches!(self.stdout.read(&mut rest), Ok(n) if n > 0);
        let (status, errors) = self.reap(trailing);
        if status.is_some_and(|s| s.success()) && !trailing {
            return Ok(None);
        }
        Err(VideoError::Died {
            path: self.path.clone(),
            frame: self.next,
            reason: errors.last().cloned().unwrap_or_else(|| {
                if trailing {
                    "ffmpeg wrote a frame it did not log".into()
                } else {
                    describe_status(status)
                }
            }),
        })
    }

    /// Kills the process and makes a [`VideoError::Died`] of `reason`.
    fn fail(&mut self, reason: String) -> VideoError {
        self.reap(true);
        VideoError::Died {
            path: self.path.clone(),
            frame: self.next,
            reason,
        }
    }

    /// Ends the process, waits for it and for the log reader: its exit
    /// status (`None`: killed by us) and the error lines it logged. With
    /// `kill` it is killed at once; otherwise it is expected to be exiting
    /// (its pipes closed) and is killed only if it has not within a second.
    fn reap(&mut self, kill: bool) -> (Option<ExitStatus>, Vec<String>) {
        self.done = true;
        let status = if kill {
            None
        } else {
            wait_briefly(&self.child)
        };
        if status.is_none() {
            kill_and_reap(&self.child);
        }
        let errors = self
            .stderr
            .take()
            .and_then(|h| h.join().ok())
            .unwrap_or_default();
        (status, errors)
    }
}

impl Drop for Ffmpeg {
    fn drop(&mut self) {
        if !self.done || self.stderr.is_some() {
            kill_and_reap(&self.child);
            if let Some(h) = self.stderr.take() {
                let _ = h.join();
            }
        }
    }
}

/// Waits up to a second for a process that is expected to be exiting.
fn wait_briefly(child: &Mutex<Child>) -> Option<ExitStatus> {
    for _ in 0..200 {
        match child.lock().unwrap_or_else(|p| p.into_inner()).try_wait() {
            Ok(Some(s)) => return Some(s),
            Ok(None) => {}
            Err(_) => return None,
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    None
}

fn kill_and_reap(child: &Mutex<Child>) {
    let mut c = child.lock().unwrap_or_else(|p| p.into_inner());
    let _ = c.kill();
    let _ = c.wait();
}

fn describe_status(status: Option<ExitStatus>) -> String {
    match status {
        Some(s) => format!("ffmpeg exited with {s}"),
        None => "ffmpeg did not exit and was stopped".into(),
    }
}

/// Reads ffmpeg's log: frame lines of `showinfo` go to `frame` (until it
/// returns false), `[error]` and `[fatal]` lines are returned (the last
/// few), everything else is ignored.
fn read_log(stderr: impl Read, mut frame: impl FnMut(FrameInfo) -> bool) -> Vec<String> {
    let mut r = BufReader::new(stderr);
    let mut errors: Vec<String> = Vec::new();
    let mut time_base: Option<(i64, i64)> = None;
    let mut line = Vec::new();
    let mut sending = true;
    loop {
        line.clear();
        match r.read_until(b'\n', &mut line) {
            Ok(0) | Err(_) => break,
            Ok(_) => {}
        }
        let text = String::from_utf8_lossy(&line);
        let text = text.trim_end();
        if text.contains("Parsed_showinfo") {
            if let Some(tb) = parse_time_base(text) {
                time_base = Some(tb);
            } else if let Some(info) = parse_showinfo(text, time_base) {
                if sending {
                    sending = frame(info);
                }
            }
        } else if let Some(msg) = error_message(text) {
            if errors.len() == 8 {
                errors.remove(0);
            }
            errors.push(msg);
        }
    }
    errors
}

/// `[error] msg` or `[... @ 0x..] [fatal] msg`: the message.
fn error_message(line: &str) -> Option<String> {
    for tag in ["[error] ", "[fatal] "] {
        if let Some(k) = line.find(tag) {
            let msg = line[k + tag.len()..].trim();
            if !msg.is_empty() && !msg.starts_with("Conversion failed") {
                return Some(msg.to_owned());
            }
        }
    }
    None
}

/// `config in time_base: 1/15360, ...` (showinfo, ffmpeg 5 on).
fn parse_time_base(line: &str) -> Option<(i64, i64)> {
    let rest = &line[line.find("config in time_base:")? + "config in time_base:".len()..];
    let tb = rest.split(',').next()?.trim();
    let (n, d) = tb.split_once('/')?;
    let (n, d) = (n.trim().parse().ok()?, d.trim().parse().ok()?);
    (n > 0 && d > 0).then_some((n, d))
}

/// The value of `key` in a showinfo line (`n:   3`, `n:1234`, `s:640x480`).
fn field<'a>(tokens: &[&'a str], key: &str) -> Option<&'a str> {
    let k = tokens.iter().position(|t| t.starts_with(key))?;
    let v = &tokens[k][key.len()..];
    if v.is_empty() {
        tokens.get(k + 1).copied()
    } else {
        Some(v)
    }
}

/// A showinfo frame line: `n: 0 pts: 512 pts_time:0.0333 ... s:640x480 ...`.
fn parse_showinfo(line: &str, time_base: Option<(i64, i64)>) -> Option<FrameInfo> {
    let body = &line[line
        .find("] n:")
        .map(|k| k + 2)
        .or_else(|| line.find(" n:"))?..];
    let tokens: Vec<&str> = body.split_whitespace().collect();
    let index = field(&tokens, "n:")?.parse().ok()?;
    let (w, h) = field(&tokens, "s:")?.split_once('x')?;
    let (width, height) = (w.parse().ok()?, h.parse().ok()?);
    // pts in the time base is exact; pts_time is printed to 6 digits.
    let pts: Option<i64> = field(&tokens, "pts:").and_then(|p| p.parse().ok());
    let time_s = match (pts, time_base) {
        (Some(p), Some((n, d))) => p as f64 * n as f64 / d as f64,
        _ => field(&tokens, "pts_time:")
            .and_then(|t| t.parse().ok())
            .unwrap_or(f64::NAN),
    };
    Some(FrameInfo {
        index,
        time_s,
        width,
        height,
    })
}

/// The FFmpeg prober, which comes with the ffmpeg program.
pub const FFPROBE: &str = "ffprobe";

/// How many frames the container of `path` says its first video stream
/// has: its frame count, else its duration times its mean frame rate;
/// `None` where ffprobe is missing or says neither. For progress only.
pub fn probe_frame_count(path: &Path) -> Option<usize> {
    let input = file_input(path);
    let out = Command::new(FFPROBE)
        .args(["-v", "error", "-select_streams", "v:0", "-show_entries"])
        .arg("stream=nb_frames,avg_frame_rate,duration:format=duration")
        .args(["-of", "default=noprint_wrappers=1"])
        .arg(input)
        .stdin(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    parse_probe(&String::from_utf8_lossy(&out.stdout))
}

/// The frame count from ffprobe's `key=value` lines (module
/// [`probe_frame_count`]).
fn parse_probe(text: &str) -> Option<usize> {
    let mut nb_frames = None;
    let mut rate = None;
    let mut duration = None;
    for line in text.lines() {
        let Some((key, value)) = line.trim().split_once('=') else {
            continue;
        };
        match key {
            "nb_frames" => nb_frames = value.parse::<usize>().ok().filter(|n| *n > 0),
            "avg_frame_rate" => {
                rate = value.split_once('/').and_then(|(a, b)| {
                    let (a, b) = (a.parse::<f64>().ok()?, b.parse::<f64>().ok()?);
                    (b > 0.0 && a > 0.0).then_some(a / b)
                })
            }
            // The stream's duration comes first; the container's fills in.
            "duration" if duration.is_none() => {
                duration = value.parse::<f64>().ok().filter(|d| *d > 0.0);
            }
            _ => {}
        }
    }
    let from_duration = || {
        let n = (duration? * rate?).round();
        (1.0..1e9).contains(&n).then_some(n as usize)
    };
    nb_frames.or_else(from_duration)
}

/// A file as ffmpeg's input: "file:" keeps ffmpeg from reading a name
/// with a colon as a protocol, or one starting with '-' as an option.
pub(crate) fn file_input(path: &Path) -> OsString {
    let mut input = OsString::from("file:");
    input.push(path.as_os_str());
    input
}

/// The input arguments of a video file decoded as fast as it goes.
pub(crate) fn file_args(path: &Path) -> Vec<OsString> {
    vec!["-i".into(), file_input(path)]
}

/// The input arguments of a video file read at its own frame rate
/// (`-re`), as a camera would deliver it.
pub(crate) fn replay_args(path: &Path) -> Vec<OsString> {
    vec!["-re".into(), "-i".into(), file_input(path)]
}

/// The input arguments of a V4L2 camera at `width` x `height`.
pub(crate) fn v4l2_args(device: &Path, width: u32, height: u32) -> Vec<OsString> {
    vec![
        "-f".into(),
        "v4l2".into(),
        "-video_size".into(),
        format!("{width}x{height}").into(),
        "-i".into(),
        device.to_path_buf().into_os_string(),
    ]
}

/// Refuses frames whose size is not the camera's.
pub(crate) fn check_size(
    path: &Path,
    camera: &Intrinsics,
    camera_path: &Path,
    (got_w, got_h): (u32, u32),
) -> Result<(), VideoError> {
    if (got_w, got_h) != (camera.width, camera.height) {
        return Err(VideoError::FrameSize {
            path: path.to_owned(),
            camera: camera_path.to_owned(),
            got_w,
            got_h,
            want_w: camera.width,
            want_h: camera.height,
        });
    }
    Ok(())
}

/// Undistorts `image` when there is an undistorter.
pub(crate) fn undistort(
    und: Option<&Undistorter>,
    image: image::RgbImage,
    path: &Path,
) -> Result<image::RgbImage, VideoError> {
    match und {
        Some(u) => u.apply(&image).map_err(|reason| VideoError::Undistort {
            path: path.to_owned(),
            reason,
        }),
        None => Ok(image),
    }
}

#[cfg(test)]
mod probe_tests {
    use super::parse_probe;

    #[test]
    fn the_frame_count_comes_from_the_count_else_duration_times_rate() {
        let mp4 = "avg_frame_rate=15/1\nduration=2.000000\nnb_frames=30\nduration=2.000000\n";
        assert_eq!(parse_probe(mp4), Some(30));
        // Matroska and WebM streams carry no count or duration: the
        // container's duration.
        let mkv = "avg_frame_rate=30000/1001\nduration=N/A\nnb_frames=N/A\nduration=10.010000\n";
        assert_eq!(parse_probe(mkv), Some(300));
        assert_eq!(parse_probe("avg_frame_rate=0/0\nnb_frames=N/A\n"), None);
        assert_eq!(parse_probe(""), None);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn showinfo_lines_parse_across_ffmpeg_versions() {
        // ffmpeg 5.1 (Debian 12), with the time base line before.
        let tb = parse_time_base(
            "[Parsed_showinfo_0 @ 0x5641] [info] config in time_base: 1/15360, frame_rate: 30/1",
        );
        assert_eq!(tb, Some((1, 15360)));
        let l = "[Parsed_showinfo_0 @ 0x5641] [info] n:   3 pts:   1536 pts_time:0.1       pos:    48 fmt:yuv420p sar:1/1 s:640x480 i:P iskey:0 type:P checksum:715B001D";
        let i = parse_showinfo(l, tb).unwrap();
        assert_eq!((i.index, i.width, i.height), (3, 640, 480));
        assert!((i.time_s - 0.1).abs() < 1e-12);
        // ffmpeg 4 (no time base line: pts_time), a wide frame number, and
        // ffmpeg 6's duration fields.
        let l = "[Parsed_showinfo_0 @ 0x1] [info] n:12345 pts:12345 pts_time:411.5 duration:1 duration_time:0.0333 pos:-1 fmt:rgb24 sar:0/1 s:320x240 i:P iskey:1 type:I";
        let i = parse_showinfo(l, None).unwrap();
        assert_eq!(
            (i.index, i.time_s, i.width, i.height),
            (12345, 411.5, 320, 240)
        );
        // No timestamp.
        let l = "[Parsed_showinfo_0 @ 0x1] [info] n:   0 pts:NOPTS pts_time:NOPTS pos: 1 fmt:yuv420p sar:1/1 s:64x48 i:P";
        assert!(parse_showinfo(l, Some((1, 30))).unwrap().time_s.is_nan());
        // Side-data lines of showinfo are not frames.
        for l in [
            "[Parsed_showinfo_0 @ 0x1] [info]   side data - User Data Unregistered:",
            "[Parsed_showinfo_0 @ 0x1] [info] color_range:unknown color_space:unknown",
        ] {
            assert_eq!(parse_showinfo(l, tb), None, "{l}");
        }
        assert_eq!(
            error_message("[error] /tmp/x.mp4: Invalid data found when processing input"),
            Some("/tmp/x.mp4: Invalid data found when processing input".into())
        );
        assert_eq!(
            error_message("[mov,mp4 @ 0x1] [error] moov atom not found"),
            Some("moov atom not found".into())
        );
        assert_eq!(error_message("[info] Stream #0:0: Video: h264"), None);
    }

    #[test]
    fn the_log_reader_sends_frames_and_keeps_errors() {
        let log = "[info] Input #0\n\
            [Parsed_showinfo_0 @ 0x1] [info] config in time_base: 1/15, frame_rate: 15/1\n\
            [Parsed_showinfo_0 @ 0x1] [info] n:   0 pts:      0 pts_time:0 pos: 1 fmt:yuv420p sar:1/1 s:64x48 i:P\n\
            [h264 @ 0x2] [error] corrupt macroblock\n\
            [Parsed_showinfo_0 @ 0x1] [info] n:   1 pts:      1 pts_time:0.0666667 pos: 1 fmt:yuv420p sar:1/1 s:64x48 i:P\n";
        let mut got = Vec::new();
        let errors = read_log(log.as_bytes(), |i| {
            got.push(i);
            true
        });
        assert_eq!(got.len(), 2);
        assert_eq!(got[1].time_s, 1.0 / 15.0);
        assert_eq!(errors, vec!["corrupt macroblock".to_string()]);
    }
}
