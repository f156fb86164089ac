//! The splatter ([`Splatter`]) on either device: the GPU's passes
//! (`splatter`, `render`, `resolve`, `compute`) or the host's (`host`).
//! The calls that render, read and gather take the device they run on (a
//! [`GpuContext`] or a [`crate::Device`]); those that hand GPU buffers on
//! take a context and are refused on the CPU device.

use super::SplatImage;
use super::cpu_device::{self, Depth};
use super::error::SplatError;
use super::model::GpuModel;
use super::occluders::{Occluder, OccluderSet};
use super::params::{Backend, SplatParams};
use super::resolve::PendingGather;
use super::splatter::GpuSplatter;
use super::targets::SplatTargets;
use super::{Attribute, Attributes, GatherMode, GatherSample};
use crate::device::AsDevice;
use crate::geometry::{Intrinsics, Pose};
use crate::gpu::{GpuContext, GpuTimer, PassChain};

/// The splatter: on a GPU, pipelines for the three passes and the gather
/// kernel; on the CPU device, [`super::cpu`]'s splatter with its
/// accumulators kept in the targets. Create once per device; its models
/// ([`GpuModel`]) and targets ([`SplatTargets`]) are made on the same
/// device.
pub struct Splatter {
    params: SplatParams,
    /// `None` on the CPU device.
    gpu: Option<GpuSplatter>,
    /// The CPU device's splatter, its threads' scratch kept between
    /// renders (unused on a GPU, where it holds no buffer and no thread:
    /// both are made by its first render).
    host: std::sync::Mutex<super::cpu::HostSplatter>,
    /// Other objects splatted into every render's visibility pass.
    occluders: OccluderSet,
}

impl Splatter {
    /// A splatter with default [`SplatParams`] on `device` (a
    /// [`GpuContext`] or a [`crate::Device`]); fails where the adapter
    /// cannot splat.
    pub fn new(device: &impl AsDevice) -> Result<Self, SplatError> {
        Self::with_params(device, SplatParams::default())
    }

    /// A splatter with `params` on `device`; on a GPU its back end is
    /// resolved on the adapter ([`SplatError::Unsupported`] where none
    /// works).
    pub fn with_params(device: &impl AsDevice, params: SplatParams) -> Result<Self, SplatError> {
        let gpu = match device.gpu_context() {
            Some(ctx) => Some(GpuSplatter::with_params(ctx, params)?),
            None => None,
        };
        let host = std::sync::Mutex::new(super::cpu::HostSplatter::new());
        Ok(Self {
            params,
            gpu,
            host,
            occluders: OccluderSet::default(),
        })
    }

