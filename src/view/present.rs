//! Drawing the live view's picture onto the display (an OS window's
//! surface) with the tracker's wgpu device: the composed RGBA picture is
//! uploaded as a texture and drawn by `shaders/present.wgsl`, scaled to
//! fit the target and letterboxed ([`letterbox`]); [`present_cpu`] is its
//! CPU reference.

use crate::gpu::{GpuContext, GpuError, buffer_entry, texture_entry};
use image::RgbaImage;

/// The presentation's shader (the render pass onto the window).
pub(crate) static SHADER: crate::shaders::Shader = crate::shaders::Shader {
    name: "present",
    parts: &[crate::wgsl_file!("present.wgsl")],
    constants: &[],
};

crate::wgsl_struct! {
    /// The uniform of `present.wgsl` (keep the field order in sync with
    /// the WGSL).
    #[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
    pub struct PresentParams {
        /// The picture's rectangle in the target, pixels: x0, y0, x1, y1.
        pub rect: [f32; 4],
        /// The colour around it (RGBA, 0-1).
        pub background: [f32; 4],
        /// The picture's size, pixels.
        pub size: [u32; 2],
        /// Padding to a 16-byte multiple.
        pub _pad0: u32,
        /// Padding to a 16-byte multiple.
        pub _pad1: u32,
    }
}

/// The colour around the picture when the display's shape differs.
pub const BACKGROUND: [u8; 4] = [0, 0, 0, 255];

/// The rectangle (x0, y0, x1, y1, whole pixels) that a `src` picture
/// (width, height) fills in a `dst` target: as large as fits, aspect kept,
/// centred.
pub fn letterbox(src: (u32, u32), dst: (u32, u32)) -> [u32; 4] {
    let (sw, sh) = (src.0.max(1) as f64, src.1.max(1) as f64);
    let (dw, dh) = (dst.0, dst.1);
    let s = (dw as f64 / sw).min(dh as f64 / sh);
    let w = ((sw * s).round() as u32).clamp(1, dw.max(1));
    let h = ((sh * s).round() as u32).clamp(1, dh.max(1));
    let (x0, y0) = ((dw.saturating_sub(w)) / 2, (dh.saturating_sub(h)) / 2);
    [x0, y0, x0 + w, y0 + h]
}

/// The uniform for drawing `src` into `dst`.
pub fn params(src: (u32, u32), dst: (u32, u32)) -> PresentParams {
    PresentParams {
        rect: letterbox(src, dst).map(|v| v as f32),
        background: BACKGROUND.map(|v| v as f32 / 255.0),
        size: [src.0, src.1],
        _pad0: 0,
        _pad1: 0,
    }
}

/// CPU reference of `present.wgsl`: `picture` drawn into a `dst` target,
/// the same f32 arithmetic per pixel (bilinear between the four nearest
/// pixels, edges clamped), rounded to 8 bits.
pub fn present_cpu(picture: &RgbaImage, dst: (u32, u32)) -> RgbaImage {
    let src = picture.dimensions();
    let p = params(src, dst);
    let [rx0, ry0, rx1, ry1] = p.rect;
    let (sw, sh) = (src.0 as f32, src.1 as f32);
    let texel = |x: i64, y: i64| -> [f32; 4] {
        let x = x.clamp(0, src.0 as i64 - 1) as u32;
        let y = y.clamp(0, src.1 as i64 - 1) as u32;
        picture.get_pixel(x, y).0.map(|v| v as f32 / 255.0)
    };
    let mix = |a: [f32; 4], b: [f32; 4], t: f32| -> [f32; 4] {
        std::array::from_fn(|k| a[k] * (1.0 - t) + b[k] * t)
    };
    RgbaImage::from_fn(dst.0, dst.1, |x, y| {
        let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
        if px < rx0 || py < ry0 || px >= rx1 || py >= ry1 {
            return image::Rgba(BACKGROUND);
        }
        let u = (px - rx0) * sw / (rx1 - rx0) - 0.5;
        let v = (py - ry0) * sh / (ry1 - ry0) - 0.5;
        let (x0, y0) = (u.floor(), v.floor());
        let (fx, fy) = (u - x0, v - y0);
        let (ix, iy) = (x0 as i64, y0 as i64);
        let top = mix(texel(ix, iy), texel(ix + 1, iy), fx);
        let bottom = mix(texel(ix, iy + 1), texel(ix + 1, iy + 1), fx);
        image::Rgba(mix(top, bottom, fy).map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8))
    })
}

/// The blit of `present.wgsl` for one target format, with the picture's
/// texture kept between frames (reallocated only when its size changes).
pub struct Presenter {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    picture: Option<wgpu::Texture>,
    format: wgpu::TextureFormat,
}

