//! Several objects in one video ([`MultiTracker`]): one [`Tracker`] an
//! object, each with its own model, keyframes, settings, status and
//! check, fed the same frames.

use super::config::Modalities;
use super::error::TrackError;
use super::occlusion::{DepthLayer, DepthProxy, Hidden};
use super::result::{LostReason, StageTimes, Status, TrackResult};
use super::state::Tracker;
use super::verify::Unverified;
use crate::splat::{MAX_OCCLUDERS, Occluder};
use thiserror::Error;

/// An object less visible than this (the fraction of it that shows, by
/// the coarse depth images of [`super::occlusion`]) is not tracked in the
/// frame: `lost`, [`LostReason::Occluded`]. Half-hidden objects track
/// (their renders leave the hidden part out); below a quarter too little
/// of the outline and texture is left to hold all six degrees of freedom.
const MIN_VISIBLE: f64 = 0.25;

/// Depths this much nearer (relative) than a point hide it in the coarse
/// depth images (their discs' error; objects that touch).
const HIDE_TOLERANCE: f32 = 0.02;

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
    /// More objects than a render takes occluders, plus one.
    #[error("{0} objects: at most {max} are tracked together", max = MAX_OCCLUDERS + 1)]
    TooMany(usize),
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
///     let tracker = Tracker::builder(&device, model, cam)
///         .initial_pose(init)
///         .build()?;
///     objects.push((name.to_string(), tracker));
/// }
/// let mut multi = MultiTracker::new(objects)?;
/// # let frames: Vec<image::RgbImage> = Vec::new();
/// for frame in &frames {
///     let results = multi.track(frame)?;
///     for (name, r) in multi.names().zip(results) {
///         println!("{name}: {} {:?}", r.status, r.pose.translation);
///     }
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct MultiTracker {
    names: Vec<String>,
    trackers: Vec<Tracker>,
    /// Each object's coarse depth image, at its current pose.
    proxies: Vec<DepthProxy>,
    layers: Vec<DepthLayer>,
    /// Whether each object hides the others: tracked in its last frame.
    shows: Vec<bool>,
    /// The other objects' nearest depth, for the object being tracked.
    hidden: Option<Hidden>,
}