    /// The CPU device's parameters, host splatter and occluders.
    fn host_parts(&self) -> cpu_device::HostParts<'_> {
        cpu_device::HostParts {
            params: &self.params,
            splatter: &self.host,
            occluders: &self.occluders,
        }
    }

    /// Sets the objects that hide part of every later render (none at
    /// first): each render of a model by this splatter ([`Self::render`],
    /// [`Self::render_timed`], [`Self::render_image`],
    /// [`Self::render_depth`]) first splats every occluder, at its own
    /// pose, with the render's camera (and so its window), into the same
    /// visibility depth buffer, then the model's visibility pass, then the
    /// model's attribute pass alone. The targets hold only the model's
    /// attributes: empty (weight 0, as where no splat reaches) wherever an
    /// occluder is nearer than the model beyond the visibility push-back
    /// ([`SplatParams::epsilon`]), and elsewhere what a render without
    /// occluders gives (bit for bit on the host splatter and the render
    /// pass; the compute back end's sums are relative to the pixel's
    /// visibility depth, which an occluder within the push-back of the
    /// model's surface moves). A depth-only render reads empty where an
    /// occluder hides the model, never the occluder's depth. With no
    /// occluders a render is what it was without this call; occluders
    /// whose bounding sphere misses the image or lies behind the model's
    /// are skipped, and those partly outside the image cost a setup per
    /// splat beyond it.
    ///
    /// Refused (the set unchanged) where an occluder's model is of the
    /// other device kind ([`SplatError::WrongDevice`]), a pose is not
    /// rigid, or there are more than [`super::MAX_OCCLUDERS`]. Every
    /// change of the set (not the same models at the same poses) gives it
    /// a new [`Self::occluder_generation`]; targets remember the
    /// generation of their last render ([`SplatTargets::occluder_generation`])
    /// and their [`SplatTargets::last_view`] is `None` once the splatter's
    /// set has changed since, so that no cache keyed by the view hands back
    /// a render made behind other occluders.
    pub fn set_occluders(&mut self, occluders: Vec<Occluder>) -> Result<(), SplatError> {
        self.occluders.set(self.on_cpu(), occluders)
    }

    /// The occluders of every render ([`Self::set_occluders`]).
    pub fn occluders(&self) -> &[Occluder] {
        &self.occluders.list
    }

    /// A number naming the occluder set: 0 before any is set, and new
    /// (unique across splatters) at every change.
    pub fn occluder_generation(&self) -> u64 {
        self.occluders.generation()
    }

    /// Whether this is the CPU device's splatter.
    pub fn on_cpu(&self) -> bool {
        self.gpu.is_none()
    }

    /// The GPU splatter and context for a call on `device` with `model`
    /// and `targets` (none given: not checked), or `None` on the CPU
    /// device; objects of the other device are refused.
    fn on<'a>(
        &'a self,
        device: &'a impl AsDevice,
        model: Option<&GpuModel>,
        targets: Option<&SplatTargets>,
    ) -> Result<Option<(&'a GpuSplatter, &'a GpuContext)>, SplatError> {
        let cpu = self.gpu.is_none();
        if device.gpu_context().is_none() != cpu {
            return Err(SplatError::WrongDevice("the device given"));
        }
        if model.is_some_and(|m| m.on_cpu() != cpu) {
            return Err(SplatError::WrongDevice("the model"));
        }
        if targets.is_some_and(|t| t.on_cpu() != cpu) {
            return Err(SplatError::WrongDevice("the targets"));
        }
        Ok(self.gpu.as_ref().zip(device.gpu_context()))
    }

    /// The GPU splatter and context of a call that only a GPU can make.
    fn gpu_only<'a>(
        &'a self,
        targets: Option<&SplatTargets>,
    ) -> Result<&'a GpuSplatter, SplatError> {
        match &self.gpu {
            Some(g) if targets.is_none_or(|t| !t.on_cpu()) => Ok(g),
            _ => Err(SplatError::WrongDevice("GPU buffers on the CPU device")),
        }
    }

    /// The back end that renders `model` at `pose`: [`Splatter::backend`],
    /// except for `auto` on a CPU adapter, where renders whose typical
    /// splat (the median radius at the depth of the model's centre) is
    /// wider than [`super::AUTO_CPU_RENDER_PASS_ABOVE_PX`] pixels go
    /// through the render pass. Both write the same targets.
    pub fn backend_for(&self, model: &GpuModel, cam: &Intrinsics, pose: &Pose) -> Backend {
        self.gpu
            .as_ref()
            .map_or(Backend::Auto, |g| g.backend_for(model, cam, pose))
    }

    /// The splatting parameters.
    pub fn params(&self) -> &SplatParams {
        &self.params
    }

    /// The back end that renders on a GPU: [`Backend::RenderPass`] or
    /// [`Backend::Compute`] (what [`Backend::Auto`] chose on this adapter;
    /// on a CPU adapter `auto` still sends renders of large splats through
    /// the render pass: [`Splatter::backend_for`]); [`Backend::Auto`] on
    /// the CPU device, whose host splatter is neither.
    pub fn backend(&self) -> Backend {
        self.gpu.as_ref().map_or(Backend::Auto, |g| g.backend())
    }

    /// One-shot convenience: render and read one attribute.
    pub fn render_image(
        &self,
        device: &impl AsDevice,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        attribute: Attribute,
    ) -> Result<SplatImage, SplatError> {
        let mut targets = SplatTargets::new(device, cam.width, cam.height);
        self.render(device, model, cam, pose, attribute.needs(), &mut targets)?;
        self.read(device, &targets, attribute)
    }

    /// Splats `model` at `pose` into `targets` (whose size must be the
    /// camera's), behind the occluders ([`Self::set_occluders`]). On a
    /// GPU, submits the work and returns without waiting; on the CPU
    /// device, renders colour, weight and the groups of `attrs`.
    pub fn render(
        &self,
        device: &impl AsDevice,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        attrs: Attributes,
        targets: &mut SplatTargets,
    ) -> Result<(), SplatError> {
        self.render_timed(device, model, cam, pose, attrs, targets, None)
    }

    /// [`Splatter::render`] with GPU timestamps for the passes "visibility"
    /// and "attributes" (resolved into `timer`; read it after the submit).
    /// Untimed on the CPU device.
    #[allow(clippy::too_many_arguments)]
    pub fn render_timed(
        &self,
        device: &impl AsDevice,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        attrs: Attributes,
        targets: &mut SplatTargets,
        timer: Option<&mut GpuTimer>,
    ) -> Result<(), SplatError> {
        match self.on(device, Some(model), Some(targets))? {
            Some((g, ctx)) => {
                let occluders = &self.occluders;
                g.render_timed(ctx, model, cam, pose, attrs, targets, timer, occluders)?
            }
            None => {
                return self.render_on_host(model, cam, pose, attrs, Depth::Averaged, targets);
            }
        }
        targets.occluders = Some(self.occluders.stamp());
        Ok(())
    }

    /// The CPU device's render (`depth` says which depth it keeps), its
    /// targets stamped with the occluders it was made behind.
    fn render_on_host(
        &self,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        attrs: Attributes,
        depth: Depth,
        targets: &mut SplatTargets,
    ) -> Result<(), SplatError> {
        cpu_device::render(self.host_parts(), model, cam, pose, attrs, depth, targets)?;
        targets.occluders = Some(self.occluders.stamp());
        Ok(())
    }

    /// On the CPU device: [`Self::render_timed`] that keeps its visibility
    /// pass's depth too, so that [`Attribute::Depth`] reads what
    /// [`Self::render_depth`] would give, bit for bit (the same pass), and
    /// every other attribute the full render's. One render serves a
    /// depth-only reader and a full one. On a GPU the render's visibility
    /// depth is not kept: [`SplatError::Unsupported`].
    pub(crate) fn render_keeping_depth(
        &self,
        device: &impl AsDevice,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        attrs: Attributes,
        targets: &mut SplatTargets,
    ) -> Result<(), SplatError> {
        if self.on(device, Some(model), Some(targets))?.is_some() {
            return Err(SplatError::Unsupported(
                "a render that keeps its visibility depth runs on the CPU device only".into(),
            ));
        }
        self.render_on_host(model, cam, pose, attrs, Depth::Kept, targets)
    }

    /// A depth-only render: the visibility pass alone (one pass over the
    /// splats instead of two, no attribute sums), behind the occluders
    /// (empty where one is nearer than the model's pushed-back depth). Afterwards
    /// [`Splatter::read`] gives [`Attribute::Depth`], the depth of the
    /// nearest surface pushed back by the visibility epsilon (`epsilon *
    /// r` along the ray, [`SplatParams::epsilon`]: what the attribute pass
    /// tests against, within a splat radius behind the averaged depth of a
    /// full render), and [`Attribute::Weight`], 1 where covered; the
    /// coverage is exactly a full render's (a pixel is covered when a
    /// splat's kernel reaches it, and the nearest such splat passes the
    /// attribute pass's test). Other reads fail with
    /// [`SplatError::NotRendered`]. [`super::cpu::visibility_depth`] is
    /// the reference, and what the CPU device runs. Timed as "visibility"
    /// (and, on the compute back end, "depth": its large splats and the
    /// conversion).
    #[allow(clippy::too_many_arguments)]
    pub fn render_depth(
        &self,
        device: &impl AsDevice,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        targets: &mut SplatTargets,
        timer: Option<&mut GpuTimer>,
    ) -> Result<(), SplatError> {
        match self.on(device, Some(model), Some(targets))? {
            Some((g, ctx)) => {
                g.render_depth(ctx, model, cam, pose, targets, timer, &self.occluders)?
            }
            None => cpu_device::render(
                self.host_parts(),
                model,
                cam,
                pose,
                Attributes::GEOMETRY,
                cpu_device::Depth::Only,
                targets,
            )?,
        }
        targets.occluders = Some(self.occluders.stamp());
        Ok(())
    }

    /// Normalises one attribute of the last render and reads the whole
    /// image (for the CLI and tests; the tracker uses
    /// [`Splatter::gather`]).
    pub fn read(
        &self,
        device: &impl AsDevice,
        targets: &SplatTargets,
        attribute: Attribute,
    ) -> Result<SplatImage, SplatError> {
        match self.on(device, None, Some(targets))? {
            Some((g, ctx)) => g.read(ctx, targets, attribute),
            None => cpu_device::read(targets, attribute),
        }
    }

    /// Motion predictors, depth and validity at `points` (OpenCV pixel
    /// coordinates) from the last render, which must include the motion
    /// predictors ([`Attributes::MOTION`] or [`Attributes::ALL`]). The depth
    /// comes from the predictors (`fx / (du/dtx)`: the harmonic mean of the
    /// fragments' depths, eq. 5), so no geometry needs rendering. On a GPU
    /// reads back 14 floats per point only.
    pub fn gather(
        &self,
        device: &impl AsDevice,
        targets: &SplatTargets,
        points: &[[f32; 2]],
        mode: GatherMode,
    ) -> Result<Vec<GatherSample>, SplatError> {
        self.gather_later(device, targets, points, mode)?
            .wait(device)
    }

    /// [`Splatter::gather`] without waiting: on a GPU the gather is
    /// recorded and submitted (within a batch, put off with it) and its
    /// readback goes with the calling thread's next one
    /// ([`GpuContext::read_buffer_later`]); [`PendingGather::wait`]
    /// returns the samples. The next gather submits a put-off one first
    /// (they share the points' buffer). On the CPU device the samples are
    /// made now.
    pub fn gather_later(
        &self,
        device: &impl AsDevice,
        targets: &SplatTargets,
        points: &[[f32; 2]],
        mode: GatherMode,
    ) -> Result<PendingGather, SplatError> {
        match self.on(device, None, Some(targets))? {
            Some((g, ctx)) => g.gather_later(ctx, targets, points, mode),
            None => Ok(PendingGather {
                read: None,
                n: points.len(),
                ready: Some(cpu_device::gather(targets, points, mode)?),
            }),
        }
    }

    /// Normalises one attribute of the last render on the GPU into `out`
    /// (at least width x height x channels floats, `STORAGE`), where it
    /// stays: nothing is read back. Submitted at once. A GPU's only.
    pub fn resolve_into(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        attribute: Attribute,
        out: &wgpu::Buffer,
    ) -> Result<(), SplatError> {
        self.gpu_only(Some(targets))?
            .resolve_into(ctx, targets, attribute, out)
    }

    /// [`Splatter::resolve_into`] recorded as a stage of `passes` (its
    /// parameters queued), for the caller to submit with the stages
    /// around it: in one compute pass with them where untimed. Resolves
    /// of different attributes may share a submission (each kind has
    /// its parameters). A GPU's only.
    pub fn record_resolve(
        &self,
        ctx: &GpuContext,
        passes: &mut PassChain,
        targets: &SplatTargets,
        attribute: Attribute,
        out: &wgpu::Buffer,
    ) -> Result<(), SplatError> {
        self.gpu_only(Some(targets))?
            .record_resolve(ctx, passes, targets, attribute, out)
    }

    /// The buffer of points [`Splatter::gather_written_later`] gathers
    /// at, grown to hold `n` (8 bytes each: x, y as f32), for work on the
    /// GPU to write into (such as [`crate::features::Harris::export_corners`]).
    /// The next [`Splatter::gather_later`] overwrites it. A GPU's only.
    pub fn gather_points(&self, ctx: &GpuContext, n: usize) -> Result<wgpu::Buffer, SplatError> {
        self.gpu_only(None)?.gather_points(ctx, n)
    }

    /// The buffer the last gather wrote its samples into
    /// ([`super::GATHER_STRIDE`] floats a point, its validity last), for
    /// work on the GPU fed from them (such as
    /// [`crate::features::NccMatcher::match_resident_exported_b`]'s gate),
    /// recorded after that gather; the next gather overwrites it. A GPU's
    /// only.
    pub fn gathered_samples(&self, ctx: &GpuContext) -> Result<wgpu::Buffer, SplatError> {
        Ok(self.gpu_only(None)?.gathered_samples(ctx))
    }

    /// [`Splatter::gather_later`] at the first `n` points written on the
    /// GPU into [`Splatter::gather_points`] (recorded before this call).
    /// A GPU's only.
    pub fn gather_written_later(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        n: usize,
        mode: GatherMode,
    ) -> Result<PendingGather, SplatError> {
        self.gpu_only(Some(targets))?
            .gather_written_later(ctx, targets, n, mode)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Device;
    use crate::model::shapes;
    use nalgebra::Vector3;
    use std::sync::Arc;

    /// A render keeping its visibility depth on the CPU device, behind an
    /// occluder: its depth read is the depth-only render's and its colour
    /// and weight the full render's, bit for bit; the next plain render in
    /// the same targets reads its own depth again.
    #[test]
    fn a_render_keeping_its_depth_reads_as_both_renders() {
        let device = Device::Cpu;
        let mut splatter = Splatter::new(&device).expect("splatter");
        let model = GpuModel::new(&device, &shapes::sphere(glam::Vec3::ZERO, 0.1, 4000, 1.5))
            .expect("model");
        let occluder = GpuModel::new(&device, &shapes::sphere(glam::Vec3::ZERO, 0.04, 500, 1.5))
            .expect("occluder");
        let at = |x: f64, z: f64| {
            Pose::new(nalgebra::Matrix3::identity(), Vector3::new(x, 0.0, z)).expect("pose")
        };
        splatter
            .set_occluders(vec![Occluder {
                model: Arc::new(occluder),
                pose: at(0.05, 0.7),
            }])
            .expect("occluders");
        let cam = Intrinsics::new(96, 72, 90.0, 90.0, 47.5, 35.5);
        let pose = at(0.0, 1.0);
        let read = |t: &SplatTargets, a| splatter.read(&device, t, a).expect("read");
        let bits = |i: &SplatImage| i.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        let attrs = Attributes::MOTION;
        let mut kept = SplatTargets::new(&device, 96, 72);
        splatter
            .render_keeping_depth(&device, &model, &cam, &pose, attrs, &mut kept)
            .expect("render");
        let mut only = SplatTargets::new(&device, 96, 72);
        splatter
            .render_depth(&device, &model, &cam, &pose, &mut only, None)
            .expect("depth only");
        let mut full = SplatTargets::new(&device, 96, 72);
        splatter
            .render(&device, &model, &cam, &pose, attrs, &mut full)
            .expect("full");
        let depth = read(&kept, Attribute::Depth);
        assert!(depth.data.iter().any(|z| z.is_finite()));
        assert_eq!(bits(&depth), bits(&read(&only, Attribute::Depth)));
        // Not the full render's own depth (from its predictors).
        assert_ne!(bits(&depth), bits(&read(&full, Attribute::Depth)));
        for a in [Attribute::Color, Attribute::Weight] {
            assert_eq!(bits(&read(&kept, a)), bits(&read(&full, a)), "{a:?}");
        }
        splatter
            .render(&device, &model, &cam, &pose, attrs, &mut kept)
            .expect("again");
        let own = read(&kept, Attribute::Depth);
        assert_eq!(bits(&own), bits(&read(&full, Attribute::Depth)));
    }
}
