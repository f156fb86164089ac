//! Triangle meshes and an ordinary wgpu triangle rasteriser (colour, depth,
//! normal), independent of the splatter: tests compare splatted point models
//! with the mesh they were sampled from, and synthetic sequences can be
//! rendered without the renderer under test (DESIGN.md section 7).
//!
//! How it works: a standard vertex/fragment pipeline with a depth buffer;
//! the projection maps OpenCV pixels to clip space with the +0.5 pixel-centre
//! shift, and the camera-space depth is interpolated perspective-correctly
//! (exact for planar triangles).

use super::SplatError;
use super::gpu_data::CameraUniform;
use crate::geometry::{Intrinsics, Pose};
use crate::gpu::GpuContext;
use crate::model::{AttributeSource, ModelError, PointModel};
use glam::Vec3;
use nalgebra::Vector3;

/// A vertex as the mesh pipeline reads it. Keep in sync with `VertexIn`
/// in shaders/mesh.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct MeshVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub color: [f32; 3],
}
const _: () = assert!(std::mem::size_of::<MeshVertex>() == 36);

/// An indexed triangle mesh with per-vertex normals and linear RGB colours.
#[derive(Debug, Clone, Default)]
pub struct TriangleMesh {
    pub vertices: Vec<MeshVertex>,
    /// Counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleMesh {
    fn push(&mut self, p: Vec3, n: Vec3, color: [f32; 3]) -> u32 {
        self.vertices.push(MeshVertex {
            position: p.into(),
            normal: n.into(),
            color,
        });
        self.vertices.len() as u32 - 1
    }

    /// A UV sphere with `stacks x slices` quads (split into triangles),
    /// smooth normals, colours from [`super::shapes::color_field`].
    pub fn uv_sphere(center: Vec3, radius: f32, stacks: u32, slices: u32) -> Self {
        let mut m = Self::default();
        for i in 0..=stacks {
            let theta = std::f32::consts::PI * i as f32 / stacks as f32;
            for j in 0..=slices {
                let phi = std::f32::consts::TAU * j as f32 / slices as f32;
                let n = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                let p = center + n * radius;
                m.push(p, n, super::shapes::color_field(p, 2.0 * radius));
            }
        }
        let row = slices + 1;
        for i in 0..stacks {
            for j in 0..slices {
                let (a, b, c, d) = (
                    i * row + j,
                    i * row + j + 1,
                    (i + 1) * row + j,
                    (i + 1) * row + j + 1,
                );
                if i != 0 {
                    m.triangles.push([a, c, b]);
                }
                if i + 1 != stacks {
                    m.triangles.push([b, c, d]);
                }
            }
        }
        m
    }

    /// An axis-aligned box with flat faces, each face split into `k x k`
    /// quads (fine tessellation lets per-vertex colours vary).
    pub fn cuboid(center: Vec3, half: Vec3, k: u32) -> Self {
        let mut m = Self::default();
        for axis in 0..3 {
            let (ua, va) = ((axis + 1) % 3, (axis + 2) % 3);
            for sign in [-1.0f32, 1.0] {
                let mut n = Vec3::ZERO;
                n[axis] = sign;
                let base = m.vertices.len() as u32;
                for i in 0..=k {
                    for j in 0..=k {
                        let mut p = Vec3::ZERO;
                        p[axis] = sign * half[axis];
                        p[ua] = half[ua] * (2.0 * i as f32 / k as f32 - 1.0);
                        p[va] = half[va] * (2.0 * j as f32 / k as f32 - 1.0);
                        let p = center + p;
                        m.push(
                            p,
                            n,
                            super::shapes::color_field(p, 2.0 * half.max_element()),
                        );
                    }
                }
                for i in 0..k {
                    for j in 0..k {
                        let a = base + i * (k + 1) + j;
                        let (b, c, d) = (a + k + 1, a + 1, a + k + 2);
                        // u x v = +axis: (a, b, d) is counter-clockwise for sign +.
                        if sign > 0.0 {
                            m.triangles.push([a, b, d]);
                            m.triangles.push([a, d, c]);
                        } else {
                            m.triangles.push([a, d, b]);
                            m.triangles.push([a, c, d]);
                        }
                    }
                }
            }
        }
        m
    }

