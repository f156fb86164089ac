//! Helpers shared by the keyframe and tracker integration tests: small
//! synthetic scenes rendered by the synth CPU triangle rasteriser (never by
//! the splatter under test), their point models and keyframe stores.
#![allow(dead_code)]

use splattrack::geometry::{Intrinsics, Pose};
use splattrack::gpu::shared_test_context;
use splattrack::io::{PoseRow, Sequence, read_poses};
use splattrack::keyframes::{KeyframeConfig, KeyframeStore};
use splattrack::model::{AttributeSource, PointModel, Provenance, TriangleMesh};
use splattrack::rng::Rng;
use splattrack::splat::Splatter;
use splattrack::synth::raster::{self, Rendering};
use splattrack::synth::sequence::sample_model;
use splattrack::synth::{
    Light, SynthConfig, SynthFrame, SynthObject, Trajectory, background, keyframe_poses,
    render_frame, to_image,
};
use std::path::PathBuf;

/// 320x240 with the synth command's 56-degree field of view.
pub fn camera_320() -> Intrinsics {
    Intrinsics::new(320, 240, 300.0, 300.0, 159.5, 119.5)
}

/// A synthetic scene: object, camera, background and the point model
/// sampled from the object's mesh.
pub struct Scene {
    pub object: SynthObject,
    pub cam: Intrinsics,
    pub bg: Vec<[f32; 3]>,
    pub model: PointModel,
    /// Bounding-sphere diameter of the mesh (model units).
    pub diameter: f64,
}

impl Scene {
    pub fn new(object: &str, cam: Intrinsics, points: usize) -> Self {
        let object = SynthObject::by_name(object).expect("built-in object");
        let bg = background(&cam, 7);
        let model = sample_model(&object, points, 3).expect("sample model");
        let diameter = object.mesh.diameter();
        Self {
            object,
            cam,
            bg,
            model,
            diameter,
        }
    }

    /// The rasterised rendering at `pose` (3x3 supersampling).
    pub fn render(&self, pose: &Pose, light_phase: f64) -> Rendering {
        raster::render(
            &self.object,
            pose,
            &self.cam,
            &Light::moving(light_phase),
            &self.bg,
            3,
        )
    }

    /// The rendering as an 8-bit frame with sensor noise.
    pub fn image(&self, r: &Rendering, noise: f64, seed: u64) -> image::RgbImage {
        to_image(&r.rgb, &self.cam, noise, &mut Rng::new(seed))
    }

    /// Keyframe images at the synth viewpoints (as `splattrack synth`
    /// writes them: light phase 0.3 k, noise 0.01).
    pub fn keyframe_images(&self, distance: f64) -> Vec<(String, image::RgbImage, Pose)> {
        keyframe_poses(distance)
            .into_iter()
            .enumerate()
            .map(|(k, pose)| {
                let r = self.render(&pose, 0.3 * k as f64);
                (
                    format!("kf{k:02}"),
                    self.image(&r, 0.01, 0xCAFE + k as u64),
                    pose,
                )
            })
            .collect()
    }

    /// The keyframe store built from [`Scene::keyframe_images`].
    pub fn keyframe_store(&self, distance: f64) -> KeyframeStore {
        let ctx = shared_test_context();
        let splatter = Splatter::new(ctx).expect("splatter");
        KeyframeStore::build(
            ctx,
            &splatter,
            &self.model,
            &self.cam,
            &self.keyframe_images(distance),
            &KeyframeConfig::default(),
        )
        .expect("build keyframe store")
    }
}

/// The blob on the 100-frame Fig. 10 trajectory at 320x240 (60k points),
/// its keyframe store and the frames asked for.
pub struct Fig10 {
    pub scene: Scene,
    pub store: KeyframeStore,
    pub frames: Vec<SynthFrame>,
}

impl Fig10 {
    /// Renders `frames` (indices into the 100-frame sequence).
    pub fn blob(frames: impl IntoIterator<Item = usize>) -> Self {
        let cam = camera_320();
        let scene = Scene::new("blob", cam, 60_000);
        let cfg = SynthConfig {
            camera: cam,
            frames: 100,
            trajectory: Trajectory::Fig10,
            ..Default::default()
        };
        let store = scene.keyframe_store(cfg.distance);
        let frames = frames
            .into_iter()
            .map(|i| render_frame(&cfg, &scene.object, &scene.bg, i))
            .collect();
        Self {
            scene,
            store,
            frames,
        }
    }
}

