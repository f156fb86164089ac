//! Synthetic scenes of several objects that cross and hide each other.
//!
//! Every object moves on its own path across the image at its own depth,
//! turning as the one-object trajectories do. All objects are rasterised
//! together with one depth test ([`raster::render_many`]), so occlusion
//! between them is exact, and the rasteriser's per-sample object id gives
//! the ground truth of how much of each object is visible.

use super::Background;
use super::background::make_background;
use super::error::SynthError;
use super::framing::{apparent_size_px, distance_for_size};
use super::objects::{Light, SynthObject};
use super::raster;
use super::scene::{SynthConfig, base_pose, keyframe_images, to_image};
use crate::geometry::{Intrinsics, Pose, rotation_exp};
use crate::rng::Rng;
use nalgebra::{Vector2, Vector3};

/// How the objects of a [`MultiScene`] move relative to each other.
/// Objects are listed from the farthest to the nearest.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// Two objects cross in opposite directions at different depths; the
    /// nearer hides about half of the farther at the crossing.
    Cross,
    /// The nearer passes wholly in front of the slowly moving farther,
    /// which is hidden completely for about an eighth of the sequence.
    Hide,
    /// As [`Layout::Cross`], for a textured and an untextured object, the
    /// nearer hiding at most about 40% of the farther.
    Mixed,
    /// Three objects at three depths: the middle one and the nearest cross
    /// the farthest (and each other) in opposite directions.
    Cross3,
}

impl Layout {
    /// The names [`Layout::by_name`] accepts.
    pub const NAMES: [&'static str; 4] = ["cross", "hide", "mixed", "cross3"];

    /// The layout called `name` (one of [`Layout::NAMES`]).
    pub fn by_name(name: &str) -> Option<Self> {
        match name {
            "cross" => Some(Self::Cross),
            "hide" => Some(Self::Hide),
            "mixed" => Some(Self::Mixed),
            "cross3" => Some(Self::Cross3),
            _ => None,
        }
    }

    /// Its name, as [`Layout::by_name`] takes it.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Cross => "cross",
            Self::Hide => "hide",
            Self::Mixed => "mixed",
            Self::Cross3 => "cross3",
        }
    }

    /// The built-in objects it uses by default, farthest first.
    pub fn default_objects(&self) -> &'static [&'static str] {
        match self {
            Self::Cross => &["blob", "box"],
            Self::Hide => &["box", "blob"],
            Self::Mixed => &["blob", "plain"],
            Self::Cross3 => &["blob", "torus", "box"],
        }
    }

    /// How many objects it takes.
    pub fn object_count(&self) -> usize {
        self.default_objects().len()
    }
}

/// Settings of a synthetic sequence of several objects.
#[derive(Debug, Clone)]
pub struct MultiConfig {
    /// How the objects move.
    pub layout: Layout,
    /// Built-in objects ([`OBJECT_NAMES`](super::objects::OBJECT_NAMES)),
    /// farthest first; empty for the layout's
    /// [`default_objects`](Layout::default_objects).
    pub objects: Vec<String>,
    /// Number of frames.
    pub frames: usize,
    /// The camera (no distortion).
    pub camera: Intrinsics,
    /// Standard deviation of the additive sensor noise (0..1 intensities).
    pub noise: f64,
    /// Supersampling per axis (odd, so depth is taken at the pixel centre).
    pub samples: usize,
    /// Seed of the background, the models' sampling and the noise.
    pub seed: u64,
    /// What is behind the objects (clutter is made in the farthest
    /// object's colours).
    pub background: Background,
}

impl Default for MultiConfig {
    fn default() -> Self {
        Self {
            layout: Layout::Cross,
            objects: Vec::new(),
            frames: 90,
            camera: Intrinsics::new(640, 480, 600.0, 600.0, 319.5, 239.5),
            noise: 0.01,
            samples: 3,
            seed: 1,
            background: Background::Shapes,
        }
    }
}

