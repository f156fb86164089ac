//! GPU EWA surface splatting: novel views, depth, normals and dense motion
//! predictors of a point model (Dehais et al. 2010, sections 2.3, 3.1, 3.2).
//!
//! # How it works
//!
//! Each point is an oriented disc (splat) with centre `p`, normal `n` and
//! radius `r`, carrying a Gaussian reconstruction kernel (Zwicker et al.
//! 2001, "Surface splatting"). At a pose, every splat is drawn as one
//! instanced screen-space quad that bounds its projection; the fragment
//! shader intersects the pixel's ray with the splat's plane (Botsch et al.
//! 2005, "High-quality surface splatting on today's GPUs") and evaluates the
//! kernel there:
//!
//! - `rho_obj = |X - c| / r` at the intersection `X`, and
//!   `rho_scr = |x - pi(c)| / h` in pixels, with `h` the low-pass radius
//!   ([`SplatParams::lowpass_px`], 0.75 px: just above the 0.707 px that
//!   guarantees a pixel centre). The kernel is evaluated at
//!   `rho = min(rho_obj, rho_scr)`, Botsch et al.'s approximation of the EWA
//!   screen-space low-pass filter, so splats smaller than a pixel still cover
//!   one; it is truncated at `rho = 1` and `w = exp(-2 rho^2)` (a Gaussian of
//!   standard deviation `r/2`).
//! - The surface point seen through the pixel is `X` when `rho_obj <= 1` or
//!   when `X` is within `r + 3 h z / f` of the centre (the low-pass part of a
//!   splat seen at up to ~70 degrees: still on its plane, so planar surfaces
//!   get exact depth at any density); else (low-pass part of a near edge-on
//!   splat) the point of the ray at the centre's depth.
//! - Back-facing splats (`n_c . c >= 0` in camera space) are culled, as are
//!   splats whose centre is not in front of the near plane.
//!
//! Three passes (DESIGN.md section 3):
//! 1. visibility: depth only, the depth of the nearest surface pushed back
//!    by `epsilon * r` along the ray ([`SplatParams::epsilon`]);
//! 2. attributes: additive blending of `w * A` and `w` into RGBA32F targets,
//!    depth-tested (less-or-equal) against pass 1 without writing depth, so
//!    only splats of the visible surface contribute;
//! 3. normalisation: division by the summed weight, in a compute kernel that
//!    either resolves whole images ([`Splatter::read`], for the CLI and
//!    tests) or samples a few pixels ([`Splatter::gather`], for the tracker).
//!    Pixels with no weight are empty (NaN).
//!
//! Depth in the depth buffer is camera-space `z` mapped linearly from
//! `[near, far]` to `[0, 1]`, with `near`/`far` the model's bounding sphere
//! (grown by the largest splat radius and the push-back) at the pose; the
//! depth *attribute* is the true ray-plane intersection `z`, in model units.
//!
//! Attribute targets (see shaders/splat.wgsl):
//! `T0 = (w r, w g, w b, w)`, `T1 = w (z, nx, ny, nz)`,
//! `T2..T4 = w (du_tx, dv_tx, du_ty, dv_ty | tz, rx | ry, rz)`. The motion
//! predictors are computed per fragment from `X` with the formulas of
//! [`Intrinsics::motion_predictors`], in pixels (OpenCV convention).
//!
//! [`cpu`] is the reference implementation of the same maths, used by tests.

pub mod cpu;
pub mod gpu_data;
pub mod viz;

use crate::geometry::{Intrinsics, Pose};
use crate::gpu::{GpuContext, GpuError, GpuTimer, STORAGE_OUT};
use crate::model::PointModel;
use gpu_data::{CameraUniform, ResolveParams, SplatGpu};
use nalgebra::{Matrix2x6, Vector3};

