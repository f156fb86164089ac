//! Images that stay on the GPU between the stages of a frame (issue 13):
//! a frame's grey levels uploaded once and read by every NCC matching of
//! the frame (IT, KF) and by the next frame's IT, and a novel view packed
//! by Harris on the GPU ([`super::Harris::resident_view`]), matched
//! without coming back to the host ([`super::NccMatcher::match_resident`]).

use super::FeatureError;
use super::gpu_data::{Pixel, pack_with_holes_into};
use super::image::GreyImage;
use crate::gpu::{
    GpuContext, GrowBuffer, STORAGE_IN, WORKGROUP_2D, compute_entry, storage, workgroups,
};
use bytemuck::{Pod, Zeroable};

/// An image on the GPU: `width x height` packed pixels, row-major (8 bytes
/// each: the grey value and flags, pinholes flagged, as the host's
/// packing for NCC packs them).
#[derive(Clone, Copy)]
pub struct ResidentImage<'a> {
    /// The pixels (at least `width x height` of them).
    pub pixels: &'a wgpu::Buffer,
    /// The image's width, pixels.
    pub width: usize,
    /// The image's height, pixels.
    pub height: usize,
}

impl ResidentImage<'_> {
    /// Checks that `rows` lie in the image and the buffer holds them.
    pub(crate) fn check(&self, rows: &std::ops::Range<usize>) -> Result<(), FeatureError> {
        let px = std::mem::size_of::<Pixel>() as u64;
        let need = (self.width * self.height) as u64 * px;
        if need > self.pixels.size() {
            return Err(FeatureError::ImageSize {
                width: self.width,
                height: self.height,
                len: (self.pixels.size() / px) as usize,
            });
        }
        if rows.end > self.height || rows.start > rows.end {
            return Err(FeatureError::Config(format!(
                "rows {}..{} of an image of {} rows",
                rows.start, rows.end, self.height
            )));
        }
        Ok(())
    }
}

/// A grey image kept on the GPU across calls (a grow-only buffer): the
/// tracker uploads each frame once into one of two and keeps the previous
/// frame's for IT.
pub struct GpuGrey {
    buf: GrowBuffer,
    width: usize,
    height: usize,
    /// The packed pixels on the host, kept between uploads.
    packed: Vec<Pixel>,
}

impl Default for GpuGrey {
    fn default() -> Self {
        Self::new()
    }
}

impl GpuGrey {
    /// An empty image (no buffer yet).
    pub fn new() -> Self {
        Self {
            buf: GrowBuffer::new("resident grey", STORAGE_IN),
            width: 0,
            height: 0,
            packed: Vec::new(),
        }
    }

    /// Uploads `img` (packed as NCC packs a host image: NaN invalid,
    /// pinholes flagged), growing the buffer if needed (on the GPU and on
    /// the host: once grown, an upload allocates nothing).
    pub fn upload(&mut self, ctx: &GpuContext, img: &GreyImage) {
        let px = std::mem::size_of::<Pixel>();
        self.buf.ensure(ctx, (img.data.len().max(1) * px) as u64);
        pack_with_holes_into(img, None, false, &mut self.packed);
        ctx.queue
            .write_buffer(self.buf.get(), 0, bytemuck::cast_slice(&self.packed));
        (self.width, self.height) = (img.width, img.height);
    }

    /// The image as the matcher reads it; `None` before the first upload.
    pub fn image(&self) -> Option<ResidentImage<'_>> {
        (self.width > 0 && self.height > 0).then(|| ResidentImage {
            pixels: self.buf.get(),
            width: self.width,
            height: self.height,
        })
    }
}

crate::wgsl_struct! {
    /// Keep in sync with `FrameParams` in shaders/frame.wgsl.
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    pub(crate) struct FrameParams {
        width: u32,
        height: u32,
        _pad0: u32,
        _pad1: u32,
    }
}

crate::wgsl_struct! {
    /// Keep in sync with `WindowParams` in shaders/frame.wgsl.
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    pub(crate) struct WindowParams {
        frame_width: u32,
        frame_height: u32,
        x0: u32,
        y0: u32,
        width: u32,
        height: u32,
        ax0: u32,
        ay0: u32,
        ax1: u32,
        ay1: u32,
        pad0: u32,
        pad1: u32,
    }
}