/// One object's motion: a straight path across the image at a depth,
/// turning about its centre.
#[derive(Debug, Clone, Copy)]
struct Path {
    /// Where the centre starts and ends, in fractions of the image's
    /// width and height.
    from: Vector2<f64>,
    to: Vector2<f64>,
    /// Distance from the camera, metres.
    distance: f64,
    /// How far the distance swings about [`Path::distance`], metres.
    swing: f64,
    /// The viewpoint of the object's resting orientation, degrees.
    azimuth: f64,
    elevation: f64,
    /// Amplitude of the turns about the camera's three axes, radians.
    turn: f64,
    /// Phase of the turns and of the depth's swing, radians.
    phase: f64,
    /// Follow the path with a smooth start and stop (fastest at the
    /// middle) instead of at constant speed.
    ease: bool,
}

/// How far the depth swings about [`Path::distance`] by default, metres.
const DEPTH_SWING: f64 = 0.015;

impl Path {
    /// The pose at `s` in [0, 1] of the sequence seen by `cam`.
    fn pose(&self, s: f64, cam: &Intrinsics) -> Pose {
        let tau = std::f64::consts::TAU;
        let e = if self.ease {
            s * s * (3.0 - 2.0 * s)
        } else {
            s
        };
        let f = self.from + (self.to - self.from) * e;
        let (u, v) = (f.x * cam.width as f64, f.y * cam.height as f64);
        let z = self.distance + self.swing * (tau * s + self.phase).sin();
        let t = Vector3::new((u - cam.cx) / cam.fx * z, (v - cam.cy) / cam.fy * z, z);
        // The one-object trajectories' rotation amplitude, slower.
        let rate = [1.0, 1.5, 0.75];
        let w =
            Vector3::from_fn(|j, _| self.turn * (tau * rate[j] * s + self.phase + j as f64).sin());
        let base = base_pose(self.distance, self.azimuth, self.elevation);
        Pose {
            rotation: rotation_exp(&w) * base.rotation,
            translation: t,
        }
    }
}

/// One object of a [`MultiScene`].
#[derive(Debug, Clone)]
pub struct MultiObject {
    /// Its name in the sequence's files: the built-in object's, with `-2`,
    /// `-3` appended to a second and third of the same.
    pub name: String,
    /// The object.
    pub object: SynthObject,
    path: Path,
}

impl MultiObject {
    /// Its mean distance from the camera, metres.
    pub fn distance(&self) -> f64 {
        self.path.distance
    }
}

/// One rendered frame of a [`MultiScene`].
pub struct MultiFrame {
    /// The 8-bit frame, noise included.
    pub image: image::RgbImage,
    /// Each object's ground-truth object-to-camera pose.
    pub poses: Vec<Pose>,
    /// Each object's visible fraction of its silhouette (0..1,
    /// [`raster::JointRendering::visible_fraction`]).
    pub visibility: Vec<f64>,
    /// The object seen at each pixel centre (its index), or
    /// [`raster::NO_OBJECT`].
    pub id: Vec<u8>,
    /// Camera-space depth of the nearest object at each pixel centre (NaN
    /// off every object).
    pub depth: Vec<f32>,
}

/// A synthetic sequence of several objects ready to render.
pub struct MultiScene {
    /// The settings (objects filled in where they were left empty).
    pub config: MultiConfig,
    /// The objects, farthest first.
    pub objects: Vec<MultiObject>,
    /// The static background (linear RGB, the camera's size, row-major).
    pub background: Vec<[f32; 3]>,
    /// The keyframes' background: over clutter, clutter of another seed.
    keyframe_background: Option<Vec<[f32; 3]>>,
}

/// The apparent sizes the layouts aim at, as fractions of the image
/// width: about the one-object default's (0.3).
const FAR_SIZE: f64 = 0.25;
const NEAR_SIZE: f64 = 0.27;

/// The hidden fraction of the farther object at the crossing that
/// [`Layout::Cross`] and [`Layout::Mixed`] aim at (of any object, for
/// [`Layout::Cross3`]).
fn target_hidden(layout: Layout) -> f64 {
    match layout {
        Layout::Mixed => 0.33,
        _ => 0.45,
    }
}

/// The part of the sequence about its middle throughout which
/// [`Layout::Hide`] hides the farther object wholly (at least).
const HIDE_SPAN: f64 = 0.1;