/// Errors of the splatter.
#[derive(Debug, thiserror::Error)]
pub enum SplatError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error("the point model is empty")]
    EmptyModel,
    #[error("the point model has {got} {what} for {expected} points")]
    Inconsistent {
        what: &'static str,
        got: usize,
        expected: usize,
    },
    #[error(
        "point {index} of the model has a non-finite position/normal or a radius that is not > 0"
    )]
    BadPoint { index: usize },
    #[error(
        "the model has {points} points ({bytes} bytes), more than the adapter's storage binding limit of {limit} bytes"
    )]
    TooLarge {
        points: usize,
        bytes: u64,
        limit: u64,
    },
    #[error("the object is entirely behind the camera (its bounding sphere ends at z = {far:.4})")]
    BehindCamera { far: f64 },
    #[error("invalid camera: {0}")]
    Camera(String),
    #[error("invalid pose: {0}")]
    Pose(#[from] crate::geometry::PoseError),
    #[error("splat targets are {got_w}x{got_h} but the camera is {want_w}x{want_h}")]
    SizeMismatch {
        got_w: u32,
        got_h: u32,
        want_w: u32,
        want_h: u32,
    },
    #[error("{0:?} was not rendered into these targets (render with it first)")]
    NotRendered(Attribute),
    #[error("the adapter cannot splat: {0}")]
    Unsupported(String),
}

/// One attribute image that can be read back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Attribute {
    /// Linear RGB, 3 channels.
    Color,
    /// Camera-space z (model units), 1 channel.
    Depth,
    /// Camera-space unit normal, 3 channels.
    Normal,
    /// Motion predictors, 12 channels: du_tx, dv_tx, du_ty, dv_ty, ..., du_rz, dv_rz.
    Motion,
    /// The summed kernel weight (not normalised; 0 where empty), 1 channel.
    Weight,
}

impl Attribute {
    pub fn channels(self) -> usize {
        match self {
            Self::Color | Self::Normal => 3,
            Self::Depth | Self::Weight => 1,
            Self::Motion => 12,
        }
    }

    fn kind(self) -> u32 {
        match self {
            Self::Color => 0,
            Self::Depth => 1,
            Self::Normal => 2,
            Self::Motion => 3,
            Self::Weight => 4,
        }
    }

    /// Which attribute set must have been rendered to read this one.
    fn needs(self) -> Attributes {
        match self {
            Self::Color | Self::Weight => Attributes::COLOR,
            Self::Depth | Self::Normal => Attributes::GEOMETRY,
            Self::Motion => Attributes::MOTION,
        }
    }
}

/// Which attribute groups a render produces, besides colour and weight
/// (always produced). Each group costs render targets: colour 1, geometry
/// (depth + normal) 1, motion 3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Attributes {
    pub geometry: bool,
    pub motion: bool,
}

impl Attributes {
    /// Colour and weight only (novel views).
    pub const COLOR: Self = Self {
        geometry: false,
        motion: false,
    };
    /// Colour, depth and normal.
    pub const GEOMETRY: Self = Self {
        geometry: true,
        motion: false,
    };
    /// Colour and the motion predictors (the paper's single pass: 16 floats).
    pub const MOTION: Self = Self {
        geometry: false,
        motion: true,
    };
    /// Everything: colour, depth, normal, predictors (what gather needs).
    pub const ALL: Self = Self {
        geometry: true,
        motion: true,
    };

    fn contains(self, other: Self) -> bool {
        (self.geometry || !other.geometry) && (self.motion || !other.motion)
    }

    fn index(self) -> usize {
        self.geometry as usize + 2 * self.motion as usize
    }
}

/// Which splatting implementation renders. Only the render-pass path exists
/// now; DESIGN.md section 5 measured a compute path (fixed-point atomics)
/// ~14x faster on an H100, which would be a second variant writing the same
/// accumulation targets, tested against [`cpu`] like this one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Backend {
    #[default]
    RenderPass,
}

