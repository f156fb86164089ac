//! A synthetic sequence's scene: the trajectory, the configuration, the
//! background, the keyframes' viewpoints and the frames rendered from them.

use super::background::{Background, distractors, lower_contrast, luminance, make_background};
use super::framing::shift_for_exit;
use super::objects::{Light, SynthObject};
use super::raster;
use crate::geometry::{Intrinsics, Pose, look_at, rotation_exp};
use crate::rng::Rng;
use nalgebra::{Vector2, Vector3, Vector6};

/// How the object moves in front of the fixed camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Trajectory {
    /// Like the paper's Fig. 10: translations along camera x, y, z, then
    /// rotations about x, y, z (about the object's centre), each out and
    /// back, one after the other.
    Fig10,
    /// The same motions combined and about four times as fast.
    Fast,
    /// A full turn about the object's vertical axis: keyframes are
    /// indispensable, since most of the surface is new at some point.
    Turn,
}

impl Trajectory {
    /// The names [`Trajectory::by_name`] accepts.
    pub const NAMES: [&'static str; 3] = ["fig10", "fast", "turn"];

    /// The trajectory called `name` (one of [`Trajectory::NAMES`]).
    pub fn by_name(name: &str) -> Option<Self> {
        match name {
            "fig10" => Some(Self::Fig10),
            "fast" => Some(Self::Fast),
            "turn" => Some(Self::Turn),
            _ => None,
        }
    }

    /// Its name, as [`Trajectory::by_name`] takes it.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Fig10 => "fig10",
            Self::Fast => "fast",
            Self::Turn => "turn",
        }
    }

    /// The offset from the base pose at `s` in [0, 1]: a camera-frame twist
    /// about the object's centre (translation in metres, rotation in
    /// radians), its translations scaled by `scale`.
    fn offset(&self, s: f64, scale: f64) -> Vector6<f64> {
        let tau = std::f64::consts::TAU;
        // Amplitudes per generator: x, y (m), z (m), rotations (rad).
        let amp = Vector6::new(0.04 * scale, 0.03 * scale, 0.08 * scale, 0.35, 0.35, 0.35);
        match self {
            Self::Fig10 => {
                // Six equal segments; each goes out and back smoothly.
                let seg = ((s * 6.0).floor() as usize).min(5);
                let local = s * 6.0 - seg as f64;
                let mut v = Vector6::zeros();
                v[seg] = amp[seg] * (local * tau).sin();
                v
            }
            Self::Fast => {
                // All six at once, incommensurate frequencies, 4x the rate.
                let f = [4.0, 3.0, 2.5, 3.5, 4.5, 2.0];
                Vector6::from_fn(|j, _| amp[j] * (s * f[j] * tau * 0.5 + j as f64).sin())
            }
            Self::Turn => Vector6::zeros(),
        }
    }
}

/// Settings of a synthetic sequence.
#[derive(Debug, Clone)]
pub struct SynthConfig {
    /// A built-in object ([`OBJECT_NAMES`](super::objects::OBJECT_NAMES)).
    pub object: String,
    /// How the object moves.
    pub trajectory: Trajectory,
    /// Number of frames; the whole trajectory spans them, so fewer frames
    /// mean faster motion.
    pub frames: usize,
    /// The camera (no distortion).
    pub camera: Intrinsics,
    /// Object distance from the camera, metres.
    pub distance: f64,
    /// Standard deviation of the additive sensor noise (0..1 intensities).
    pub noise: f64,
    /// Supersampling per axis (odd, so depth is taken at the pixel centre).
    pub samples: usize,
    /// Seed of the background, the model sampling and the noise.
    pub seed: u64,
    /// What is behind the object.
    pub background: Background,
    /// Lower the background's grey-level contrast until it is about the
    /// object's own grey (hues kept).
    pub low_contrast: bool,
    /// The fraction (0..1) of the object's silhouette that the middle frame
    /// puts outside the image's right edge: the object slides out and
    /// back on top of its trajectory (0: it stays in view).
    pub exit: f64,
    /// Distractor objects in front of the object, near its path, that hide
    /// parts of it in some frames (0: none).
    pub occluders: usize,
}

