//! The keyframe store (Dehais et al. 2010, sections 3.3 and 5.1): images of
//! the object with accurately known poses, turned into per-point colours so
//! that a novel view of the object can be rendered at any pose from the
//! keyframe closest to it.
//!
//! How it works: for each keyframe the model's depth is splatted at the
//! keyframe pose; a model point is *visible* in the keyframe when it faces
//! the camera, projects inside the image and lies on the splatted surface
//! there (within a tolerance of a few splat radii), i.e. visibility comes
//! from the rendered depth, not from normals alone. Visible points take the
//! keyframe image's colour at their projection (bilinear). Points hidden in
//! a keyframe take the colour of the nearest keyframe (by viewing direction)
//! that sees them, else the model's own colour; they are flagged so that a
//! consumer can tell. The store is saved to a small binary file, so it is
//! built once per object.

#![warn(missing_docs)]

use crate::device::AsDevice;
use crate::geometry::{Intrinsics, Pose, PoseError, sample_bilinear_rgb};
use crate::io::poses::PoseRow;
use crate::model::PointModel;
use crate::splat::{Attribute, Attributes, GpuModel, SplatError, SplatTargets, Splatter};
use nalgebra::Vector3;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Errors of building, loading and saving keyframe stores.
#[derive(Debug, thiserror::Error)]
pub enum KeyframeError {
    /// A store file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A keyframe image could not be decoded.
    #[error("{path}: cannot read keyframe image: {source}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// Why.
        #[source]
        source: image::ImageError,
    },
    /// A keyframe image is not the camera's size.
    #[error("{path}: keyframe image is {got_w}x{got_h}, the camera is {want_w}x{want_h}")]
    ImageSize {
        /// The image file.
        path: PathBuf,
        /// The image's width, pixels.
        got_w: u32,
        /// The image's height, pixels.
        got_h: u32,
        /// The camera's width, pixels.
        want_w: u32,
        /// The camera's height, pixels.
        want_h: u32,
    },
    /// The file is not a keyframe store (wrong magic, truncated,
    /// inconsistent sizes, corrupt poses).
    #[error("{path}: not a keyframe store: {reason}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// The store was built for another model (see
    /// [`KeyframeStore::check_model`]).
    #[error(
        "{path}: the keyframe store was built for another model ({stored} points, fingerprint {stored_fp:016x}; this model: {points} points, {fp:016x})"
    )]
    WrongModel {
        /// The store's file.
        path: PathBuf,
        /// The store's point count.
        stored: u64,
        /// The store's model fingerprint.
        stored_fp: u64,
        /// The model's point count.
        points: u64,
        /// The model's fingerprint ([`model_fingerprint`]).
        fp: u64,
    },
    /// A row of the keyframe poses (its frame label) has no image in the
    /// directory.
    #[error("{0}: no keyframe image found for pose row {1:?}")]
    MissingImage(PathBuf, String),
    /// The model is not seen at all from a keyframe's pose.
    #[error("keyframe {name}: the object is not visible (no model point seen)")]
    NothingVisible {
        /// The keyframe's name.
        name: String,
    },
    /// The keyframe poses file is unreadable.
    #[error(transparent)]
    Poses(#[from] crate::io::poses::PoseFileError),
    /// Splatting the model's depth failed.
    #[error(transparent)]
    Splat(#[from] SplatError),
    /// A keyframe pose is not a rigid transform.
    #[error(transparent)]
    Pose(#[from] PoseError),
}

/// One keyframe: its pose and the colour it gives every model point.
#[derive(Debug, Clone)]
pub struct Keyframe {
    /// The image's file stem (or a label such as `model colours`).
    pub name: String,
    /// The object-to-camera pose the image was taken at.
    pub pose: Pose,
    /// One colour per model point (linear 0..1 values as in the image).
    pub colors: Vec<[f32; 3]>,
    /// Whether the keyframe itself sees the point (else the colour is
    /// borrowed from another keyframe or the model).
    pub visible: Vec<bool>,
}

impl Keyframe {
    /// How many model points this keyframe sees itself.
    pub fn visible_count(&self) -> usize {
        self.visible.iter().filter(|&&v| v).count()
    }
}

/// Keyframes of one model.
#[derive(Debug, Clone)]
pub struct KeyframeStore {
    /// The keyframes, in the order they were given.
    pub keyframes: Vec<Keyframe>,
    /// Number of points and a fingerprint of their positions, to refuse a
    /// store built for another model.
    pub points: u64,
    /// See [`model_fingerprint`].
    pub fingerprint: u64,
    /// The centre of the model's bounding box, the pivot for viewpoints.
    pub center: Vector3<f64>,
}

/// A fingerprint of a model's point positions (FNV-1a over their bits).
pub fn model_fingerprint(model: &PointModel) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in &model.positions {
        for v in [p.x, p.y, p.z] {
            for b in v.to_bits().to_le_bytes() {
                h ^= b as u64;
                h = h.wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
    h
}

fn model_center(model: &PointModel) -> Vector3<f64> {
    let (lo, hi) = model.bounds();
    let c = (lo + hi) * 0.5;
    Vector3::new(c.x as f64, c.y as f64, c.z as f64)
}

/// Unit viewing direction (object frame, from the object's centre towards
/// the camera) and camera distance of a pose.
pub fn viewpoint(pose: &Pose, center: &Vector3<f64>) -> (Vector3<f64>, f64) {
    let eye = -(pose.rotation.transpose() * pose.translation);
    let d = eye - center;
    let dist = d.norm();
    (d / dist.max(1e-12), dist)
}

/// Settings of keyframe extraction.
#[derive(Debug, Clone, Copy)]
pub struct KeyframeConfig {
    /// A point is on the splatted surface when its depth is within this
    /// many splat radii of the rendered depth...
    pub depth_tolerance_radii: f32,
    /// ...plus this fraction of its depth.
    pub depth_tolerance_rel: f32,
    /// Points seen at a grazing angle (|cos| below this) get no colour.
    pub min_cos: f32,
}

impl Default for KeyframeConfig {
    fn default() -> Self {
        Self {
            depth_tolerance_radii: 3.0,
            depth_tolerance_rel: 0.004,
            min_cos: 0.15,
        }
    }
}

/// Converts an 8-bit RGB image to the 0..1 floats the splatter carries.
fn rgb_to_f32(p: image::Rgb<u8>) -> [f32; 3] {
    p.0.map(|v| v as f32 / 255.0)
}

impl KeyframeStore {
    /// Builds the store from keyframe images and their poses: `frames`
    /// holds (name, image, object-to-camera pose), each image undistorted
    /// and of `cam`'s size. Every keyframe must see some of the model
    /// ([`KeyframeError::NothingVisible`] otherwise). `ctx` is the
    /// splatter's device (a [`crate::GpuContext`] or a [`crate::Device`]).
    pub fn build(
        ctx: &impl AsDevice,
        splatter: &Splatter,
        model: &PointModel,
        cam: &Intrinsics,
        frames: &[(String, image::RgbImage, Pose)],
        cfg: &KeyframeConfig,
    ) -> Result<Self, KeyframeError> {
        let gpu_model = GpuModel::new(ctx, model)?;
        let mut targets = SplatTargets::new(ctx, cam.width, cam.height);
        let center = model_center(model);
        let mut keyframes = Vec::with_capacity(frames.len());
        for (name, img, pose) in frames {
            pose.validate()?;
            splatter.render(
                ctx,
                &gpu_model,
                cam,
                pose,
                Attributes::GEOMETRY,
                &mut targets,
            )?;
            let depth = splatter.read(ctx, &targets, Attribute::Depth)?;
            let mut colors = vec![[0.0f32; 3]; model.len()];
            let mut visible = vec![false; model.len()];
            for i in 0..model.len() {
                let p = model.positions[i];
                let n = model.normals[i];
                let x = pose.transform_point(&Vector3::new(p.x as f64, p.y as f64, p.z as f64));
                let nc = pose.rotation * Vector3::new(n.x as f64, n.y as f64, n.z as f64);
                // Facing the camera, not at a grazing angle.
                if -(nc.dot(&x)) / x.norm() < cfg.min_cos as f64 {
                    continue;
                }
                let Some(uv) = cam.project(&x) else { continue };
                let (u, v) = (uv.x.round(), uv.y.round());
                if u < 0.0 || v < 0.0 || u >= cam.width as f64 || v >= cam.height as f64 {
                    continue;
                }
                let z = depth.pixel(u as u32, v as u32)[0];
                let tol = cfg.depth_tolerance_radii * model.radii[i]
                    + cfg.depth_tolerance_rel * x.z as f32;
                if z.is_nan() || (x.z as f32 - z) > tol {
                    continue;
                }
                if let Some(c) = sample_bilinear_rgb(img, uv.x as f32, uv.y as f32) {
                    colors[i] = rgb_to_f32(c);
                    visible[i] = true;
                }
            }
            let kf = Keyframe {
                name: name.clone(),
                pose: *pose,
                colors,
                visible,
            };
            if kf.visible_count() == 0 {
                return Err(KeyframeError::NothingVisible { name: name.clone() });
            }
            log::info!(
                "keyframe {name}: {} of {} points visible",
                kf.visible_count(),
                model.len()
            );
            keyframes.push(kf);
        }
        let mut store = Self {
            keyframes,
            points: model.len() as u64,
            fingerprint: model_fingerprint(model),
            center,
        };
        store.fill_hidden(model);
        Ok(store)
    }

    /// Gives points hidden in a keyframe the colour of the keyframe with the
    /// closest viewpoint that sees them (else the model's colour, else grey).
    fn fill_hidden(&mut self, model: &PointModel) {
        let dirs: Vec<Vector3<f64>> = self
            .keyframes
            .iter()
            .map(|k| viewpoint(&k.pose, &self.center).0)
            .collect();
        let n = self.keyframes.len();
        for k in 0..n {
            let mut order: Vec<usize> = (0..n).filter(|&j| j != k).collect();
            order.sort_by(|&a, &b| dirs[k].dot(&dirs[b]).total_cmp(&dirs[k].dot(&dirs[a])));
            for i in 0..model.len() {
                if self.keyframes[k].visible[i] {
                    continue;
                }
                let borrowed = order
                    .iter()
                    .find(|&&j| self.keyframes[j].visible[i])
                    .map(|&j| self.keyframes[j].colors[i]);
                self.keyframes[k].colors[i] = borrowed
                    .or_else(|| model.colors.as_ref().map(|c| c[i]))
                    .unwrap_or([0.5; 3]);
            }
        }
    }

    /// A single texture from the model's own colours (when there are no
    /// keyframes): every point counts as visible from `pose`.
    pub fn from_model_colors(model: &PointModel, pose: &Pose) -> Option<Self> {
        let colors = model.colors.clone()?;
        Some(Self {
            keyframes: vec![Keyframe {
                name: "model colours".into(),
                pose: *pose,
                colors,
                visible: vec![true; model.len()],
            }],
            points: model.len() as u64,
            fingerprint: model_fingerprint(model),
            center: model_center(model),
        })
    }

    /// The store for `model`, a merge of the store's model
    /// ([`PointModel::merged`]; `group`: each former point's index in
    /// `model`): a merged point takes the mean colour of its members that
    /// the keyframe sees, and is seen where one of them is; where none is,
    /// the mean of the members' borrowed colours. A `group` that does not
    /// fit (not one entry a point of the store, or an index past `model`)
    /// gives `None`.
    pub fn merged(&self, model: &PointModel, group: &[u32]) -> Option<Self> {
        let n = model.len();
        if group.len() as u64 != self.points || group.iter().any(|&g| g as usize >= n) {
            return None;
        }
        let keyframes = self
            .keyframes
            .iter()
            .map(|k| {
                // Sums of the seen members, then of all; counts likewise.
                let mut seen = vec![([0.0f64; 3], 0u32); n];
                let mut all = vec![([0.0f64; 3], 0u32); n];
                for (i, &g) in group.iter().enumerate() {
                    let c = k.colors.get(i).copied().unwrap_or([0.5; 3]);
                    let add = |(sum, count): &mut ([f64; 3], u32)| {
                        for (s, v) in sum.iter_mut().zip(c) {
                            *s += v as f64;
                        }
                        *count += 1;
                    };
                    if k.visible.get(i).copied().unwrap_or(false) {
                        add(&mut seen[g as usize]);
                    }
                    add(&mut all[g as usize]);
                }
                let mean = |(sum, count): &([f64; 3], u32)| sum.map(|s| (s / *count as f64) as f32);
                let visible: Vec<bool> = seen.iter().map(|s| s.1 > 0).collect();
                let colors = seen
                    .iter()
                    .zip(&all)
                    .map(|(s, a)| if s.1 > 0 { mean(s) } else { mean(a) })
                    .collect();
                Keyframe {
                    name: k.name.clone(),
                    pose: k.pose,
                    colors,
                    visible,
                }
            })
            .collect();
        Some(Self {
            keyframes,
            points: n as u64,
            fingerprint: model_fingerprint(model),
            center: model_center(model),
        })
    }

    /// Loads keyframe images and poses from a directory (docs/formats.md:
    /// `keyframes/poses.csv`, images named by its frame column, extension
    /// optional) and builds the store.
    pub fn build_from_dir(
        ctx: &impl AsDevice,
        splatter: &Splatter,
        model: &PointModel,
        cam: &Intrinsics,
        dir: &Path,
        cfg: &KeyframeConfig,
    ) -> Result<Self, KeyframeError> {
        let rows = crate::io::poses::read_poses(&dir.join("poses.csv"))?;
        let frames = load_keyframe_images(dir, &rows, cam)?;
        Self::build(ctx, splatter, model, cam, &frames, cfg)
    }

    /// The index of the keyframe whose viewpoint is closest to `pose`: the
    /// smallest angle between viewing directions, plus a penalty of 10
    /// degrees per factor e of distance ratio.
    pub fn closest(&self, pose: &Pose) -> usize {
        let (d, r) = viewpoint(pose, &self.center);
        let score = |k: &Keyframe| {
            let (dk, rk) = viewpoint(&k.pose, &self.center);
            d.dot(&dk).clamp(-1.0, 1.0).acos().to_degrees() + 10.0 * (r / rk).ln().abs()
        };
        (0..self.keyframes.len())
            .min_by(|&a, &b| score(&self.keyframes[a]).total_cmp(&score(&self.keyframes[b])))
            .unwrap_or(0)
    }

    /// The model with keyframe `k`'s colours.
    pub fn textured(&self, model: &PointModel, k: usize) -> PointModel {
        let mut m = model.clone();
        m.colors = Some(self.keyframes[k].colors.clone());
        m
    }

    /// Refuses a store built for another model.
    pub fn check_model(&self, model: &PointModel, path: &Path) -> Result<(), KeyframeError> {
        let fp = model_fingerprint(model);
        if self.points != model.len() as u64 || self.fingerprint != fp {
            return Err(KeyframeError::WrongModel {
                path: path.to_owned(),
                stored: self.points,
                stored_fp: self.fingerprint,
                points: model.len() as u64,
                fp,
            });
        }
        // The centre is the model's (model_center): another one is a
        // corrupt or hostile store, whose keyframe choice would be wrong.
        let (lo, hi) = model.bounds();
        let extent = (hi - lo).length().max(f32::MIN_POSITIVE) as f64;
        let want = model_center(model);
        if (self.center - want).norm() > 1e-3 * extent {
            return Err(KeyframeError::Format {
                path: path.to_owned(),
                reason: format!(
                    "the stored model centre ({:.4}, {:.4}, {:.4}) is not the model's ({:.4}, {:.4}, {:.4})",
                    self.center.x, self.center.y, self.center.z, want.x, want.y, want.z
                ),
            });
        }
        Ok(())
    }

    /// Saves to `path` (format: see [`KeyframeStore::load`]), atomically.
    pub fn save(&self, path: &Path) -> Result<(), KeyframeError> {
        let io = |source| KeyframeError::Io {
            path: path.to_owned(),
            source,
        };
        crate::io::atomic::write_atomic(path, |f| {
            f.write_all(MAGIC)?;
            for v in [self.points, self.fingerprint, self.keyframes.len() as u64] {
                f.write_all(&v.to_le_bytes())?;
            }
            for v in self.center.iter() {
                f.write_all(&v.to_le_bytes())?;
            }
            for k in &self.keyframes {
                let name = k.name.as_bytes();
                f.write_all(&(name.len() as u32).to_le_bytes())?;
                f.write_all(name)?;
                for v in k.pose.to_row_major() {
                    f.write_all(&v.to_le_bytes())?;
                }
                for (c, &vis) in k.colors.iter().zip(&k.visible) {
                    let q = c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8);
                    f.write_all(&[q[0], q[1], q[2], vis as u8])?;
                }
            }
            Ok(())
        })
        .map_err(io)
    }

    /// Loads a store saved by [`KeyframeStore::save`]: the magic
    /// `SPLATKF1`, u64 point count, u64 fingerprint, u64 keyframe count,
    /// 3 f64 centre; per keyframe a u32-prefixed UTF-8 name, 12 f64 pose
    /// values (R row-major, t) and per point 4 bytes (r, g, b, visible).
    pub fn load(path: &Path) -> Result<Self, KeyframeError> {
        let bytes = std::fs::read(path).map_err(|source| KeyframeError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::from_bytes(&bytes, path)
    }

    /// [`KeyframeStore::load`] of a file's bytes (`path` names it in errors).
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, KeyframeError> {
        let bad = |reason: &str| KeyframeError::Format {
            path: path.to_owned(),
            reason: reason.to_owned(),
        };
        let mut r = bytes;
        let mut magic = [0u8; 8];
        r.read_exact(&mut magic)
            .map_err(|_| bad("file too short"))?;
        if &magic != MAGIC {
            return Err(bad("wrong magic (expected SPLATKF1)"));
        }
        let mut u64s = [0u64; 3];
        for v in &mut u64s {
            let mut b = [0u8; 8];
            r.read_exact(&mut b).map_err(|_| bad("truncated header"))?;
            *v = u64::from_le_bytes(b);
        }
        let [points, fingerprint, count] = u64s;
        if count == 0 {
            return Err(bad("the store holds no keyframe"));
        }
        if points == 0 {
            return Err(bad("the store is for a model of 0 points"));
        }
        let per_kf = points.checked_mul(4).and_then(|v| v.checked_add(4 + 96));
        match per_kf.and_then(|p| p.checked_mul(count)) {
            Some(need) if need <= bytes.len() as u64 => {}
            _ => return Err(bad("header counts exceed the file size")),
        }
        let read_f64 = |r: &mut &[u8]| -> Result<f64, KeyframeError> {
            let mut b = [0u8; 8];
            r.read_exact(&mut b).map_err(|_| bad("truncated"))?;
            Ok(f64::from_le_bytes(b))
        };
        let center = Vector3::new(read_f64(&mut r)?, read_f64(&mut r)?, read_f64(&mut r)?);
        if !center.iter().all(|v| v.is_finite() && v.abs() <= 1e9) {
            return Err(bad(
                "the model centre is not finite or absurdly far (above 1e9)",
            ));
        }
        let mut keyframes = Vec::with_capacity(count as usize);
        for k in 0..count {
            let mut b = [0u8; 4];
            r.read_exact(&mut b).map_err(|_| bad("truncated"))?;
            let len = u32::from_le_bytes(b) as usize;
            if len > r.len() {
                return Err(bad("truncated name"));
            }
            let name =
                String::from_utf8(r[..len].to_vec()).map_err(|_| bad("name is not UTF-8"))?;
            r = &r[len..];
            let mut v = [0.0; 12];
            for x in &mut v {
                *x = read_f64(&mut r)?;
            }
            // A corrupt pose is a corrupt file: name the file, not just the pose.
            let pose = Pose::from_row_major(&v)
                .map_err(|e| bad(&format!("keyframe {k} ({name}): {e}")))?;
            let n = points as usize;
            if r.len() < 4 * n {
                return Err(bad("truncated colours"));
            }
            let (colors, visible) = r[..4 * n]
                .chunks_exact(4)
                .map(|c| ([c[0], c[1], c[2]].map(|v| v as f32 / 255.0), c[3] != 0))
                .unzip();
            r = &r[4 * n..];
            keyframes.push(Keyframe {
                name,
                pose,
                colors,
                visible,
            });
        }
        if !r.is_empty() {
            return Err(bad("trailing bytes"));
        }
        Ok(Self {
            keyframes,
            points,
            fingerprint,
            center,
        })
    }
}

const MAGIC: &[u8; 8] = b"SPLATKF1";

/// Reads the images named by `rows` from `dir` (the label with or without
/// its extension; .png, .jpg or .jpeg) and checks their size.
pub fn load_keyframe_images(
    dir: &Path,
    rows: &[PoseRow],
    cam: &Intrinsics,
) -> Result<Vec<(String, image::RgbImage, Pose)>, KeyframeError> {
    let mut out = Vec::with_capacity(rows.len());
    for row in rows {
        let direct = dir.join(&row.frame);
        let candidates = [
            direct.clone(),
            dir.join(format!("{}.png", row.frame_stem())),
            dir.join(format!("{}.jpg", row.frame_stem())),
            dir.join(format!("{}.jpeg", row.frame_stem())),
        ];
        let path = candidates
            .iter()
            .find(|p| p.is_file())
            .ok_or_else(|| KeyframeError::MissingImage(dir.to_owned(), row.frame.clone()))?;
        let img = image::open(path)
            .map_err(|source| KeyframeError::Image {
                path: path.clone(),
                source,
            })?
            .to_rgb8();
        if img.width() != cam.width || img.height() != cam.height {
            return Err(KeyframeError::ImageSize {
                path: path.clone(),
                got_w: img.width(),
                got_h: img.height(),
                want_w: cam.width,
                want_h: cam.height,
            });
        }
        out.push((row.frame_stem().to_owned(), img, row.pose));
    }
    Ok(out)
}

/// Default GPU memory for the keyframe colours of [`TexturedCache`]:
/// 64 MB (16 keyframes of a million points, 160 of 100k), so that a
/// 1M-point model's whole GPU memory at 640x480 stays under 256 MB
/// (docs/performance.md); a dropped keyframe costs one 4-bytes-a-point
/// upload when it is needed again.
pub const DEFAULT_TEXTURED_BUDGET: u64 = 64 << 20;

/// GPU bytes of one point's colour (RGBA8); the geometry is shared.
const COLOR_BYTES: u64 = 4;

/// The model textured by each keyframe on the GPU: the model's geometry
/// uploaded once and shared, and one colour buffer (4 bytes a point) per
/// keyframe, uploaded on first use and kept within a memory budget: when
/// one more would exceed it, the least recently used is dropped (and
/// uploaded again if needed), so a store of any size holds a bounded
/// amount of GPU memory. At least one is always kept.
pub struct TexturedCache {
    slots: Vec<Option<(GpuModel, u64)>>,
    clock: u64,
    max_resident: usize,
    uploads: u64,
}

impl TexturedCache {
    /// A cache for `keyframes` keyframes of a model of `points` points
    /// holding at most `budget_bytes` of keyframe colours.
    pub fn new(keyframes: usize, points: usize, budget_bytes: u64) -> Self {
        let per_model = (points as u64).max(1) * COLOR_BYTES;
        Self {
            slots: (0..keyframes).map(|_| None).collect(),
            clock: 0,
            max_resident: ((budget_bytes / per_model) as usize).max(1),
            uploads: 0,
        }
    }

    /// The model textured by keyframe `k` of `store`: `geometry` (the
    /// model on the GPU, shared) with keyframe `k`'s colours, uploaded when
    /// absent (`ctx`: the model's device).
    pub fn get(
        &mut self,
        ctx: &impl AsDevice,
        store: &KeyframeStore,
        geometry: &GpuModel,
        k: usize,
    ) -> Result<&GpuModel, SplatError> {
        self.clock += 1;
        let now = self.clock;
        if self.slots[k].is_none() {
            while self.resident() >= self.max_resident {
                let oldest = self
                    .slots
                    .iter()
                    .enumerate()
                    .filter_map(|(i, s)| s.as_ref().map(|(_, t)| (*t, i)))
                    .min()
                    .map(|(_, i)| i);
                match oldest {
                    Some(i) => self.slots[i] = None,
                    None => break,
                }
            }
            let colors = &store.keyframes[k].colors;
            self.slots[k] = Some((geometry.with_colors(ctx, colors)?, now));
            self.uploads += 1;
        }
        let (gm, stamp) = self.slots[k].as_mut().expect("filled above");
        *stamp = now;
        Ok(gm)
    }

    /// GPU bytes of the keyframe colours resident now (the geometry is
    /// the tracker's model, counted there).
    pub fn gpu_bytes(&self) -> u64 {
        self.slots
            .iter()
            .flatten()
            .map(|(m, _)| m.color_bytes())
            .sum()
    }

    /// Textured models on the GPU now.
    pub fn resident(&self) -> usize {
        self.slots.iter().filter(|s| s.is_some()).count()
    }

    /// The most that may be resident at once.
    pub fn max_resident(&self) -> usize {
        self.max_resident
    }

    /// Uploads so far (a re-upload after eviction counts again).
    pub fn uploads(&self) -> u64 {
        self.uploads
    }
}
