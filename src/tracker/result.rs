//! What the tracker reports: each frame's [`TrackResult`], its
//! [`Status`] and [`LostReason`], where its time went ([`StageTimes`]),
//! and the GPU memory the tracker holds ([`GpuMemoryUse`]).

use super::config::Modalities;
use super::verify::{Unverified, VerifyScores};
use crate::geometry::Pose;
use crate::pose::SolveError;
use std::fmt;
use std::time::Duration;

/// Wall-clock time of each stage of one frame (GPU work included, since
/// every stage waits for its results).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StageTimes {
    /// Harris corners of the frame.
    pub features: Duration,
    /// The frame-to-frame step.
    pub it: Duration,
    /// The keyframe step(s).
    pub kf: Duration,
    /// The contour step (its iterations).
    #[serde(default)]
    pub contour: Duration,
    /// The check of the reported pose against the image.
    #[serde(default)]
    pub verify: Duration,
    /// The whole-frame search for the object (initialisation, re-detection).
    #[serde(default)]
    pub search: Duration,
    /// Within IT: the render at the previous pose and the gathers.
    #[serde(default)]
    pub it_render: Duration,
    /// Within IT: NCC matching.
    #[serde(default)]
    pub it_ncc: Duration,
    /// Within KF: the novel view's render and read-back.
    #[serde(default)]
    pub kf_render: Duration,
    /// Within KF: Harris corners of the novel view.
    #[serde(default)]
    pub kf_harris: Duration,
    /// Within KF: NCC matching, the gathers and the sub-pixel refinement.
    #[serde(default)]
    pub kf_ncc: Duration,
    /// GPU time of each pass, milliseconds, as "stage kernel pass" (from
    /// timestamp queries; empty unless [`super::Execution::gpu_timing`]).
    #[serde(default)]
    pub gpu: Vec<(String, f64)>,
    /// When the GPU worked during the frame, from the same timestamps:
    /// its passes' busy time and the gaps between them.
    #[serde(default)]
    pub gpu_timeline: crate::gpu::GpuTimeline,
    /// Bytes read back from the GPU during the call
    /// ([`GpuStats::bytes_read`](crate::gpu::GpuStats::bytes_read); a mean over frames is fractional).
    #[serde(default)]
    pub readback_bytes: f64,
    /// Readbacks (waits for the GPU) during the call
    /// ([`GpuStats::readbacks`](crate::gpu::GpuStats::readbacks)).
    #[serde(default)]
    pub readbacks: f64,
    /// The time the host spent blocked in those readbacks' waits
    /// ([`GpuStats::wait_time`](crate::gpu::GpuStats::wait_time)): the GPU's work queued before them and the
    /// round trip; the rest of `total` is the host's own work.
    #[serde(default)]
    pub gpu_wait: Duration,
    /// That time by stage.
    #[serde(default)]
    pub waits: StageWaits,
    /// The host's time finishing command encoders (wgpu's encoding and
    /// validation of the passes; [`GpuStats::finish_time`](crate::gpu::GpuStats::finish_time)): part of its
    /// own work.
    #[serde(default)]
    pub gpu_finish: Duration,
    /// The host's time in `Queue::submit` ([`GpuStats::submit_time`](crate::gpu::GpuStats::submit_time)).
    #[serde(default)]
    pub gpu_submit: Duration,
    /// Submissions of GPU work during the call
    /// ([`GpuStats::submissions`](crate::gpu::GpuStats::submissions)).
    #[serde(default)]
    pub submissions: f64,
    /// Command buffers in those submissions
    /// ([`GpuStats::command_buffers`](crate::gpu::GpuStats::command_buffers)).
    #[serde(default)]
    pub command_buffers: f64,
    /// Uploads during the call ([`crate::gpu::GpuContext::write_buffer`]: each a
    /// staging buffer of wgpu's), and parameter uploads skipped as
    /// unchanged ([`crate::gpu::Uniform`]).
    #[serde(default)]
    pub uploads: f64,
    /// Parameter uploads skipped as unchanged during the call.
    #[serde(default)]
    pub uploads_skipped: f64,
    /// Passes recorded during the call ([`GpuStats::passes`](crate::gpu::GpuStats::passes)): one a
    /// stage where `--profile`'s timer times them.
    #[serde(default)]
    pub passes: f64,
    /// The passes an untimed call records (a chain of stages in one).
    #[serde(default)]
    pub passes_untimed: f64,
    /// Renders of the model during the call, every step's (the
    /// search's too; a mean over frames is fractional): the novel views,
    /// the contour's and the pose check's, a render taken over from an
    /// earlier step not counted again.
    #[serde(default)]
    pub renders: f64,
    /// Rounds (searches and solves) of the contour step during the call
    /// (a mean over frames is fractional).
    #[serde(default)]
    pub contour_rounds: f64,
    /// The renders of those rounds (a round after a small correction moves
    /// the last render's points instead).
    #[serde(default)]
    pub contour_renders: f64,
    /// The contour's colour learning from a tracked frame, wherever it ran:
    /// by default on a thread of its own, beside the next frame's texture
    /// steps (counted in the frame it finished in, and not in `total`
    /// then); see [`super::Execution::background_learning`].
    #[serde(default)]
    pub colour_learning: Duration,
    /// Within the contour step: waiting for that thread to finish the
    /// previous frame's learning.
    #[serde(default)]
    pub colour_wait: Duration,
    /// The whole call to [`super::Tracker::track`].
    pub total: Duration,
}