impl Default for SynthConfig {
    fn default() -> Self {
        Self {
            object: "blob".into(),
            trajectory: Trajectory::Fig10,
            frames: 120,
            camera: Intrinsics::new(640, 480, 600.0, 600.0, 319.5, 239.5),
            distance: 0.55,
            noise: 0.01,
            samples: 3,
            seed: 1,
            background: Background::Shapes,
            low_contrast: false,
            exit: 0.0,
            occluders: 0,
        }
    }
}

impl SynthConfig {
    /// These settings with the distance at which `object` appears `px`
    /// pixels across at the base viewpoint (the larger side of its
    /// silhouette's bounding box, [`framing::apparent_size_px`](super::framing::apparent_size_px)).
    pub fn with_object_px(mut self, object: &SynthObject, px: f64) -> Self {
        self.distance = super::framing::distance_for_size(&object.mesh, &self.camera, px, |d| {
            base_pose(d, 30.0, 25.0)
        });
        self
    }
}

/// The base viewpoint: looking at the object's centre from `distance`,
/// 30 degrees to the side and 25 degrees above, object +z up in the image.
pub fn base_pose(distance: f64, azimuth_deg: f64, elevation_deg: f64) -> Pose {
    let (az, el) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
    let eye = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin()) * distance;
    look_at(&eye, &Vector3::zeros(), &Vector3::new(0.0, 0.0, 1.0))
}

/// The distance the trajectories' translations are made for: at others
/// they scale with it, so the motion in the image stays the same.
const REFERENCE_DISTANCE: f64 = 0.55;

/// The ground-truth pose of frame `i` of `n` (without
/// [`SynthConfig::exit`]'s slide: [`SynthScene::pose`] adds it).
pub fn trajectory_pose(traj: Trajectory, distance: f64, i: usize, n: usize) -> Pose {
    let s = if n > 1 {
        i as f64 / (n - 1) as f64
    } else {
        0.0
    };
    let base = base_pose(distance, 30.0, 25.0);
    match traj {
        Trajectory::Turn => {
            // Turn the object about its own vertical axis.
            let r = rotation_exp(&Vector3::new(0.0, 0.0, s * std::f64::consts::TAU));
            Pose {
                rotation: base.rotation * r,
                translation: base.translation,
            }
        }
        _ => {
            let off = traj.offset(s, distance / REFERENCE_DISTANCE);
            let w = Vector3::new(off[3], off[4], off[5]);
            // Rotate about the object's centre (at base.translation in the
            // camera frame), then translate.
            Pose {
                rotation: rotation_exp(&w) * base.rotation,
                translation: base.translation + Vector3::new(off[0], off[1], off[2]),
            }
        }
    }
}

/// Viewpoints for keyframes spread over the viewing sphere: eight around
/// the object at the base elevation and four from higher up.
pub fn keyframe_poses(distance: f64) -> Vec<Pose> {
    let mut v: Vec<Pose> = (0..8)
        .map(|k| base_pose(distance, 30.0 + 45.0 * k as f64, 25.0))
        .collect();
    v.extend((0..4).map(|k| base_pose(distance, 75.0 + 90.0 * k as f64, 60.0)));
    v
}

/// Converts a linear 0..1 rendering to an 8-bit image with Gaussian noise.
pub fn to_image(rgb: &[[f32; 3]], cam: &Intrinsics, noise: f64, rng: &mut Rng) -> image::RgbImage {
    image::RgbImage::from_fn(cam.width, cam.height, |x, y| {
        let p = rgb[(y * cam.width + x) as usize];
        image::Rgb(p.map(|v| {
            let n = if noise > 0.0 {
                rng.normal() * noise
            } else {
                0.0
            };
            ((v as f64 + n).clamp(0.0, 1.0) * 255.0).round() as u8
        }))
    })
}

/// The keyframe images of a sequence, named `kf00.png`, `kf01.png`, ...:
/// rendered at [`keyframe_poses`] by the same rasteriser, each under its
/// own light direction and with its own noise.
pub fn keyframe_images(
    cfg: &SynthConfig,
    object: &SynthObject,
    bg: &[[f32; 3]],
) -> Vec<(String, image::RgbImage, Pose)> {
    keyframe_poses(cfg.distance)
        .into_iter()
        .enumerate()
        .map(|(k, pose)| {
            let light = Light::moving(0.3 * k as f64);
            let r = raster::render(object, &pose, &cfg.camera, &light, bg, cfg.samples);
            let mut rng = Rng::new(cfg.seed ^ (0xCAFE + k as u64));
            let img = to_image(&r.rgb, &cfg.camera, cfg.noise, &mut rng);
            (format!("kf{k:02}.png"), img, pose)
        })
        .collect()
}

