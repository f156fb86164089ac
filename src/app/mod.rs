//! The application layer: what `splattrack track`, `splattrack demo` and a
//! program embedding the crate share. Loading everything a tracking run
//! needs ([`TrackInputs`], and [`ObjectInputs`] for each object of a run
//! of several), the keyframe store from a file or from keyframe images
//! ([`load_keyframes`], [`load_or_build_keyframes`]), and the run over a
//! sequence, a video or a camera ([`TrackRun`], frames from any
//! [`crate::io::source::FrameSource`]): frames in order, undistorted, one
//! pose row per frame and object written as it is tracked (crash-safe),
//! optional overlays and BOP results, progress through a
//! [`crate::progress::ProgressFn`], a callback per frame and a
//! [`crate::view::FrameSink`] (the live view).

mod error;
mod inputs;
mod objects;
pub mod refused;
mod run;
mod stats;
mod tuning;

pub use error::AppError;
pub use inputs::{ObjectInputs, TrackInputs};
pub use run::{TRACKING_STAGE, TrackRun};
pub use stats::{FrameMs, ObjectStats, RunStats};
pub use tuning::{MAX_CORNERS, Tuning, TuningError, run_mode};

use crate::device::AsDevice;
use crate::geometry::{Intrinsics, Undistorter};
use crate::io::poses::{PoseRow, read_poses};
use crate::keyframes::{KeyframeConfig, KeyframeStore, load_keyframe_images};
use crate::model::PointModel;
use crate::splat::Splatter;
use crate::tracker::TrackResult;
use std::path::Path;

/// Loads the keyframe store `path` names: a store file saved by
/// [`KeyframeStore::save`] (refused when built for another model), or a
/// directory of keyframe images with `poses.csv`, built into a store here.
/// `cam` is the camera of the images as calibrated (distortion included).
pub fn load_keyframes(
    ctx: &impl AsDevice,
    model: &PointModel,
    cam: &Intrinsics,
    path: &Path,
) -> Result<KeyframeStore, AppError> {
    if path.is_file() {
        let store = KeyframeStore::load(path)?;
        store.check_model(model, path)?;
        return Ok(store);
    }
    build_keyframes(ctx, model, cam, path)
}

/// Builds a keyframe store from a directory of keyframe images and their
/// `poses.csv`, undistorting the images when `cam` has distortion.
pub fn build_keyframes(
    ctx: &impl AsDevice,
    model: &PointModel,
    cam: &Intrinsics,
    dir: &Path,
) -> Result<KeyframeStore, AppError> {
    let poses = dir.join("poses.csv");
    if !poses.is_file() {
        return Err(AppError::NotKeyframes(dir.to_owned()));
    }
    let rows = read_poses(&poses)?;
    let mut images = load_keyframe_images(dir, &rows, cam)?;
    if cam.has_distortion() {
        let und = Undistorter::new(cam);
        for (_, img, _) in &mut images {
            *img = und.apply(img).map_err(|reason| AppError::Undistort {
                path: dir.to_owned(),
                reason,
            })?;
        }
    }
    let splatter = Splatter::new(ctx)?;
    KeyframeStore::build(
        ctx,
        &splatter,
        model,
        &cam.undistorted(),
        &images,
        &KeyframeConfig::default(),
    )
    .map_err(|source| AppError::BuildKeyframes {
        path: dir.to_owned(),
        source,
    })
}

/// Where [`load_or_build_keyframes`] got its store.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeyframeOrigin {
    /// The cached store, which matched the model.
    Loaded,
    /// Built from the images (no cache, or a stale or unreadable one) and
    /// saved as the cache.
    Built,
}

/// The keyframe store cached at `cache` when it loads and was built for
/// `model`; otherwise built from the images in `dir` ([`build_keyframes`])
/// and saved to `cache`, so the next run skips the build.
pub fn load_or_build_keyframes(
    ctx: &impl AsDevice,
    model: &PointModel,
    cam: &Intrinsics,
    dir: &Path,
    cache: &Path,
) -> Result<(KeyframeStore, KeyframeOrigin), AppError> {
    if cache.is_file() {
        match KeyframeStore::load(cache).and_then(|s| s.check_model(model, cache).map(|_| s)) {
            Ok(store) => return Ok((store, KeyframeOrigin::Loaded)),
            Err(e) => log::info!("rebuilding the keyframe store: {e}"),
        }
    }
    let store = build_keyframes(ctx, model, cam, dir)?;
    store.save(cache)?;
    Ok((store, KeyframeOrigin::Built))
}

/// The columns the tracker output adds after the pose (FORMATS.md
/// "Tracker output"; `cues`: [`cues_name`] of [`TrackResult::cues`]).
pub const RESULT_COLUMNS: [&str; 4] = ["inliers", "residual_px", "status", "cues"];

/// The column a run over a video or a camera adds after [`RESULT_COLUMNS`]:
/// the frame's timestamp in seconds (FORMATS.md, `track --video`).
pub const TIME_COLUMN: &str = "time_s";

/// The tracker output row of a frame.
pub fn result_row(label: &str, r: &TrackResult) -> PoseRow {
    let mut row = PoseRow::new(label, r.pose);
    let residual = if r.residual_px.is_finite() {
        format!("{:.3}", r.residual_px)
    } else {
        "nan".into()
    };
    row.extra = [
        r.inliers.to_string(),
        residual,
        r.status.name().into(),
        cues_name(r.cues),
    ]
    .into_iter()
    .zip(RESULT_COLUMNS)
    .map(|(v, k)| (k.to_string(), v))
    .collect();
    row
}

/// The cues of a frame as the `cues` column writes them: `texture`,
/// `contour`, `texture+contour` (no comma inside a CSV field) or `none`.
pub fn cues_name(m: crate::tracker::Modalities) -> String {
    m.name().replace(',', "+")
}