/// A camera frame's way in (issue 13): its 8-bit RGB bytes uploaded as
/// they are (3 bytes a pixel, against 8 for packed grey) and turned into
/// a [`GpuGrey`] on the GPU (`shaders/frame.wgsl`), so that the host
/// neither converts nor packs the frame for the resident matching. The
/// pixels are bit for bit those of [`GpuGrey::upload`] of
/// [`GreyImage::from_rgb8`]: the shader sums the same tabulated channel
/// terms in the same order.
pub struct FrameIntake {
    ctx: GpuContext,
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    terms: wgpu::Buffer,
    rgb: GrowBuffer,
    /// Bind groups by output buffer (the tracker alternates two),
    /// dropped when the input buffer grows.
    binds: Vec<(wgpu::Buffer, wgpu::BindGroup)>,
    window_layout: wgpu::BindGroupLayout,
    window_pipeline: wgpu::ComputePipeline,
    window_params: wgpu::Buffer,
    /// Bind groups of [`FrameIntake::pack_window`] by (frame, output).
    window_binds: Vec<((wgpu::Buffer, wgpu::Buffer), wgpu::BindGroup)>,
    values_layout: wgpu::BindGroupLayout,
    values_pipeline: wgpu::ComputePipeline,
    values_params: wgpu::Buffer,
    /// Bind groups of [`FrameIntake::window_values`] by (frame, output).
    values_binds: Vec<((wgpu::Buffer, wgpu::Buffer), wgpu::BindGroup)>,
}

/// Bind groups kept by [`FrameIntake::pack_window`] (frames alternate
/// between two images; Harris's input may grow).
const KEPT_WINDOW_BINDS: usize = 4;

impl FrameIntake {
    /// The kernel (compiled once) and its channel table; the input buffer
    /// is made on first use.
    pub fn new(ctx: &GpuContext) -> Result<Self, FeatureError> {
        let layout = ctx.bind_group_layout(
            "frame",
            &[
                compute_entry(0, wgpu::BufferBindingType::Uniform),
                compute_entry(1, storage(true)),
                compute_entry(2, storage(true)),
                compute_entry(3, storage(false)),
            ],
        );
        let pipeline = ctx
            .compute_pipelines("frame", &layout, &["grey_pack"])?
            .pop()
            .expect("one pipeline");
        let terms: Vec<f32> = super::image::LUMA_TERMS.iter().flatten().copied().collect();
        let window_layout = ctx.bind_group_layout(
            "frame window",
            &[
                compute_entry(3, storage(false)),
                compute_entry(4, storage(false)),
                compute_entry(5, wgpu::BufferBindingType::Uniform),
            ],
        );
        let window_pipeline = ctx
            .compute_pipelines("frame", &window_layout, &["window_pack"])?
            .pop()
            .expect("one pipeline");
        let values_layout = ctx.bind_group_layout(
            "frame values",
            &[
                compute_entry(3, storage(false)),
                compute_entry(5, wgpu::BufferBindingType::Uniform),
                compute_entry(6, storage(false)),
            ],
        );
        let values_pipeline = ctx
            .compute_pipelines("frame", &values_layout, &["window_values"])?
            .pop()
            .expect("one pipeline");
        let uniform = |label| {
            ctx.buffer(
                label,
                std::mem::size_of::<WindowParams>() as u64,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            )
        };
        Ok(Self {
            ctx: ctx.clone(),
            layout,
            pipeline,
            params: ctx.buffer(
                "frame params",
                std::mem::size_of::<FrameParams>() as u64,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            ),
            terms: ctx.buffer_init("frame luma terms", &terms, STORAGE_IN),
            rgb: GrowBuffer::new("frame rgb", STORAGE_IN),
            binds: Vec::new(),
            window_layout,
            window_pipeline,
            window_params: uniform("frame window params"),
            window_binds: Vec::new(),
            values_layout,
            values_pipeline,
            values_params: uniform("frame values params"),
            values_binds: Vec::new(),
        })
    }