/// The host's time blocked waiting for the GPU within each stage of
/// [`StageTimes`] ([`GpuStats::wait_time`](crate::gpu::GpuStats::wait_time)): what the stage's time is not
/// the host's own work.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StageWaits {
    /// In [`StageTimes::features`].
    pub features: Duration,
    /// In [`StageTimes::it`].
    pub it: Duration,
    /// In [`StageTimes::kf`].
    pub kf: Duration,
    /// In [`StageTimes::contour`].
    pub contour: Duration,
    /// In [`StageTimes::verify`].
    pub verify: Duration,
    /// In [`StageTimes::search`].
    pub search: Duration,
}

impl StageTimes {
    /// Adds `other`'s times multiplied by `k` (for means over frames).
    pub fn add_scaled(&mut self, other: &StageTimes, k: f64) {
        let pairs = [
            (&mut self.features, other.features),
            (&mut self.it, other.it),
            (&mut self.kf, other.kf),
            (&mut self.contour, other.contour),
            (&mut self.verify, other.verify),
            (&mut self.search, other.search),
            (&mut self.it_render, other.it_render),
            (&mut self.it_ncc, other.it_ncc),
            (&mut self.kf_render, other.kf_render),
            (&mut self.kf_harris, other.kf_harris),
            (&mut self.kf_ncc, other.kf_ncc),
            (&mut self.colour_learning, other.colour_learning),
            (&mut self.colour_wait, other.colour_wait),
            (&mut self.gpu_wait, other.gpu_wait),
            (&mut self.gpu_finish, other.gpu_finish),
            (&mut self.gpu_submit, other.gpu_submit),
            (&mut self.waits.features, other.waits.features),
            (&mut self.waits.it, other.waits.it),
            (&mut self.waits.kf, other.waits.kf),
            (&mut self.waits.contour, other.waits.contour),
            (&mut self.waits.verify, other.waits.verify),
            (&mut self.waits.search, other.waits.search),
            (&mut self.total, other.total),
        ];
        for (acc, d) in pairs {
            *acc += d.mul_f64(k);
        }
        self.readback_bytes += other.readback_bytes * k;
        self.readbacks += other.readbacks * k;
        self.submissions += other.submissions * k;
        self.uploads += other.uploads * k;
        self.uploads_skipped += other.uploads_skipped * k;
        self.passes += other.passes * k;
        self.passes_untimed += other.passes_untimed * k;
        self.command_buffers += other.command_buffers * k;
        self.renders += other.renders * k;
        self.contour_rounds += other.contour_rounds * k;
        self.contour_renders += other.contour_renders * k;
        for (label, ms) in &other.gpu {
            add(&mut self.gpu, label, ms * k);
        }
        self.gpu_timeline.add_scaled(&other.gpu_timeline, k);
    }
}

