//! The contour's silhouette points on the GPU (no image readback
//! in the loop). The splatter resolves the contour render's depth into a
//! buffer held here ([`GpuOutline::depth_target`]); `shaders/outline.wgsl`
//! finds the points of [`super::contour::extract_contour`] (its CPU
//! reference) in it and packs the window's coverage into bits. What comes
//! back is a few integers a point and a bit a pixel, not the depth's four
//! bytes a pixel; the host finishes each point with the reference's own
//! arithmetic (`contour::contour_point`), so the points are the
//! reference's bit for bit. `tests/outline_gpu.rs` compares the two.

use super::contour::{ContourPoint, contour_point};
use crate::gpu::{
    GpuContext, GpuError, GpuTimer, GrowBuffer, PassChain, STORAGE_IN, STORAGE_OUT, TimerReport,
    Timings, WORKGROUP_1D, WORKGROUP_2D, compute_entry, storage, workgroups,
};
use crate::shaders::{Shader, WgslValue};
use crate::wgsl_struct;
use bytemuck::{Pod, Zeroable};

/// Half-width of the window giving a contour point's normal and offset
/// (pixels; shared with shaders/outline.wgsl).
pub const OUTLINE_WINDOW: u32 = 5;
/// Least length of a contour point's offset sum over its window: a
/// straight edge through the centre gives 330 (11 x 11); thin parts and
/// corners give less, and their normal is unreliable.
pub const OUTLINE_MIN_GRADIENT: u32 = 120;

/// The outline's shader.
pub(crate) static SHADER: Shader = Shader {
    name: "outline",
    parts: &[crate::wgsl_file!("outline.wgsl")],
    constants: &[&[
        ("WORKGROUP_1D", WgslValue::U32(WORKGROUP_1D)),
        ("WORKGROUP_2D", WgslValue::U32(WORKGROUP_2D)),
        ("OUTLINE_WINDOW", WgslValue::U32(OUTLINE_WINDOW)),
        ("OUTLINE_MIN_GRADIENT", WgslValue::U32(OUTLINE_MIN_GRADIENT)),
    ]],
};

wgsl_struct! {
    /// Keep in sync with `OutlineParams` in shaders/outline.wgsl.
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    pub(crate) struct OutlineParams {
        width: u32,
        height: u32,
        spacing: u32,
        cells_x: u32,
        cells: u32,
        capacity: u32,
        words: u32,
        _pad: u32,
    }
}

wgsl_struct! {
    /// A silhouette pixel as the GPU finds it. Keep in sync with
    /// `OutlinePoint` in shaders/outline.wgsl.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
    pub(crate) struct OutlinePoint {
        x: u32,
        y: u32,
        gx: i32,
        gy: i32,
        covered: u32,
        depth: f32,
    }
}

/// The silhouette of a depth window: [`super::contour::extract_contour`]'s
/// points (window pixels), the depth at each point's pixel, and the
/// window's coverage.
#[derive(Debug, Clone, PartialEq)]
pub struct Outline {
    /// The window's width.
    pub width: u32,
    /// The window's height.
    pub height: u32,
    /// The points, in window pixels, in raster order of their pixels.
    pub points: Vec<ContourPoint>,
    /// The splatted depth at each point's pixel.
    pub depths: Vec<f32>,
    /// Row-major coverage (a finite depth), 32 pixels a word, the first in
    /// the lowest bit.
    pub bits: Vec<u32>,
}

impl Outline {
    /// Whether pixel `(x, y)` of the window is covered.
    pub fn covered(&self, x: u32, y: u32) -> bool {
        let i = (y * self.width + x) as usize;
        self.bits[i / 32] >> (i % 32) & 1 == 1
    }
}

/// The outline's kernels and buffers, kept across frames (grow-only).
pub struct GpuOutline {
    ctx: GpuContext,
    layout: wgpu::BindGroupLayout,
    candidates: wgpu::ComputePipeline,
    points_of_cells: wgpu::ComputePipeline,
    coverage: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    depth: GrowBuffer,
    first: GrowBuffer,
    count: GrowBuffer,
    points: GrowBuffer,
    bits: GrowBuffer,
    bind: Option<wgpu::BindGroup>,
    /// Points found by the last extraction, to size the next readback.
    recent: usize,
    timer: Option<GpuTimer>,
    timings: Timings,
    /// Whether the tracker finds its outlines here ([`GpuOutline::resident`]).
    resident: bool,
}