    /// A torus around the z axis (major radius `big`, minor `small`).
    pub fn torus(center: Vec3, big: f32, small: f32, rings: u32, sides: u32) -> Self {
        let mut m = Self::default();
        for i in 0..=rings {
            let a = std::f32::consts::TAU * i as f32 / rings as f32;
            let dir = Vec3::new(a.cos(), a.sin(), 0.0);
            for j in 0..=sides {
                let b = std::f32::consts::TAU * j as f32 / sides as f32;
                let n = dir * b.cos() + Vec3::Z * b.sin();
                let p = center + dir * big + n * small;
                m.push(p, n, super::shapes::color_field(p, big));
            }
        }
        let row = sides + 1;
        for i in 0..rings {
            for j in 0..sides {
                let (a, b, c, d) = (
                    i * row + j,
                    i * row + j + 1,
                    (i + 1) * row + j,
                    (i + 1) * row + j + 1,
                );
                m.triangles.push([a, c, b]);
                m.triangles.push([b, c, d]);
            }
        }
        m
    }

    fn corners(&self, t: &[u32; 3]) -> [Vec3; 3] {
        t.map(|i| Vec3::from(self.vertices[i as usize].position))
    }

    /// Total surface area.
    pub fn area(&self) -> f32 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = self.corners(t);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// Samples `n` points evenly over the surface with the model crate's
    /// mesh sampler (as a scanner would: positions on the triangles, their
    /// geometric normals, interpolated colours), with splat radius
    /// `radius_factor * sqrt(area / n)` (about 2 covers the surface).
    pub fn sample_points(
        &self,
        n: usize,
        radius_factor: f32,
        seed: u64,
    ) -> Result<PointModel, ModelError> {
        let mesh = crate::model::TriangleMesh {
            vertices: self
                .vertices
                .iter()
                .map(|v| Vec3::from(v.position))
                .collect(),
            triangles: self.triangles.clone(),
            colors: Some(self.vertices.iter().map(|v| v.color).collect()),
            path: None,
        };
        let mut model = mesh.sample(n, seed)?;
        let r = radius_factor * (self.area() / model.len() as f32).sqrt();
        model.radii.fill(r);
        model.provenance.radii = AttributeSource::Estimated;
        Ok(model)
    }

    /// Bounding sphere (box centre, farthest vertex).
    fn bounds(&self) -> (Vector3<f64>, f64) {
        super::bounding_sphere(self.vertices.iter().map(|v| {
            Vector3::new(
                v.position[0] as f64,
                v.position[1] as f64,
                v.position[2] as f64,
            )
        }))
    }
}

/// A mesh on the GPU.
pub struct GpuMesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    count: u32,
    center: Vector3<f64>,
    radius: f64,
}

impl GpuMesh {
    pub fn new(ctx: &GpuContext, mesh: &TriangleMesh) -> Result<Self, SplatError> {
        if mesh.triangles.is_empty() {
            return Err(SplatError::EmptyModel);
        }
        let nv = mesh.vertices.len() as u32;
        if mesh.triangles.iter().flatten().any(|&i| i >= nv) {
            return Err(SplatError::Inconsistent {
                what: "triangle vertex indices in range",
                got: 0,
                expected: mesh.triangles.len() * 3,
            });
        }
        let (center, radius) = mesh.bounds();
        Ok(Self {
            vertices: ctx.buffer_init("mesh vertices", &mesh.vertices, wgpu::BufferUsages::VERTEX),
            indices: ctx.buffer_init("mesh indices", &mesh.triangles, wgpu::BufferUsages::INDEX),
            count: mesh.triangles.len() as u32 * 3,
            center,
            radius,
        })
    }
}

/// Colour, depth and normal images of a mesh render; NaN where empty.
#[derive(Debug, Clone)]
pub struct MeshImage {
    pub width: u32,
    pub height: u32,
    /// Linear RGB.
    pub color: Vec<[f32; 3]>,
    /// Camera-space z.
    pub depth: Vec<f32>,
    /// Camera-space unit normal.
    pub normal: Vec<[f32; 3]>,
}

