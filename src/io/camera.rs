//! Camera files (docs/formats.md): `camera.json` and OpenCV calibration YAML,
//! read into [`Intrinsics`].

use crate::geometry::Intrinsics;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Errors of camera files and camera parameters.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// The camera file could not be read.
    #[error("{path}: cannot read camera file: {source}")]
    Io {
        /// The camera file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file's text is not valid `camera.json` or OpenCV calibration YAML.
    #[error("{path}: not a valid camera file: {reason}")]
    Parse {
        /// The camera file.
        path: PathBuf,
        /// What is wrong with the text.
        reason: String,
    },
    /// The file parses but describes an impossible or implausible camera.
    #[error("{path}: impossible camera: {reason}")]
    Invalid {
        /// The camera file.
        path: PathBuf,
        /// Which parameter is wrong, and why.
        reason: String,
    },
}

/// `camera.json` as written (docs/formats.md): the distortion list is optional
/// and may have any length up to OpenCV's.
#[derive(Deserialize)]
struct CameraJson {
    width: u32,
    height: u32,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    #[serde(default)]
    distortion: Option<Vec<f64>>,
}

impl Intrinsics {
    /// Loads `camera.json` (docs/formats.md) or an OpenCV calibration YAML
    /// (`.yaml`/`.yml`, as written by OpenCV's calibration sample).
    pub fn load(path: &Path) -> Result<Self, CameraError> {
        let text = std::fs::read_to_string(path).map_err(|source| CameraError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::from_text(&text, path)
    }

    /// [`Intrinsics::load`] of a file's text: `path` names it in errors and
    /// its extension says JSON or YAML.
    pub fn from_text(text: &str, path: &Path) -> Result<Self, CameraError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let looks_yaml = text.trim_start().starts_with("%YAML") || text.contains("camera_matrix");
        let cam = if ext == "yaml" || ext == "yml" || (ext != "json" && looks_yaml) {
            Self::parse_opencv_yaml(text)
        } else {
            Self::parse_json(text)
        }
        .map_err(|reason| CameraError::Parse {
            path: path.to_owned(),
            reason,
        })?;
        cam.validate()
            .and_then(|()| plausible(&cam))
            .map_err(|reason| CameraError::Invalid {
                path: path.to_owned(),
                reason,
            })?;
        Ok(cam)
    }

    fn parse_json(text: &str) -> Result<Self, String> {
        let j: CameraJson = serde_json::from_str(text).map_err(|e| e.to_string())?;
        let distortion = match j.distortion {
            None => [0.0; 5],
            Some(d) => distortion_from_slice(&d)?,
        };
        Ok(Self {
            width: j.width,
            height: j.height,
            fx: j.fx,
            fy: j.fy,
            cx: j.cx,
            cy: j.cy,
            distortion,
        })
    }

    /// Parses the subset of OpenCV's FileStorage YAML that calibration files
    /// use: scalar `image_width`/`image_height` and `!!opencv-matrix` blocks
    /// with `rows`, `cols`, `dt`, `data: [ ... ]` (which may span lines).
    fn parse_opencv_yaml(text: &str) -> Result<Self, String> {
        let scalar = |key: &str| -> Result<f64, String> {
            for line in text.lines() {
                let l = line.trim();
                if let Some(rest) = l.strip_prefix(key) {
                    if let Some(v) = rest.trim_start().strip_prefix(':') {
                        return v
                            .trim()
                            .parse::<f64>()
                            .map_err(|_| format!("{key} is not a number: {:?}", v.trim()));
                    }
                }
            }
            Err(format!("missing {key}"))
        };
        let matrix = |key: &str| -> Result<Option<Vec<f64>>, String> {
            let Some(start) = text.find(&format!("{key}:")) else {
                return Ok(None);
            };
            let rest = &text[start..];
            let Some(d) = rest.find("data:") else {
                return Err(format!("{key} has no data"));
            };
            let rest = &rest[d + 5..];
            let open = rest
                .find('[')
                .ok_or(format!("{key}: data is not a [ list ]"))?;
            let close = rest
                .find(']')
                .ok_or(format!("{key}: data list is not closed"))?;
            if close < open {
                return Err(format!("{key}: malformed data list"));
            }
            rest[open + 1..close]
                .split(',')
                .map(|s| s.trim())
                .filter(|s| !s.is_empty())
                .map(|s| {
                    s.parse::<f64>()
                        .map_err(|_| format!("{key}: {s:?} is not a number"))
                })
                .collect::<Result<Vec<_>, _>>()
                .map(Some)
        };
        let w = scalar("image_width")?;
        let h = scalar("image_height")?;
        if !(w >= 1.0 && h >= 1.0 && w.fract() == 0.0 && h.fract() == 0.0 && w < 1e6 && h < 1e6) {
            return Err(format!(
                "image size {w} x {h} is not a positive integer size"
            ));
        }
        let k = matrix("camera_matrix")?.ok_or("missing camera_matrix")?;
        if k.len() != 9 {
            return Err(format!("camera_matrix has {} values, expected 9", k.len()));
        }
        let distortion = match matrix("distortion_coefficients")? {
            None => [0.0; 5],
            Some(d) => distortion_from_slice(&d)?,
        };
        Ok(Self {
            width: w as u32,
            height: h as u32,
            fx: k[0],
            fy: k[4],
            cx: k[2],
            cy: k[5],
            distortion,
        })
    }
}

