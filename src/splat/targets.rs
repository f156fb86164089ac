//! The render targets of the splatter ([`SplatTargets`]).

use super::cpu::Accumulators;
use super::gpu_data::TARGETS;
use super::occluders::Stamp;
use super::scratch::Scratch;
use super::{Attribute, Attributes, SplatError, SplatImage};
use crate::device::AsDevice;
use crate::geometry::{Intrinsics, Pose};
use crate::gpu::GpuContext;

pub(super) const ACC_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
pub(super) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The result of a render: on a GPU, accumulation targets (weighted sums)
/// and the visibility depth; on the CPU device, the host's accumulators.
/// Allocate once per image size and reuse.
pub struct SplatTargets {
    pub(super) width: u32,
    pub(super) height: u32,
    /// The GPU's textures (`None` on the CPU device).
    pub(super) gpu: Option<GpuTargets>,
    /// The CPU device's last render (`None` on a GPU, or before a render).
    pub(super) host: Option<HostRender>,
    pub(super) rendered: Option<Attributes>,
    /// The last render was [`super::Splatter::render_depth`]'s: only the
    /// depth and the coverage can be read.
    pub(super) depth_only: bool,
    /// The pose and camera of the last render (`None` before one, or from
    /// the start of a render that then failed).
    pub(super) view: Option<(Pose, Intrinsics)>,
    /// The occluder set of the last render (its splatter's generation).
    pub(super) occluders: Option<Stamp>,
    /// [`Attribute::Depth`] comes from the predictors wherever they were
    /// rendered, with the geometry or not ([`SplatTargets::motion_depth`]).
    pub(super) motion_depth: bool,
}

/// What the CPU device's last render left in its targets.
pub(super) enum HostRender {
    /// A full render's five accumulators, and the visibility pass's depth
    /// where the render kept it ([`super::Splatter::render_keeping_depth`]).
    Full(Accumulators, Option<SplatImage>),
    /// A depth-only render's depth (NaN where empty).
    Depth(SplatImage),
}

/// The GPU side of [`SplatTargets`].
pub(super) struct GpuTargets {
    acc: Vec<wgpu::Texture>,
    pub(super) acc_views: Vec<wgpu::TextureView>,
    pub(super) depth_view: wgpu::TextureView,
    pub(super) uniform: wgpu::Buffer,
    /// The render pass back end's occluders' camera uniforms, one per
    /// occluder of the most occluded render here.
    pub(super) occluder_uniforms: Vec<wgpu::Buffer>,
    /// Scratch of the compute back end, made on its first render here.
    pub(super) compute: Option<Scratch>,
}

impl SplatTargets {
    /// Render targets of `width x height` pixels on `device` (a
    /// [`GpuContext`] or a [`crate::Device`]), with no render yet.
    pub fn new(device: &impl AsDevice, width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            gpu: device
                .gpu_context()
                .map(|ctx| GpuTargets::new(ctx, width, height)),
            host: None,
            rendered: None,
            depth_only: false,
            view: None,
            occluders: None,
            motion_depth: false,
        }
    }

    /// These targets with [`Attribute::Depth`] read from the predictors
    /// wherever they were rendered, also beside the geometry: the
    /// tracker's steps read the predictors' depth (eq. 5), and its check
    /// renders the normals with them for its shading fit.
    pub(crate) fn motion_depth(mut self) -> Self {
        self.motion_depth = true;
        self
    }

    /// Whether these targets are the CPU device's.
    pub fn on_cpu(&self) -> bool {
        self.gpu.is_none()
    }

    /// The GPU side; the splatter checks the device before its GPU paths
    /// run.
    pub(super) fn g(&self) -> &GpuTargets {
        self.gpu
            .as_ref()
            .expect("GPU targets (the device is checked first)")
    }

    /// [`Self::g`], mutable.
    pub(super) fn g_mut(&mut self) -> &mut GpuTargets {
        self.gpu
            .as_mut()
            .expect("GPU targets (the device is checked first)")
    }
}