#[path = "../data_common/mod.rs"]
pub mod data_common;

/// The real sequence `name` in the folder `SPLATTRACK_DATA` names; `None`
/// (said on the terminal) when that is unset.
pub fn real_data_dir(name: &str) -> Option<PathBuf> {
    let dir = data_common::real_data(name)?;
    assert!(
        dir.join("poses.csv").is_file(),
        "{}: no poses.csv",
        dir.display()
    );
    Some(dir)
}

/// A real sequence loaded for tracking: model, frames and camera, the
/// keyframe store built from its keyframes folder, and the ground truth.
pub struct RealSequence {
    pub dir: PathBuf,
    pub model: PointModel,
    pub seq: Sequence,
    pub store: KeyframeStore,
    pub gt: Vec<PoseRow>,
}

impl RealSequence {
    /// Loads `name` ([`real_data_dir`] says when it may be absent).
    pub fn load(name: &str) -> Option<Self> {
        let dir = real_data_dir(name)?;
        let ctx = shared_test_context();
        let model = PointModel::load(dir.join("model.ply")).expect("model");
        let seq = Sequence::open(&dir).expect("sequence");
        let splatter = Splatter::new(ctx).expect("splatter");
        let store = KeyframeStore::build_from_dir(
            ctx,
            &splatter,
            &model,
            &seq.camera,
            &dir.join("keyframes"),
            &KeyframeConfig::default(),
        )
        .expect("keyframe store");
        let gt = read_poses(&dir.join("poses.csv")).expect("ground truth");
        Some(Self {
            dir,
            model,
            seq,
            store,
            gt,
        })
    }

    /// Frame `i` as an 8-bit image.
    pub fn image(&self, i: usize) -> image::RgbImage {
        image::open(&self.seq.frames[i]).expect("frame").to_rgb8()
    }
}

/// Points drawn uniformly at random over the mesh's surface (triangle by
/// area, then uniform barycentric coordinates), face normals, one radius.
pub fn random_sample(mesh: &TriangleMesh, n: usize, radius: f32, seed: u64) -> PointModel {
    let tri = |t: &[u32; 3]| {
        let v = |i: u32| mesh.vertices[i as usize];
        (v(t[0]), v(t[1]), v(t[2]))
    };
    let areas: Vec<f64> = mesh
        .triangles
        .iter()
        .map(|t| {
            let (a, b, c) = tri(t);
            0.5 * (b - a).cross(c - a).length()
        })
        .collect();
    let total: f64 = areas.iter().sum();
    let mut rng = Rng::new(seed);
    let (mut positions, mut normals) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for _ in 0..n {
        let mut target = rng.next_f64() * total;
        let mut k = 0;
        while k + 1 < areas.len() && target >= areas[k] {
            target -= areas[k];
            k += 1;
        }
        let (a, b, c) = tri(&mesh.triangles[k]);
        let (mut u, mut v) = (rng.next_f64(), rng.next_f64());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        positions.push((a + (b - a) * u + (c - a) * v).as_vec3());
        normals.push((b - a).cross(c - a).normalize().as_vec3());
    }
    PointModel {
        radii: vec![radius; n],
        positions,
        normals,
        colors: None,
        provenance: Provenance {
            path: None,
            normals: AttributeSource::FromMesh,
            radii: AttributeSource::Loaded,
            colors: AttributeSource::Absent,
            dropped_non_finite: 0,
            normals_reestimated: 0,
        },
    }
}

/// A fresh directory under the temp dir, removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> Self {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let p = std::env::temp_dir().join(format!("splattrack-{tag}-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).expect("create temp dir");
        Self(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Writes a small synthetic sequence under the tests' temporary folder,
/// named `name`: `frames` frames of the blob at 160x120, a 4000-point
/// model, the 12 synth keyframes.
pub fn small_sequence(name: &str, frames: usize) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    let cfg = SynthConfig {
        frames,
        camera: Intrinsics::new(160, 120, 150.0, 150.0, 79.5, 59.5),
        ..Default::default()
    };
    splattrack::synth::sequence::write_sequence(&cfg, &dir, 4000, None)
        .expect("write the sequence");
    dir
}

/// A fresh, empty folder `group/name` under the tests' temporary folder.
pub fn workdir(group: &str, name: &str) -> PathBuf {
    let d = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(group)
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}
