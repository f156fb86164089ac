//! The CPU device's splatter: a render is [`cpu::splat_packed`] (or
//! [`cpu::visibility_depth`]) at the window's camera, its accumulators
//! kept in the targets; reads resolve them and gathers sample them with
//! the GPU gather's maths ([`cpu::sample_at`]).

use super::SplatImage;
use super::cpu;
use super::model::{GpuModel, ModelStore};
use super::targets::{HostRender, SplatTargets};
use super::{Attribute, Attributes, GatherMode, GatherSample, SplatError, SplatParams};
use crate::geometry::{Intrinsics, Pose};

/// Splats `model` at `pose` into `targets`: every attribute group (the
/// host splatter computes them together), or the visibility pass alone.
#[allow(clippy::too_many_arguments)]
pub(super) fn render(
    params: &SplatParams,
    model: &GpuModel,
    cam: &Intrinsics,
    pose: &Pose,
    attrs: Attributes,
    depth_only: bool,
    targets: &mut SplatTargets,
) -> Result<(), SplatError> {
    if targets.width != cam.width || targets.height != cam.height {
        return Err(SplatError::SizeMismatch {
            got_w: targets.width,
            got_h: targets.height,
            want_w: cam.width,
            want_h: cam.height,
        });
    }
    let ModelStore::Host(packed) = &model.store else {
        return Err(SplatError::WrongDevice("the model"));
    };
    targets.view = None;
    targets.host = None;
    let uniform = model.bounds.view(cam, pose, params)?;
    if depth_only {
        targets.host = Some(HostRender::Depth(cpu::visibility_depth(packed, &uniform)));
        targets.rendered = None;
    } else {
        targets.host = Some(HostRender::Full(cpu::splat_packed(packed, &uniform)));
        targets.rendered = Some(attrs);
    }
    targets.depth_only = depth_only;
    targets.view = Some((*pose, *cam));
    Ok(())
}

/// One attribute of the last render, normalised (the GPU read's values).
pub(super) fn read(targets: &SplatTargets, attribute: Attribute) -> Result<SplatImage, SplatError> {
    targets.check(attribute.needs(), attribute)?;
    match &targets.host {
        Some(HostRender::Full(acc))
            if attribute == Attribute::Depth && targets.depth_from_motion() =>
        {
            Ok(acc.depth_from_motion(targets.fx()))
        }
        Some(HostRender::Full(acc)) => Ok(acc.resolve(attribute)),
        Some(HostRender::Depth(depth)) => Ok(match attribute {
            // Coverage: 1 where a splat reaches, 0 elsewhere, as the GPU's
            // depth-only weight.
            Attribute::Weight => SplatImage {
                data: depth
                    .data
                    .iter()
                    .map(|z| if z.is_nan() { 0.0 } else { 1.0 })
                    .collect(),
                ..depth.clone()
            },
            _ => depth.clone(),
        }),
        None => Err(SplatError::NotRendered(attribute)),
    }
}

/// The predictors and depth at `points` of the last render.
pub(super) fn gather(
    targets: &SplatTargets,
    points: &[[f32; 2]],
    mode: GatherMode,
) -> Result<Vec<GatherSample>, SplatError> {
    targets.check(Attributes::MOTION, Attribute::Motion)?;
    if points.is_empty() {
        return Ok(Vec::new());
    }
    let Some(HostRender::Full(acc)) = &targets.host else {
        return Err(SplatError::NotRendered(Attribute::Motion));
    };
    let motion = acc.resolve(Attribute::Motion);
    Ok(cpu::sample_at(&motion, targets.fx(), points, mode))
}