/// What [`super::Tracker::track`] says about a frame. Serialised field by field
/// (a NaN residual as `null`).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct TrackResult {
    /// The object-to-camera pose of the frame; on a lost frame, the last
    /// good pose (a pose that failed is never reported).
    pub pose: Pose,
    /// Inliers of the last robust solve of this frame.
    pub inliers: usize,
    /// Their RMS reprojection residual, pixels (NaN on a lost frame
    /// without any solve).
    #[serde(with = "nan_as_null")]
    pub residual_px: f64,
    /// Whether the track holds at this frame.
    pub status: Status,
    /// Why the frame is lost (when it is); its `Display` is the text.
    pub reason: Option<LostReason>,
    /// The keyframe used by the KF step, if any.
    pub keyframe: Option<usize>,
    /// Where the time went.
    pub times: StageTimes,
    /// What the check of the pose against the image measured (`None`
    /// when it did not run: verification off, or no pose to check).
    #[serde(default)]
    pub verify: Option<VerifyScores>,
    /// Whether the texture steps were trusted but their pose failed the
    /// check on its appearance, so that the contour alone gave this
    /// frame's pose (checked by its edges): the texture matched something
    /// the keyframes do not show, such as an untextured object's shading.
    #[serde(default)]
    pub texture_set_aside: bool,
    /// The cues that held this frame's pose: `texture` (a trusted IT or KF
    /// step gave it), `contour` (the contour step alone), both (a trusted
    /// texture step refined or started by the contour), or
    /// [`Modalities::NONE`] on a lost frame and on a first frame kept at
    /// the initial pose without any step.
    #[serde(default = "no_cues")]
    pub cues: Modalities,
    /// On a `lost` frame, the estimate that was not reported (the frame's
    /// `reason` says why): a step's pose that the decision rules or the
    /// check refused, the initial pose that failed the check, or the
    /// search's best candidate. `None` on a `tracking` frame, where no
    /// step gave a pose and on a frozen frame (which runs no step).
    #[serde(default)]
    pub refused: Option<Refused>,
}

/// A novel view of the model at a pose ([`super::Tracker::novel_view`]),
/// row-major over the camera's image.
#[derive(Debug, Clone, PartialEq)]
pub struct NovelView {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// RGB bytes, 3 a pixel (the keyframes' own scale; 0 where empty).
    pub color: Vec<u8>,
    /// Camera-space depth, model units (NaN where empty).
    pub depth: Vec<f32>,
    /// Whether the model covers each pixel.
    pub mask: Vec<bool>,
    /// The keyframe that textured the view (`None`: the model's colours,
    /// or none).
    pub keyframe: Option<usize>,
}

/// An estimate a `lost` frame did not report ([`TrackResult::refused`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Refused {
    /// The pose refused.
    pub pose: Pose,
    /// Where it came from.
    pub source: Source,
    /// Inliers of the solve that gave it (0 for the initial pose or a
    /// search candidate).
    pub inliers: usize,
    /// Their RMS residual, pixels (NaN without a solve).
    #[serde(with = "nan_as_null")]
    pub residual_px: f64,
    /// The check's scores at that pose, when the check ran on it (not
    /// where the decision rules refused it first).
    pub scores: Option<VerifyScores>,
}

/// Where a [`Refused`] estimate came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// The frame-to-frame step.
    It,
    /// The keyframe step.
    Kf,
    /// The contour step.
    Contour,
    /// The whole-frame search (its best candidate).
    Search,
    /// The pose a track starts from, checked at its first frame: the
    /// initial pose, or where the search found the object.
    Initial,
}

impl Source {
    /// The name in the refused file's `stage` column.
    pub fn name(&self) -> &'static str {
        match self {
            Source::It => "it",
            Source::Kf => "kf",
            Source::Contour => "contour",
            Source::Search => "search",
            Source::Initial => "initial",
        }
    }
}

impl From<Stage> for Source {
    fn from(s: Stage) -> Self {
        match s {
            Stage::It => Source::It,
            Stage::Kf => Source::Kf,
            Stage::Contour => Source::Contour,
        }
    }
}

fn no_cues() -> Modalities {
    Modalities::NONE
}

/// serde of an `f64` that may be NaN, which JSON cannot write: NaN as
/// `null`, and back.
mod nan_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_nan() {
            s.serialize_none()
        } else {
            s.serialize_some(v)
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }
}

/// Whether the track holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// The frame's pose passed the inlier and residual checks.
    Tracking,
    /// It did not: the reported pose is the last good one.
    Lost,
}

impl Status {
    /// `tracking` or `lost`, as in the tracker output's `status` column.
    pub fn name(&self) -> &'static str {
        match self {
            Status::Tracking => "tracking",
            Status::Lost => "lost",
        }
    }
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The steps of a frame that estimate a pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    /// The frame-to-frame step.
    It,
    /// The step against the keyframes' novel view.
    Kf,
    /// The contour step (fused with the texture inliers).
    Contour,
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Stage::It => "IT",
            Stage::Kf => "KF",
            Stage::Contour => "contour",
        })
    }
}

