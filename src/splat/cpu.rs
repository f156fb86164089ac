//! The splatter on the host: the maths of shaders/splat.wgsl and
//! shaders/splat_resolve.wgsl in `f32` from the same [`CameraUniform`],
//! on every core ([`HostSplatter`]). It is both the GPU splatters'
//! reference, which tests compare with pixel by pixel, and the renderer
//! of the CPU back end: the same sums bit for bit on any number of
//! threads.
//!
//! The fast path: keep one [`HostSplatter`] and one [`Accumulators`] and
//! call [`HostSplatter::render`] with the attribute groups needed (and
//! [`HostSplatter::render_depth`] for depth alone), then read with
//! [`Accumulators::resolve`] or [`Accumulators::gather`]. The functions
//! below do the same with new scratch each call.

pub use super::accumulators::Accumulators;
use super::accumulators::gather_with;
use super::gpu_data::CameraUniform;
pub use super::host::HostSplatter;
use super::{
    Attributes, GatherMode, GatherSample, ModelBounds, PackedModel, SplatError, SplatImage,
    SplatParams, pack_model,
};
use crate::geometry::{Intrinsics, Pose};
use crate::model::PointModel;

/// Splats a packed model with a view uniform: passes 1 and 2, every
/// attribute group, on every core.
pub fn splat_packed(model: &PackedModel, uniform: &CameraUniform) -> Accumulators {
    let mut out = Accumulators::default();
    HostSplatter::new().render(model, uniform, Attributes::ALL, &mut out);
    out
}

/// The reference of [`super::Splatter::render_depth`] read as
/// [`super::Attribute::Depth`]: the visibility pass alone, one channel,
/// the pushed-back camera-space z of the nearest surface (that of the
/// first splat to reach it, in the model's order), NaN where no splat
/// covers the pixel.
pub fn visibility_depth(model: &PackedModel, uniform: &CameraUniform) -> SplatImage {
    let mut out = SplatImage {
        width: 0,
        height: 0,
        channels: 1,
        data: Vec::new(),
    };
    HostSplatter::new().render_depth(model, uniform, &mut out);
    out
}

/// [`splat_packed`] behind occluders, each a packed model with its own
/// view (its pose, the same camera, `uniform`'s depth range:
/// [`CameraUniform::with_depth_range`]): the reference of a render by a
/// [`super::Splatter`] with [`super::Splatter::set_occluders`].
pub fn splat_packed_occluded(
    model: &PackedModel,
    uniform: &CameraUniform,
    occluders: &[(&PackedModel, CameraUniform)],
) -> Accumulators {
    let mut out = Accumulators::default();
    HostSplatter::new().render_occluded(model, uniform, occluders, Attributes::ALL, &mut out);
    out
}

/// [`visibility_depth`] behind occluders (as in
/// [`splat_packed_occluded`]): NaN too where an occluder hides the model.
pub fn visibility_depth_occluded(
    model: &PackedModel,
    uniform: &CameraUniform,
    occluders: &[(&PackedModel, CameraUniform)],
) -> SplatImage {
    let mut out = SplatImage {
        width: 0,
        height: 0,
        channels: 1,
        data: Vec::new(),
    };
    HostSplatter::new().render_depth_occluded(model, uniform, occluders, &mut out);
    out
}

/// The view of an occluder at `pose` in a render whose model's view is
/// `model_view`: its own bounds and near plane, the model's depth range.
pub fn occluder_view(
    occluder: &PointModel,
    cam: &Intrinsics,
    pose: &Pose,
    params: &SplatParams,
    model_view: &CameraUniform,
) -> Result<CameraUniform, SplatError> {
    let (near, far) = model_view.depth_range();
    Ok(ModelBounds::of(occluder)
        .view(cam, pose, params)?
        .with_depth_range(near, far))
}

/// A whole render on the host: the same checks, bounds and uniform as the
/// GPU path.
pub fn splat(
    model: &PointModel,
    cam: &Intrinsics,
    pose: &Pose,
    params: &SplatParams,
) -> Result<Accumulators, SplatError> {
    let packed = pack_model(model, params)?;
    let uniform = ModelBounds::of(model).view(cam, pose, params)?;
    Ok(splat_packed(&packed, &uniform))
}

/// The gather kernel on a full image of predictors (12 channels): the
/// predictors sampled at `points` with the same rule as the GPU (`gather`
/// in shaders/splat_resolve.wgsl), and the depth they give, `fx / (du/dtx)`
/// (`fx`: the render's focal length in x, pixels).
/// [`Accumulators::gather`] does the same without the resolved image.
pub fn sample_at(
    motion: &SplatImage,
    fx: f32,
    points: &[[f32; 2]],
    mode: GatherMode,
) -> Vec<GatherSample> {
    let load = |x: i64, y: i64| -> Option<[f32; 12]> {
        if !motion.is_valid(x as u32, y as u32) {
            return None;
        }
        let mut v = [0.0; 12];
        v.copy_from_slice(motion.pixel(x as u32, y as u32));
        Some(v)
    };
    gather_with(motion.width, motion.height, load, fx, points, mode)
}