/// Tunable constants of the splatting maths (shared with [`cpu`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplatParams {
    /// Visibility push-back along the ray, in splat radii.
    pub epsilon: f32,
    /// Radius of the screen-space low-pass disc, pixels.
    pub lowpass_px: f32,
    /// Colour of models without colours (linear RGB).
    pub default_color: [f32; 3],
    pub backend: Backend,
}

impl Default for SplatParams {
    fn default() -> Self {
        Self {
            epsilon: 1.0,
            lowpass_px: 0.75,
            default_color: [0.75, 0.75, 0.75],
            backend: Backend::RenderPass,
        }
    }
}

/// A bounding sphere of points: the centre of their bounding box and the
/// distance to the farthest point from it.
pub fn bounding_sphere(points: impl Iterator<Item = Vector3<f64>> + Clone) -> (Vector3<f64>, f64) {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for p in points.clone() {
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    let center = (lo + hi) / 2.0;
    let radius = points.map(|p| (p - center).norm()).fold(0.0, f64::max);
    (center, radius)
}

/// The bounding sphere and largest radius of a model: enough to choose the
/// depth range at any pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelBounds {
    pub center: Vector3<f64>,
    pub radius: f64,
    pub max_splat_radius: f64,
}

impl ModelBounds {
    /// Bounds of a checked model (the centre of the bounding box, the
    /// farthest point from it).
    pub fn of(model: &PointModel) -> Self {
        let (center, radius) = bounding_sphere(
            model
                .positions
                .iter()
                .map(|p| Vector3::new(p.x as f64, p.y as f64, p.z as f64)),
        );
        let max_splat_radius = model.radii.iter().fold(0.0f64, |m, &r| m.max(r as f64));
        Self {
            center,
            radius,
            max_splat_radius,
        }
    }

    /// The uniform of a view: near and far planes from the bounding sphere at
    /// the pose (grown by the largest splat and its push-back).
    pub fn view(
        &self,
        cam: &Intrinsics,
        pose: &Pose,
        params: &SplatParams,
    ) -> Result<CameraUniform, SplatError> {
        cam.validate().map_err(SplatError::Camera)?;
        pose.validate()?;
        let zc = pose.transform_point(&self.center).z;
        let rr = self.radius + (2.0 + params.epsilon as f64) * self.max_splat_radius;
        let far = zc + rr;
        if far.is_nan() || far <= 0.0 {
            return Err(SplatError::BehindCamera { far });
        }
        let near = (zc - rr).max(far * 1e-4);
        Ok(CameraUniform::new(
            cam,
            pose,
            near as f32,
            far as f32,
            params.epsilon,
            params.lowpass_px,
        ))
    }
}

/// Checks a model and packs it for the GPU (and the CPU reference).
pub fn pack_model(model: &PointModel, params: &SplatParams) -> Result<Vec<SplatGpu>, SplatError> {
    let n = model.positions.len();
    if n == 0 {
        return Err(SplatError::EmptyModel);
    }
    let check = |what, got| {
        if got == n {
            Ok(())
        } else {
            Err(SplatError::Inconsistent {
                what,
                got,
                expected: n,
            })
        }
    };
    check("normals", model.normals.len())?;
    check("radii", model.radii.len())?;
    if let Some(c) = &model.colors {
        check("colours", c.len())?;
    }
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let (p, nrm, r) = (model.positions[i], model.normals[i], model.radii[i]);
        let len = nrm.length();
        if !(p.is_finite() && nrm.is_finite() && len > 0.0 && r > 0.0 && r.is_finite()) {
            return Err(SplatError::BadPoint { index: i });
        }
        let nrm = nrm / len;
        let c = model.colors.as_ref().map_or(params.default_color, |c| c[i]);
        out.push(SplatGpu {
            pos_radius: [p.x, p.y, p.z, r],
            normal: [nrm.x, nrm.y, nrm.z, 0.0],
            color: [c[0], c[1], c[2], 1.0],
        });
    }
    Ok(out)
}

