//! The trackers of a run: one object's [`Tracker`], or several objects'
//! [`MultiTracker`], and the objects' silhouettes at their tracked poses
//! for the overlays and the live view.

use crate::device::Device;
use crate::geometry::{Intrinsics, Pose};
use crate::splat::{Attribute, GpuModel, SplatTargets, Splatter};
use crate::tracker::{MultiTracker, TrackError, TrackResult, Tracker};

/// The run's trackers.
pub(super) enum Trackers {
    /// One object: its tracker, whose silhouettes reuse its last render
    /// where they can.
    One(Box<Tracker>),
    /// Several objects, and what draws their silhouettes (made on the
    /// first frame that needs one).
    Many {
        multi: Box<MultiTracker>,
        masks: Option<Box<Masks>>,
    },
}

/// Splats each object's model at its tracked pose for its silhouette:
/// the [`MultiTracker`] lends its trackers only to read, so the
/// silhouettes come from a splatter of the run's own.
pub(super) struct Masks {
    splatter: Splatter,
    models: Vec<GpuModel>,
    targets: SplatTargets,
}

impl Trackers {
    /// Tracks one frame: one result an object, in their order.
    pub fn track(&mut self, image: &image::RgbImage) -> Result<Vec<TrackResult>, TrackError> {
        match self {
            Trackers::One(t) => Ok(vec![t.track(image)?]),
            Trackers::Many { multi, .. } => multi.track(image),
        }
    }

    /// Object `i`'s tracker.
    pub fn tracker(&self, i: usize) -> &Tracker {
        match self {
            Trackers::One(t) => t,
            Trackers::Many { multi, .. } => multi.tracker(i),
        }
    }

    /// The number of objects.
    pub fn len(&self) -> usize {
        match self {
            Trackers::One(_) => 1,
            Trackers::Many { multi, .. } => multi.len(),
        }
    }

    /// Each object's silhouette at its pose in `results` (one flag per
    /// pixel of the frames `cam` sees).
    pub fn silhouettes(
        &mut self,
        device: &Device,
        cam: &Intrinsics,
        results: &[TrackResult],
    ) -> Result<Vec<Vec<bool>>, TrackError> {
        match self {
            Trackers::One(t) => Ok(vec![t.silhouette(&results[0].pose)?]),
            Trackers::Many { multi, masks } => {
                if masks.is_none() {
                    let models = multi
                        .trackers()
                        .iter()
                        .map(|t| GpuModel::new(device, t.model()))
                        .collect::<Result<Vec<_>, _>>()?;
                    *masks = Some(Box::new(Masks {
                        splatter: Splatter::new(device)?,
                        models,
                        targets: SplatTargets::new(device, cam.width, cam.height),
                    }));
                }
                let Masks {
                    splatter,
                    models,
                    targets,
                } = &mut **masks.as_mut().expect("made above");
                results
                    .iter()
                    .zip(models.iter())
                    .map(|(r, model)| silhouette(splatter, targets, device, model, cam, &r.pose))
                    .collect()
            }
        }
    }
}

/// `model`'s coverage at `pose`, splatted over the whole frame.
fn silhouette(
    splatter: &Splatter,
    targets: &mut SplatTargets,
    device: &Device,
    model: &GpuModel,
    cam: &Intrinsics,
    pose: &Pose,
) -> Result<Vec<bool>, TrackError> {
    splatter.render(device, model, cam, pose, Attribute::Weight.needs(), targets)?;
    let weight = splatter.read(device, targets, Attribute::Weight)?;
    Ok(weight
        .data
        .iter()
        .map(|v| *v > 0.0 && !v.is_nan())
        .collect())
}
