//! The CPU device's splatter: a render is [`cpu::HostSplatter::render`]
//! (or [`cpu::HostSplatter::render_depth`]) at the window's camera, of the
//! attribute groups asked for, its accumulators kept in the targets and
//! reused by the next render; reads resolve them and gathers sample them
//! with the GPU gather's maths ([`cpu::Accumulators::gather`]).

use super::SplatImage;
use super::cpu;
use super::gpu_data::CameraUniform;
use super::model::{GpuModel, ModelStore};
use super::occluders::OccluderSet;
use super::targets::{HostRender, SplatTargets};
use super::{
    Attribute, Attributes, GatherMode, GatherSample, PackedModel, SplatError, SplatParams,
};
use crate::geometry::{Intrinsics, Pose};
use std::sync::Mutex;

/// The depth a host render leaves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Depth {
    /// A full render's own (averaged, or from its predictors).
    Averaged,
    /// The visibility pass alone: its depth and coverage, nothing else.
    Only,
    /// A full render that keeps its visibility pass's depth too: what
    /// [`Depth::Only`] would read, bit for bit.
    Kept,
}

fn empty_depth() -> SplatImage {
    SplatImage {
        width: 0,
        height: 0,
        channels: 1,
        data: Vec::new(),
    }
}

/// What a host render needs of the splatter.
pub(super) struct HostParts<'a> {
    pub params: &'a SplatParams,
    /// The splatter's own host splatter.
    pub splatter: &'a Mutex<cpu::HostSplatter>,
    /// The splatter's occluders.
    pub occluders: &'a OccluderSet,
}

/// Splats `model` at `pose` into `targets`, behind the splatter's
/// occluders: colour, weight and the groups of `attrs` (and, with
/// [`Depth::Kept`], the visibility pass's depth beside them), or the
/// visibility pass alone ([`Depth::Only`]).
pub(super) fn render(
    host: HostParts<'_>,
    model: &GpuModel,
    cam: &Intrinsics,
    pose: &Pose,
    attrs: Attributes,
    depth: Depth,
    targets: &mut SplatTargets,
) -> Result<(), SplatError> {
    targets.check_size(cam)?;
    let ModelStore::Host(packed) = &model.store else {
        return Err(SplatError::WrongDevice("the model"));
    };
    targets.view = None;
    // The last render's buffers are written over (no allocation when the
    // window keeps its size).
    let previous = targets.host.take();
    let uniform = model.bounds.view(cam, pose, host.params)?;
    let occluders = host
        .occluders
        .views(cam, host.params, &uniform)?
        .into_iter()
        .map(|(m, u)| match &m.store {
            ModelStore::Host(p) => Ok((&**p, u)),
            ModelStore::Gpu { .. } => Err(SplatError::WrongDevice("an occluder's model")),
        })
        .collect::<Result<Vec<(&PackedModel, CameraUniform)>, _>>()?;
    let mut splatter = host.splatter.lock().unwrap_or_else(|p| p.into_inner());
    let depth_only = depth == Depth::Only;
    if depth_only {
        let mut depth = match previous {
            Some(HostRender::Depth(d)) => d,
            _ => empty_depth(),
        };
        splatter.render_depth_occluded(packed, &uniform, &occluders, &mut depth);
        targets.host = Some(HostRender::Depth(depth));
        targets.rendered = None;
    } else {
        let (mut acc, z) = match previous {
            Some(HostRender::Full(a, z)) => (a, z),
            _ => (cpu::Accumulators::default(), None),
        };
        let z = if depth == Depth::Kept {
            let mut z = z.unwrap_or_else(empty_depth);
            splatter
                .render_occluded_with_depth(packed, &uniform, &occluders, attrs, &mut acc, &mut z);
            Some(z)
        } else {
            splatter.render_occluded(packed, &uniform, &occluders, attrs, &mut acc);
            None
        };
        targets.host = Some(HostRender::Full(acc, z));
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
        // The visibility pass's depth, where the render kept it: a
        // depth-only render's.
        Some(HostRender::Full(_, Some(z))) if attribute == Attribute::Depth => Ok(z.clone()),
        Some(HostRender::Full(acc, _))
            if attribute == Attribute::Depth && targets.depth_from_motion() =>
        {
            Ok(acc.depth_from_motion(targets.fx()))
        }
        Some(HostRender::Full(acc, _)) => Ok(acc.resolve(attribute)),
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
    let Some(HostRender::Full(acc, _)) = &targets.host else {
        return Err(SplatError::NotRendered(Attribute::Motion));
    };
    Ok(acc.gather(targets.fx(), points, mode))
}