impl MultiTracker {
    /// The objects, named, each with its tracker (built on the same device
    /// and camera). Refused when there is none or more than
    /// [`MAX_OCCLUDERS`] + 1 (every other object occludes each one's
    /// renders), when two names are the same or a name cannot be a CSV
    /// field, or when the cameras differ.
    pub fn new(objects: Vec<(String, Tracker)>) -> Result<Self, MultiError> {
        if objects.is_empty() {
            return Err(MultiError::Empty);
        }
        if objects.len() > MAX_OCCLUDERS + 1 {
            return Err(MultiError::TooMany(objects.len()));
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
        let (w, h) = (
            trackers[0].cam.width as usize,
            trackers[0].cam.height as usize,
        );
        let proxies: Vec<DepthProxy> = trackers.iter().map(|t| DepthProxy::new(&t.model)).collect();
        let mut layers = vec![DepthLayer::new(w, h); trackers.len()];
        for ((t, p), l) in trackers.iter().zip(&proxies).zip(&mut layers) {
            if !t.searching() {
                p.draw(&t.pose(), &t.cam, l);
            }
        }
        let shows = trackers.iter().map(|t| !t.searching()).collect();
        Ok(Self {
            names,
            trackers,
            proxies,
            layers,
            shows,
            hidden: Some(Hidden {
                others: DepthLayer::new(w, h),
                tolerance: HIDE_TOLERANCE,
            }),
        })
    }

    /// Tracks one frame (RGB, undistorted, the camera's size) for every
    /// object: one result an object, in the order the objects were given.
    ///
    /// The objects are tracked nearest first (by their centres' depths at
    /// their current poses), each with the others at their latest poses
    /// (this frame's for those already tracked) as what may hide it: an
    /// object that shows less than a quarter of itself is `lost`
    /// ([`LostReason::Occluded`]) without being tracked, and looked for
    /// again where it was once it shows.
    pub fn track(&mut self, frame: &image::RgbImage) -> Result<Vec<TrackResult>, TrackError> {
        if self.trackers.len() == 1 {
            return Ok(vec![self.trackers[0].track(frame)?]);
        }
        let mut order: Vec<usize> = (0..self.trackers.len()).collect();
        let depth = |t: &Tracker| {
            if t.searching() {
                f64::INFINITY
            } else {
                t.pose().transform_point(&t.center).z
            }
        };
        order.sort_by(|&a, &b| depth(&self.trackers[a]).total_cmp(&depth(&self.trackers[b])));
        let mut out: Vec<Option<TrackResult>> = (0..self.trackers.len()).map(|_| None).collect();
        for i in order {
            let mut hidden = self.hidden.take().expect("kept between objects");
            let others = self
                .layers
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i && self.shows[j])
                .map(|(_, l)| l);
            hidden.others.nearest_of(others);
            let occluders: Vec<Occluder> = (0..self.trackers.len())
                .filter(|&j| j != i && self.shows[j])
                .map(|j| Occluder {
                    model: self.trackers[j].gpu_model().clone(),
                    pose: self.trackers[j].pose(),
                })
                .collect();
            let tracker = &mut self.trackers[i];
            tracker.splatter.set_occluders(occluders)?;
            let visible = if tracker.searching() {
                1.0
            } else {
                hidden.visible_fraction(&self.layers[i])
            };
            let r = if visible < MIN_VISIBLE {
                Ok(tracker.occluded_frame(visible))
            } else if hidden.others.rect.is_some() {
                // Lent to the tracker for the frame, kept again after.
                tracker.hidden = Some(hidden);
                let r = tracker.track(frame);
                hidden = tracker.hidden.take().expect("lent for the frame");
                r
            } else {
                tracker.track(frame)
            };
            self.hidden = Some(hidden);
            let r = r?;
            // A frozen frame changes nothing: the object hides others as
            // it did.
            let frozen = r.reason == Some(LostReason::Unverified(Unverified::FrozenFrame));
            self.shows[i] = r.status == Status::Tracking || (frozen && self.shows[i]);
            if !tracker.searching() {
                // Where it is expected: a hidden object's drift carries
                // it on, so that the share of it in view is measured where
                // it will show.
                let at = tracker.expected_pose();
                self.proxies[i].draw(&at, &tracker.cam, &mut self.layers[i]);
            }
            out[i] = Some(r);
        }
        Ok(out
            .into_iter()
            .map(|r| r.expect("every object tracked"))
            .collect())
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

impl Tracker {
    /// Where the search for this object looks for the frame's corners:
    /// not on another tracked object (whose texture would crowd this
    /// one's out of the corners kept, and match nothing of it); `None`:
    /// the whole frame.
    pub(super) fn search_mask(&self) -> Option<Vec<bool>> {
        let others = &self.hidden.as_ref()?.others;
        Some(others.depth.iter().map(|d| !d.is_finite()).collect())
    }

    /// A frame in which other objects hide this one: `lost`, nothing
    /// tracked. The frame before it is forgotten (the next tracked frame
    /// has no frame to follow from), and the track is recovering: when the
    /// object shows again it is looked for around its last pose first.
    fn occluded_frame(&mut self, visible: f64) -> TrackResult {
        if let Some(old) = self.prev.take() {
            self.spare_frame = Some(old.rgb);
        }
        self.lost_streak = 1;
        self.lost.reset();
        self.recovery_turn = 0;
        self.recovery_next = None;
        self.recovery_hidden = true;
        self.steady.clear();
        self.drift.lost();
        TrackResult {
            pose: self.pose,
            inliers: 0,
            residual_px: f64::NAN,
            status: Status::Lost,
            reason: Some(LostReason::Occluded { visible }),
            keyframe: None,
            times: StageTimes::default(),
            verify: None,
            texture_set_aside: false,
            cues: Modalities::NONE,
            refused: None,
        }
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