impl GpuTargets {
    fn new(ctx: &GpuContext, width: u32, height: u32) -> Self {
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let tex = |label, format, usage| {
            ctx.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let acc: Vec<wgpu::Texture> = (0..TARGETS)
            .map(|_| {
                tex(
                    "splat accumulator",
                    ACC_FORMAT,
                    wgpu::TextureUsages::RENDER_ATTACHMENT
                        | wgpu::TextureUsages::TEXTURE_BINDING
                        | wgpu::TextureUsages::COPY_SRC
                        // Written by the compute back end.
                        | wgpu::TextureUsages::STORAGE_BINDING,
                )
            })
            .collect();
        let acc_views = acc
            .iter()
            .map(|t| t.create_view(&Default::default()))
            .collect();
        let depth = tex(
            "splat visibility depth",
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let depth_view = depth.create_view(&Default::default());
        let uniform = super::gpu_data::camera_buffer(ctx);
        Self {
            acc,
            acc_views,
            depth_view,
            uniform,
            occluder_uniforms: Vec::new(),
            compute: None,
        }
    }
}

impl SplatTargets {
    /// GPU bytes these targets hold: the five RGBA32F accumulators and the
    /// 32-bit depth (84 bytes a pixel), the camera uniform, and the compute
    /// back end's scratch once it has rendered here (40 bytes a pixel and
    /// 4 a splat of the largest model; `compute::Scratch`). None on the
    /// CPU device.
    pub fn gpu_bytes(&self) -> u64 {
        let Some(g) = &self.gpu else {
            return 0;
        };
        let pixels = self.width as u64 * self.height as u64;
        let acc: u64 = g
            .acc
            .iter()
            .map(|t| {
                let s = t.size();
                s.width as u64
                    * s.height as u64
                    * t.format().block_copy_size(None).unwrap_or(16) as u64
            })
            .sum();
        acc + pixels * DEPTH_FORMAT.block_copy_size(None).unwrap_or(4) as u64
            + g.uniform.size()
            + g.occluder_uniforms.iter().map(|b| b.size()).sum::<u64>()
            + g.compute.as_ref().map_or(0, |c| c.gpu_bytes())
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The attribute groups of the last render, if any (`None` after a
    /// depth-only render too: [`Self::depth_only`]).
    pub fn rendered(&self) -> Option<Attributes> {
        self.rendered
    }

    /// The focal length in x (pixels) of the last render's camera: what
    /// `gather` and a depth read turn the predictors into depth with (0
    /// before a render).
    pub(super) fn fx(&self) -> f32 {
        self.view.map_or(0.0, |(_, cam)| cam.fx as f32)
    }

    /// Refused ([`SplatError::SizeMismatch`]) unless the targets are the
    /// size of `cam`'s image, as every render into them needs.
    pub fn check_size(&self, cam: &Intrinsics) -> Result<(), SplatError> {
        if self.width != cam.width || self.height != cam.height {
            return Err(SplatError::SizeMismatch {
                got_w: self.width,
                got_h: self.height,
                want_w: cam.width,
                want_h: cam.height,
            });
        }
        Ok(())
    }

    /// The pose and camera of the last render, whose images these targets
    /// hold (`None` before any render, after one that failed, or once the
    /// splatter that made it has other occluders: a render at this view
    /// would no longer give these images, so a cache keyed by the view
    /// must not hand them back).
    pub fn last_view(&self) -> Option<&(Pose, Intrinsics)> {
        self.view
            .as_ref()
            .filter(|_| self.occluders.as_ref().is_none_or(|s| s.current()))
    }

    /// The generation of the occluder set the last render was made with
    /// ([`super::Splatter::occluder_generation`] then; `None` before a
    /// render): part of what identifies the render, with its view.
    pub fn occluder_generation(&self) -> Option<u64> {
        self.occluders.as_ref().map(|s| s.generation)
    }

    /// Whether the last render was depth-only
    /// ([`super::Splatter::render_depth`]).
    pub fn depth_only(&self) -> bool {
        self.depth_only
    }

    /// The raw accumulation textures (weighted sums; layout in the module
    /// docs), for passes that consume them on the GPU (none on the CPU
    /// device).
    pub fn accumulators(&self) -> &[wgpu::Texture] {
        self.gpu.as_ref().map_or(&[], |g| &g.acc)
    }

    pub(super) fn check(&self, need: Attributes, what: Attribute) -> Result<(), SplatError> {
        if self.depth_only {
            return match what {
                Attribute::Depth | Attribute::Weight => Ok(()),
                _ => Err(SplatError::NotRendered(what)),
            };
        }
        match self.rendered {
            Some(r) if r.contains(need) => Ok(()),
            // Depth from the predictors (`depth_from_motion`).
            Some(r) if what == Attribute::Depth && r.motion => Ok(()),
            _ => Err(SplatError::NotRendered(what)),
        }
    }

    /// Whether [`Attribute::Depth`] of the last render comes from its
    /// predictors (rendered without the geometry, or beside it where
    /// [`SplatTargets::motion_depth`]).
    pub(super) fn depth_from_motion(&self) -> bool {
        !self.depth_only
            && self
                .rendered
                .is_some_and(|r| r.motion && (!r.geometry || self.motion_depth))
    }
}

/// The colour attachments of a pass that clears (and then adds to) the
/// accumulation targets `attrs` writes; `None` for the others.
pub(super) fn cleared_attachments(
    targets: &SplatTargets,
    attrs: Attributes,
) -> Vec<Option<wgpu::RenderPassColorAttachment<'_>>> {
    target_slots(attrs)
        .iter()
        .zip(&targets.g().acc_views)
        .map(|(&on, view)| {
            on.then_some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })
        })
        .collect()
}

/// Which of the five accumulation targets a render writes.
pub(super) fn target_slots(attrs: Attributes) -> [bool; TARGETS] {
    [
        true,
        attrs.geometry,
        attrs.motion,
        attrs.motion,
        attrs.motion,
    ]
}
