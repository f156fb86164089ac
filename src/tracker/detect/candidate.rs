//! What a detection by features ([`super`]) finds and keeps between its
//! steps: the frame's described corners and the candidate poses.

use super::features::Descriptor;
use crate::geometry::Pose;

/// KF steps refining a candidate pose.
pub(in crate::tracker) const DETECT_REFINE_STEPS: usize = 2;

/// A candidate pose from one keyframe's matches.
#[derive(Debug, Clone)]
pub(in crate::tracker) struct Candidate {
    pub(in crate::tracker) keyframe: usize,
    pub(in crate::tracker) pose: Pose,
    pub(in crate::tracker) inliers: usize,
    pub(in crate::tracker) spread: f64,
}

/// A frame's corners (the detector's) and the descriptors of those that
/// could be described (index into `pts`, descriptor).
pub(in crate::tracker) struct Described {
    pub(in crate::tracker) pts: Vec<[f32; 2]>,
    pub(in crate::tracker) described: Vec<(usize, Descriptor)>,
    pub(in crate::tracker) descs: Vec<Descriptor>,
}
