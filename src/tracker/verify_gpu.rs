//! The pose check's scores on the GPU (no image readback in the
//! loop). The splatter resolves the check's render (weight and colour)
//! into buffers held here ([`GpuCheck::targets`]); `shaders/verify.wgsl`
//! scores them against the frame's grey levels over the window and
//! reduces everything to [`CHECK_SUMS`] floats, the only readback. The CPU
//! reference is [`super::verify::score`]; `tests/verify_gpu.rs` compares
//! the two on random views and frames.

use super::verify::{VerifyConfig, VerifyScores, laplacian_rms, zncc_of_sums};
use crate::features::GreyImage;
use crate::gpu::{
    GpuContext, GpuError, GrowBuffer, PassChain, STORAGE_IN, STORAGE_OUT, Uniform, compute_entry,
    storage,
};
use crate::shaders::{Shader, WgslValue};
use crate::wgsl_struct;
use bytemuck::{Pod, Zeroable};

/// Floats each row (and the whole window) reduces to (shaders/verify.wgsl).
pub const CHECK_SUMS: u32 = 11;
/// Threads (rows) per workgroup of the check's row pass.
pub const CHECK_WORKGROUP: u32 = 64;

/// The check's shader.
pub(crate) static SHADER: Shader = Shader {
    name: "verify",
    parts: &[crate::wgsl_file!("verify.wgsl")],
    constants: &[
        &[
            ("CHECK_SUMS", WgslValue::U32(CHECK_SUMS)),
            ("CHECK_WORKGROUP", WgslValue::U32(CHECK_WORKGROUP)),
        ],
        crate::features::image::LUMA_CONSTANTS,
    ],
};

/// Grey levels are summed less this (ZNCC ignores an offset; f32 sums of
/// squares then keep the variance of values near mid-grey).
const CENTRE: f32 = 0.5;

wgsl_struct! {
    /// Keep in sync with `CheckParams` in shaders/verify.wgsl.
    #[derive(Clone, Copy, Debug, Pod, Zeroable)]
    pub(crate) struct CheckParams {
        width: u32,
        height: u32,
        search: u32,
        gradient: f32,
        centre: f32,
        texture_step: u32,
        contrast: f32,
        band: u32,
    }
}

/// The check's kernels and buffers, kept across frames (grow-only).
pub struct GpuCheck {
    ctx: GpuContext,
    layout: wgpu::BindGroupLayout,
    rows: wgpu::ComputePipeline,
    sum_rows: wgpu::ComputePipeline,
    rows_tiled: wgpu::ComputePipeline,
    sum_rows_tiled: wgpu::ComputePipeline,
    /// A workgroup a row and a sum ([`GpuCheck::set_tiled`]).
    tiled: bool,
    params: Uniform,
    weight: GrowBuffer,
    colour: GrowBuffer,
    frame: GrowBuffer,
    partial: GrowBuffer,
    total: GrowBuffer,
    bind: Option<wgpu::BindGroup>,
    timer: Option<crate::gpu::GpuTimer>,
    timings: crate::gpu::Timings,
    /// Whether the tracker scores here ([`GpuCheck::resident`]).
    resident: bool,
}

impl GpuCheck {
    /// The kernels (compiled once); buffers are made on first use.
    pub fn new(ctx: &GpuContext) -> Result<Self, GpuError> {
        let mut entries = vec![compute_entry(0, wgpu::BufferBindingType::Uniform)];
        entries.extend((1..4).map(|b| compute_entry(b, storage(true))));
        entries.extend((4..6).map(|b| compute_entry(b, storage(false))));
        let layout = ctx.bind_group_layout("verify", &entries);
        let [rows, sum_rows, rows_tiled, sum_rows_tiled]: [wgpu::ComputePipeline; 4] = ctx
            .compute_pipelines(
                &SHADER,
                &layout,
                &["rows", "sum_rows", "rows_tiled", "sum_rows_tiled"],
            )?
            .try_into()
            .expect("four pipelines");
        Ok(Self {
            ctx: ctx.clone(),
            layout,
            rows,
            sum_rows,
            rows_tiled,
            sum_rows_tiled,
            tiled: !ctx.is_cpu(),
            params: Uniform::new(
                ctx,
                "verify params",
                std::mem::size_of::<CheckParams>() as u64,
            ),
            weight: GrowBuffer::new("verify weight", STORAGE_OUT),
            colour: GrowBuffer::new("verify colour", STORAGE_OUT),
            frame: GrowBuffer::new("verify frame", STORAGE_IN),
            partial: GrowBuffer::new("verify rows", STORAGE_OUT),
            total: GrowBuffer::new("verify total", STORAGE_OUT),
            bind: None,
            timer: None,
            timings: Default::default(),
            resident: !ctx.is_cpu(),
        })
    }