/// One rendered frame of a sequence: the image and the object's mask.
pub struct SynthFrame {
    /// The 8-bit frame, noise included.
    pub image: image::RgbImage,
    /// The ground-truth object-to-camera pose.
    pub pose: Pose,
    /// Object coverage per pixel (0..1).
    pub coverage: Vec<f32>,
    /// Camera-space depth at each pixel centre (NaN off the object).
    pub depth: Vec<f32>,
}

/// Renders frame `i` of the sequence `cfg` describes over `bg` (used as
/// given). Each call prepares the scene anew ([`SynthScene`] prepares it
/// once: the exit slide is solved for, which takes some rasterising).
pub fn render_frame(
    cfg: &SynthConfig,
    object: &SynthObject,
    bg: &[[f32; 3]],
    i: usize,
) -> SynthFrame {
    SynthScene::with_background(cfg.clone(), object.clone(), bg.to_vec()).frame(i)
}

/// A synthetic sequence ready to render: the configuration, the object,
/// its background, the occluders in front and the exit slide.
pub struct SynthScene {
    /// The settings.
    pub config: SynthConfig,
    /// The object.
    pub object: SynthObject,
    /// The static background (linear RGB, the camera's size, row-major).
    pub background: Vec<[f32; 3]>,
    /// Distractors in front of the object ([`SynthConfig::occluders`]).
    occluders: Vec<(SynthObject, Pose)>,
    /// The exit slide's peak, metres along camera x.
    exit_shift: f64,
    /// The keyframes' background, where it differs from the frames'.
    keyframe_background: Option<Vec<[f32; 3]>>,
}

impl SynthScene {
    /// The scene `config` describes for `object` (its background from
    /// [`SynthConfig::background`] and [`SynthConfig::low_contrast`]).
    /// Over clutter, the keyframes are rendered over clutter of another
    /// seed: the camera that took them saw other surroundings.
    pub fn new(config: SynthConfig, object: SynthObject) -> Self {
        let bg = scene_background(&config, &object, config.seed);
        let kf_bg = (config.background == Background::Clutter)
            .then(|| scene_background(&config, &object, config.seed ^ 0x4B46_4247));
        let mut scene = Self::with_background(config, object, bg);
        scene.keyframe_background = kf_bg;
        scene
    }

    /// The scene with `background` as given (for the keyframes too).
    pub fn with_background(
        config: SynthConfig,
        object: SynthObject,
        background: Vec<[f32; 3]>,
    ) -> Self {
        let n = config.frames;
        let cam = config.camera;
        let exit_shift = if config.exit > 0.0 {
            let peak = trajectory_pose(config.trajectory, config.distance, peak_frame(n), n);
            shift_for_exit(&object.mesh, &peak, &cam, config.exit.min(1.0))
        } else {
            0.0
        };
        let occluders = if config.occluders > 0 {
            // Near where the object starts, well in front of it.
            let p0 = trajectory_pose(config.trajectory, config.distance, 0, n);
            let c = cam
                .project(&p0.translation)
                .unwrap_or(Vector2::new(cam.cx, cam.cy));
            let r = cam.fx * object.mesh.diameter() / config.distance * 0.4;
            let at = super::background::Placement {
                count: config.occluders,
                depth: (0.55, 0.75),
                region: (c - Vector2::repeat(r), c + Vector2::repeat(r)),
                size: (0.2, 0.35),
                own: false,
            };
            let mut rng = Rng::new(config.seed ^ 0x0CC1);
            distractors(&object, &cam, config.distance, &at, &mut rng)
        } else {
            Vec::new()
        };
        Self {
            config,
            object,
            background,
            occluders,
            exit_shift,
            keyframe_background: None,
        }
    }

