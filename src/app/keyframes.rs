//! The keyframe store of a run: loaded from a store file, built from
//! keyframe images, or kept as a cache beside them.

use super::AppError;
use crate::device::AsDevice;
use crate::geometry::{Intrinsics, Undistorter};
use crate::io::poses::read_poses;
use crate::keyframes::{KeyframeConfig, KeyframeStore, load_keyframe_images};
use crate::model::PointModel;
use crate::splat::Splatter;
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