impl MeshImage {
    pub fn is_valid(&self, x: u32, y: u32) -> bool {
        !self.depth[(y * self.width + x) as usize].is_nan()
    }
}

/// The triangle rasteriser.
pub struct MeshRenderer {
    pipeline: wgpu::RenderPipeline,
}

const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

impl MeshRenderer {
    pub fn new(ctx: &GpuContext) -> Result<Self, SplatError> {
        let module = ctx.shader("mesh")?;
        let attrs = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x3];
        let target = Some(wgpu::ColorTargetState {
            format: COLOR_FORMAT,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        });
        let pipeline = ctx.catch("mesh pipeline", || {
            ctx.device
                .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some("mesh"),
                    layout: None,
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some("vs_mesh"),
                        compilation_options: Default::default(),
                        buffers: &[Some(wgpu::VertexBufferLayout {
                            array_stride: std::mem::size_of::<MeshVertex>() as u64,
                            step_mode: wgpu::VertexStepMode::Vertex,
                            attributes: &attrs,
                        })],
                    },
                    primitive: wgpu::PrimitiveState::default(),
                    depth_stencil: Some(wgpu::DepthStencilState {
                        format: wgpu::TextureFormat::Depth32Float,
                        depth_write_enabled: Some(true),
                        depth_compare: Some(wgpu::CompareFunction::Less),
                        stencil: Default::default(),
                        bias: Default::default(),
                    }),
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some("fs_mesh"),
                        compilation_options: Default::default(),
                        targets: &[target.clone(), target],
                    }),
                    multiview_mask: None,
                    cache: None,
                })
        })?;
        Ok(Self { pipeline })
    }

    /// Renders `mesh` at `pose` and reads colour, depth and normal back.
    pub fn render(
        &self,
        ctx: &GpuContext,
        mesh: &GpuMesh,
        cam: &Intrinsics,
        pose: &Pose,
    ) -> Result<MeshImage, SplatError> {
        cam.validate().map_err(SplatError::Camera)?;
        pose.validate()?;
        let zc = pose.transform_point(&mesh.center).z;
        let far = zc + mesh.radius * 1.01;
        if far.is_nan() || far <= 0.0 {
            return Err(SplatError::BehindCamera { far });
        }
        let near = (zc - mesh.radius * 1.01).max(far * 1e-4);
        let uniform = CameraUniform::new(cam, pose, near as f32, far as f32, 0.0, 0.0);
        let ubuf = ctx.buffer_init("mesh camera", &[uniform], wgpu::BufferUsages::UNIFORM);
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("mesh"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: ubuf.as_entire_binding(),
            }],
        });
        let size = wgpu::Extent3d {
            width: cam.width,
            height: cam.height,
            depth_or_array_layers: 1,
        };
        let tex = |format, usage| {
            ctx.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("mesh target"),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let color = tex(COLOR_FORMAT, usage);
        let geom = tex(COLOR_FORMAT, usage);
        let depth = tex(
            wgpu::TextureFormat::Depth32Float,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let (cv, gv, dv) = (
            color.create_view(&Default::default()),
            geom.create_view(&Default::default()),
            depth.create_view(&Default::default()),
        );
        let attach = |view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })
        };
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("mesh"),
                color_attachments: &[attach(&cv), attach(&gv)],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &dv,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.set_vertex_buffer(0, mesh.vertices.slice(..));
            pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..mesh.count, 0, 0..1);
        }
        ctx.queue.submit([enc.finish()]);
        let c: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&ctx.read_texture(&color, 16)?);
        let g: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&ctx.read_texture(&geom, 16)?);
        let mut out = MeshImage {
            width: cam.width,
            height: cam.height,
            color: Vec::with_capacity(c.len()),
            depth: Vec::with_capacity(c.len()),
            normal: Vec::with_capacity(c.len()),
        };
        for (c, g) in c.iter().zip(&g) {
            if c[3] > 0.5 {
                out.color.push([c[0], c[1], c[2]]);
                out.depth.push(g[0]);
                out.normal.push([g[1], g[2], g[3]]);
            } else {
                out.color.push([f32::NAN; 3]);
                out.depth.push(f32::NAN);
                out.normal.push([f32::NAN; 3]);
            }
        }
        Ok(out)
    }
}