    /// The ground-truth pose of frame `i`: the trajectory's, plus the exit
    /// slide (out to the right and back, farthest at the middle frame).
    pub fn pose(&self, i: usize) -> Pose {
        let cfg = &self.config;
        let mut pose = trajectory_pose(cfg.trajectory, cfg.distance, i, cfg.frames);
        if self.exit_shift != 0.0 {
            let bump = |k: usize| {
                let s = k as f64 / (cfg.frames.max(2) - 1) as f64;
                (std::f64::consts::PI * s).sin().powi(2)
            };
            pose.translation.x += self.exit_shift * bump(i) / bump(peak_frame(cfg.frames));
        }
        pose
    }

    /// Renders frame `i`: the object over the background, then the
    /// occluders over both (the coverage and depth are the object's
    /// visible part).
    pub fn frame(&self, i: usize) -> SynthFrame {
        let cfg = &self.config;
        let pose = self.pose(i);
        let phase = i as f64 / cfg.frames.max(1) as f64 * std::f64::consts::PI;
        let light = Light::moving(phase);
        let r = raster::render(
            &self.object,
            &pose,
            &cfg.camera,
            &light,
            &self.background,
            cfg.samples,
        );
        let (mut rgb, mut coverage, mut depth) = (r.rgb, r.coverage, r.depth);
        let black = vec![[0.0f32; 3]; rgb.len()];
        for (occ, p) in &self.occluders {
            // Over black, an occluder's colour comes premultiplied by its
            // coverage.
            let o = raster::render(occ, p, &cfg.camera, &light, &black, cfg.samples);
            for k in 0..rgb.len() {
                let a = o.coverage[k];
                if a > 0.0 {
                    rgb[k] = [0, 1, 2].map(|c| o.rgb[k][c] + (1.0 - a) * rgb[k][c]);
                    coverage[k] *= 1.0 - a;
                }
                if o.depth[k].is_finite() {
                    depth[k] = f32::NAN;
                }
            }
        }
        let mut rng = Rng::new(cfg.seed.wrapping_mul(1_000_003).wrapping_add(i as u64));
        SynthFrame {
            image: to_image(&rgb, &cfg.camera, cfg.noise, &mut rng),
            pose,
            coverage,
            depth,
        }
    }

    /// The keyframe images ([`keyframe_images`]; no occluders).
    pub fn keyframe_images(&self) -> Vec<(String, image::RgbImage, Pose)> {
        let bg = self
            .keyframe_background
            .as_ref()
            .unwrap_or(&self.background);
        keyframe_images(&self.config, &self.object, bg)
    }
}

/// The background `config` asks for, from `seed`, its contrast lowered
/// where asked.
fn scene_background(config: &SynthConfig, object: &SynthObject, seed: u64) -> Vec<[f32; 3]> {
    let cam = &config.camera;
    let mut bg = make_background(config.background, cam, object, config.distance, seed);
    if config.low_contrast {
        // The object's mean grey as frame 0 shows it.
        let pose = trajectory_pose(config.trajectory, config.distance, 0, config.frames);
        let black = vec![[0.0; 3]; bg.len()];
        let r = raster::render(object, &pose, cam, &Light::moving(0.0), &black, 1);
        let (sum, n) = r
            .rgb
            .iter()
            .zip(&r.coverage)
            .filter(|(_, c)| **c > 0.99)
            .fold((0.0, 0usize), |(s, n), (c, _)| (s + luminance(*c), n + 1));
        lower_contrast(&mut bg, if n > 0 { sum / n as f32 } else { 0.5 });
    }
    bg
}

