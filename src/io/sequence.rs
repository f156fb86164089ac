//! Sequence directories (docs/formats.md): `camera.json` (or
//! an OpenCV `camera.yaml`), `frames/` (png or jpg, sorted by name),
//! `init.csv`, optional `poses.csv` (ground truth) and `keyframes/`.
//! [`Sequence::frames`] yields the frames in order, undistorted when the
//! camera has distortion, ready for a tracker on [`Sequence::tracking_camera`].

use crate::geometry::{Intrinsics, Undistorter};
use crate::io::camera::CameraError;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Errors of opening a sequence directory and reading its frames.
#[derive(Debug, thiserror::Error)]
pub enum SequenceError {
    /// The sequence path is not a directory.
    #[error("{0}: not a directory")]
    NotADirectory(PathBuf),
    /// The sequence directory has no `camera.json`, `camera.yaml` or `camera.yml`.
    #[error("{0}: no camera file (expected camera.json, camera.yaml or camera.yml)")]
    NoCamera(PathBuf),
    /// `frames/` is missing or holds no images (the path is `frames/`).
    #[error("{0}: no frames (expected .png or .jpg images in frames/)")]
    NoFrames(PathBuf),
    /// A directory could not be listed.
    #[error("{path}: {source}")]
    Io {
        /// The directory.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The camera file could not be loaded.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// A frame image could not be opened or decoded.
    #[error("{path}: cannot read frame: {source}")]
    FrameImage {
        /// The frame image file.
        path: PathBuf,
        /// The decoder's error.
        #[source]
        source: image::ImageError,
    },
    /// A frame's size differs from the camera's.
    #[error("{path}: frame is {got_w}x{got_h}, the camera ({camera}) is {want_w}x{want_h}")]
    FrameSize {
        /// The frame image file.
        path: PathBuf,
        /// The camera file.
        camera: PathBuf,
        /// The frame's width in pixels.
        got_w: u32,
        /// The frame's height in pixels.
        got_h: u32,
        /// The camera's width in pixels.
        want_w: u32,
        /// The camera's height in pixels.
        want_h: u32,
    },
    /// Undistorting a frame failed.
    #[error("{path}: cannot undistort: {reason}")]
    Undistort {
        /// The frame image file.
        path: PathBuf,
        /// Why undistortion failed.
        reason: String,
    },
}

/// One frame of a sequence, as the tracker wants it.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Its position in the sequence (0 for the first).
    pub index: usize,
    /// Its label in pose files ([`Sequence::frame_label`]).
    pub label: String,
    /// The image file (for a video or a camera: the file or device).
    pub path: PathBuf,
    /// The image, undistorted when the camera has distortion.
    pub image: image::RgbImage,
    /// Its timestamp in seconds, for frames of a video or a camera (`None`
    /// for image files).
    pub time_s: Option<f64>,
}

/// A sequence on disk; frames are read lazily.
#[derive(Clone)]
pub struct Sequence {
    /// The sequence directory.
    pub dir: PathBuf,
    /// The camera as calibrated (with its distortion, if any).
    pub camera: Intrinsics,
    /// The camera file the camera was read from.
    pub camera_path: PathBuf,
    /// Frame image paths, sorted by file name.
    pub frames: Vec<PathBuf>,
    /// Built once when the camera has distortion.
    undistorter: Option<Arc<Undistorter>>,
}

impl std::fmt::Debug for Sequence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Sequence")
            .field("dir", &self.dir)
            .field("camera", &self.camera)
            .field("camera_path", &self.camera_path)
            .field("frames", &self.frames.len())
            .field("undistorts", &self.undistorter.is_some())
            .finish()
    }
}

