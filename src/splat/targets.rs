//! The render targets of the splatter ([`SplatTargets`]) and normalised
//! images read back from them ([`SplatImage`]).

use super::gpu_data::CameraUniform;
use super::scratch::Scratch;
use super::{Attribute, Attributes, SplatError};
use crate::geometry::{Intrinsics, Pose};
use crate::gpu::GpuContext;

pub(super) const ACC_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
pub(super) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
pub(super) const TARGETS: usize = 5;

/// The GPU-resident result of a render: accumulation targets (weighted sums)
/// and the visibility depth. Allocate once per image size and reuse.
pub struct SplatTargets {
    pub(super) width: u32,
    pub(super) height: u32,
    acc: Vec<wgpu::Texture>,
    pub(super) acc_views: Vec<wgpu::TextureView>,
    pub(super) depth_view: wgpu::TextureView,
    pub(super) uniform: wgpu::Buffer,
    pub(super) rendered: Option<Attributes>,
    /// The last render was [`super::Splatter::render_depth`]'s: only the
    /// depth and the coverage can be read.
    pub(super) depth_only: bool,
    /// Scratch of the compute back end, made on its first render here.
    pub(super) compute: Option<Scratch>,
    /// The pose and camera of the last render (`None` before one, or from
    /// the start of a render that then failed).
    pub(super) view: Option<(Pose, Intrinsics)>,
}

impl SplatTargets {
    /// Render targets of `width x height` pixels, with no render yet.
    pub fn new(ctx: &GpuContext, width: u32, height: u32) -> Self {
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
        let uniform = ctx.buffer(
            "splat camera",
            std::mem::size_of::<CameraUniform>() as u64,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        Self {
            width,
            height,
            acc,
            acc_views,
            depth_view,
            uniform,
            rendered: None,
            depth_only: false,
            compute: None,
            view: None,
        }
    }

    /// GPU bytes these targets hold: the five RGBA32F accumulators and the
    /// 32-bit depth (84 bytes a pixel), the camera uniform, and the compute
    /// back end's scratch once it has rendered here (40 bytes a pixel and
    /// 4 a splat of the largest model; `compute::Scratch`).
    pub fn gpu_bytes(&self) -> u64 {
        let pixels = self.width as u64 * self.height as u64;
        let acc: u64 = self
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
            + self.uniform.size()
            + self.compute.as_ref().map_or(0, |c| c.gpu_bytes())
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

    /// The pose and camera of the last render, whose images these targets
    /// hold (`None` before any render, or after one that failed).
    pub fn last_view(&self) -> Option<&(Pose, Intrinsics)> {
        self.view.as_ref()
    }

    /// Whether the last render was depth-only
    /// ([`super::Splatter::render_depth`]).
    pub fn depth_only(&self) -> bool {
        self.depth_only
    }

    /// The raw accumulation textures (weighted sums; layout in the module
    /// docs), for passes that consume them on the GPU.
    pub fn accumulators(&self) -> &[wgpu::Texture] {
        &self.acc
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
    /// predictors (rendered without the geometry).
    pub(super) fn depth_from_motion(&self) -> bool {
        !self.depth_only && self.rendered.is_some_and(|r| r.motion && !r.geometry)
    }
}

/// A normalised attribute image read back to the host: row-major
/// `height x width x channels`, NaN in every channel of empty pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct SplatImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Channels per pixel (see [`Attribute::channels`]).
    pub channels: usize,
    /// `height * width * channels` values, row-major; NaN where empty.
    pub data: Vec<f32>,
}

impl SplatImage {
    /// The channels of pixel (x, y).
    pub fn pixel(&self, x: u32, y: u32) -> &[f32] {
        let i = (y as usize * self.width as usize + x as usize) * self.channels;
        &self.data[i..i + self.channels]
    }

    /// True where a splat covers the pixel.
    pub fn is_valid(&self, x: u32, y: u32) -> bool {
        !self.pixel(x, y)[0].is_nan()
    }

    /// Number of covered pixels.
    pub fn coverage(&self) -> usize {
        self.data
            .chunks(self.channels)
            .filter(|p| !p[0].is_nan())
            .count()
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
        .zip(&targets.acc_views)
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

/// Whether the adapter can run the compute back end (it writes the five
/// accumulation targets as storage textures in one pass).
pub(super) fn compute_supported(ctx: &GpuContext) -> bool {
    ctx.limits.max_storage_textures_per_shader_stage >= TARGETS as u32
}
