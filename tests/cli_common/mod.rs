//! Helpers shared by the tests that run the `splattrack` binary: a run
//! with a deadline (a hang fails the test), success and one-line failure
//! checks, and the ffmpeg program for the video tests.
#![allow(dead_code)]

use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// How long one run of the binary may take before it counts as a hang.
pub const DEADLINE: Duration = Duration::from_secs(240);

/// Runs the binary with `env` added (lavapipe unless
/// `SPLATTRACK_ADAPTER` says otherwise), killing it after [`DEADLINE`]:
/// (success, stdout, stderr).
pub fn run_env(args: &[&str], env: &[(&str, &str)]) -> (bool, String, String) {
    let mut c = Command::new(env!("CARGO_BIN_EXE_splattrack"));
    if std::env::var_os("SPLATTRACK_ADAPTER").is_none() {
        c.env("SPLATTRACK_ADAPTER", "cpu");
    }
    let mut child = c
        .args(args)
        .envs(env.iter().copied())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run splattrack");
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > DEADLINE {
            let _ = child.kill();
            panic!("{args:?} still running after {DEADLINE:?} (a hang)");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let (mut out, mut err) = (String::new(), String::new());
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut out)
        .unwrap();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    (status.success(), out, err)
}

/// [`run_env`] without extra environment.
pub fn run(args: &[&str]) -> (bool, String, String) {
    run_env(args, &[])
}

/// Expects success without a panic: stdout.
pub fn ok(args: &[&str]) -> String {
    let (success, out, err) = run(args);
    assert!(success, "{args:?} failed: {err}");
    assert!(!err.contains("panicked"), "{err}");
    out
}

/// Expects a failure with one line on stderr holding every needle: stderr.
pub fn fails_env(args: &[&str], env: &[(&str, &str)], needles: &[&str]) -> String {
    let (success, _, err) = run_env(args, env);
    assert!(!success, "{args:?} succeeded");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: {err:?} lacks {n:?}");
    }
    err
}

/// [`fails_env`] without extra environment.
pub fn fails(args: &[&str], needles: &[&str]) -> String {
    fails_env(args, &[], needles)
}

/// A path as the `&str` an argument list takes.
pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Runs ffmpeg to make a test video; fails loudly when it is missing.
pub fn ffmpeg(args: &[&str]) {
    let out = Command::new("ffmpeg")
        .args(["-hide_banner", "-loglevel", "error", "-y"])
        .args(args)
        .output()
        .unwrap_or_else(|e| {
            panic!("these tests need the ffmpeg program (apt install ffmpeg): {e}")
        });
    assert!(
        out.status.success(),
        "ffmpeg {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The frames of the pose file `out` reported `tracking`, each asserted
/// within `bound_deg` degrees of the ground truth `gt` (a pose file from
/// the same first frame on); `refused` (the refused estimates' file) is
/// printed with a failure, `what` names the run. (frames tracking, frames
/// in `out`).
pub fn tracking_within(
    out: &Path,
    gt: &Path,
    refused: &Path,
    bound_deg: f64,
    what: &str,
) -> (usize, usize) {
    use splattrack::io::read_poses;
    let rows = read_poses(out).unwrap();
    let gt = read_poses(gt).unwrap();
    assert!(
        rows.len() <= gt.len(),
        "{what}: more frames than the truth's"
    );
    let refusals = std::fs::read_to_string(refused).unwrap_or_default();
    let mut tracking = 0;
    for (r, g) in rows.iter().zip(&gt) {
        if r.extra[2].1 != "tracking" {
            continue;
        }
        tracking += 1;
        let rot = r.pose.rotation_error_deg(&g.pose);
        assert!(
            rot < bound_deg,
            "{what}: frame {} tracking {rot:.1} degrees off; refused:\n{refusals}",
            r.frame
        );
    }
    (tracking, rows.len())
}