/// Why a step gave no estimate.
#[derive(Debug, Clone, PartialEq, thiserror::Error, serde::Serialize, serde::Deserialize)]
pub enum StepError {
    /// The robust solve refused the matches.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// Splatting, feature detection or matching failed on the GPU (the
    /// error's message: GPU errors are neither `Clone` nor serialisable).
    #[error("{0}")]
    Gpu(String),
    /// The KF step ran without keyframes.
    #[error("no keyframes")]
    NoKeyframes,
}

impl From<crate::splat::SplatError> for StepError {
    fn from(e: crate::splat::SplatError) -> Self {
        StepError::Gpu(e.to_string())
    }
}

impl From<crate::features::FeatureError> for StepError {
    fn from(e: crate::features::FeatureError) -> Self {
        StepError::Gpu(e.to_string())
    }
}

/// Why a frame is lost. Its `Display` is the text the tracker has always
/// printed, e.g. `KF: 5 inliers, residual 0.80 px (need >= 8 and <= 3.0 px)`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum LostReason {
    /// A step failed.
    Failed {
        /// Which step.
        stage: Stage,
        /// Why.
        error: StepError,
    },
    /// A step's estimate has too few inliers or too large a residual.
    Untrusted {
        /// Which step.
        stage: Stage,
        /// Its inliers.
        inliers: usize,
        /// Their RMS residual, pixels.
        residual_px: f64,
        /// The least trusted inlier count.
        min_inliers: usize,
        /// The largest trusted residual, pixels.
        max_residual_px: f64,
    },
    /// KF+IT: IT's estimate is sound, but IT alone has stood in for the
    /// keyframes for as many frames as allowed.
    ItOnlyTooLong {
        /// Why the KF step was not used.
        kf: Option<Box<LostReason>>,
        /// [`super::TrackerConfig::max_it_only_frames`].
        frames: usize,
    },
    /// No step ran.
    NothingToTrackAgainst,
    /// The pose the steps gave (or the initial pose) fails the check of
    /// the model against the image ([`super::verify`]).
    Unverified(Unverified),
    /// Automatic initialisation or re-detection found no candidate pose
    /// that passes the check.
    NotFound,
    /// The search found an object whose views show shading only by its
    /// outline alone: the start is held
    /// (tracked, not reported) until it has tracked consistently for
    /// [`super::InitConfig::confirm_frames`] frames.
    Confirming {
        /// Frames still to track before the start is reported.
        left: usize,
    },
    /// A start held for confirmation did not track consistently (its pose
    /// turned too far in a frame, or failed the search's check): the search
    /// runs again.
    Unconfirmed {
        /// How far the pose turned from the previous frame's, degrees.
        turn_deg: f64,
        /// The search's check's verdict, where it failed.
        check: Option<Unverified>,
    },
    /// Other objects, nearer the camera, hide this one (several objects,
    /// [`super::MultiTracker`]): nothing of it to track; it is looked for
    /// again where it was once enough of it shows.
    Occluded {
        /// The fraction of it that shows, 0-1.
        visible: f64,
    },
}

impl LostReason {
    /// A short name of the reason (the refused file's `reason` column):
    /// the check's failure (`not_in_view`, `too_small`, `appearance`,
    /// `shading_only`, `recovery`, `frozen_frame`, `edge_drop`,
    /// `shading_drop`) or the decision rule (`failed`, `untrusted`,
    /// `it_only_too_long`, `nothing_to_track_against`, `not_found`,
    /// `confirming`, `unconfirmed`, `occluded`).
    pub fn code(&self) -> &'static str {
        match self {
            LostReason::Failed { .. } => "failed",
            LostReason::Untrusted { .. } => "untrusted",
            LostReason::ItOnlyTooLong { .. } => "it_only_too_long",
            LostReason::NothingToTrackAgainst => "nothing_to_track_against",
            LostReason::Unverified(Unverified::NotInView { .. }) => "not_in_view",
            LostReason::Unverified(Unverified::TooSmall { .. }) => "too_small",
            LostReason::Unverified(Unverified::Appearance { .. }) => "appearance",
            LostReason::Unverified(Unverified::ShadingOnly { .. }) => "shading_only",
            LostReason::Unverified(Unverified::Recovery { .. }) => "recovery",
            LostReason::Unverified(Unverified::FrozenFrame) => "frozen_frame",
            LostReason::Unverified(Unverified::EdgeDrop { .. }) => "edge_drop",
            LostReason::Unverified(Unverified::ShadingDrop { .. }) => "shading_drop",
            LostReason::NotFound => "not_found",
            LostReason::Confirming { .. } => "confirming",
            LostReason::Unconfirmed { .. } => "unconfirmed",
            LostReason::Occluded { .. } => "occluded",
        }
    }
}