fn is_image(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .map(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
        .unwrap_or(false)
}

/// Orders file names as people number them: runs of digits compare by
/// value, so `2.png` comes before `10.png` (plain text order puts `10`
/// first); other characters compare as text.
pub fn natural_cmp(a: &str, b: &str) -> std::cmp::Ordering {
    use std::cmp::Ordering;
    let (mut a, mut b) = (a.as_bytes(), b.as_bytes());
    loop {
        match (a.first(), b.first()) {
            (None, None) => return Ordering::Equal,
            (None, Some(_)) => return Ordering::Less,
            (Some(_), None) => return Ordering::Greater,
            (Some(x), Some(y)) if x.is_ascii_digit() && y.is_ascii_digit() => {
                let da = a.iter().take_while(|c| c.is_ascii_digit()).count();
                let db = b.iter().take_while(|c| c.is_ascii_digit()).count();
                let (na, nb) = (&a[..da], &b[..db]);
                // Compare by value without parsing (any length): strip
                // leading zeros, then the longer number is the larger.
                let ta = &na[na.iter().take_while(|&&c| c == b'0').count()..];
                let tb = &nb[nb.iter().take_while(|&&c| c == b'0').count()..];
                let o = ta
                    .len()
                    .cmp(&tb.len())
                    .then_with(|| ta.cmp(tb))
                    .then_with(|| da.cmp(&db));
                if o != Ordering::Equal {
                    return o;
                }
                a = &a[da..];
                b = &b[db..];
            }
            (Some(x), Some(y)) => {
                if x != y {
                    return x.cmp(y);
                }
                a = &a[1..];
                b = &b[1..];
            }
        }
    }
}

/// Image files of a directory, in [`natural_cmp`] order of their names
/// (`1.png`, `2.png`, `10.png`).
pub fn list_images(dir: &Path) -> Result<Vec<PathBuf>, SequenceError> {
    let rd = std::fs::read_dir(dir).map_err(|source| SequenceError::Io {
        path: dir.to_owned(),
        source,
    })?;
    let mut v: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && is_image(p))
        .collect();
    v.sort_by(|a, b| {
        let name = |p: &PathBuf| {
            p.file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned()
        };
        natural_cmp(&name(a), &name(b)).then_with(|| a.cmp(b))
    });
    Ok(v)
}

