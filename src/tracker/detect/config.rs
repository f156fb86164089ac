//! The settings of the detection by features ([`super`]).

/// Settings of the detection by features.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct DetectConfig {
    /// Whether the search tries features first.
    pub enabled: bool,
    /// Most Harris corners of the whole frame.
    pub frame_corners: usize,
    /// Most corners per keyframe.
    pub keyframe_corners: usize,
    /// The Harris threshold of the detection's corners, relative to the
    /// image's strongest response (lower than the tracker's: a keyframe's
    /// splatted view is smoother than a camera frame, and clutter's
    /// corners are stronger than the object's).
    pub harris_threshold: f32,
    /// Scales each keyframe corner is described at (a scale `s` matches
    /// the object seen `1 / s` times as large as in the keyframe).
    pub scales: Vec<f32>,
    /// Descriptors turned to the dominant gradient orientation (tolerate
    /// in-plane rotation); else upright patches.
    pub oriented: bool,
    /// Lowest NCC of a match.
    pub min_score: f32,
    /// Ratio test: largest ratio of the best to the second best
    /// descriptor distance.
    pub ratio: f32,
    /// RANSAC inlier threshold, pixels.
    pub inlier_px: f64,
    /// Fewest PnP inliers of a candidate.
    pub min_inliers: usize,
    /// Smallest extent of the inliers (the larger side of their bounding
    /// box) as a fraction of the object's projected diameter.
    pub min_spread: f64,
    /// Candidate poses (one per keyframe, most inliers first) refined and
    /// checked.
    pub candidates: usize,
    /// With fewer described corners than this in every keyframe (an
    /// object without texture), the template search runs whenever the
    /// features find nothing.
    pub min_keyframe_features: usize,
    /// On a textured object, the template search (seconds at 640x480 on
    /// lavapipe) runs after the first search the features fail, then
    /// after every this many failed ones (0: never), so that a lost
    /// object's searches do not stall the track.
    pub templates_every: usize,
}

impl Default for DetectConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            frame_corners: 1500,
            keyframe_corners: 600,
            harris_threshold: 0.0005,
            scales: vec![0.7, 1.0, 1.4],
            oriented: true,
            min_score: 0.6,
            ratio: 0.85,
            inlier_px: 4.0,
            min_inliers: 10,
            min_spread: 0.25,
            candidates: 3,
            min_keyframe_features: 40,
            templates_every: 4,
        }
    }
}