impl MultiScene {
    /// The scene `config` describes: the objects are placed and their
    /// paths solved for the layout's occlusion (which takes some
    /// rasterising).
    pub fn new(mut config: MultiConfig) -> Result<Self, SynthError> {
        let layout = config.layout;
        if config.objects.is_empty() {
            config.objects = layout
                .default_objects()
                .iter()
                .map(|s| s.to_string())
                .collect();
        }
        if config.objects.len() != layout.object_count() {
            return Err(SynthError::ObjectCount {
                layout: layout.name(),
                want: layout.object_count(),
                got: config.objects.len(),
            });
        }
        if config.frames < 2 {
            return Err(SynthError::TooFewFrames(config.frames));
        }
        let objects = config
            .objects
            .iter()
            .map(|n| SynthObject::by_name(n).ok_or_else(|| SynthError::UnknownObject(n.clone())))
            .collect::<Result<Vec<_>, _>>()?;
        let names = object_names(&config.objects);
        let paths = place(layout, &objects, &config.camera);
        let objects: Vec<MultiObject> = objects
            .into_iter()
            .zip(names)
            .zip(paths)
            .map(|((object, name), path)| MultiObject { name, object, path })
            .collect();
        let far = &objects[0];
        let bg = |seed| {
            make_background(
                config.background,
                &config.camera,
                &far.object,
                far.path.distance,
                seed,
            )
        };
        let background = bg(config.seed);
        let keyframe_background =
            (config.background == Background::Clutter).then(|| bg(config.seed ^ 0x4B46_4247));
        Ok(Self {
            config,
            objects,
            background,
            keyframe_background,
        })
    }

    /// The objects' names, farthest first.
    pub fn names(&self) -> Vec<&str> {
        self.objects.iter().map(|o| o.name.as_str()).collect()
    }

    /// The ground-truth pose of object `k` at frame `i`.
    pub fn pose(&self, k: usize, i: usize) -> Pose {
        let n = self.config.frames.max(2);
        self.objects[k]
            .path
            .pose(i as f64 / (n - 1) as f64, &self.config.camera)
    }

    /// Renders frame `i`: all objects at once over the background, under
    /// the one-object sequences' moving light and noise.
    pub fn frame(&self, i: usize) -> MultiFrame {
        let cfg = &self.config;
        let poses: Vec<Pose> = (0..self.objects.len()).map(|k| self.pose(k, i)).collect();
        let phase = i as f64 / cfg.frames.max(1) as f64 * std::f64::consts::PI;
        let light = Light::moving(phase);
        let items: Vec<(&SynthObject, &Pose)> =
            self.objects.iter().map(|o| &o.object).zip(&poses).collect();
        let r = raster::render_many(&items, &cfg.camera, &light, &self.background, cfg.samples);
        let visibility = (0..items.len()).map(|k| r.visible_fraction(k)).collect();
        let mut rng = Rng::new(cfg.seed.wrapping_mul(1_000_003).wrapping_add(i as u64));
        MultiFrame {
            image: to_image(&r.rgb, &cfg.camera, cfg.noise, &mut rng),
            poses,
            visibility,
            id: r.id,
            depth: r.depth,
        }
    }

    /// Object `k`'s keyframe images, rendered with that object alone
    /// ([`keyframe_images`] at its distance).
    pub fn keyframe_images(&self, k: usize) -> Vec<(String, image::RgbImage, Pose)> {
        let bg = self
            .keyframe_background
            .as_ref()
            .unwrap_or(&self.background);
        keyframe_images(&self.object_config(k), &self.objects[k].object, bg)
    }

    /// Object `k` as a one-object sequence's settings (its distance, the
    /// camera, noise and a seed of its own).
    pub fn object_config(&self, k: usize) -> SynthConfig {
        let cfg = &self.config;
        SynthConfig {
            object: self.objects[k].object.name.to_string(),
            frames: cfg.frames,
            camera: cfg.camera,
            distance: self.objects[k].path.distance,
            noise: cfg.noise,
            samples: cfg.samples,
            seed: cfg.seed.wrapping_add(k as u64),
            background: cfg.background,
            ..SynthConfig::default()
        }
    }

    /// Object `k`'s apparent size at frame 0, pixels across (the larger
    /// side of its silhouette's bounding box).
    pub fn size_px(&self, k: usize) -> f64 {
        apparent_size_px(
            &self.objects[k].object.mesh,
            &self.pose(k, 0),
            &self.config.camera,
        )
    }
}

