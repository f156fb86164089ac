//! The per-point machinery that normal and radius estimation and gap
//! closing share: the points centred for the k-d tree, the threads, the
//! loop over ranges of points, and the error of a failed estimate.

use super::error::ModelError;
use super::stage::Stage;
use glam::{DVec3, Vec3};
use std::path::Path;

/// Coordinates (after centring) beyond this cannot have their squared
/// distances represented in f32.
pub(super) const MAX_COORDINATE: f32 = 1e15;
pub(super) const PROGRESS_STEP: usize = 1 << 14;

/// The points relative to their centroid, as f32 arrays for the k-d
/// tree (precise near the model even far from the origin); refuses
/// coordinates spanning more than [`MAX_COORDINATE`] (or NaN).
pub(super) fn centred_points(
    positions: &[Vec3],
    path: &Path,
    what: &'static str,
) -> Result<Vec<[f32; 3]>, ModelError> {
    let centroid = positions
        .iter()
        .fold(DVec3::ZERO, |acc, p| acc + p.as_dvec3())
        / positions.len().max(1) as f64;
    let centre = centroid.as_vec3();
    positions
        .iter()
        .map(|p| {
            let q = *p - centre;
            let extent = q.abs().max_element();
            if extent.is_nan() || extent > MAX_COORDINATE {
                return Err(err(
                    path,
                    what,
                    format!("coordinates span more than {MAX_COORDINATE:e} model units"),
                ));
            }
            Ok(q.to_array())
        })
        .collect()
}

/// Threads for the per-point loops: the machine's cores, at most 16.
pub(super) fn threads() -> usize {
    crate::par::cores().min(16)
}

/// Runs `work` over `0..n` cut into `threads` contiguous ranges, one thread
/// each, and returns the ranges' results in order: the same, point for
/// point, as one range on one thread. `work` reports the points it
/// finishes through its second argument; the calling thread passes each
/// report on to `bar` as it comes.
pub(super) fn par_ranges<T: Send>(
    n: usize,
    threads: usize,
    bar: &Stage<'_>,
    work: impl Fn(std::ops::Range<usize>, &dyn Fn(usize)) -> T + Sync,
) -> Vec<T> {
    let threads = threads.clamp(1, n.max(1));
    if threads == 1 {
        return vec![work(0..n, &|units| bar.advance(units as u64))];
    }
    let step = n.div_ceil(threads);
    let (tx, rx) = std::sync::mpsc::channel::<usize>();
    let ranges: Vec<_> = (0..threads)
        .map(|t| (t * step).min(n)..((t + 1) * step).min(n))
        .collect();
    std::thread::scope(|scope| {
        // A range whose thread cannot be started (the system out of
        // threads) is worked on here afterwards.
        let handles: Vec<_> = ranges
            .iter()
            .map(|range| {
                let (work, tx, range) = (&work, tx.clone(), range.clone());
                std::thread::Builder::new()
                    .name("splattrack-estimate".into())
                    .spawn_scoped(scope, move || {
                        work(range, &|units| {
                            let _ = tx.send(units);
                        })
                    })
                    .ok()
            })
            .collect();
        drop(tx);
        // Ends when every started worker has ended (and dropped its sender).
        for units in rx {
            bar.advance(units as u64);
        }
        handles
            .into_iter()
            .zip(ranges)
            .map(|(h, range)| match h {
                Some(h) => match h.join() {
                    Ok(v) => v,
                    Err(panic) => std::panic::resume_unwind(panic),
                },
                None => work(range, &|units| bar.advance(units as u64)),
            })
            .collect()
    })
}

pub(super) fn err(path: &Path, what: &'static str, reason: impl Into<String>) -> ModelError {
    ModelError::Estimation {
        path: path.to_path_buf(),
        what,
        reason: reason.into(),
    }
}
