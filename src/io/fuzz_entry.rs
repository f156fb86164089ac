//! The entry points the fuzz targets (`fuzz/`, run with `cargo fuzz`) and
//! the corpus replay test (`tests/fuzz_corpus.rs`) share: each feeds
//! arbitrary bytes to one reader of untrusted files. They must return
//! (an error, usually), never panic, hang or allocate without bound.

use std::path::{Path, PathBuf};

/// The readers fuzzed, by the name of their target and corpus folder.
pub const TARGETS: [&str; 7] = [
    "ply",
    "camera_json",
    "camera_yaml",
    "poses_csv",
    "keyframe_store",
    "stl",
    "correspondences_csv",
];

/// Feeds `data` to the reader `target` names ([`TARGETS`]); true when it
/// accepted the input, false when it refused it with an error. Panics only
/// on an unknown target name (or on a bug the fuzzer is there to find).
pub fn run(target: &str, data: &[u8]) -> bool {
    match target {
        "ply" => ply(data),
        "camera_json" => camera(data, "camera.json"),
        "camera_yaml" => camera(data, "camera.yaml"),
        "poses_csv" => poses(data),
        "keyframe_store" => keyframe_store(data),
        "stl" => stl(data),
        "correspondences_csv" => correspondences(data),
        other => panic!("no fuzz target {other:?} (known: {TARGETS:?})"),
    }
}

/// The PLY loader (through a file: it reads from disk).
pub fn ply(data: &[u8]) -> bool {
    let path = scratch("ply");
    if std::fs::write(&path, data).is_err() {
        return false;
    }
    let ok = crate::model::PointModel::load(&path).is_ok();
    let _ = std::fs::remove_file(&path);
    ok
}

/// The camera reader, JSON or OpenCV YAML by `name`'s extension.
pub fn camera(data: &[u8], name: &str) -> bool {
    match std::str::from_utf8(data) {
        Ok(text) => crate::Intrinsics::from_text(text, Path::new(name)).is_ok(),
        Err(_) => false,
    }
}

/// The pose CSV reader.
pub fn poses(data: &[u8]) -> bool {
    match std::str::from_utf8(data) {
        Ok(text) => crate::io::poses::parse_poses(text, Path::new("poses.csv")).is_ok(),
        Err(_) => false,
    }
}

/// The readers of `init`'s `corr.csv` and `pts.csv` (the same bytes to
/// both; accepted when either accepts).
pub fn correspondences(data: &[u8]) -> bool {
    use crate::io::correspondences::{parse_named_points, parse_point_pairs};
    match std::str::from_utf8(data) {
        Ok(text) => {
            let pairs = parse_point_pairs(text, Path::new("corr.csv")).is_ok();
            let named = parse_named_points(text, Path::new("pts.csv")).is_ok();
            pairs || named
        }
        Err(_) => false,
    }
}

/// The keyframe store reader.
pub fn keyframe_store(data: &[u8]) -> bool {
    crate::keyframes::KeyframeStore::from_bytes(data, Path::new("store.stkf")).is_ok()
}

/// The STL reader (binary and ASCII), then the sampling of what it read.
pub fn stl(data: &[u8]) -> bool {
    match crate::model::parse_stl(data, Path::new("mesh.stl")) {
        Ok(mesh) => mesh.sample(64, 0).is_ok(),
        Err(_) => false,
    }
}

/// A file of this process and thread for readers that read from disk.
fn scratch(ext: &str) -> PathBuf {
    let dir = std::env::temp_dir();
    let id = format!("{:?}", std::thread::current().id());
    let id: String = id.chars().filter(char::is_ascii_digit).collect();
    dir.join(format!("splattrack-fuzz-{}-{id}.{ext}", std::process::id()))
}
