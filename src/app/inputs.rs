//! What a tracking run reads: the model, camera, sequence, keyframes and
//! first pose ([`TrackInputs`]), and each object of a run of several
//! ([`ObjectInputs`]).

use super::{AppError, load_keyframes};
use crate::device::AsDevice;
use crate::geometry::{Intrinsics, Pose};
use crate::io::poses::read_poses;
use crate::io::sequence::Sequence;
use crate::keyframes::KeyframeStore;
use crate::model::{LoadOptions, PointModel};
use crate::tracker::TrackerConfig;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Everything a tracking run needs, loaded and checked.
pub struct TrackInputs {
    /// The object's point model (shared with each run's tracker, not
    /// copied, where the tracker keeps its radii: [`crate::tracker::Tracker::builder`]).
    pub model: Arc<PointModel>,
    /// The sequence, its camera and frames, when the frames come from a
    /// sequence directory (`None`: from a video or a camera, given to the
    /// run by [`super::TrackRun::source`]).
    pub sequence: Option<Sequence>,
    /// The camera as calibrated (with its distortion, if any).
    pub camera: Intrinsics,
    /// The camera file.
    pub camera_path: PathBuf,
    /// The pose of the first frame; `None`: the tracker searches the
    /// frames for the object ([`crate::tracker::TrackerBuilder::initial_pose`]).
    pub init: Option<Pose>,
    /// The keyframe store, when there is one (shared with each run's
    /// tracker, not copied: [`crate::tracker::TrackerBuilder::keyframes`]).
    pub keyframes: Option<Arc<KeyframeStore>>,
}

impl TrackInputs {
    /// Loads the model (a mesh sampled into one:
    /// [`PointModel::load_any_with`]), opens the sequence, reads the initial pose (`init`,
    /// default `SEQUENCE/init.csv` when present: its first row; neither:
    /// none, the object is searched for) and loads or builds the
    /// keyframe store `keyframes` names ([`load_keyframes`]; default
    /// `SEQUENCE/keyframes` when present, else none). `model_options`
    /// says how the model is loaded (progress, estimation settings).
    pub fn load(
        ctx: &impl AsDevice,
        model: &Path,
        model_options: &LoadOptions,
        sequence: &Path,
        keyframes: Option<&Path>,
        init: Option<&Path>,
    ) -> Result<Self, AppError> {
        let model = PointModel::load_any_with(model, 0, model_options)?;
        let sequence = Sequence::open(sequence)?;
        let init_path = init.map(Path::to_owned).or_else(|| {
            let p = sequence.init_path();
            p.exists().then_some(p)
        });
        let init = match init_path {
            Some(p) => Some(read_poses(&p)?[0].pose),
            None => None,
        };
        let kf_path = keyframes
            .map(Path::to_owned)
            .or_else(|| sequence.keyframes_dir());
        let keyframes = match kf_path {
            Some(p) => Some(load_keyframes(ctx, &model, &sequence.camera, &p)?),
            None => None,
        };
        Ok(Self {
            model: Arc::new(model),
            camera: sequence.camera,
            camera_path: sequence.camera_path.clone(),
            sequence: Some(sequence),
            init,
            keyframes: keyframes.map(Arc::new),
        })
    }

    /// For frames from a video or a camera: loads the model (a mesh
    /// sampled into one), the camera
    /// file `camera` (camera.json or an OpenCV yaml), the initial pose
    /// (`init`: its first row is the pose of the first frame tracked;
    /// `None`: the object is searched for) and the keyframe store
    /// `keyframes` names, if any ([`load_keyframes`]).
    pub fn load_with_camera(
        ctx: &impl AsDevice,
        model: &Path,
        model_options: &LoadOptions,
        camera: &Path,
        keyframes: Option<&Path>,
        init: Option<&Path>,
    ) -> Result<Self, AppError> {
        let model = PointModel::load_any_with(model, 0, model_options)?;
        let cam = Intrinsics::load(camera)?;
        let init = match init {
            Some(p) => Some(read_poses(p)?[0].pose),
            None => None,
        };
        let keyframes = match keyframes {
            Some(p) => Some(load_keyframes(ctx, &model, &cam, p)?),
            None => None,
        };
        Ok(Self {
            model: Arc::new(model),
            sequence: None,
            camera: cam,
            camera_path: camera.to_owned(),
            init,
            keyframes: keyframes.map(Arc::new),
        })
    }

    /// Whether the KF step's views have a texture: keyframes, or colours
    /// in the model ([`super::run_mode`]).
    pub fn textured(&self) -> bool {
        self.keyframes.is_some() || self.model.colors.is_some()
    }

    /// The camera of the frames the tracker sees: the calibrated one
    /// without its distortion.
    pub fn tracking_camera(&self) -> Intrinsics {
        self.camera.undistorted()
    }
}

/// One object of a run of several ([`super::TrackRun::objects`]): its
/// name (the `object` column of the outputs), model, first pose,
/// keyframes and tracker settings.
pub struct ObjectInputs {
    /// The object's name: non-empty, without commas, quotes or line
    /// breaks, unique in the run.
    pub name: String,
    /// The object's point model (shared with the run's tracker).
    pub model: Arc<PointModel>,
    /// Its pose in the first frame; `None`: searched for in the frames.
    pub init: Option<Pose>,
    /// Its keyframe store, when there is one.
    pub keyframes: Option<Arc<KeyframeStore>>,
    /// Its tracker's settings (mode, cues, tuning).
    pub config: TrackerConfig,
}

impl ObjectInputs {
    /// Loads object `name`: its model (a mesh sampled into one), and the
    /// keyframe store `keyframes` names, if any ([`super::load_keyframes`];
    /// `camera`: the frames' camera as calibrated). No first pose and the
    /// default settings: set [`Self::init`] and [`Self::config`] after.
    pub fn load(
        ctx: &impl AsDevice,
        name: &str,
        model: &Path,
        model_options: &LoadOptions,
        camera: &Intrinsics,
        keyframes: Option<&Path>,
    ) -> Result<Self, AppError> {
        let model = PointModel::load_any_with(model, 0, model_options)?;
        let keyframes = match keyframes {
            Some(p) => Some(Arc::new(load_keyframes(ctx, &model, camera, p)?)),
            None => None,
        };
        Ok(Self {
            name: name.to_owned(),
            model: Arc::new(model),
            init: None,
            keyframes,
            config: TrackerConfig::default(),
        })
    }

    /// Whether the KF step's views have a texture: keyframes, or colours
    /// in the model ([`super::run_mode`]).
    pub fn textured(&self) -> bool {
        self.keyframes.is_some() || self.model.colors.is_some()
    }
}