impl GpuOutline {
    /// The kernels (compiled once); buffers are made on first use.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let mut entries = vec![compute_entry(0, wgpu::BufferBindingType::Uniform)];
        entries.push(compute_entry(1, storage(true)));
        entries.extend((2..6).map(|b| compute_entry(b, storage(false))));
        let layout = ctx.bind_group_layout("outline", &entries);
        let [candidates, points_of_cells, coverage]: [wgpu::ComputePipeline; 3] = ctx
            .compute_pipelines(
                &SHADER,
                &layout,
                &["candidates", "points_of_cells", "coverage"],
            )?
            .try_into()
            .expect("three pipelines");
        Ok(Self {
            ctx: ctx.clone(),
            layout,
            candidates,
            points_of_cells,
            coverage,
            params: ctx.buffer(
                "outline params",
                std::mem::size_of::<OutlineParams>() as u64,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            ),
            depth: GrowBuffer::new("outline depth", STORAGE_IN),
            first: GrowBuffer::new("outline cells", STORAGE_OUT),
            count: GrowBuffer::new("outline count", STORAGE_OUT),
            points: GrowBuffer::new("outline points", STORAGE_OUT),
            bits: GrowBuffer::new("outline coverage", STORAGE_OUT),
            bind: None,
            recent: 0,
            timer: None,
            timings: Default::default(),
            resident: !ctx.is_cpu(),
        })
    }

    /// Whether the tracker finds the contour's outline here (the default
    /// on GPUs) or reads the window's depth back and finds it on the host
    /// with [`super::contour::extract_contour`] (the default on CPU
    /// adapters such as lavapipe, whose shader threads share the host's
    /// cores). Both give the same points, bit for bit.
    pub fn resident(&self) -> bool {
        self.resident
    }

    /// Overrides [`GpuOutline::resident`].
    pub fn set_resident(&mut self, on: bool) {
        self.resident = on;
    }

    /// Times the three passes with GPU timestamp queries from now on.
    pub fn enable_timing(&mut self) {
        self.timer = Some(GpuTimer::new(&self.ctx, 3));
    }

    /// Per-pass GPU durations of the extractions since the timings were
    /// last taken (the last [`GpuOutline::extract`]'s, read after each).
    pub fn last_timings(&mut self) -> TimerReport {
        std::mem::take(&mut self.timings).wait(&self.ctx)
    }

    /// The timings of the passes run since they were last taken, their
    /// timestamps still to come with a readback: a frame loop gathers
    /// them and reads them at its end without a wait of their own.
    pub fn take_timings(&mut self) -> Timings {
        std::mem::take(&mut self.timings)
    }

    /// Whether a `width x height` window fits the kernels: raster indices
    /// below 2^31 (the cells' inverted indices never 0) and buffers within
    /// the device's limits.
    pub fn fits(&self, width: u32, height: u32) -> bool {
        let n = width as u64 * height as u64;
        let limit = self
            .ctx
            .limits
            .max_storage_buffer_binding_size
            .min(self.ctx.limits.max_buffer_size);
        let groups = self.ctx.limits.max_compute_workgroups_per_dimension as u64;
        width >= 1
            && height >= 1
            && n < 1 << 31
            && n * 24 <= limit
            && (width as u64).div_ceil(WORKGROUP_2D as u64) <= groups
            && (height as u64).div_ceil(WORKGROUP_2D as u64) <= groups
            && n.div_ceil(WORKGROUP_1D as u64) <= groups
    }

    /// The buffer the splatter resolves a `width x height` window's depth
    /// into (one f32 a pixel, NaN where empty) for
    /// [`GpuOutline::extract`].
    pub fn depth_target(&mut self, width: u32, height: u32) -> wgpu::Buffer {
        self.prepare(width, height, 1);
        self.depth.get().clone()
    }

    /// Sizes the buffers for a `width x height` window of `cells` cells
    /// (at most a point a cell).
    fn prepare(&mut self, width: u32, height: u32, cells: u64) {
        let n = width as u64 * height as u64;
        let ctx = &self.ctx;
        let mut changed = self.depth.ensure(ctx, n * 4);
        changed |= self.first.ensure(ctx, cells * 4);
        changed |= self.count.ensure(ctx, 16);
        changed |= self
            .points
            .ensure(ctx, cells * std::mem::size_of::<OutlinePoint>() as u64);
        changed |= self.bits.ensure(ctx, n.div_ceil(32) * 4);
        if changed || self.bind.is_none() {
            let bufs = [
                &self.params,
                self.depth.get(),
                self.first.get(),
                self.count.get(),
                self.points.get(),
                self.bits.get(),
            ];
            self.bind = ctx.bind_buffers("outline", &self.layout, &bufs).ok();
        }
    }

    /// The outline of the depth in [`GpuOutline::depth_target`] (a
    /// `width x height` window), one point per `spacing x spacing` cell:
    /// [`super::contour::extract_contour`] of its coverage, bit for bit.
    /// One readback: the count, as many points as the last extraction
    /// found and a quarter more (the first: the window's perimeter in
    /// cells), and the coverage bits; the rest of the points, when there
    /// are more, in a second.
    pub fn extract(&mut self, width: u32, height: u32, spacing: u32) -> Result<Outline, GpuError> {
        if !self.fits(width, height) {
            return Err(GpuError::Readback(format!(
                "a {width}x{height} window is beyond the GPU outline"
            )));
        }
        let spacing = spacing.max(1);
        let cells_x = width.div_ceil(spacing);
        let cells = cells_x * height.div_ceil(spacing);
        self.prepare(width, height, cells as u64);
        let ctx = &self.ctx.clone();
        let words = (width * height).div_ceil(32);
        let params = OutlineParams {
            width,
            height,
            spacing,
            cells_x,
            cells,
            capacity: cells,
            words,
            _pad: 0,
        };
        ctx.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let bind = self
            .bind
            .as_ref()
            .ok_or_else(|| GpuError::Readback("the outline's bind group failed".into()))?;
        let mut enc = ctx.encoder();
        enc.clear_buffer(self.first.get(), 0, Some(cells as u64 * 4));
        enc.clear_buffer(self.count.get(), 0, None);
        let passes = [
            (
                &self.candidates,
                "candidates",
                (
                    workgroups(width, WORKGROUP_2D),
                    workgroups(height, WORKGROUP_2D),
                ),
            ),
            (
                &self.points_of_cells,
                "points",
                (workgroups(cells, WORKGROUP_1D), 1),
            ),
            (
                &self.coverage,
                "coverage",
                (workgroups(words, WORKGROUP_1D), 1),
            ),
        ];
        // One compute pass, one a stage where timed.
        let mut chain = PassChain::new(ctx, &mut enc);
        for (pipeline, label, (x, y)) in passes {
            let pass = chain.stage(label, self.timer.as_mut());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
        drop(chain);
        if let Some(t) = self.timer.as_mut() {
            // The timestamps come with the outline.
            self.timings.append(t.resolve_later(ctx, &mut enc)?);
        }
        let size = std::mem::size_of::<OutlinePoint>();
        // Before any: the window's perimeter in cells (an object filling
        // the window).
        let guess = if self.recent == 0 {
            2 * (cells_x + height.div_ceil(spacing)) as usize
        } else {
            self.recent * 5 / 4 + 64
        }
        .min(cells as usize);
        let parts = ctx.read_buffers_after(
            enc,
            &[
                (self.count.get(), 4),
                (self.points.get(), (guess * size) as u64),
                (self.bits.get(), words as u64 * 4),
            ],
        )?;
        let count = (u32::from_le_bytes(parts[0][..4].try_into().expect("4 bytes")) as usize)
            .min(cells as usize);
        self.recent = count;
        let mut found: Vec<OutlinePoint> = if count <= guess {
            bytemuck::pod_collect_to_vec(&parts[1][..count * size])
        } else {
            ctx.read_buffer(self.points.get(), count)?
        };
        // The reference's order: raster order of the points' pixels.
        found.sort_unstable_by_key(|p| (p.y, p.x));
        Ok(Outline {
            width,
            height,
            points: found
                .iter()
                .map(|p| contour_point(p.x, p.y, p.gx as i64, p.gy as i64, p.covered))
                .collect(),
            depths: found.iter().map(|p| p.depth).collect(),
            bits: bytemuck::pod_collect_to_vec(&parts[2]),
        })
    }

    /// [`GpuOutline::extract`] of a depth window given on the host (NaN or
    /// any non-finite value where empty): for tests against the CPU
    /// reference.
    pub fn extract_host(
        &mut self,
        depth: &[f32],
        width: u32,
        height: u32,
        spacing: u32,
    ) -> Result<Outline, GpuError> {
        if depth.len() != width as usize * height as usize {
            return Err(GpuError::Readback(format!(
                "a {width}x{height} window with {} depths",
                depth.len()
            )));
        }
        if !self.fits(width, height) {
            return Err(GpuError::Readback(format!(
                "a {width}x{height} window is beyond the GPU outline"
            )));
        }
        let target = self.depth_target(width, height);
        self.ctx
            .write_buffer(&target, 0, bytemuck::cast_slice(depth));
        self.extract(width, height, spacing)
    }
}