    /// Packs the window `at` (x0, y0, width, height) of `frame` (an image
    /// this intake filled) into `out` as Harris reads its input
    /// ([`super::Harris::input_target`]): the window's pixels row by row,
    /// allowed inside `allowed` (x0, y0, x1, y1, inclusive, in window
    /// coordinates) and nowhere else: what the host's packing of the
    /// window's crop with that rectangle as its mask gives, bit for bit.
    /// Submitted; nothing comes back.
    pub fn pack_window(
        &mut self,
        frame: ResidentImage,
        at: [u32; 4],
        allowed: [u32; 4],
        out: &wgpu::Buffer,
    ) -> Result<(), FeatureError> {
        let [x0, y0, w, h] = at.map(|v| v as usize);
        if w == 0 || h == 0 {
            return Ok(());
        }
        if x0 + w > frame.width || y0 + h > frame.height {
            return Err(FeatureError::Config(format!(
                "a {w}x{h} window at ({x0}, {y0}) of a {}x{} frame",
                frame.width, frame.height
            )));
        }
        frame.check(&(0..frame.height))?;
        let need = (w * h * std::mem::size_of::<Pixel>()) as u64;
        if need > out.size() {
            return Err(FeatureError::Config(format!(
                "a {w}x{h} window into a {}-byte buffer",
                out.size()
            )));
        }
        let ctx = &self.ctx;
        let params = WindowParams {
            frame_width: frame.width as u32,
            frame_height: frame.height as u32,
            x0: at[0],
            y0: at[1],
            width: at[2],
            height: at[3],
            ax0: allowed[0],
            ay0: allowed[1],
            ax1: allowed[2],
            ay1: allowed[3],
            pad0: 0,
            pad1: 0,
        };
        ctx.queue
            .write_buffer(&self.window_params, 0, bytemuck::bytes_of(&params));
        let key = (frame.pixels.clone(), out.clone());
        let bind = match self.window_binds.iter().position(|(k, _)| *k == key) {
            Some(i) => self.window_binds[i].1.clone(),
            None => {
                let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("frame window"),
                    layout: &self.window_layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: frame.pixels.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: out.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 5,
                            resource: self.window_params.as_entire_binding(),
                        },
                    ],
                });
                self.window_binds.insert(0, (key, bind.clone()));
                self.window_binds.truncate(KEPT_WINDOW_BINDS);
                bind
            }
        };
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.window_pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(
                workgroups(at[2], WORKGROUP_2D),
                workgroups(at[3], WORKGROUP_2D),
                1,
            );
        }
        ctx.queue.submit([enc.finish()]);
        Ok(())
    }

    /// Writes the grey levels of the window `at` (x0, y0, width, height)
    /// of `frame` (an image this intake filled) into `out`, one f32 a
    /// pixel row by row, NaN beyond the frame: what the host's crop of
    /// the frame to that window holds, bit for bit (the pose check's
    /// input, [`crate::tracker::verify_gpu::GpuCheck::frame_target`]).
    /// Submitted; nothing comes back.
    pub fn window_values(
        &mut self,
        frame: ResidentImage,
        at: [u32; 4],
        out: &wgpu::Buffer,
    ) -> Result<(), FeatureError> {
        let [w, h] = [at[2], at[3]].map(|v| v as usize);
        if w == 0 || h == 0 {
            return Ok(());
        }
        frame.check(&(0..frame.height))?;
        if (w * h * 4) as u64 > out.size() {
            return Err(FeatureError::Config(format!(
                "a {w}x{h} window into a {}-byte buffer",
                out.size()
            )));
        }
        let ctx = &self.ctx;
        let params = WindowParams {
            frame_width: frame.width as u32,
            frame_height: frame.height as u32,
            x0: at[0],
            y0: at[1],
            width: at[2],
            height: at[3],
            ax0: 0,
            ay0: 0,
            ax1: 0,
            ay1: 0,
            pad0: 0,
            pad1: 0,
        };
        ctx.queue
            .write_buffer(&self.values_params, 0, bytemuck::bytes_of(&params));
        let key = (frame.pixels.clone(), out.clone());
        let bind = match self.values_binds.iter().position(|(k, _)| *k == key) {
            Some(i) => self.values_binds[i].1.clone(),
            None => {
                let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("frame values"),
                    layout: &self.values_layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: frame.pixels.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 5,
                            resource: self.values_params.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 6,
                            resource: out.as_entire_binding(),
                        },
                    ],
                });
                self.values_binds.insert(0, (key, bind.clone()));
                self.values_binds.truncate(KEPT_WINDOW_BINDS);
                bind
            }
        };
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.values_pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(
                workgroups(at[2], WORKGROUP_2D),
                workgroups(at[3], WORKGROUP_2D),
                1,
            );
        }
        ctx.queue.submit([enc.finish()]);
        Ok(())
    }

    /// Uploads `frame`'s bytes and converts them into `into` on the GPU
    /// (submitted; the matchings that read `into` are submitted after).
    pub fn upload(&mut self, frame: &image::RgbImage, into: &mut GpuGrey) {
        let ctx = &self.ctx;
        let (w, h) = (frame.width() as usize, frame.height() as usize);
        let bytes = frame.as_raw();
        if w == 0 || h == 0 || bytes.len() != 3 * w * h {
            (into.width, into.height) = (0, 0);
            return;
        }
        if self.rgb.ensure(ctx, bytes.len().next_multiple_of(4) as u64) {
            self.binds.clear();
        }
        // Whole words, then the last one to three bytes padded to a word
        // (a write's size must be a multiple of 4).
        let whole = bytes.len() / 4 * 4;
        ctx.queue.write_buffer(self.rgb.get(), 0, &bytes[..whole]);
        if whole < bytes.len() {
            let mut tail = [0u8; 4];
            tail[..bytes.len() - whole].copy_from_slice(&bytes[whole..]);
            ctx.queue.write_buffer(self.rgb.get(), whole as u64, &tail);
        }
        let px = std::mem::size_of::<Pixel>();
        if into.buf.ensure(ctx, (w * h * px) as u64) {
            self.binds.retain(|(b, _)| b != into.buf.get());
        }
        let params = FrameParams {
            width: w as u32,
            height: h as u32,
            _pad0: 0,
            _pad1: 0,
        };
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let out = into.buf.get();
        let bind = match self.binds.iter().find(|(b, _)| b == out) {
            Some((_, bind)) => bind.clone(),
            None => {
                let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("frame"),
                    layout: &self.layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: self.params.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: self.terms.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: self.rgb.get().as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: out.as_entire_binding(),
                        },
                    ],
                });
                self.binds.push((out.clone(), bind.clone()));
                bind
            }
        };
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(
                workgroups(w as u32, WORKGROUP_2D),
                workgroups(h as u32, WORKGROUP_2D),
                1,
            );
        }
        ctx.queue.submit([enc.finish()]);
        (into.width, into.height) = (w, h);
    }
}

/// The largest [`Refinement::window`] the GPU refines.
pub const MAX_REFINE_WINDOW: u32 = 63;

/// The sub-pixel refinement of [`super::NccMatcher::match_resident`]: the
/// arguments of [`super::refine_match`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refinement {
    /// Window side, pixels (an even side uses the odd one below, as
    /// [`super::refine_match`] does).
    pub window: u32,
    /// The integer search, pixels each way.
    pub max_shift: u32,
    /// The least peak score.
    pub min_score: f32,
}

impl Refinement {
    pub(crate) fn validate(&self) -> Result<(), FeatureError> {
        if self.window > MAX_REFINE_WINDOW || self.max_shift > 16 {
            return Err(FeatureError::Config(format!(
                "refinement window {} (at most 63) or shift {} (at most 16)",
                self.window, self.max_shift
            )));
        }
        Ok(())
    }
}

/// A mutual match of [`super::NccMatcher::match_resident`]: feature `a`
/// and `b`, their NCC score, and where `b`'s point lies in its image
/// (pixels): refined when a refinement was asked for (`None` where it
/// failed), else `b`'s position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResidentMatch {
    pub a: usize,
    pub b: usize,
    pub score: f32,
    pub at: Option<[f64; 2]>,
}