    /// Chooses the kernels: a workgroup a row (its threads taking every
    /// [`CHECK_WORKGROUP`]-th pixel, their sums added pairwise in
    /// workgroup memory) and a workgroup a sum over the rows (the default
    /// on GPUs: a thread a row took 0.27 ms of the real cube's frame on
    /// the H200), or a thread a row and a thread a sum, with no barrier
    /// (the default on CPU adapters). The counts are the same; the sums
    /// are added in another order (both within tests/verify_gpu.rs's
    /// tolerances of the CPU reference).
    pub fn set_tiled(&mut self, tiled: bool) {
        self.tiled = tiled;
    }

    /// Whether the tracker scores its check here (the default on GPUs) or
    /// reads the view back and scores it on the host with
    /// [`super::verify::score`] (the default on CPU adapters such as
    /// lavapipe, where that measured faster: about 1 ms against 10 ms for
    /// a 416 x 384 window, the kernel's per-pixel branches running in
    /// masked SIMD lanes). Both give the same scores (tests/verify_gpu.rs).
    pub fn resident(&self) -> bool {
        self.resident
    }

    /// Overrides [`GpuCheck::resident`].
    pub(crate) fn set_resident(&mut self, on: bool) {
        self.resident = on;
    }

    /// Times the two passes with GPU timestamp queries from now on.
    pub(crate) fn enable_timing(&mut self) {
        self.timer = Some(crate::gpu::GpuTimer::new(&self.ctx, 2));
    }

    /// Per-pass GPU durations of the scorings since the timings were last
    /// taken (the last [`GpuCheck::score`]'s, read after each).
    pub fn last_timings(&mut self) -> crate::gpu::TimerReport {
        std::mem::take(&mut self.timings).wait(&self.ctx)
    }

    /// The timings of the passes run since they were last taken, their
    /// timestamps still to come with a readback: a frame loop gathers
    /// them and reads them at its end without a wait of their own.
    pub fn take_timings(&mut self) -> crate::gpu::Timings {
        std::mem::take(&mut self.timings)
    }

    /// Whether a `width x height` window can be scored here: the counts
    /// are f32 sums, exact below 2^24 pixels.
    pub fn fits(&self, width: u32, height: u32) -> bool {
        // (A workgroup a row: at most 65535 of them in a dispatch.)
        (width as u64 * height as u64) < (1 << 24) && width >= 1 && (1..=65535).contains(&height)
    }

    /// The buffers the splatter resolves the view's weight (1 float per
    /// pixel) and colour (3) into, sized for a `width x height` window.
    pub fn targets(&mut self, width: u32, height: u32) -> (&wgpu::Buffer, &wgpu::Buffer) {
        self.prepare(width, height);
        (self.weight.get(), self.colour.get())
    }

    fn prepare(&mut self, width: u32, height: u32) {
        let n = width as u64 * height as u64;
        let ctx = &self.ctx;
        let mut changed = self.weight.ensure(ctx, n * 4);
        changed |= self.colour.ensure(ctx, n * 12);
        changed |= self.frame.ensure(ctx, n * 4);
        changed |= self
            .partial
            .ensure(ctx, height as u64 * CHECK_SUMS as u64 * 4);
        changed |= self.total.ensure(ctx, CHECK_SUMS as u64 * 4);
        if changed || self.bind.is_none() {
            let bufs = [
                self.params.buffer(),
                self.weight.get(),
                self.colour.get(),
                self.frame.get(),
                self.partial.get(),
                self.total.get(),
            ];
            self.bind = ctx.bind_buffers("verify", &self.layout, &bufs).ok();
        }
    }

    /// Scores the view in [`GpuCheck::targets`] (resolved there for a
    /// window of `frame`'s size) against `frame` (the frame's grey levels
    /// over that window): [`super::verify::score`] on the GPU, reading
    /// back [`CHECK_SUMS`] floats. `textured`: whether the view has a
    /// texture to correlate (else no ZNCC and no view texture);
    /// `texture_step`: the view texture's Laplacian step
    /// ([`super::verify::texture_step`]).
    pub fn score(
        &mut self,
        frame: &GreyImage,
        textured: bool,
        visible: f64,
        texture_step: usize,
        cfg: &VerifyConfig,
    ) -> Result<VerifyScores, GpuError> {
        let (w, h) = (frame.width as u32, frame.height as u32);
        if !self.fits(w, h) {
            return Err(GpuError::Readback(format!(
                "a {w}x{h} window is beyond the GPU check"
            )));
        }
        self.prepare(w, h);
        self.ctx
            .write_buffer(self.frame.get(), 0, bytemuck::cast_slice(&frame.data));
        self.score_prepared(w, h, textured, visible, texture_step, cfg, |_| {
            Ok::<(), GpuError>(())
        })
    }

    /// The buffer a `width x height` window of the frame's grey levels
    /// goes into on the GPU (one f32 a pixel, NaN where invalid:
    /// [`crate::features::FrameIntake::window_values`]) for
    /// [`GpuCheck::score_prepared`].
    pub fn frame_target(&mut self, width: u32, height: u32) -> wgpu::Buffer {
        self.prepare(width, height);
        self.frame.get().clone()
    }