impl fmt::Display for LostReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LostReason::Failed { stage, error } => write!(f, "{stage}: {error}"),
            LostReason::Untrusted {
                stage,
                inliers,
                residual_px,
                min_inliers,
                max_residual_px,
            } => write!(
                f,
                "{stage}: {inliers} inliers, residual {residual_px:.2} px (need >= {min_inliers} and <= {max_residual_px:.1} px)"
            ),
            LostReason::ItOnlyTooLong { kf, frames } => {
                if let Some(kf) = kf {
                    write!(f, "{kf}")?;
                }
                write!(f, "; IT alone has stood in for {frames} frames and drifts")
            }
            LostReason::NothingToTrackAgainst => f.write_str("nothing to track against"),
            LostReason::Unverified(why) => write!(f, "verification: {why}"),
            LostReason::NotFound => f.write_str("object not found in the image"),
            LostReason::Confirming { left } => write!(
                f,
                "found by its outline alone: confirming over {left} more frame(s)"
            ),
            LostReason::Unconfirmed { turn_deg, check } => {
                write!(
                    f,
                    "start not confirmed: turned {turn_deg:.1} deg in a frame"
                )?;
                match check {
                    Some(why) => write!(f, "; {why}"),
                    None => Ok(()),
                }
            }
            LostReason::Occluded { visible } => write!(
                f,
                "hidden by other objects ({:.0}% of it shows)",
                visible * 100.0
            ),
        }
    }
}

/// GPU memory the splatting of a [`super::Tracker`] holds (bytes), from the sizes
/// of the buffers and textures it created ([`crate::splat::GpuModel::gpu_bytes`],
/// [`crate::splat::SplatTargets::gpu_bytes`], `TexturedCache::gpu_bytes`). Not counted:
/// the Harris and NCC buffers (grow-only, sized by the frame and the
/// features), pipelines, and the driver's own allocations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GpuMemoryUse {
    /// The model's geometry and colours.
    pub model: u64,
    /// The keyframe colours resident in the textured cache.
    pub keyframe_colors: u64,
    /// Every set of render targets (the current one, the spare ones, the
    /// kept render), with the compute splatter's scratch.
    pub targets: u64,
}

impl GpuMemoryUse {
    /// All of it.
    pub fn total(&self) -> u64 {
        self.model + self.keyframe_colors + self.targets
    }
}

/// Adds `ms` to the entry `label` of `acc` (a new one at the end).
pub(super) fn add(acc: &mut Vec<(String, f64)>, label: &str, ms: f64) {
    match acc.iter_mut().find(|(l, _)| l == label) {
        Some((_, v)) => *v += ms,
        None => acc.push((label.to_owned(), ms)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn track_result_serde_roundtrip() {
        let r = TrackResult {
            pose: Pose::new(
                crate::geometry::rotation_exp(&Vector3::new(0.1, -0.2, 0.3)),
                Vector3::new(0.01, 0.02, 0.6),
            )
            .unwrap(),
            inliers: 0,
            residual_px: f64::NAN,
            status: Status::Lost,
            reason: Some(LostReason::NothingToTrackAgainst),
            keyframe: Some(3),
            times: StageTimes {
                features: Duration::from_micros(1500),
                total: Duration::from_millis(20),
                ..Default::default()
            },
            verify: None,
            texture_set_aside: true,
            cues: Modalities::CONTOUR,
            refused: Some(Refused {
                pose: Pose::identity(),
                source: Source::Search,
                inliers: 0,
                residual_px: f64::NAN,
                scores: None,
            }),
        };
        let json = serde_json::to_string(&r).unwrap();
        assert!(json.contains(r#""residual_px":null"#), "{json}");
        let back: TrackResult = serde_json::from_str(&json).unwrap();
        assert!(back.residual_px.is_nan());
        // serde_json reads floats to within an ulp.
        assert!((back.pose.to_matrix4() - r.pose.to_matrix4()).amax() < 1e-15);
        assert_eq!((back.inliers, back.keyframe), (r.inliers, r.keyframe));
        assert!(back.texture_set_aside);
        let refused = back.refused.unwrap();
        assert_eq!(refused.source, Source::Search);
        assert!(refused.residual_px.is_nan());
        assert_eq!(
            (back.status, back.reason, back.times),
            (r.status, r.reason, r.times)
        );
    }
}