impl Sequence {
    /// Opens a sequence directory: loads its camera, lists `frames/` and
    /// checks the first frame's size against the camera.
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
        // The first frame's size, from its header, before anything the
        // camera's size decides is allocated (undistortion maps, render
        // targets): a camera file that claims 20000 x 20000 for 640 x 480
        // frames is refused here.
        let (got_w, got_h) =
            image::image_dimensions(&frames[0]).map_err(|source| SequenceError::FrameImage {
                path: frames[0].clone(),
                source,
            })?;
        if (got_w, got_h) != (camera.width, camera.height) {
            return Err(SequenceError::FrameSize {
                path: frames[0].clone(),
                camera: camera_path,
                got_w,
                got_h,
                want_w: camera.width,
                want_h: camera.height,
            });
        }
        let undistorter = camera
            .has_distortion()
            .then(|| Arc::new(Undistorter::new(&camera)));
        Ok(Self {
            dir: dir.to_owned(),
            camera,
            camera_path,
            frames,
            undistorter,
        })
    }

    /// The camera of the frames [`Sequence::frame`] returns: the calibrated
    /// one without its distortion.
    pub fn tracking_camera(&self) -> Intrinsics {
        self.camera.undistorted()
    }

    /// Frame `i` (`i < frames.len()`), checked against the camera's size and
    /// undistorted when the camera has distortion.
    pub fn frame(&self, i: usize) -> Result<Frame, SequenceError> {
        let path = &self.frames[i];
        let image = image::open(path)
            .map_err(|source| SequenceError::FrameImage {
                path: path.clone(),
                source,
            })?
            .to_rgb8();
        let cam = &self.camera;
        if image.width() != cam.width || image.height() != cam.height {
            return Err(SequenceError::FrameSize {
                path: path.clone(),
                camera: self.camera_path.clone(),
                got_w: image.width(),
                got_h: image.height(),
                want_w: cam.width,
                want_h: cam.height,
            });
        }
        let image = match &self.undistorter {
            Some(u) => u.apply(&image).map_err(|reason| SequenceError::Undistort {
                path: path.clone(),
                reason,
            })?,
            None => image,
        };
        Ok(Frame {
            index: i,
            label: self.frame_label(i),
            path: path.clone(),
            image,
            time_s: None,
        })
    }

    /// The frames in order, read one at a time ([`Sequence::frame`]).
    pub fn iter_frames(&self) -> impl Iterator<Item = Result<Frame, SequenceError>> + '_ {
        (0..self.frames.len()).map(|i| self.frame(i))
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

    /// The label of frame `i` in pose files: its index, as docs/formats.md says.
    pub fn frame_label(&self, i: usize) -> String {
        i.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_sequences_open() {
        let Some(root) = crate::io::testing::real_data("") else {
            return;
        };
        for name in ["visp_rbt_cube", "visp_rbt_dragon"] {
            let s = Sequence::open(&root.join(name)).unwrap();
            assert_eq!(s.frames.len(), 99, "{name}");
            assert!(s.ground_truth_path().is_some() && s.keyframes_dir().is_some());
            assert!(s.frames.windows(2).all(|w| w[0] < w[1]));
        }
    }

    fn write_camera(dir: &Path, distortion: &str) {
        std::fs::write(
            dir.join("camera.json"),
            format!(
                r#"{{"width": 64, "height": 48, "fx": 50, "fy": 50, "cx": 31.5, "cy": 23.5{distortion}}}"#
            ),
        )
        .unwrap();
    }

    /// A picture with structure everywhere, so undistortion changes it.
    fn picture(seed: u8) -> image::RgbImage {
        image::RgbImage::from_fn(64, 48, |x, y| {
            image::Rgb([(x * 4) as u8 ^ seed, (y * 5) as u8, ((x + y) * 3) as u8])
        })
    }

    #[test]
    fn frames_come_in_name_order_and_undistorted() {
        let dir = std::env::temp_dir().join(format!("splattrack-seqframes-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("frames")).unwrap();
        // Written out of order; a non-image file is ignored.
        for (name, seed) in [("000002.png", 2), ("000000.png", 0), ("000001.png", 1)] {
            picture(seed).save(dir.join("frames").join(name)).unwrap();
        }
        std::fs::write(dir.join("frames/notes.txt"), "x").unwrap();
        write_camera(&dir, "");
        let s = Sequence::open(&dir).unwrap();
        assert_eq!(s.frames.len(), 3);
        assert_eq!(s.tracking_camera(), s.camera);
        for (i, f) in s.iter_frames().enumerate() {
            let f = f.unwrap();
            assert_eq!((f.index, f.label.as_str()), (i, i.to_string().as_str()));
            assert!(f.path.ends_with(format!("{i:06}.png")));
            assert_eq!(f.image, picture(i as u8));
        }
        // With distortion: the frames are what the Undistorter makes of them,
        // for the camera without distortion.
        write_camera(&dir, r#", "distortion": [-0.2, 0.05, 0.001, -0.001, 0.0]"#);
        let s = Sequence::open(&dir).unwrap();
        assert!(s.camera.has_distortion() && !s.tracking_camera().has_distortion());
        let want = Undistorter::new(&s.camera).apply(&picture(1)).unwrap();
        let got = s.frame(1).unwrap().image;
        assert_eq!(got, want);
        assert_ne!(got, picture(1));
        // A frame of the wrong size names the frame, both sizes and the camera.
        image::RgbImage::new(10, 8)
            .save(dir.join("frames/000001.png"))
            .unwrap();
        let e = s.frame(1).unwrap_err().to_string();
        for want in ["000001.png", "10x8", "64x48", "camera.json"] {
            assert!(e.contains(want), "{e}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
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