/// Names for `objects` in a sequence's files: a second and third of the
/// same get `-2`, `-3`.
pub fn object_names(objects: &[String]) -> Vec<String> {
    objects
        .iter()
        .enumerate()
        .map(
            |(k, n)| match objects[..k].iter().filter(|o| *o == n).count() {
                0 => n.clone(),
                c => format!("{n}-{}", c + 1),
            },
        )
        .collect()
}

/// The radius of the sphere about the object's origin that holds it.
fn radius(object: &SynthObject) -> f64 {
    object
        .mesh
        .vertices
        .iter()
        .map(|v| v.length())
        .fold(0.0, f64::max)
}

/// The distance at which `object` seen from (`azimuth`, `elevation`)
/// appears `fraction` of the image width across.
fn distance_for(object: &SynthObject, cam: &Intrinsics, fraction: f64, az: f64, el: f64) -> f64 {
    distance_for_size(&object.mesh, cam, fraction * cam.width as f64, |d| {
        base_pose(d, az, el)
    })
}

/// The depth between the centres of two objects on paths `pa` and `pb`
/// that keeps them apart in space however they turn and swing.
fn gap(a: &SynthObject, pa: &Path, b: &SynthObject, pb: &Path) -> f64 {
    radius(a) + radius(b) + pa.swing + pb.swing + 0.01
}

