//! Harris corners on the GPU (`shaders/harris_*.wgsl`): the detector, its
//! options and its pending detections here; the map passes in
//! [`maps`], the selection among the candidates in [`select`], the
//! detections in [`detect`] and the export of their corners in
//! [`export`]. The CPU reference is [`super::cpu`], the shared host steps
//! are in [`super::shared`].

mod detect;
mod export;
mod maps;
mod options;
mod passes;
mod select;

pub use options::HarrisGpuOptions;
pub(crate) use passes::SHADER;

use super::host::Scratch;
use super::{Corner, HarrisConfig};
use crate::features::FeatureError;
use crate::features::gpu_data::{
    ExportParams, FUSED_BYTES, HarrisParams, MERGE_ROUNDS, SELECT_MAX, SELECT_MAX_CPU,
};
use crate::features::image::GreyImage;
use crate::gpu::{
    BindCache, GpuContext, GpuTimer, GrowBuffer, PendingRead, STORAGE_IN, STORAGE_OUT, TimerReport,
    Timings, Uniform, compute_entry, storage,
};
use passes::{PASSES, SELECT_ENTRIES, select_passes};

/// Harris corners on the GPU. Pipelines are built once; buffers grow to the
/// largest image seen and are reused, so calling [`Harris::detect`] on
/// every frame allocates nothing in the steady state.
pub struct Harris {
    ctx: GpuContext,
    config: HarrisConfig,
    /// The code paths asked for ([`Harris::set_options`]); the fields
    /// below hold what they resolve to on this adapter.
    options: HarrisGpuOptions,
    layout: wgpu::BindGroupLayout,
    passes: Vec<wgpu::ComputePipeline>,
    /// The four filter passes in one (`maps_fused`), where the adapter
    /// has its workgroup memory ([`HarrisGpuOptions::fused_maps`]).
    fused: Option<wgpu::ComputePipeline>,
    /// The fused filter pass forced on or off; `None`: on GPUs, where the
    /// radii fit.
    fuse: Option<bool>,
    refine: wgpu::ComputePipeline,
    /// The selection's pipelines ([`SELECT_ENTRIES`]), on a layout of
    /// their own (the map passes' holds eight storage buffers already).
    select_layout: wgpu::BindGroupLayout,
    select: Vec<wgpu::ComputePipeline>,
    /// `select_sizes`'s layout: the sizes it writes are read by the
    /// indirect dispatches, so no bind group of theirs may hold them.
    sizes_layout: wgpu::BindGroupLayout,
    grey: wgpu::ComputePipeline,
    /// A resolved view's grey levels, packed (`grey_pack_f32`).
    grey_pack_f32: wgpu::ComputePipeline,
    /// RGBA8 frames, or a view's resolved colour (3 f32 a pixel).
    rgba: GrowBuffer,
    /// The grey levels of a resolved view, kept for the host.
    grey_out: GrowBuffer,
    params: Uniform,
    pixels: GrowBuffer,
    tmp: GrowBuffer,
    grad: GrowBuffer,
    response: GrowBuffer,
    counters: GrowBuffer,
    candidates: GrowBuffer,
    corners: GrowBuffer,
    /// The selection's scratch: ranks and places, then the merge's links
    /// ((1 + MERGE_LINKS) x SELECT_MAX u32); the merge's decisions
    /// (SELECT_MAX u32); the selected corners in the merge's order
    /// (SELECT_MAX corners).
    select_index: GrowBuffer,
    select_state: GrowBuffer,
    ordered: GrowBuffer,
    /// The indirect dispatches' sizes (`select_sizes`).
    select_args: GrowBuffer,
    bind: Option<wgpu::BindGroup>,
    select_bind: Option<wgpu::BindGroup>,
    sizes_bind: Option<wgpu::BindGroup>,
    timer: Option<GpuTimer>,
    timings: Timings,
    /// Detect on the host ([`HarrisGpuOptions::host`]), in these images.
    host: bool,
    scratch: Scratch,
    /// The corner counts of the last two detections (on the GPU) of
    /// frames (0) and of resolved views (1), to size the next one's
    /// readback (a view's window keeps far fewer than a frame's, or more).
    recent_corners: [[usize; 2]; 2],
    /// What the detection being finished ran on (0: a frame, 1: a view).
    kind: usize,
    /// The merge's parallel rounds ([`MERGE_ROUNDS`]; the tests try
    /// none, leaving the whole merge to the host's finish).
    merge_rounds: usize,
    /// The most candidates selected on the GPU ([`HarrisGpuOptions::select_limit`]).
    select_limit: usize,
    /// Whether the selection's O(n^2) passes share tiles of the items in
    /// workgroup memory ([`HarrisGpuOptions::tiled_selection`]).
    tiled_select: bool,
    /// The selection in one workgroup forced on or off
    /// ([`HarrisGpuOptions::small_selection`]); `None`: by the candidates of the
    /// last detection of the kind (`recent_candidates`).
    small_select: Option<bool>,
    /// The candidates of the last detection (on the GPU) of frames (0)
    /// and views (1); `usize::MAX` before any.
    recent_candidates: [usize; 2],
    /// The export of a detection's corners to the next stages
    /// ([`Harris::export_corners`]): its layout, pipeline, parameters and
    /// last bind group (with the buffers it binds).
    export_layout: wgpu::BindGroupLayout,
    export: wgpu::ComputePipeline,
    export_params: Uniform,
    export_bind: BindCache<4>,
    /// The points of an export that needs none.
    export_scratch: GrowBuffer,
}

