//! Writing a synthetic sequence directory in the layout of docs/formats.md
//! ("Sequence directory"), so that `splattrack track` reads it like any
//! recorded sequence.

use super::{MultiConfig, MultiScene, SynthConfig, SynthObject, SynthScene, keyframe_poses};
use crate::geometry::Intrinsics;
use crate::geometry::Pose;
use crate::io::{PoseRow, write_poses};
use crate::model::{AttributeSource, PointModel};
use crate::progress::{ProgressEvent, ProgressFn};
use glam::Vec3;
use std::path::{Path, PathBuf};

pub use super::error::SynthError;

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

/// Writes `cam` as a camera.json (no distortion).
fn write_camera(cam: &Intrinsics, path: &Path) -> Result<(), SynthError> {
    let cam_json = format!(
        "{{\"width\": {}, \"height\": {}, \"fx\": {}, \"fy\": {}, \"cx\": {}, \"cy\": {}, \"distortion\": [0.0, 0.0, 0.0, 0.0, 0.0]}}\n",
        cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy
    );
    std::fs::write(path, cam_json).map_err(io_err(path))
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
    write_camera(&cfg.camera, &dir.join("camera.json"))?;
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

/// What [`write_multi_sequence`] wrote, with the numbers of its occlusion.
#[derive(Debug, Clone)]
pub struct MultiSequenceSummary {
    /// The sequence directory.
    pub dir: PathBuf,
    /// Frames written to `frames/`.
    pub frames: usize,
    /// The objects' names (their folders under `objects/`), farthest first.
    pub names: Vec<String>,
    /// Keyframes written per object.
    pub keyframes: usize,
    /// Points in each object's `model.ply`.
    pub model_points: usize,
    /// Each object's apparent size in frame 0, pixels across.
    pub sizes_px: Vec<f64>,
    /// Each object's ground-truth pose per frame (as in `poses.csv`).
    pub poses: Vec<Vec<Pose>>,
    /// Each object's visible fraction per frame (as in `visibility.csv`).
    pub visibility: Vec<Vec<f64>>,
}

impl MultiSequenceSummary {
    /// The largest hidden fraction (1 - visible) of object `k` over the
    /// sequence.
    pub fn peak_hidden(&self, k: usize) -> f64 {
        self.visibility[k]
            .iter()
            .map(|v| 1.0 - v)
            .fold(0.0, f64::max)
    }

    /// The frames in which object `k` is wholly hidden.
    pub fn frames_hidden(&self, k: usize) -> usize {
        self.visibility[k].iter().filter(|&&v| v == 0.0).count()
    }
}

/// Writes the sequence of several objects `cfg` describes into `dir`:
/// camera.json, frames/, init.csv and poses.csv (one row per object per
/// frame, with the `object` column), visibility.csv, and per object
/// `objects/NAME/model.ply` (`model_points` points sampled from its mesh),
/// `objects/NAME/mesh.obj` and `objects/NAME/keyframes/` (rendered with that object alone, and
/// their poses.csv). `progress` hears of each image written (stage
/// "images": frames, then each object's keyframes).
pub fn write_multi_sequence(
    cfg: &MultiConfig,
    dir: &Path,
    model_points: usize,
    progress: Option<&ProgressFn>,
) -> Result<MultiSequenceSummary, SynthError> {
    let scene = MultiScene::new(cfg.clone())?;
    let frames_dir = dir.join("frames");
    for d in [dir, &frames_dir] {
        std::fs::create_dir_all(d).map_err(io_err(d))?;
    }
    write_camera(&cfg.camera, &dir.join("camera.json"))?;
    let names: Vec<String> = scene.names().iter().map(|n| n.to_string()).collect();
    let n_obj = names.len();
    let n_kf = keyframe_poses(1.0).len();
    let total = cfg.frames + n_obj * n_kf;
    let report = |done: usize| {
        if let Some(report) = progress {
            report(ProgressEvent {
                stage: "images",
                done: done as u64,
                total: total as u64,
            });
        }
    };
    let mut model_len = 0;
    for (k, name) in names.iter().enumerate() {
        let obj_dir = dir.join("objects").join(name);
        std::fs::create_dir_all(&obj_dir).map_err(io_err(&obj_dir))?;
        let seed = cfg.seed.wrapping_add(k as u64);
        let object = &scene.objects[k].object;
        let obj_path = obj_dir.join("mesh.obj");
        std::fs::write(&obj_path, object.mesh.to_obj("splattrack synthetic object"))
            .map_err(io_err(&obj_path))?;
        let model = sample_model(object, model_points, seed)?;
        model.save_ply(obj_dir.join("model.ply"))?;
        model_len = model.len();
    }
    let mut rows = Vec::with_capacity(cfg.frames * n_obj);
    let mut vis_lines = format!("{VISIBILITY_HEADER}\n");
    let mut poses = vec![Vec::with_capacity(cfg.frames); n_obj];
    let mut visibility = vec![Vec::with_capacity(cfg.frames); n_obj];
    for i in 0..cfg.frames {
        let f = scene.frame(i);
        save_png(&f.image, &frames_dir.join(format!("{i:06}.png")))?;
        for (k, name) in names.iter().enumerate() {
            rows.push(PoseRow::new(format!("{i:06}"), f.poses[k]).of_object(name.clone()));
            vis_lines.push_str(&format!("{name},{i:06},{:.6}\n", f.visibility[k]));
            poses[k].push(f.poses[k]);
            visibility[k].push(f.visibility[k]);
        }
        report(i + 1);
    }
    write_poses(&dir.join("poses.csv"), &rows)?;
    write_poses(&dir.join("init.csv"), &rows[..n_obj])?;
    let vis_path = dir.join("visibility.csv");
    std::fs::write(&vis_path, vis_lines).map_err(io_err(&vis_path))?;

    let mut done = cfg.frames;
    for (k, name) in names.iter().enumerate() {
        let kf_dir = dir.join("objects").join(name).join("keyframes");
        std::fs::create_dir_all(&kf_dir).map_err(io_err(&kf_dir))?;
        let mut kf_rows = Vec::new();
        for (kf_name, img, pose) in scene.keyframe_images(k) {
            save_png(&img, &kf_dir.join(&kf_name))?;
            kf_rows.push(PoseRow::new(kf_name, pose));
            done += 1;
            report(done);
        }
        write_poses(&kf_dir.join("poses.csv"), &kf_rows)?;
    }
    Ok(MultiSequenceSummary {
        dir: dir.to_owned(),
        frames: cfg.frames,
        sizes_px: (0..n_obj).map(|k| scene.size_px(k)).collect(),
        names,
        keyframes: n_kf,
        model_points: model_len,
        poses,
        visibility,
    })
}

/// One row of a sequence's `visibility.csv` (docs/formats.md, "Several
/// objects").
#[derive(Debug, Clone, PartialEq)]
pub struct VisibilityRow {
    /// The object's name.
    pub object: String,
    /// The frame's label, as in `poses.csv`.
    pub frame: String,
    /// The fraction (0..1) of the object's silhouette the frame shows.
    pub visible: f64,
}

/// The header line of `visibility.csv`.
pub const VISIBILITY_HEADER: &str = "object,frame,visible";

/// Reads a `visibility.csv`: its header, then `object,frame,visible` rows
/// with `visible` in 0..1.
pub fn read_visibility(path: &Path) -> Result<Vec<VisibilityRow>, SynthError> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    let bad = |line: usize, reason: String| SynthError::Visibility {
        path: path.to_owned(),
        line,
        reason,
    };
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim() == VISIBILITY_HEADER => {}
        _ => return Err(bad(1, format!("the header must be {VISIBILITY_HEADER}"))),
    }
    lines
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(k, l)| {
            let f: Vec<&str> = l.trim().split(',').collect();
            let [object, frame, visible] = f[..] else {
                return Err(bad(k + 1, format!("{} fields, want 3", f.len())));
            };
            let visible: f64 = visible
                .parse()
                .ok()
                .filter(|v: &f64| (0.0..=1.0).contains(v))
                .ok_or_else(|| {
                    bad(
                        k + 1,
                        format!("visible {visible:?} is not a number in 0..1"),
                    )
                })?;
            if object.is_empty() || frame.is_empty() {
                return Err(bad(k + 1, "an empty object or frame".into()));
            }
            Ok(VisibilityRow {
                object: object.to_owned(),
                frame: frame.to_owned(),
                visible,
            })
        })
        .collect()
}
