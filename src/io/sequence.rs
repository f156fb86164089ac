//! Sequence directories (FORMATS.md "Sequence directory"): `camera.json` (or
//! an OpenCV `camera.yaml`), `frames/` (png or jpg, sorted by name),
//! `init.csv`, optional `poses.csv` (ground truth) and `keyframes/`.

use crate::geometry::Intrinsics;
use crate::io::camera::CameraError;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum SequenceError {
    #[error("{0}: not a directory")]
    NotADirectory(PathBuf),
    #[error("{0}: no camera file (expected camera.json, camera.yaml or camera.yml)")]
    NoCamera(PathBuf),
    #[error("{0}: no frames (expected .png or .jpg images in frames/)")]
    NoFrames(PathBuf),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Camera(#[from] CameraError),
}

/// A sequence on disk; frames are read lazily.
#[derive(Debug, Clone)]
pub struct Sequence {
    pub dir: PathBuf,
    pub camera: Intrinsics,
    pub camera_path: PathBuf,
    /// Frame image paths, sorted by file name.
    pub frames: Vec<PathBuf>,
}

fn is_image(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .map(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
        .unwrap_or(false)
}

/// Image files of a directory, sorted by name.
pub fn list_images(dir: &Path) -> Result<Vec<PathBuf>, SequenceError> {
    let rd = std::fs::read_dir(dir).map_err(|source| SequenceError::Io {
        path: dir.to_owned(),
        source,
    })?;
    let mut v: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && is_image(p))
        .collect();
    v.sort();
    Ok(v)
}

impl Sequence {
    pub fn open(dir: &Path) -> Result<Self, SequenceError> {
        if !dir.is_dir() {
            return Err(SequenceError::NotADirectory(dir.to_owned()));
        }
        let camera_path = ["camera.json", "camera.yaml", "camera.yml"]
            .iter()
            .map(|n| dir.join(n))
            .find(|p| p.is_file())
            .ok_or_else(|| SequenceError::NoCamera(dir.to_owned()))?;
        let camera = Intrinsics::load(&camera_path)?;
        let frames_dir = dir.join("frames");
        if !frames_dir.is_dir() {
            return Err(SequenceError::NoFrames(frames_dir));
        }
        let frames = list_images(&frames_dir)?;
        if frames.is_empty() {
            return Err(SequenceError::NoFrames(frames_dir));
        }
        Ok(Self {
            dir: dir.to_owned(),
            camera,
            camera_path,
            frames,
        })
    }

    /// `init.csv` of the sequence.
    pub fn init_path(&self) -> PathBuf {
        self.dir.join("init.csv")
    }

    /// `poses.csv` (ground truth), when present.
    pub fn ground_truth_path(&self) -> Option<PathBuf> {
        Some(self.dir.join("poses.csv")).filter(|p| p.is_file())
    }

    /// `keyframes/`, when it has a poses.csv.
    pub fn keyframes_dir(&self) -> Option<PathBuf> {
        Some(self.dir.join("keyframes")).filter(|p| p.join("poses.csv").is_file())
    }

    /// The label of frame `i` in pose files: its index, as FORMATS.md says.
    pub fn frame_label(&self, i: usize) -> String {
        i.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_sequences_open() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
        for name in ["visp_rbt_cube", "visp_rbt_dragon"] {
            let s = Sequence::open(&root.join(name)).unwrap();
            assert_eq!(s.frames.len(), 99, "{name}");
            assert!(s.ground_truth_path().is_some() && s.keyframes_dir().is_some());
            assert!(s.frames.windows(2).all(|w| w[0] < w[1]));
        }
    }

    #[test]
    fn missing_parts_are_named() {
        let dir = std::env::temp_dir().join(format!("splattrack-seq-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let e = Sequence::open(&dir).unwrap_err().to_string();
        assert!(e.contains("no camera file"), "{e}");
        std::fs::write(
            dir.join("camera.json"),
            r#"{"width": 64, "height": 48, "fx": 50, "fy": 50, "cx": 31.5, "cy": 23.5}"#,
        )
        .unwrap();
        let e = Sequence::open(&dir).unwrap_err().to_string();
        assert!(e.contains("no frames"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(matches!(
            Sequence::open(&dir),
            Err(SequenceError::NotADirectory(_))
        ));
    }
}