/// A point model uploaded to the GPU.
pub struct GpuModel {
    buffer: wgpu::Buffer,
    count: u32,
    pub bounds: ModelBounds,
}

impl GpuModel {
    pub fn new(ctx: &GpuContext, model: &PointModel) -> Result<Self, SplatError> {
        Self::with_params(ctx, model, &SplatParams::default())
    }

    pub fn with_params(
        ctx: &GpuContext,
        model: &PointModel,
        params: &SplatParams,
    ) -> Result<Self, SplatError> {
        let packed = pack_model(model, params)?;
        let bytes = (packed.len() * std::mem::size_of::<SplatGpu>()) as u64;
        let limit = ctx
            .limits
            .max_storage_buffer_binding_size
            .min(ctx.limits.max_buffer_size);
        if bytes > limit || packed.len() > u32::MAX as usize {
            return Err(SplatError::TooLarge {
                points: packed.len(),
                bytes,
                limit,
            });
        }
        let buffer = ctx.buffer_init(
            "splats",
            &packed,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        );
        Ok(Self {
            buffer,
            count: packed.len() as u32,
            bounds: ModelBounds::of(model),
        })
    }

    pub fn len(&self) -> usize {
        self.count as usize
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
}

const ACC_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
const TARGETS: usize = 5;

/// The GPU-resident result of a render: accumulation targets (weighted sums)
/// and the visibility depth. Allocate once per image size and reuse.
pub struct SplatTargets {
    width: u32,
    height: u32,
    acc: Vec<wgpu::Texture>,
    acc_views: Vec<wgpu::TextureView>,
    depth_view: wgpu::TextureView,
    uniform: wgpu::Buffer,
    rendered: Option<Attributes>,
}

impl SplatTargets {
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
                        | wgpu::TextureUsages::COPY_SRC,
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
        }
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// The attribute groups of the last render, if any.
    pub fn rendered(&self) -> Option<Attributes> {
        self.rendered
    }

    /// The raw accumulation textures (weighted sums; layout in the module
    /// docs), for passes that consume them on the GPU.
    pub fn accumulators(&self) -> &[wgpu::Texture] {
        &self.acc
    }

    fn check(&self, need: Attributes, what: Attribute) -> Result<(), SplatError> {
        match self.rendered {
            Some(r) if r.contains(need) => Ok(()),
            _ => Err(SplatError::NotRendered(what)),
        }
    }
}

/// A normalised attribute image read back to the host: row-major
/// `height x width x channels`, NaN in every channel of empty pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct SplatImage {
    pub width: u32,
    pub height: u32,
    pub channels: usize,
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

/// How [`Splatter::gather`] samples between pixel centres.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GatherMode {
    /// The pixel whose centre is nearest.
    Nearest,
    /// Bilinear interpolation of the normalised values when all four
    /// surrounding pixels are covered; else the nearest pixel.
    #[default]
    Bilinear,
}

/// Motion predictors and depth at one position, as [`Splatter::gather`]
/// returns them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GatherSample {
    /// du_tx, dv_tx, ..., du_rz, dv_rz (NaN when invalid).
    pub motion: [f32; 12],
    /// Camera-space z (NaN when invalid).
    pub depth: f32,
    /// False where no splat covers the position (or it is outside the image).
    pub valid: bool,
}

/// Floats per gathered point: 12 predictors, depth, validity.
pub const GATHER_STRIDE: usize = 14;

impl GatherSample {
    pub fn from_floats(v: &[f32]) -> Self {
        Self {
            motion: std::array::from_fn(|k| v[k]),
            depth: v[12],
            valid: v[13] > 0.5,
        }
    }

    /// The predictors as the 2x6 matrix `L` of [`Intrinsics::motion_predictors`].
    pub fn matrix(&self) -> Matrix2x6<f64> {
        Matrix2x6::from_fn(|r, c| self.motion[2 * c + r] as f64)
    }
}

