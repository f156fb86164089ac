//! Writing a synthetic sequence directory in the layout of docs/formats.md
//! ("Sequence directory"), so that `splattrack track` reads it like any
//! recorded sequence.

use super::{SynthConfig, SynthObject, SynthScene, keyframe_poses};
use crate::geometry::Pose;
use crate::io::{PoseRow, write_poses};
use crate::model::{AttributeSource, PointModel};
use crate::progress::{ProgressEvent, ProgressFn};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// Errors of [`write_sequence`].
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// No built-in object has this name.
    #[error("unknown object {0:?} (built-in objects: {list})", list = super::objects::OBJECT_NAMES.join(", "))]
    UnknownObject(String),
    /// A directory or file could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// An image could not be encoded or written.
    #[error("{path}: cannot write image: {source}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// Why.
        #[source]
        source: image::ImageError,
    },
    /// Sampling or saving the point model failed.
    #[error(transparent)]
    Model(#[from] crate::model::ModelError),
    /// Writing a pose file failed.
    #[error(transparent)]
    Poses(#[from] crate::io::poses::PoseFileError),
    /// A sequence needs at least two frames (the trajectory's start and end).
    #[error("a sequence needs at least 2 frames, got {0}")]
    TooFewFrames(usize),
}

/// Points sampled from a built-in object's mesh, coloured with its texture.
pub fn sample_model(
    object: &SynthObject,
    n_points: usize,
    seed: u64,
) -> Result<PointModel, SynthError> {
    // Sampled from single-precision vertices, as a mesh file would hold them.
    let verts: Vec<Vec3> = object.mesh.vertices.iter().map(|v| v.as_vec3()).collect();
    let mut model = PointModel::from_mesh(&verts, &object.mesh.triangles, n_points, seed)?;
    let colors = model
        .positions
        .iter()
        .zip(&model.normals)
        .map(|(p, n)| {
            let p = nalgebra::Vector3::new(p.x as f64, p.y as f64, p.z as f64);
            let n = nalgebra::Vector3::new(n.x as f64, n.y as f64, n.z as f64);
            object.texture.albedo(&p, &n)
        })
        .collect();
    model.colors = Some(colors);
    model.provenance.colors = AttributeSource::FromMesh;
    Ok(model)
}

/// What [`write_sequence`] wrote.
#[derive(Debug, Clone)]
pub struct SequenceSummary {
    /// The sequence directory.
    pub dir: PathBuf,
    /// Frames written to `frames/`.
    pub frames: usize,
    /// Keyframes written to `keyframes/`.
    pub keyframes: usize,
    /// Points in `model.ply`.
    pub model_points: usize,
    /// The mesh's bounding-box diagonal, metres.
    pub diameter: f64,
    /// The ground-truth pose of every frame (as in `poses.csv`).
    pub poses: Vec<Pose>,
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> SynthError + '_ {
    move |source| SynthError::Io {
        path: path.to_owned(),
        source,
    }
}

fn save_png(img: &image::RgbImage, path: &Path) -> Result<(), SynthError> {
    img.save(path).map_err(|source| SynthError::Image {
        path: path.to_owned(),
        source,
    })
}

/// Writes the sequence `cfg` describes into `dir`: camera.json, frames/,
/// init.csv, poses.csv (ground truth), keyframes/ (images and poses.csv),
/// model.ply (`model_points` points sampled from the mesh) and mesh.obj.
/// `progress` hears of each image written (stage "images": frames, then
/// keyframes).
pub fn write_sequence(
    cfg: &SynthConfig,
    dir: &Path,
    model_points: usize,
    progress: Option<&ProgressFn>,
) -> Result<SequenceSummary, SynthError> {
    let object = SynthObject::by_name(&cfg.object)
        .ok_or_else(|| SynthError::UnknownObject(cfg.object.clone()))?;
    if cfg.frames < 2 {
        return Err(SynthError::TooFewFrames(cfg.frames));
    }
    let frames_dir = dir.join("frames");
    let kf_dir = dir.join("keyframes");
    for d in [dir, &frames_dir, &kf_dir] {
        std::fs::create_dir_all(d).map_err(io_err(d))?;
    }
    let cam = &cfg.camera;
    let cam_path = dir.join("camera.json");
    let cam_json = format!(
        "{{\"width\": {}, \"height\": {}, \"fx\": {}, \"fy\": {}, \"cx\": {}, \"cy\": {}, \"distortion\": [0.0, 0.0, 0.0, 0.0, 0.0]}}\n",
        cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy
    );
    std::fs::write(&cam_path, cam_json).map_err(io_err(&cam_path))?;
    let obj_path = dir.join("mesh.obj");
    std::fs::write(&obj_path, object.mesh.to_obj("splattrack synthetic object"))
        .map_err(io_err(&obj_path))?;
    let model = sample_model(&object, model_points, cfg.seed)?;
    model.save_ply(dir.join("model.ply"))?;

    let scene = SynthScene::new(cfg.clone(), object);
    let n_kf = keyframe_poses(cfg.distance).len();
    let total = cfg.frames + n_kf;
    let report = |done: usize| {
        if let Some(report) = progress {
            report(ProgressEvent {
                stage: "images",
                done: done as u64,
                total: total as u64,
            });
        }
    };
    let mut rows = Vec::with_capacity(cfg.frames);
    let mut poses = Vec::with_capacity(cfg.frames);
    for i in 0..cfg.frames {
        let f = scene.frame(i);
        save_png(&f.image, &frames_dir.join(format!("{i:06}.png")))?;
        rows.push(PoseRow::new(format!("{i:06}"), f.pose));
        poses.push(f.pose);
        report(i + 1);
    }
    write_poses(&dir.join("poses.csv"), &rows)?;
    write_poses(&dir.join("init.csv"), &rows[..1])?;

    let mut kf_rows = Vec::new();
    for (k, (name, img, pose)) in scene.keyframe_images().into_iter().enumerate() {
        save_png(&img, &kf_dir.join(&name))?;
        kf_rows.push(PoseRow::new(name, pose));
        report(cfg.frames + k + 1);
    }
    write_poses(&kf_dir.join("poses.csv"), &kf_rows)?;
    Ok(SequenceSummary {
        dir: dir.to_owned(),
        frames: cfg.frames,
        keyframes: kf_rows.len(),
        model_points: model.len(),
        diameter: scene.object.mesh.diameter(),
        poses,
    })
}