/// A detection whose corners come back with a later readback
/// ([`Harris::detect_resolved_resident_later`]); [`Harris::finish_later`]
/// returns them.
#[must_use = "a pending detection is only useful finished"]
pub struct PendingCorners {
    counters: PendingRead,
    corners: PendingRead,
    /// The corners read back with the counters.
    rows: usize,
    /// The most corners the detection keeps.
    slots: usize,
    width: usize,
    height: usize,
    /// Frames (0) or views (1): whose recent detections size the readback.
    kind: usize,
    /// The most candidates it selects on the GPU (the host selects beyond).
    limit: usize,
}

impl PendingCorners {
    /// The corners that come back with the counters (a guess from recent
    /// detections; a detection keeping more reads the rest in a readback of
    /// its own): the rows of exported work worth reading with them.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The most corners the detection can keep: the slots
    /// [`Harris::export_corners`] writes.
    pub fn slots(&self) -> usize {
        self.slots
    }
}

/// The corners of a detection finished by [`Harris::finish_later`].
#[derive(Debug, Clone)]
pub struct Detected {
    /// Strongest first, as [`Harris::detect`] gives them.
    pub corners: Vec<Corner>,
    /// Whether these are the corners [`Harris::export_corners`] handed on,
    /// all within [`PendingCorners::rows`]: the selection ran on the GPU
    /// and finished there, and none came back in a readback of its own.
    /// Otherwise the exported slots hold none (the host finished the
    /// selection) or more than were read back, and work fed from them is
    /// to be done again from `corners`.
    pub exported: bool,
}

/// Where [`Harris::export_corners`] puts a detection's corners among an
/// NCC matching's positions: each corner moved by `origin` (the
/// detection's window in the matched image's pixels), left out (a point
/// far outside any image) where outside `clip` (`[x0, y0, x1, y1)` in those
/// pixels, as the host leaves features outside its crop out), less
/// `band_y0` in y (the first row of the band NCC reads), from slot `first`
/// of the positions on (A's features first, then B's).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExportPlace {
    /// Offset added to each corner: the detection window's top-left
    /// corner, in the matched image's pixels.
    pub origin: [f32; 2],
    /// Corners outside `[x0, y0, x1, y1)` (matched image's pixels) are
    /// left out; `None` keeps all.
    pub clip: Option<[f32; 4]>,
    /// Subtracted from each corner's y: the first row of the band NCC reads.
    pub band_y0: f32,
    /// First position slot written (A's features come first, then B's).
    pub first: usize,
}

impl ExportPlace {
    /// In the detection's own pixels, every corner kept, from slot 0: NCC's
    /// A side of a view matched where it was detected.
    pub fn band(band_y0: f32) -> Self {
        Self {
            band_y0,
            ..Self::default()
        }
    }
}