/// The paths of `objects` (farthest first) in `layout`.
fn place(layout: Layout, objects: &[SynthObject], cam: &Intrinsics) -> Vec<Path> {
    let path = |from: (f64, f64), to: (f64, f64), az: f64, el: f64, phase: f64| Path {
        from: Vector2::new(from.0, from.1),
        to: Vector2::new(to.0, to.1),
        distance: 0.0,
        swing: DEPTH_SWING,
        azimuth: az,
        elevation: el,
        turn: 0.35,
        phase,
        ease: false,
    };
    match layout {
        Layout::Cross | Layout::Mixed => {
            let (far, near) = (&objects[0], &objects[1]);
            let mut paths = vec![
                path((0.27, 0.5), (0.73, 0.5), 30.0, 25.0, 0.0),
                path((0.75, 0.5), (0.25, 0.5), -35.0, 20.0, 2.0),
            ];
            paths[1].distance = distance_for(near, cam, NEAR_SIZE, -35.0, 20.0);
            paths[0].distance = distance_for(far, cam, FAR_SIZE, 30.0, 25.0)
                .max(paths[1].distance + gap(far, &paths[0], near, &paths[1]));
            let meshes = [far, near];
            let target = target_hidden(layout);
            // Apart vertically by `dv` (fraction of the height): the far
            // one below the middle, the near one above.
            let with = |dv: f64| {
                let mut p = paths.clone();
                p[0].from.y += dv / 2.0;
                p[0].to.y += dv / 2.0;
                p[1].from.y -= dv / 2.0;
                p[1].to.y -= dv / 2.0;
                p
            };
            let hidden = |dv: f64| peak_hidden(&meshes, &with(dv), cam, 0);
            let dv = solve_decreasing(hidden, target, 0.0, 0.8);
            with(dv)
        }
        Layout::Hide => {
            let (far, near) = (&objects[0], &objects[1]);
            let mut paths = vec![
                path((0.46, 0.5), (0.54, 0.5), 30.0, 25.0, 0.0),
                path((0.77, 0.5), (0.23, 0.5), -35.0, 20.0, 2.0),
            ];
            paths[0].turn = 0.15;
            paths[1].ease = true;
            // No swing in depth: the near one may then be smaller.
            paths[0].swing = 0.0;
            paths[1].swing = 0.0;
            paths[0].distance = distance_for(far, cam, 0.2, 30.0, 25.0);
            paths[1].distance = paths[0].distance - gap(far, &paths[0], near, &paths[1]);
            let meshes = [far, near];
            // Wholly hidden at both ends of the span about the middle and
            // at the middle itself.
            let hides = |p: &[Path]| {
                [0.5 - HIDE_SPAN / 2.0, 0.5, 0.5 + HIDE_SPAN / 2.0]
                    .iter()
                    .all(|&s| visible_at(&meshes, p, cam, s)[0] == 0.0)
            };
            let raised = |dv: f64| {
                let mut p = paths.clone();
                p[1].from.y -= dv;
                p[1].to.y -= dv;
                p
            };
            if hides(&paths) {
                // Larger than needed: pass off centre, so that it hides
                // the far one for no longer than the span.
                let (mut lo, mut hi) = (0.0, 0.5);
                for _ in 0..12 {
                    let mid = 0.5 * (lo + hi);
                    if hides(&raised(mid)) {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                raised(lo)
            } else {
                // Too small: come nearer until it hides the span.
                let at = |d: f64| {
                    let mut p = paths.clone();
                    p[1].distance = d;
                    p
                };
                let (mut lo, mut hi) = (0.3 * paths[1].distance, paths[1].distance);
                for _ in 0..12 {
                    let mid = 0.5 * (lo + hi);
                    if hides(&at(mid)) {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                at(lo)
            }
        }
        Layout::Cross3 => {
            let (far, mid, near) = (&objects[0], &objects[1], &objects[2]);
            // The middle one crosses the farthest at the middle of the
            // sequence, the nearest later, and they cross each other in
            // between.
            let mut paths = vec![
                path((0.45, 0.5), (0.55, 0.5), 30.0, 25.0, 0.0),
                path((0.15, 0.5), (0.85, 0.5), -35.0, 20.0, 2.0),
                path((0.85, 0.5), (0.35, 0.5), 60.0, 35.0, 4.0),
            ];
            paths[0].turn = 0.25;
            paths[2].distance = distance_for(near, cam, NEAR_SIZE, 60.0, 35.0);
            paths[1].distance = distance_for(mid, cam, NEAR_SIZE, -35.0, 20.0)
                .max(paths[2].distance + gap(mid, &paths[1], near, &paths[2]));
            paths[0].distance = distance_for(far, cam, FAR_SIZE, 30.0, 25.0)
                .max(paths[1].distance + gap(far, &paths[0], mid, &paths[1]));
            let meshes = [far, mid, near];
            // The middle one above by `dv` (fraction of the height), the
            // nearest below by as much.
            let with = |dv: f64| {
                let mut p = paths.clone();
                for (k, sign) in [(1, -1.0), (2, 1.0)] {
                    p[k].from.y += sign * dv;
                    p[k].to.y += sign * dv;
                }
                p
            };
            let hidden = |dv: f64| {
                let p = with(dv);
                (0..=50)
                    .map(|j| visible_at(&meshes, &p, cam, j as f64 / 50.0))
                    .flat_map(|v| v.into_iter().map(|v| 1.0 - v))
                    .fold(0.0, f64::max)
            };
            let dv = solve_decreasing(hidden, target_hidden(layout), 0.0, 0.5);
            with(dv)
        }
    }
}

/// Each object's visible fraction at `s` with the objects on `paths`.
fn visible_at(objects: &[&SynthObject], paths: &[Path], cam: &Intrinsics, s: f64) -> Vec<f64> {
    let poses: Vec<Pose> = paths.iter().map(|p| p.pose(s, cam)).collect();
    let meshes: Vec<_> = objects.iter().map(|o| &o.mesh).zip(&poses).collect();
    raster::visible_fractions(&meshes, cam, 1)
}

/// The largest hidden fraction of object `k` about the middle of the
/// sequence, where the paths cross.
fn peak_hidden(objects: &[&SynthObject], paths: &[Path], cam: &Intrinsics, k: usize) -> f64 {
    (-5..=5)
        .map(|j| 1.0 - visible_at(objects, paths, cam, 0.5 + 0.02 * j as f64)[k])
        .fold(0.0, f64::max)
}

/// The `x` in `lo..hi` where the decreasing `f` falls to `target` (`lo`
/// where it is below already).
fn solve_decreasing(f: impl Fn(f64) -> f64, target: f64, lo: f64, hi: f64) -> f64 {
    if f(lo) <= target {
        return lo;
    }
    let (mut lo, mut hi) = (lo, hi);
    for _ in 0..12 {
        let mid = 0.5 * (lo + hi);
        if f(mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}
