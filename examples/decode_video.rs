//! How fast `splattrack track --video` gets its frames: decodes a video
//! through [`VideoSource`] (an ffmpeg child process piping RGB frames, the
//! route `track --video` takes) and prints frames per second.
//!
//! ```text
//! cargo run --release --example decode_video -- VIDEO CAMERA.json
//! ```
//!
//! The camera file gives the frame size the video must have (and its
//! distortion, which is then removed from every frame, as when tracking).

use splattrack::Intrinsics;
use splattrack::io::source::{FrameSource, Start};
use splattrack::io::video::VideoSource;
use std::path::Path;
use std::time::Instant;

fn main() -> std::process::ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [video, camera] = args.as_slice() else {
        eprintln!("usage: decode_video VIDEO CAMERA.json");
        return std::process::ExitCode::FAILURE;
    };
    match run(Path::new(video), Path::new(camera)) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(video: &Path, camera: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let cam = Intrinsics::load(camera)?;
    let start = Instant::now();
    let mut src = VideoSource::open(video, &cam, camera, Start::Frame(0))?;
    let opened = start.elapsed().as_secs_f64();
    let mut n = 0usize;
    let mut last_t = 0.0;
    while let Some(f) = src.next_frame()? {
        n += 1;
        last_t = f.time_s.unwrap_or(f64::NAN);
    }
    let secs = start.elapsed().as_secs_f64();
    println!(
        "{}: {n} frames of {}x{} ({last_t:.3} s of video) in {secs:.2} s (first frame after {:.0} ms): {:.0} frames/s",
        video.display(),
        cam.width,
        cam.height,
        opened * 1e3,
        n as f64 / secs
    );
    Ok(())
}
