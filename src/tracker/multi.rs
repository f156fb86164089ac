//! Several objects in one video ([`MultiTracker`]): one [`Tracker`] an
//! object, each with its own model, keyframes, settings, status and
//! check, fed the same frames.

use super::error::TrackError;
use super::result::TrackResult;
use super::state::Tracker;
use thiserror::Error;

/// Why a set of trackers cannot track together.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum MultiError {
    /// No object was given.
    #[error("no object to track")]
    Empty,
    /// Two objects have the same name.
    #[error("two objects are named {0:?} (names must differ)")]
    DuplicateName(String),
    /// An object's name is empty or holds a comma, a quote or a line
    /// break (it is a column of the pose files).
    #[error("object name {0:?} must be non-empty, without commas, quotes or line breaks")]
    BadName(String),
    /// The trackers do not see the same camera.
    #[error("object {0:?} has another camera than the first object's")]
    OtherCamera(String),
}

/// Several objects tracked through the same frames. Each object has its
/// own [`Tracker`] (model, keyframes, modalities, status, reasons and
/// check): one object's loss never changes another's track. The frame is
/// given once; the objects are tracked nearest first, and each one's
/// renders leave out what the others, at their latest poses, hide.
///
/// With one object, the poses are those of that [`Tracker`] alone.
///
/// ```no_run
/// use splattrack::io::read_poses;
/// use splattrack::tracker::{MultiTracker, Tracker};
/// use splattrack::{AdapterChoice, Device, DeviceChoice, Intrinsics, PointModel};
/// use std::path::Path;
///
/// let device = Device::new(DeviceChoice::Auto, &AdapterChoice::from_env()?)?;
/// let cam = Intrinsics::load(Path::new("camera.json"))?;
/// let mut objects = Vec::new();
/// for name in ["gear", "housing"] {
///     let model = PointModel::load(format!("{name}.ply"))?;
///     let init = read_poses(Path::new(&format!("{name}_init.csv")))?[0].pose;
///     let tracker = Tracker::builder(&device, model, cam.clone())
///         .initial_pose(init)
///         .build()?;
///     objects.push((name.to_string(), tracker));
/// }
/// let mut multi = MultiTracker::new(objects)?;
/// # let frames: Vec<image::RgbImage> = Vec::new();
/// for frame in &frames {
///     for (name, r) in multi.names().zip(multi.track(frame)?) {
///         println!("{name}: {} {:?}", r.status, r.pose.translation);
///     }
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct MultiTracker {
    names: Vec<String>,
    trackers: Vec<Tracker>,
}

impl MultiTracker {
    /// The objects, named, each with its tracker (built on the same device
    /// and camera). Refused when there is none, when two names are the
    /// same or a name cannot be a CSV field, or when the cameras differ.
    pub fn new(objects: Vec<(String, Tracker)>) -> Result<Self, MultiError> {
        if objects.is_empty() {
            return Err(MultiError::Empty);
        }
        let mut names = Vec::with_capacity(objects.len());
        let mut trackers = Vec::with_capacity(objects.len());
        for (name, tracker) in objects {
            if name.is_empty() || name.contains([',', '"', '\n', '\r']) {
                return Err(MultiError::BadName(name));
            }
            if names.contains(&name) {
                return Err(MultiError::DuplicateName(name));
            }
            if let Some(first) = trackers.first()
                && !same_camera(first, &tracker)
            {
                return Err(MultiError::OtherCamera(name));
            }
            names.push(name);
            trackers.push(tracker);
        }
        Ok(Self { names, trackers })
    }

    /// Tracks one frame (RGB, undistorted, the camera's size) for every
    /// object: one result an object, in the order the objects were given.
    pub fn track(&mut self, frame: &image::RgbImage) -> Result<Vec<TrackResult>, TrackError> {
        let mut out = Vec::with_capacity(self.trackers.len());
        for tracker in &mut self.trackers {
            out.push(tracker.track(frame)?);
        }
        Ok(out)
    }

    /// The number of objects.
    pub fn len(&self) -> usize {
        self.trackers.len()
    }

    /// Whether there is no object (never: [`MultiTracker::new`] refuses).
    pub fn is_empty(&self) -> bool {
        self.trackers.is_empty()
    }

    /// The objects' names, in their order.
    pub fn names(&self) -> impl Iterator<Item = &str> + '_ {
        self.names.iter().map(String::as_str)
    }

    /// Object `i`'s tracker.
    pub fn tracker(&self, i: usize) -> &Tracker {
        &self.trackers[i]
    }

    /// The objects' trackers, in their order.
    pub fn trackers(&self) -> &[Tracker] {
        &self.trackers
    }

    /// Takes the trackers back, with their names.
    pub fn into_trackers(self) -> Vec<(String, Tracker)> {
        self.names.into_iter().zip(self.trackers).collect()
    }
}

fn same_camera(a: &Tracker, b: &Tracker) -> bool {
    let (a, b) = (&a.cam, &b.cam);
    a.width == b.width
        && a.height == b.height
        && a.fx == b.fx
        && a.fy == b.fy
        && a.cx == b.cx
        && a.cy == b.cy
}