impl Presenter {
    /// A presenter drawing into targets of `format` (which should not be
    /// an sRGB format: the picture's bytes are already sRGB-encoded and go
    /// through unchanged; draw into a non-sRGB view of an sRGB surface).
    pub fn new(ctx: &GpuContext, format: wgpu::TextureFormat) -> Result<Self, GpuError> {
        let layout = ctx.bind_group_layout(
            "present",
            &[
                buffer_entry(
                    0,
                    wgpu::ShaderStages::FRAGMENT,
                    wgpu::BufferBindingType::Uniform,
                ),
                texture_entry(1, wgpu::ShaderStages::FRAGMENT),
            ],
        );
        let module = ctx.shader(&SHADER)?;
        let pipeline = ctx.catch("present pipeline", || {
            let pl = ctx
                .device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("present"),
                    bind_group_layouts: &[Some(&layout)],
                    immediate_size: 0,
                });
            ctx.device
                .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some("present"),
                    layout: Some(&pl),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some("vs_present"),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    primitive: wgpu::PrimitiveState::default(),
                    depth_stencil: None,
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some("fs_present"),
                        compilation_options: Default::default(),
                        targets: &[Some(wgpu::ColorTargetState {
                            format,
                            blend: None,
                            write_mask: wgpu::ColorWrites::ALL,
                        })],
                    }),
                    multiview_mask: None,
                    cache: None,
                })
        })?;
        let params = ctx.buffer(
            "present params",
            std::mem::size_of::<PresentParams>() as u64,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        Ok(Self {
            pipeline,
            layout,
            params,
            picture: None,
            format,
        })
    }

    /// The target format this presenter draws into.
    pub fn format(&self) -> wgpu::TextureFormat {
        self.format
    }

    /// Uploads `picture` and records its drawing into `target` (of size
    /// `dst`) into `enc`; the caller submits.
    pub fn draw(
        &mut self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        picture: &RgbaImage,
        target: &wgpu::TextureView,
        dst: (u32, u32),
    ) -> Result<(), GpuError> {
        let (w, h) = picture.dimensions();
        ctx.check_texture_size("the live view's picture", w, h)?;
        let stale = self
            .picture
            .as_ref()
            .is_none_or(|t| (t.width(), t.height()) != (w, h));
        if stale {
            self.picture = Some(ctx.catch("present texture", || {
                ctx.device.create_texture(&wgpu::TextureDescriptor {
                    label: Some("live view picture"),
                    size: wgpu::Extent3d {
                        width: w,
                        height: h,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: wgpu::TextureFormat::Rgba8Unorm,
                    usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                    view_formats: &[],
                })
            })?);
        }
        let texture = self.picture.as_ref().expect("created above");
        ctx.queue.write_texture(
            texture.as_image_copy(),
            picture.as_raw(),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * w),
                rows_per_image: Some(h),
            },
            texture.size(),
        );
        ctx.write_buffer(&self.params, 0, bytemuck::bytes_of(&params((w, h), dst)));
        let view = texture.create_view(&Default::default());
        let bind = ctx.catch("present bind group", || {
            ctx.bind_group(&wgpu::BindGroupDescriptor {
                label: Some("present"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.params.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(&view),
                    },
                ],
            })
        })?;
        ctx.count_passes(1);
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("present"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.draw(0..3, 0..1);
        Ok(())
    }

    /// `picture` drawn into an offscreen `dst` target of this presenter's
    /// format and read back (tests, and a screenshot of what the display
    /// shows without an OS window). The format must be `Rgba8Unorm`.
    pub fn render_offscreen(
        &mut self,
        ctx: &GpuContext,
        picture: &RgbaImage,
        dst: (u32, u32),
    ) -> Result<RgbaImage, GpuError> {
        if self.format != wgpu::TextureFormat::Rgba8Unorm {
            return Err(GpuError::Readback(format!(
                "offscreen presentation reads Rgba8Unorm targets, not {:?}",
                self.format
            )));
        }
        ctx.check_texture_size("the live view's target", dst.0, dst.1)?;
        let target = ctx.catch("present target", || {
            ctx.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("present target"),
                size: wgpu::Extent3d {
                    width: dst.0,
                    height: dst.1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: self.format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        })?;
        let view = target.create_view(&Default::default());
        let mut enc = ctx.encoder();
        self.draw(ctx, &mut enc, picture, &view, dst)?;
        ctx.submit(enc);
        let bytes = ctx.read_texture(&target, 4)?;
        ctx.check()?;
        RgbaImage::from_raw(dst.0, dst.1, bytes)
            .ok_or_else(|| GpuError::Readback("short texture readback".into()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn letterbox_keeps_the_aspect_and_centres() {
        assert_eq!(letterbox((640, 480), (640, 480)), [0, 0, 640, 480]);
        assert_eq!(letterbox((640, 480), (1280, 960)), [0, 0, 1280, 960]);
        // Wider target: bars left and right.
        assert_eq!(letterbox((640, 480), (1000, 480)), [180, 0, 820, 480]);
        // Taller target: bars above and below.
        assert_eq!(letterbox((640, 480), (320, 400)), [0, 80, 320, 320]);
        // Degenerate sizes stay inside the target and non-empty.
        assert_eq!(letterbox((0, 0), (10, 10)), [0, 0, 10, 10]);
        assert_eq!(letterbox((10, 10), (1, 1)), [0, 0, 1, 1]);
    }

    #[test]
    fn the_cpu_reference_copies_at_the_same_size_and_fills_the_bars() {
        let pic = RgbaImage::from_fn(7, 5, |x, y| {
            image::Rgba([x as u8 * 30, y as u8 * 50, 9, 255])
        });
        assert_eq!(present_cpu(&pic, (7, 5)), pic);
        let wide = present_cpu(&pic, (21, 5));
        // Bars of 7 pixels either side, the picture in the middle.
        assert_eq!(wide.get_pixel(0, 2).0, BACKGROUND);
        assert_eq!(wide.get_pixel(20, 2).0, BACKGROUND);
        assert_eq!(*wide.get_pixel(7, 0), *pic.get_pixel(0, 0));
        // Twice as large: the centre of target pixel 5 (5.5) maps to 2.25,
        // a quarter of the way from source pixel 2 to pixel 3.
        let big = present_cpu(&pic, (14, 10));
        let (a, b) = (
            pic.get_pixel(2, 0).0[0] as f32,
            pic.get_pixel(3, 0).0[0] as f32,
        );
        assert_eq!(
            big.get_pixel(5, 0).0[0],
            (0.75 * a + 0.25 * b).round() as u8
        );
    }
}