/// The GPU splatter: pipelines for the three passes and the gather kernel.
/// Create once per device.
pub struct Splatter {
    params: SplatParams,
    render_layout: wgpu::BindGroupLayout,
    visibility: wgpu::RenderPipeline,
    /// Indexed by [`Attributes::index`].
    attribute: Vec<wgpu::RenderPipeline>,
    resolve_layout: wgpu::BindGroupLayout,
    resolve: wgpu::ComputePipeline,
    gather: wgpu::ComputePipeline,
    /// Bound where an entry point has no points to read.
    dummy_points: wgpu::Buffer,
}

impl Splatter {
    pub fn new(ctx: &GpuContext) -> Result<Self, SplatError> {
        Self::with_params(ctx, SplatParams::default())
    }

    pub fn with_params(ctx: &GpuContext, params: SplatParams) -> Result<Self, SplatError> {
        let need = TARGETS as u32 * 16;
        if ctx.limits.max_color_attachments < TARGETS as u32
            || ctx.limits.max_color_attachment_bytes_per_sample < need
        {
            return Err(SplatError::Unsupported(format!(
                "{} colour attachments of {need} bytes per sample needed, the adapter allows {} and {}",
                TARGETS,
                ctx.limits.max_color_attachments,
                ctx.limits.max_color_attachment_bytes_per_sample
            )));
        }
        let device = &ctx.device;
        let render_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("splat"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::VERTEX,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("splat"),
            bind_group_layouts: &[Some(&render_layout)],
            immediate_size: 0,
        });
        let module = ctx.shader("splat")?;
        let pipeline =
            |label: &str, entry: &str, write: bool, targets: &[Option<wgpu::ColorTargetState>]| {
                ctx.catch(label, || {
                    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                        label: Some(label),
                        layout: Some(&layout),
                        vertex: wgpu::VertexState {
                            module: &module,
                            entry_point: Some("vs_splat"),
                            compilation_options: Default::default(),
                            buffers: &[],
                        },
                        primitive: wgpu::PrimitiveState {
                            topology: wgpu::PrimitiveTopology::TriangleStrip,
                            ..Default::default()
                        },
                        depth_stencil: Some(wgpu::DepthStencilState {
                            format: DEPTH_FORMAT,
                            depth_write_enabled: Some(write),
                            depth_compare: Some(if write {
                                wgpu::CompareFunction::Less
                            } else {
                                wgpu::CompareFunction::LessEqual
                            }),
                            stencil: Default::default(),
                            bias: Default::default(),
                        }),
                        multisample: Default::default(),
                        fragment: Some(wgpu::FragmentState {
                            module: &module,
                            entry_point: Some(entry),
                            compilation_options: Default::default(),
                            targets,
                        }),
                        multiview_mask: None,
                        cache: None,
                    })
                })
            };
        let visibility = pipeline("splat visibility", "fs_visibility", true, &[])?;
        let additive = Some(wgpu::ColorTargetState {
            format: ACC_FORMAT,
            blend: Some(wgpu::BlendState {
                color: wgpu::BlendComponent {
                    src_factor: wgpu::BlendFactor::One,
                    dst_factor: wgpu::BlendFactor::One,
                    operation: wgpu::BlendOperation::Add,
                },
                alpha: wgpu::BlendComponent {
                    src_factor: wgpu::BlendFactor::One,
                    dst_factor: wgpu::BlendFactor::One,
                    operation: wgpu::BlendOperation::Add,
                },
            }),
            write_mask: wgpu::ColorWrites::ALL,
        });
        let mut attribute = Vec::new();
        for index in 0..4 {
            let attrs = Attributes {
                geometry: index & 1 != 0,
                motion: index & 2 != 0,
            };
            let targets = target_slots(attrs).map(|on| if on { additive.clone() } else { None });
            let entry = ["fs_attr_c", "fs_attr_cg", "fs_attr_cm", "fs_attr_cgm"][index];
            attribute.push(pipeline(entry, entry, false, &targets)?);
        }

        let tex_entry = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        let buf_entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let resolve_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("splat resolve"),
            entries: &[
                buf_entry(0, wgpu::BufferBindingType::Uniform),
                tex_entry(1),
                tex_entry(2),
                tex_entry(3),
                tex_entry(4),
                tex_entry(5),
                buf_entry(6, wgpu::BufferBindingType::Storage { read_only: false }),
                buf_entry(7, wgpu::BufferBindingType::Storage { read_only: true }),
            ],
        });
        let resolve_pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("splat resolve"),
            bind_group_layouts: &[Some(&resolve_layout)],
            immediate_size: 0,
        });
        let rmodule = ctx.shader("splat_resolve")?;
        let compute = |entry: &str| {
            ctx.catch(entry, || {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(&resolve_pl),
                    module: &rmodule,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            })
        };
        let resolve = compute("resolve")?;
        let gather = compute("gather")?;
        let dummy_points = ctx.buffer("no points", 16, wgpu::BufferUsages::STORAGE);
        Ok(Self {
            params,
            render_layout,
            visibility,
            attribute,
            resolve_layout,
            resolve,
            gather,
            dummy_points,
        })
    }

    pub fn params(&self) -> &SplatParams {
        &self.params
    }

    /// Splats `model` at `pose` into `targets` (whose size must be the
    /// camera's). Submits the work and returns without waiting.
    pub fn render(
        &self,
        ctx: &GpuContext,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        attrs: Attributes,
        targets: &mut SplatTargets,
    ) -> Result<(), SplatError> {
        self.render_timed(ctx, model, cam, pose, attrs, targets, None)
    }

    /// [`Splatter::render`] with GPU timestamps for the passes "visibility"
    /// and "attributes" (resolved into `timer`; read it after the submit).
    #[allow(clippy::too_many_arguments)]
    pub fn render_timed(
        &self,
        ctx: &GpuContext,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        attrs: Attributes,
        targets: &mut SplatTargets,
        mut timer: Option<&mut GpuTimer>,
    ) -> Result<(), SplatError> {
        if targets.width != cam.width || targets.height != cam.height {
            return Err(SplatError::SizeMismatch {
                got_w: targets.width,
                got_h: targets.height,
                want_w: cam.width,
                want_h: cam.height,
            });
        }
        let uniform = model.bounds.view(cam, pose, &self.params)?;
        ctx.queue
            .write_buffer(&targets.uniform, 0, bytemuck::bytes_of(&uniform));
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("splat"),
            layout: &self.render_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: targets.uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: model.buffer.as_entire_binding(),
                },
            ],
        });
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("splat visibility"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &targets.depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: timer
                    .as_deref_mut()
                    .and_then(|t| t.render_pass("visibility")),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.visibility);
            pass.set_bind_group(0, &bind, &[]);
            pass.draw(0..4, 0..model.count);
        }
        {
            let slots = target_slots(attrs);
            let colors: Vec<Option<wgpu::RenderPassColorAttachment>> = slots
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
                .collect();
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("splat attributes"),
                color_attachments: &colors,
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &targets.depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Load,
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: timer
                    .as_deref_mut()
                    .and_then(|t| t.render_pass("attributes")),
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.attribute[attrs.index()]);
            pass.set_bind_group(0, &bind, &[]);
            pass.draw(0..4, 0..model.count);
        }
        if let Some(t) = timer {
            t.resolve(&mut enc);
        }
        ctx.queue.submit([enc.finish()]);
        targets.rendered = Some(attrs);
        Ok(())
    }

    fn resolve_bind(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        params: ResolveParams,
        out: &wgpu::Buffer,
        points: Option<&wgpu::Buffer>,
    ) -> wgpu::BindGroup {
        let pbuf = ctx.buffer_init(
            "splat resolve params",
            &[params],
            wgpu::BufferUsages::UNIFORM,
        );
        let mut entries = vec![wgpu::BindGroupEntry {
            binding: 0,
            resource: pbuf.as_entire_binding(),
        }];
        for (i, v) in targets.acc_views.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 1 + i as u32,
                resource: wgpu::BindingResource::TextureView(v),
            });
        }
        entries.push(wgpu::BindGroupEntry {
            binding: 6,
            resource: out.as_entire_binding(),
        });
        entries.push(wgpu::BindGroupEntry {
            binding: 7,
            resource: points.unwrap_or(&self.dummy_points).as_entire_binding(),
        });
        ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("splat resolve"),
            layout: &self.resolve_layout,
            entries: &entries,
        })
    }

    /// Normalises one attribute of the last render on the GPU and reads the
    /// whole image back (for the CLI and tests; the tracker uses
    /// [`Splatter::gather`]).
    pub fn read(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        attribute: Attribute,
    ) -> Result<SplatImage, SplatError> {
        targets.check(attribute.needs(), attribute)?;
        let (w, h) = (targets.width, targets.height);
        let n = w as usize * h as usize * attribute.channels();
        let out = ctx.buffer("splat image", (n * 4) as u64, STORAGE_OUT);
        let bind = self.resolve_bind(
            ctx,
            targets,
            ResolveParams {
                width: w,
                height: h,
                kind: attribute.kind(),
                mode: 0,
            },
            &out,
            None,
        );
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.resolve);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
        }
        ctx.queue.submit([enc.finish()]);
        let data = ctx.read_buffer::<f32>(&out, n)?;
        Ok(SplatImage {
            width: w,
            height: h,
            channels: attribute.channels(),
            data,
        })
    }

    /// Motion predictors, depth and validity at `points` (OpenCV pixel
    /// coordinates) from the last render, which must include geometry and
    /// motion ([`Attributes::ALL`]). Reads back 14 floats per point only.
    pub fn gather(
        &self,
        ctx: &GpuContext,
        targets: &SplatTargets,
        points: &[[f32; 2]],
        mode: GatherMode,
    ) -> Result<Vec<GatherSample>, SplatError> {
        targets.check(Attributes::ALL, Attribute::Motion)?;
        if points.is_empty() {
            return Ok(Vec::new());
        }
        let pbuf = ctx.buffer_init("gather points", points, wgpu::BufferUsages::STORAGE);
        let n = points.len() * GATHER_STRIDE;
        let out = ctx.buffer("gather out", (n * 4) as u64, STORAGE_OUT);
        let bind = self.resolve_bind(
            ctx,
            targets,
            ResolveParams {
                width: targets.width,
                height: targets.height,
                kind: points.len() as u32,
                mode: match mode {
                    GatherMode::Nearest => 0,
                    GatherMode::Bilinear => 1,
                },
            },
            &out,
            Some(&pbuf),
        );
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.gather);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((points.len() as u32).div_ceil(64), 1, 1);
        }
        ctx.queue.submit([enc.finish()]);
        let data = ctx.read_buffer::<f32>(&out, n)?;
        Ok(data
            .chunks(GATHER_STRIDE)
            .map(GatherSample::from_floats)
            .collect())
    }

    /// One-shot convenience: upload, render and read one attribute.
    pub fn render_image(
        &self,
        ctx: &GpuContext,
        model: &GpuModel,
        cam: &Intrinsics,
        pose: &Pose,
        attribute: Attribute,
    ) -> Result<SplatImage, SplatError> {
        let mut targets = SplatTargets::new(ctx, cam.width, cam.height);
        self.render(ctx, model, cam, pose, attribute.needs(), &mut targets)?;
        self.read(ctx, &targets, attribute)
    }
}

/// Which of the five accumulation targets a render writes.
fn target_slots(attrs: Attributes) -> [bool; TARGETS] {
    [
        true,
        attrs.geometry,
        attrs.motion,
        attrs.motion,
        attrs.motion,
    ]
}