/// A camera no lens makes is refused: a field of view outside 0.01 to 179
/// degrees (a focal length absurdly small or large for the image), or a
/// principal point more than ten image sizes off the image.
fn plausible(cam: &Intrinsics) -> Result<(), String> {
    for (name, f, size) in [("fx", cam.fx, cam.width), ("fy", cam.fy, cam.height)] {
        let fov = 2.0 * (size as f64 / (2.0 * f)).atan().to_degrees();
        if !(0.01..=179.0).contains(&fov) {
            return Err(format!(
                "{name} = {f} px gives a field of view of {fov:.3} degrees over {size} px (must be 0.01 to 179)"
            ));
        }
    }
    for (name, c, size) in [("cx", cam.cx, cam.width), ("cy", cam.cy, cam.height)] {
        let s = size as f64;
        if !(c >= -10.0 * s && c <= 11.0 * s) {
            return Err(format!(
                "{name} = {c} px is more than ten image sizes off a {size} px image"
            ));
        }
    }
    Ok(())
}

fn distortion_from_slice(d: &[f64]) -> Result<[f64; 5], String> {
    if d.len() > 5 && d[5..].iter().any(|&v| v != 0.0) {
        return Err(format!(
            "{} distortion coefficients with non-zero terms beyond k3 (rational/thin-prism models are not supported)",
            d.len()
        ));
    }
    let mut out = [0.0; 5];
    for (o, v) in out.iter_mut().zip(d) {
        *o = *v;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_tmp(name: &str, text: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("splattrack-cam-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn opencv_yaml_calibration_loads() {
        // As written by OpenCV's calibration sample (data lists may wrap).
        let yaml = "%YAML:1.0\n---\ncalibration_time: \"x\"\nimage_width: 640\nimage_height: 480\n\
camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 5.7240e+02, 0., 3.2530e+02, 0.,\n       5.7360e+02, 2.4200e+02, 0., 0., 1. ]\n\
distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ -0.28, 0.09, 1.0e-03, -5.0e-04, 0. ]\n";
        let cam = Intrinsics::load(&write_tmp("cam.yaml", yaml)).unwrap();
        assert_eq!((cam.width, cam.height), (640, 480));
        assert_eq!(
            (cam.fx, cam.fy, cam.cx, cam.cy),
            (572.4, 573.6, 325.3, 242.0)
        );
        assert_eq!(cam.distortion, [-0.28, 0.09, 1.0e-3, -5.0e-4, 0.0]);
    }

    #[test]
    fn camera_json_loads_and_bad_cameras_are_named() {
        let ok = r#"{"width": 640, "height": 480, "fx": 572.4, "fy": 573.6, "cx": 325.3, "cy": 242.0,
 "distortion": [0.1, 0.0, 0.0, 0.0, 0.0]}"#;
        let cam = Intrinsics::load(&write_tmp("ok.json", ok)).unwrap();
        assert!(cam.has_distortion() && cam.fx == 572.4);
        let cases = [
            (
                "neg.json",
                r#"{"width": 640, "height": 480, "fx": -1, "fy": 5, "cx": 1, "cy": 1}"#,
                "fx",
            ),
            (
                "zero.json",
                r#"{"width": 0, "height": 480, "fx": 1, "fy": 5, "cx": 1, "cy": 1}"#,
                "image size",
            ),
            (
                "trunc.json",
                r#"{"width": 640, "height""#,
                "not a valid camera file",
            ),
            (
                "missing.json",
                r#"{"width": 640, "height": 480, "fx": 1}"#,
                "fy",
            ),
            (
                "dist.json",
                r#"{"width": 6, "height": 4, "fx": 1, "fy": 5, "cx": 1, "cy": 1, "distortion": [0,0,0,0,0,0.5]}"#,
                "beyond k3",
            ),
            ("bad.yaml", "%YAML:1.0\nimage_width: 640\n", "image_height"),
        ];
        for (name, text, want) in cases {
            let p = write_tmp(name, text);
            let e = Intrinsics::load(&p).unwrap_err().to_string();
            assert!(e.contains(want) && e.contains(name), "{name}: {e}");
        }
        let e = Intrinsics::load(Path::new("/no/such/camera.json"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/no/such/camera.json"), "{e}");
    }
}