impl Harris {
    /// A GPU Harris detector for `config` on `ctx`, with default options;
    /// fails if `config` is invalid or a pipeline cannot be built.
    pub fn new(ctx: &GpuContext, config: HarrisConfig) -> Result<Self, FeatureError> {
        config.validate()?;
        let mut entries = vec![compute_entry(0, wgpu::BufferBindingType::Uniform)];
        entries.extend((1..8).map(|b| compute_entry(b, storage(false))));
        entries.push(compute_entry(8, storage(true)));
        let layout = ctx.bind_group_layout("harris", &entries);
        let mut all = ctx.compute_pipelines(
            &SHADER,
            &layout,
            &[
                PASSES[0],
                PASSES[1],
                PASSES[2],
                PASSES[3],
                PASSES[4],
                "refine",
                "grey",
                "grey_pack_f32",
            ],
        )?;
        let grey_pack_f32 = all.pop().expect("eight pipelines");
        let grey = all.pop().expect("eight pipelines");
        let refine = all.pop().expect("eight pipelines");
        let mut select_entries = vec![compute_entry(0, wgpu::BufferBindingType::Uniform)];
        select_entries.extend([3, 5, 6, 7, 9, 10, 11].map(|b| compute_entry(b, storage(false))));
        let select_layout = ctx.bind_group_layout("harris select", &select_entries);
        let sizes_entries = [
            compute_entry(0, wgpu::BufferBindingType::Uniform),
            compute_entry(5, storage(false)),
            compute_entry(12, storage(false)),
        ];
        let sizes_layout = ctx.bind_group_layout("harris select sizes", &sizes_entries);
        let names = SELECT_ENTRIES.map(|(name, _)| name);
        let mut select = ctx.compute_pipelines(&SHADER, &sizes_layout, &names[..1])?;
        select.extend(ctx.compute_pipelines(&SHADER, &select_layout, &names[1..])?);
        let export_entries = [
            compute_entry(0, wgpu::BufferBindingType::Uniform),
            compute_entry(5, storage(false)),
            compute_entry(7, storage(false)),
            compute_entry(13, wgpu::BufferBindingType::Uniform),
            compute_entry(14, storage(false)),
            compute_entry(15, storage(false)),
        ];
        let export_layout = ctx.bind_group_layout("harris export", &export_entries);
        let export = ctx
            .compute_pipelines(&SHADER, &export_layout, &["export_corners"])?
            .pop()
            .expect("one pipeline");
        let fused = if ctx.limits.max_compute_workgroup_storage_size >= FUSED_BYTES {
            ctx.compute_pipelines(&SHADER, &layout, &["maps_fused"])?
                .pop()
        } else {
            None
        };
        Ok(Self {
            ctx: ctx.clone(),
            config,
            options: HarrisGpuOptions::default(),
            layout,
            passes: all,
            fused,
            fuse: None,
            refine,
            select_layout,
            select,
            sizes_layout,
            grey,
            grey_pack_f32,
            rgba: GrowBuffer::new("harris rgba", STORAGE_IN),
            grey_out: GrowBuffer::new("harris grey", STORAGE_OUT),
            params: Uniform::new(
                ctx,
                "harris params",
                std::mem::size_of::<HarrisParams>() as u64,
            ),
            pixels: GrowBuffer::new("harris pixels", STORAGE_IN),
            tmp: GrowBuffer::new("harris tmp", STORAGE_OUT),
            grad: GrowBuffer::new("harris grad", STORAGE_OUT),
            response: GrowBuffer::new("harris response", STORAGE_OUT),
            counters: GrowBuffer::new("harris counters", STORAGE_OUT),
            candidates: GrowBuffer::new("harris candidates", STORAGE_OUT),
            corners: GrowBuffer::new("harris corners", STORAGE_OUT),
            select_index: GrowBuffer::new("harris select index", STORAGE_OUT),
            select_state: GrowBuffer::new("harris select state", STORAGE_OUT),
            ordered: GrowBuffer::new("harris ordered corners", STORAGE_OUT),
            select_args: GrowBuffer::new(
                "harris select sizes",
                STORAGE_OUT | wgpu::BufferUsages::INDIRECT,
            ),
            bind: None,
            select_bind: None,
            sizes_bind: None,
            timer: None,
            timings: Default::default(),
            host: false,
            scratch: Scratch::default(),
            recent_corners: [[0; 2]; 2],
            kind: 0,
            merge_rounds: MERGE_ROUNDS,
            select_limit: default_select_limit(ctx),
            tiled_select: !ctx.is_cpu(),
            small_select: None,
            recent_candidates: [usize::MAX; 2],
            export_layout,
            export,
            export_params: Uniform::new(
                ctx,
                "harris export params",
                std::mem::size_of::<ExportParams>() as u64,
            ),
            export_bind: BindCache::default(),
            export_scratch: GrowBuffer::new("harris export points", STORAGE_OUT),
        })
    }

    /// The detector's parameters.
    pub fn config(&self) -> &HarrisConfig {
        &self.config
    }

    /// [`Harris::new`] running as `options` says.
    pub fn with_options(
        ctx: &GpuContext,
        config: HarrisConfig,
        options: HarrisGpuOptions,
    ) -> Result<Self, FeatureError> {
        let mut harris = Self::new(ctx, config)?;
        harris.set_options(options);
        Ok(harris)
    }

    /// The code paths asked for (`None`s stay `None`: the adapter's
    /// choice).
    pub fn options(&self) -> HarrisGpuOptions {
        self.options
    }