/// The frame the exit slide peaks at: the middle one.
fn peak_frame(n: usize) -> usize {
    n.saturating_sub(1) / 2
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projected_ground_truth_lands_on_the_rendered_object() {
        // Pixel-centre convention check: the silhouette of a box rendered
        // at its ground-truth pose against the box's analytically projected
        // corners. A half-pixel slip would show as a 0.5 px bias.
        let cam = Intrinsics::new(160, 120, 150.0, 150.0, 79.5, 59.5);
        let obj = SynthObject::printed_box();
        let pose = base_pose(0.5, 30.0, 25.0);
        let bg = vec![[0.0; 3]; 160 * 120];
        let r = raster::render(&obj, &pose, &cam, &Light::moving(0.0), &bg, 1);
        // Back-projecting every covered pixel centre with its depth must land
        // on the box surface: a rasteriser sampling at (u + 0.5, v + 0.5)
        // would put these points off the slanted faces' planes.
        let mut checked = 0;
        for y in 0..120u32 {
            for x in 0..160u32 {
                let k = (y * 160 + x) as usize;
                let z = r.depth[k];
                if z.is_nan() {
                    continue;
                }
                // Back-project the pixel centre; the point must lie on the
                // box surface (within float rounding).
                let pc = cam.unproject(&nalgebra::Vector2::new(x as f64, y as f64), z as f64);
                let po = pose.inverse().transform_point(&pc);
                let h = [0.06, 0.045, 0.03];
                let on_face = (0..3).any(|a| (po[a].abs() - h[a]).abs() < 1e-5);
                let inside = (0..3).all(|a| po[a].abs() < h[a] + 1e-5);
                assert!(on_face && inside, "pixel ({x},{y}) -> {po}");
                checked += 1;
            }
        }
        assert!(checked > 500, "{checked}");
    }

    #[test]
    fn silhouette_matches_projected_box_corners_to_a_fraction_of_a_pixel() {
        // Look straight at one face: its silhouette is a rectangle whose
        // edges are the projected corners. Coverage summed along a row
        // crossing it measures the rectangle's width to sub-pixel accuracy.
        let cam = Intrinsics::new(200, 160, 300.0, 300.0, 99.5, 79.5);
        let obj = SynthObject::printed_box();
        // Camera on the +x axis looking at the +x face (a 9 x 6 cm rectangle).
        let pose = look_at(
            &Vector3::new(0.5, 0.0, 0.0),
            &Vector3::zeros(),
            &Vector3::new(0.0, 0.0, 1.0),
        );
        let bg = vec![[0.0; 3]; 200 * 160];
        let r = raster::render(&obj, &pose, &cam, &Light::moving(0.0), &bg, 5);
        let corner = |p: Vector3<f64>| cam.project(&pose.transform_point(&p)).unwrap();
        let a = corner(Vector3::new(0.06, -0.045, -0.03));
        let b = corner(Vector3::new(0.06, 0.045, 0.03));
        let (u0, u1) = (a.x.min(b.x), a.x.max(b.x));
        let (v0, v1) = (a.y.min(b.y), a.y.max(b.y));
        let row = 80usize;
        let width: f32 = (0..200).map(|x| r.coverage[row * 200 + x]).sum();
        let col = 100usize;
        let height: f32 = (0..160).map(|y| r.coverage[y * 200 + col]).sum();
        // 5 x 5 samples quantise each edge pixel's coverage to 0.2.
        assert!(
            (width as f64 - (u1 - u0)).abs() < 0.2,
            "{width} vs {}",
            u1 - u0
        );
        assert!(
            (height as f64 - (v1 - v0)).abs() < 0.2,
            "{height} vs {}",
            v1 - v0
        );
        // And the edges sit where projected: the left edge's coverage.
        let left = u0.floor() as usize;
        let frac_left = r.coverage[row * 200 + left + 1] as f64;
        let want = ((left + 1) as f64 + 0.5 - u0).clamp(0.0, 1.0);
        assert!((frac_left - want).abs() < 0.15, "{frac_left} vs {want}");
    }

    #[test]
    fn trajectories_start_at_the_base_pose_and_move() {
        for name in Trajectory::NAMES {
            let t = Trajectory::by_name(name).unwrap();
            let p0 = trajectory_pose(t, 0.5, 0, 100);
            let mut max_rot: f64 = 0.0;
            for i in 1..100 {
                let p = trajectory_pose(t, 0.5, i, 100);
                max_rot = max_rot.max(p.rotation_error_deg(&p0));
                p.validate().unwrap();
            }
            assert!(max_rot > 10.0, "{name}: {max_rot}");
        }
        let t = trajectory_pose(Trajectory::Turn, 0.5, 50, 101);
        assert!(
            (t.rotation_error_deg(&trajectory_pose(Trajectory::Turn, 0.5, 0, 101)) - 180.0).abs()
                < 1e-6
        );
    }
}
