//! Images that stay on the GPU between the stages of a frame:
//! a frame's grey levels uploaded once and read by every NCC matching of
//! the frame (IT, KF) and by the next frame's IT, and a novel view packed
//! by Harris on the GPU ([`super::Harris::resident_view`]), matched
//! without coming back to the host ([`super::NccMatcher::match_resident`]).

use super::FeatureError;
use super::gpu_data::{Pixel, pack_with_holes_into};
use super::image::GreyImage;
use crate::gpu::{
    GpuContext, GrowBuffer, PassChain, STORAGE_IN, Uniform, WORKGROUP_2D, compute_entry, storage,
    workgroups,
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
        ctx.write_buffer(self.buf.get(), 0, bytemuck::cast_slice(&self.packed));
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

/// The frame kernels' shader (shaders/frame.wgsl: the grey levels of a
/// frame and of a window, on the GPU).
pub(crate) static SHADER: crate::shaders::Shader = crate::shaders::Shader {
    name: "frame",
    parts: &[super::gpu_data::PIXEL_WGSL, crate::wgsl_file!("frame.wgsl")],
    constants: &[
        &[(
            "WORKGROUP_2D",
            crate::shaders::WgslValue::U32(crate::gpu::WORKGROUP_2D),
        )],
        super::gpu_data::PIXEL_CONSTANTS,
    ],
};

crate::wgsl_struct! {
    /// Keep in sync with `FrameParams` in shaders/frame.wgsl.
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    pub(crate) struct FrameParams {
        width: u32,
        height: u32,
        pad0: u32,
        pad1: u32,
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

/// A camera frame's way in: its 8-bit RGB bytes uploaded as
/// they are (3 bytes a pixel, against 8 for packed grey) and turned into
/// a [`GpuGrey`] on the GPU (`shaders/frame.wgsl`), so that the host
/// neither converts nor packs the frame for the resident matching. The
/// pixels are bit for bit those of [`GpuGrey::upload`] of
/// [`GreyImage::from_rgb8`]: the shader sums the same tabulated channel
/// terms in the same order. Windows of the frame are cut there too, for
/// Harris ([`FrameIntake::pack_window`]) and the pose check
/// ([`FrameIntake::window_values`]).
pub struct FrameIntake {
    ctx: GpuContext,
    grey: Kernel,
    window: Kernel,
    values: Kernel,
    params: Uniform,
    window_params: Uniform,
    values_params: Uniform,
    terms: wgpu::Buffer,
    rgb: GrowBuffer,
}

/// One entry point of shaders/frame.wgsl, its layout and the bind groups
/// it made, kept by their buffers (frames alternate between two images;
/// buffers grow).
struct Kernel {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    binds: Vec<(Vec<wgpu::Buffer>, wgpu::BindGroup)>,
}

/// Bind groups a [`Kernel`] keeps.
const KEPT_BINDS: usize = 4;

impl Kernel {
    fn new(
        ctx: &GpuContext,
        entry: &str,
        bindings: &[(u32, wgpu::BufferBindingType)],
    ) -> Result<Self, FeatureError> {
        let entries: Vec<_> = bindings.iter().map(|&(b, t)| compute_entry(b, t)).collect();
        let layout = ctx.bind_group_layout(entry, &entries);
        let pipeline = ctx
            .compute_pipelines(&SHADER, &layout, &[entry])?
            .pop()
            .expect("one pipeline");
        Ok(Self {
            layout,
            pipeline,
            binds: Vec::new(),
        })
    }

    /// Submits one pass over `width x height` pixels with `buffers` bound
    /// (binding, buffer).
    fn run(
        &mut self,
        ctx: &GpuContext,
        buffers: &[(u32, &wgpu::Buffer)],
        width: u32,
        height: u32,
    ) -> Result<(), FeatureError> {
        let mut enc = ctx.encoder();
        self.record(
            ctx,
            &mut PassChain::new(ctx, &mut enc),
            buffers,
            width,
            height,
        )?;
        ctx.submit(enc);
        Ok(())
    }

    /// [`Kernel::run`] recorded as a stage of `passes`.
    fn record(
        &mut self,
        ctx: &GpuContext,
        passes: &mut PassChain,
        buffers: &[(u32, &wgpu::Buffer)],
        width: u32,
        height: u32,
    ) -> Result<(), FeatureError> {
        let key: Vec<wgpu::Buffer> = buffers.iter().map(|(_, b)| (*b).clone()).collect();
        let bind = match self.binds.iter().position(|(k, _)| *k == key) {
            Some(i) => self.binds[i].1.clone(),
            None => {
                let bind = ctx.bind_buffers_at("frame", &self.layout, buffers)?;
                self.binds.insert(0, (key, bind.clone()));
                self.binds.truncate(KEPT_BINDS);
                bind
            }
        };
        let pass = passes.stage("frame", None);
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(
            workgroups(width, WORKGROUP_2D),
            workgroups(height, WORKGROUP_2D),
            1,
        );
        Ok(())
    }
}

impl FrameIntake {
    /// The kernels (compiled once) and the channel table; the input
    /// buffer is made on first use.
    pub fn new(ctx: &GpuContext) -> Result<Self, FeatureError> {
        let uniform = wgpu::BufferBindingType::Uniform;
        let uniform_buffer = |label, size: usize| Uniform::new(ctx, label, size as u64);
        let window_size = std::mem::size_of::<WindowParams>();
        let terms: Vec<f32> = super::image::LUMA_TERMS.iter().flatten().copied().collect();
        Ok(Self {
            ctx: ctx.clone(),
            grey: Kernel::new(
                ctx,
                "grey_pack",
                &[
                    (0, uniform),
                    (1, storage(true)),
                    (2, storage(true)),
                    (3, storage(false)),
                ],
            )?,
            window: Kernel::new(
                ctx,
                "window_pack",
                &[(3, storage(false)), (4, storage(false)), (5, uniform)],
            )?,
            values: Kernel::new(
                ctx,
                "window_values",
                &[(3, storage(false)), (5, uniform), (6, storage(false))],
            )?,
            params: uniform_buffer("frame params", std::mem::size_of::<FrameParams>()),
            window_params: uniform_buffer("frame window params", window_size),
            values_params: uniform_buffer("frame values params", window_size),
            terms: ctx.buffer_init("frame luma terms", &terms, STORAGE_IN),
            rgb: GrowBuffer::new("frame rgb", STORAGE_IN),
        })
    }

    /// Uploads `frame`'s bytes and converts them into `into` on the GPU
    /// (submitted; the matchings that read `into` are submitted after).
    pub fn upload(
        &mut self,
        frame: &image::RgbImage,
        into: &mut GpuGrey,
    ) -> Result<(), FeatureError> {
        let ctx = &self.ctx;
        let (w, h) = (frame.width() as usize, frame.height() as usize);
        let bytes = frame.as_raw();
        if w == 0 || h == 0 || bytes.len() != 3 * w * h {
            (into.width, into.height) = (0, 0);
            return Ok(());
        }
        self.rgb.ensure(ctx, bytes.len().next_multiple_of(4) as u64);
        // Whole words, then the last one to three bytes padded to a word
        // (a write's size must be a multiple of 4).
        let whole = bytes.len() / 4 * 4;
        ctx.write_buffer(self.rgb.get(), 0, &bytes[..whole]);
        if whole < bytes.len() {
            let mut tail = [0u8; 4];
            tail[..bytes.len() - whole].copy_from_slice(&bytes[whole..]);
            ctx.write_buffer(self.rgb.get(), whole as u64, &tail);
        }
        into.buf
            .ensure(ctx, (w * h * std::mem::size_of::<Pixel>()) as u64);
        let params = FrameParams {
            width: w as u32,
            height: h as u32,
            pad0: 0,
            pad1: 0,
        };
        self.params.write(ctx, bytemuck::bytes_of(&params));
        let buffers = [
            (0, self.params.buffer()),
            (1, &self.terms),
            (2, self.rgb.get()),
            (3, into.buf.get()),
        ];
        self.grey.run(ctx, &buffers, w as u32, h as u32)?;
        (into.width, into.height) = (w, h);
        Ok(())
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
        window_fits(frame, w, h, std::mem::size_of::<Pixel>(), out)?;
        let params = window_params(frame, at, allowed);
        let ctx = &self.ctx;
        self.window_params.write(ctx, bytemuck::bytes_of(&params));
        let buffers = [
            (3, frame.pixels),
            (4, out),
            (5, self.window_params.buffer()),
        ];
        self.window.run(ctx, &buffers, at[2], at[3])
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
        if at[2] == 0 || at[3] == 0 {
            return Ok(());
        }
        let ctx = &self.ctx.clone();
        let mut enc = ctx.encoder();
        self.record_window_values(&mut PassChain::new(ctx, &mut enc), frame, at, out)?;
        ctx.submit(enc);
        Ok(())
    }

    /// [`FrameIntake::window_values`] recorded as a stage of `passes`,
    /// for the caller to submit with the stages around it.
    pub fn record_window_values(
        &mut self,
        passes: &mut PassChain,
        frame: ResidentImage,
        at: [u32; 4],
        out: &wgpu::Buffer,
    ) -> Result<(), FeatureError> {
        let [w, h] = [at[2], at[3]].map(|v| v as usize);
        if w == 0 || h == 0 {
            return Ok(());
        }
        window_fits(frame, w, h, 4, out)?;
        let params = window_params(frame, at, [0; 4]);
        let ctx = &self.ctx;
        self.values_params.write(ctx, bytemuck::bytes_of(&params));
        let buffers = [
            (3, frame.pixels),
            (5, self.values_params.buffer()),
            (6, out),
        ];
        self.values.record(ctx, passes, &buffers, at[2], at[3])
    }
}

/// Checks `frame`'s buffer and that `out` holds `w x h` values of `size`
/// bytes.
fn window_fits(
    frame: ResidentImage,
    w: usize,
    h: usize,
    size: usize,
    out: &wgpu::Buffer,
) -> Result<(), FeatureError> {
    frame.check(&(0..frame.height))?;
    if (w * h * size) as u64 > out.size() {
        return Err(FeatureError::Config(format!(
            "a {w}x{h} window into a {}-byte buffer",
            out.size()
        )));
    }
    Ok(())
}

/// The uniform of a window `at` of `frame`, `allowed` inside it.
fn window_params(frame: ResidentImage, at: [u32; 4], allowed: [u32; 4]) -> WindowParams {
    WindowParams {
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
    }
}

/// The largest [`Refinement::patch`] the GPU refines.
pub const MAX_REFINE_WINDOW: u32 = 63;

/// The sub-pixel refinement of [`super::NccMatcher::match_resident`]: the
/// arguments of [`super::refine_match`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refinement {
    /// Side of the correlation patch, pixels (an even side uses the odd
    /// one below, as [`super::refine_match`] does).
    pub patch: u32,
    /// The integer search, pixels each way.
    pub max_shift: u32,
    /// The least peak score.
    pub min_score: f32,
}

impl Refinement {
    pub(crate) fn validate(&self) -> Result<(), FeatureError> {
        if self.patch > MAX_REFINE_WINDOW || self.max_shift > 16 {
            return Err(FeatureError::Config(format!(
                "refinement patch {} (at most 63) or shift {} (at most 16)",
                self.patch, self.max_shift
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
    /// Index of the feature in the first set.
    pub a: usize,
    /// Index of the feature in the second set.
    pub b: usize,
    /// NCC of the two windows, in [-1, 1].
    pub score: f32,
    /// Where `b`'s point lies in its image (x, y), in pixels: refined if a
    /// refinement was asked for (`None` where it failed), else `b`'s position.
    pub at: Option<[f64; 2]>,
}