    /// Runs as `options` says from now on: the same corners, bit for bit,
    /// whatever they say. Timing already on keeps its timer.
    pub fn set_options(&mut self, options: HarrisGpuOptions) {
        self.set_host(options.host);
        match options.select_limit {
            Some(n) => self.set_select_limit(n),
            None => self.select_limit = default_select_limit(&self.ctx),
        }
        self.set_tiled_selection(options.tiled_selection.unwrap_or(!self.ctx.is_cpu()));
        self.set_small_selection(options.small_selection);
        self.set_fused_maps(options.fused_maps);
        if !options.timing {
            self.timer = None;
        } else if self.timer.is_none() {
            self.enable_timing();
        }
        self.options = options;
    }

    /// [`HarrisGpuOptions::host`].
    pub(crate) fn set_host(&mut self, on: bool) {
        self.host = on;
        self.options.host = on;
    }

    /// [`HarrisGpuOptions::select_limit`].
    pub(crate) fn set_select_limit(&mut self, n: usize) {
        self.select_limit = n.min(SELECT_MAX as usize);
        self.options.select_limit = Some(n);
    }

    /// [`HarrisGpuOptions::tiled_selection`].
    pub(crate) fn set_tiled_selection(&mut self, tiled: bool) {
        self.tiled_select = tiled;
        self.options.tiled_selection = Some(tiled);
    }

    /// [`HarrisGpuOptions::small_selection`].
    pub(crate) fn set_small_selection(&mut self, small: Option<bool>) {
        self.small_select = small;
        self.options.small_selection = small;
    }

    /// [`HarrisGpuOptions::fused_maps`].
    pub(crate) fn set_fused_maps(&mut self, fuse: Option<bool>) {
        self.fuse = fuse;
        self.options.fused_maps = fuse;
    }

    /// Whether detection runs on the host ([`HarrisGpuOptions::host`]).
    pub fn host(&self) -> bool {
        self.host
    }

    /// [`HarrisGpuOptions::timing`] on (a new timer).
    pub(crate) fn enable_timing(&mut self) {
        self.options.timing = true;
        // The passes, grey and pack (a resolved view), the selection's,
        // after the host selected the refinement, and the export.
        self.timer = Some(GpuTimer::new(
            &self.ctx,
            (PASSES.len() + select_passes(true, false, false, 0).len()) as u32 + 4,
        ));
    }

    /// Per-pass GPU durations of the detections since the timings were
    /// last taken (the last [`Harris::detect`]'s, read after each; empty
    /// unless timing is enabled and supported), waiting for their
    /// timestamps if no readback has brought them yet.
    pub fn last_timings(&mut self) -> TimerReport {
        std::mem::take(&mut self.timings).wait(&self.ctx)
    }

    /// The timings of the passes run since they were last taken, their
    /// timestamps still to come with a readback: a frame loop gathers
    /// them and reads them at its end without a wait of their own.
    pub fn take_timings(&mut self) -> Timings {
        std::mem::take(&mut self.timings)
    }

    /// Resolves the timestamps of the passes just run, to be read with
    /// the next readback ([`Harris::take_timings`]).
    fn finish_timing(&mut self) -> Result<(), FeatureError> {
        if let Some(t) = self.timer.as_mut() {
            let read = t.read_later(&self.ctx)?;
            self.timings.append(read);
        }
        Ok(())
    }
}

/// What [`Harris`] detects corners in.
#[derive(Clone, Copy)]
enum Input<'i> {
    Grey(&'i GreyImage),
    Rgb(&'i image::RgbImage),
    /// A view's colour resolved into `rgba` on the GPU.
    Resolved {
        width: usize,
        height: usize,
        /// Copy the grey levels out for a readback.
        keep_grey: bool,
    },
    /// Pixels packed into `pixels` on the GPU
    /// ([`Harris::input_target`]).
    Packed {
        width: usize,
        height: usize,
    },
}

impl Input<'_> {
    fn size(&self) -> (usize, usize) {
        match self {
            Input::Grey(g) => (g.width, g.height),
            Input::Rgb(c) => (c.width() as usize, c.height() as usize),
            Input::Resolved { width, height, .. } => (*width, *height),
            Input::Packed { width, height } => (*width, *height),
        }
    }
}

/// Most strict 3x3 maxima an image can hold: no two are 8-neighbours.
fn capacity(w: usize, h: usize) -> usize {
    w.div_ceil(2) * h.div_ceil(2)
}

/// The most candidates selected on the GPU by default
/// ([`HarrisGpuOptions::select_limit`]).
fn default_select_limit(ctx: &GpuContext) -> usize {
    (if ctx.is_cpu() {
        SELECT_MAX_CPU
    } else {
        SELECT_MAX
    }) as usize
}