    /// [`GpuCheck::score`] against the frame's window already in
    /// [`GpuCheck::frame_target`] (`width x height`, or written there by
    /// `before`): no upload. The stages `before` records come first (the
    /// view's resolves into [`GpuCheck::targets`], the frame's window):
    /// all in one compute pass where untimed, and one submission with the
    /// readback.
    #[allow(clippy::too_many_arguments)]
    pub fn score_prepared<E: From<GpuError>>(
        &mut self,
        w: u32,
        h: u32,
        textured: bool,
        visible: f64,
        texture_step: usize,
        cfg: &VerifyConfig,
        before: impl FnOnce(&mut PassChain) -> Result<(), E>,
    ) -> Result<VerifyScores, E> {
        if !self.fits(w, h) {
            return Err(
                GpuError::Readback(format!("a {w}x{h} window is beyond the GPU check")).into(),
            );
        }
        self.prepare(w, h);
        let ctx = &self.ctx.clone();
        let params = CheckParams {
            width: w,
            height: h,
            search: cfg.edge_search_px as u32,
            gradient: cfg.edge_gradient,
            centre: CENTRE,
            texture_step: texture_step as u32,
            contrast: cfg.edge_contrast,
            band: cfg.edge_band_px as u32,
        };
        self.params.write(ctx, bytemuck::bytes_of(&params));
        let bind = self
            .bind
            .as_ref()
            .ok_or_else(|| GpuError::Readback("the check's bind group failed".into()))?;
        let mut enc = ctx.encoder();
        // One compute pass with `before`'s stages, one a stage where
        // timed.
        let mut passes = PassChain::new(ctx, &mut enc);
        before(&mut passes)?;
        let pass = passes.stage("rows", self.timer.as_mut());
        pass.set_bind_group(0, bind, &[]);
        if self.tiled {
            pass.set_pipeline(&self.rows_tiled);
            pass.dispatch_workgroups(h, 1, 1);
        } else {
            pass.set_pipeline(&self.rows);
            pass.dispatch_workgroups(h.div_ceil(CHECK_WORKGROUP), 1, 1);
        }
        let pass = passes.stage("sum", self.timer.as_mut());
        pass.set_bind_group(0, bind, &[]);
        if self.tiled {
            pass.set_pipeline(&self.sum_rows_tiled);
            pass.dispatch_workgroups(CHECK_SUMS, 1, 1);
        } else {
            pass.set_pipeline(&self.sum_rows);
            pass.dispatch_workgroups(1, 1, 1);
        }
        drop(passes);
        if let Some(t) = self.timer.as_mut() {
            // The timestamps come with the sums.
            self.timings.append(t.resolve_later(ctx, &mut enc)?);
        }
        let s: Vec<f32> = ctx.read_buffer_after(enc, self.total.get(), CHECK_SUMS as usize)?;
        let s: Vec<f64> = s.iter().map(|v| *v as f64).collect();
        let contour = s[7].round() as usize;
        Ok(VerifyScores {
            visible,
            covered_px: s[0].round() as usize,
            zncc: if textured {
                zncc_of_sums([s[1], s[2], s[3], s[4], s[5], s[6]])
            } else {
                None
            },
            edge_support: (w >= 3 && h >= 3 && contour >= 20).then(|| s[8] / s[7]),
            view_texture: if textured {
                laplacian_rms(s[9], s[10])
            } else {
                None
            },
            // The tracker fits the shading beside these sums
            // (`Tracker::with_shading`).
            shading_rms: None,
        })
    }

    /// [`GpuCheck::score`] of a view given on the host (its weight per
    /// pixel, NaN or 0 where empty, and its colour, 3 floats a pixel): for
    /// tests against the CPU reference.
    pub fn score_host(
        &mut self,
        frame: &GreyImage,
        weight: &[f32],
        colour: Option<&[f32]>,
        visible: f64,
        texture_step: usize,
        cfg: &VerifyConfig,
    ) -> Result<VerifyScores, GpuError> {
        let (w, h) = (frame.width as u32, frame.height as u32);
        let n = frame.data.len();
        if weight.len() != n || colour.is_some_and(|c| c.len() != 3 * n) {
            return Err(GpuError::Readback(format!(
                "a {w}x{h} frame with {} weights",
                weight.len()
            )));
        }
        let (wb, cb) = self.targets(w, h);
        let (wb, cb) = (wb.clone(), cb.clone());
        self.ctx.write_buffer(&wb, 0, bytemuck::cast_slice(weight));
        if let Some(c) = colour {
            self.ctx.write_buffer(&cb, 0, bytemuck::cast_slice(c));
        }
        self.score(frame, colour.is_some(), visible, texture_step, cfg)
    }
}
