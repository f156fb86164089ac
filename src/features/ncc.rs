//! NCC matching on the GPU (`shaders/ncc_*.wgsl`): the matcher, its
//! options and its host-image matching here; the matchings of images
//! resident on the GPU in `ncc/resident.rs`, the kernels' buffers and
//! passes in `ncc/kernels.rs`, the host's side of the pairs (positions,
//! orders, mutual bests) in `ncc/pairs.rs`. The CPU reference is
//! [`ncc_match_cpu`] (in `ncc/cpu.rs`). See the module docs of [`super`].

mod config;
mod cpu;
mod kernels;
mod options;
mod pairs;
mod resident;
mod shader;

pub use config::{Match, NccConfig};
pub use cpu::ncc_match_cpu;
pub use options::NccOptions;
pub(crate) use shader::SHADER;

use crate::features::FeatureError;
use crate::features::gpu_data::{Best, NccParams, Pixel, pack_with_holes};
use crate::features::harris::Corner;
use crate::features::image::{GreyImage, check_mask};
use crate::features::resident::ResidentImage;
use crate::gpu::{
    BindCache, GpuContext, GpuTimer, GrowBuffer, PassChain, STORAGE_IN, STORAGE_OUT, TimerReport,
    Timings, Uniform, compute_entry, storage,
};
use pairs::{mutual, sanitize};
use shader::ENTRIES;

/// NCC matching on the GPU. Pipelines are built once and buffers grow to
/// the largest problem seen, so per-frame calls allocate nothing in the
/// steady state.
pub struct NccMatcher {
    ctx: GpuContext,
    config: NccConfig,
    /// The code paths asked for ([`NccMatcher::set_options`]); `tiled`
    /// and `host` hold what they resolve to on this adapter.
    options: NccOptions,
    layout: wgpu::BindGroupLayout,
    passes: Vec<wgpu::ComputePipeline>,
    score_direct: wgpu::ComputePipeline,
    /// One thread per row / column (with `score_direct`).
    bests_direct: wgpu::ComputePipeline,
    tiled: bool,
    params: Uniform,
    pixels: GrowBuffer,
    positions: GrowBuffer,
    desc: GrowBuffer,
    ok: GrowBuffer,
    scores: GrowBuffer,
    best: GrowBuffer,
    matched: GrowBuffer,
    mutual_refine: wgpu::ComputePipeline,
    /// `mutual_refine` for refinement windows over
    /// [`REFINE_LOCAL_WINDOW`] (every score sampled from the images).
    mutual_refine_wide: wgpu::ComputePipeline,
    /// Whether the last prepared refinement needs `mutual_refine_wide`.
    refine_wide: bool,
    /// `vectorize` a workgroup a window (where tiled and the window is at
    /// most [`VECTORIZE_GROUP_WINDOW`]).
    vectorize_group: wgpu::ComputePipeline,
    bind: Option<wgpu::BindGroup>,
    /// The gate ([`NccMatcher::match_resident_exported_b`]): its layout,
    /// pipeline and last bind groups (with the buffers they bind).
    gate_layout: wgpu::BindGroupLayout,
    gate: wgpu::ComputePipeline,
    gate_bind: BindCache<2>,
    timer: Option<GpuTimer>,
    timings: Timings,
    /// Match host images on the host ([`NccOptions::host`]).
    host: bool,
}

impl NccMatcher {
    /// A matcher for `config` on `ctx`, with default options; fails if `config`
    /// is invalid or a pipeline cannot be built.
    pub fn new(ctx: &GpuContext, config: NccConfig) -> Result<Self, FeatureError> {
        config.validate()?;
        // Parameters in a storage buffer, not a uniform: see shaders/ncc_score.wgsl.
        let mut entries = vec![compute_entry(0, storage(true))];
        entries.push(compute_entry(1, storage(true)));
        entries.push(compute_entry(2, storage(true)));
        entries.extend((3..8).map(|b| compute_entry(b, storage(false))));
        let layout = ctx.bind_group_layout("ncc", &entries);
        let mut passes = ctx.compute_pipelines(&SHADER, &layout, &ENTRIES)?;
        let vectorize_group = passes.pop().expect("eight pipelines");
        let mutual_refine_wide = passes.pop().expect("eight pipelines");
        let mutual_refine = passes.pop().expect("eight pipelines");
        let bests_direct = passes.pop().expect("eight pipelines");
        let score_direct = passes.pop().expect("eight pipelines");
        // The gate reads A's count from the matching's parameters.
        let gate_entries = [
            compute_entry(0, storage(true)),
            compute_entry(20, storage(true)),
            compute_entry(22, storage(false)),
        ];
        let gate_layout = ctx.bind_group_layout("ncc gate", &gate_entries);
        let gate = ctx
            .compute_pipelines(&SHADER, &gate_layout, &["gate"])?
            .pop()
            .expect("one pipeline");
        Ok(Self {
            ctx: ctx.clone(),
            config,
            options: NccOptions::default(),
            layout,
            passes,
            score_direct,
            bests_direct,
            tiled: !ctx.is_cpu(),
            params: Uniform::with_usage(
                ctx,
                "ncc params",
                std::mem::size_of::<NccParams>() as u64,
                wgpu::BufferUsages::STORAGE,
            ),
            pixels: GrowBuffer::new("ncc pixels", STORAGE_IN),
            positions: GrowBuffer::new("ncc positions", STORAGE_IN),
            desc: GrowBuffer::new("ncc descriptors", STORAGE_OUT),
            ok: GrowBuffer::new("ncc ok", STORAGE_OUT),
            scores: GrowBuffer::new("ncc scores", STORAGE_OUT),
            best: GrowBuffer::new("ncc best", STORAGE_OUT),
            matched: GrowBuffer::new("ncc matched", STORAGE_OUT),
            mutual_refine,
            mutual_refine_wide,
            refine_wide: false,
            vectorize_group,
            bind: None,
            gate_layout,
            gate,
            gate_bind: BindCache::default(),
            timer: None,
            timings: Default::default(),
            host: false,
        })
    }

    /// The matching parameters.
    pub fn config(&self) -> &NccConfig {
        &self.config
    }

    /// [`NccMatcher::new`] running as `options` says.
    pub fn with_options(
        ctx: &GpuContext,
        config: NccConfig,
        options: NccOptions,
    ) -> Result<Self, FeatureError> {
        let mut matcher = Self::new(ctx, config)?;
        matcher.set_options(options);
        Ok(matcher)
    }

    /// The code paths asked for (`None` stays `None`: the adapter's
    /// choice).
    pub fn options(&self) -> NccOptions {
        self.options
    }

    /// Runs as `options` says from now on: the same matches whatever they
    /// say. Timing already on keeps its timer.
    pub fn set_options(&mut self, options: NccOptions) {
        self.set_host(options.host);
        self.set_tiled(options.tiled.unwrap_or(!self.ctx.is_cpu()));
        if !options.timing {
            self.timer = None;
        } else if self.timer.is_none() {
            self.enable_timing();
        }
        self.options = options;
    }

    /// [`NccOptions::host`].
    pub(crate) fn set_host(&mut self, on: bool) {
        self.host = on;
        self.options.host = on;
    }

    /// Whether host images are matched on the host ([`NccOptions::host`]).
    pub fn host(&self) -> bool {
        self.host
    }

    /// [`NccOptions::tiled`].
    pub(crate) fn set_tiled(&mut self, tiled: bool) {
        self.tiled = tiled;
        self.options.tiled = Some(tiled);
    }

    /// [`NccOptions::timing`] on (a new timer).
    pub(crate) fn enable_timing(&mut self) {
        self.options.timing = true;
        // Room for every entry point twice plus the gate: a frame's chained
        // matchings record up to two matchings before one readback.
        self.timer = Some(GpuTimer::new(&self.ctx, 2 * ENTRIES.len() as u32 + 2));
    }

    /// Per-pass GPU durations of the matchings since the timings were last
    /// taken (empty unless enabled), waiting for their timestamps if no
    /// readback has brought them yet.
    pub fn last_timings(&mut self) -> TimerReport {
        std::mem::take(&mut self.timings).wait(&self.ctx)
    }

    /// The timings of the passes run since they were last taken, their
    /// timestamps still to come with a readback: a frame loop gathers
    /// them and reads them at its end without a wait of their own.
    pub fn take_timings(&mut self) -> Timings {
        std::mem::take(&mut self.timings)
    }

    /// Mutual best NCC matches between the features `a` of `img_a` and `b`
    /// of `img_b` (images may differ in size), sorted by `a`. A feature
    /// whose window leaves its image, has too few valid samples
    /// ([`NccConfig::min_valid`]), or is flat gets no match.
    pub fn match_features(
        &mut self,
        img_a: &GreyImage,
        a: &[Corner],
        img_b: &GreyImage,
        b: &[Corner],
    ) -> Result<Vec<Match>, FeatureError> {
        check_mask(img_a, None)?;
        check_mask(img_b, None)?;
        if self.host {
            self.timings = Default::default();
            return cpu::ncc_match_cpu(img_a, a, img_b, b, &self.config);
        }
        let (na, nb) = (a.len(), b.len());
        if na == 0 || nb == 0 || img_a.is_empty() || img_b.is_empty() {
            return Ok(Vec::new());
        }
        let sizes = [(img_a.width, img_a.height), (img_b.width, img_b.height)];
        self.prepare(na, nb, sizes, [0, 0], None, false)?;
        let ctx = &self.ctx.clone();
        let mut pixels: Vec<Pixel> = pack_with_holes(img_a, None, false);
        pixels.extend(pack_with_holes(img_b, None, false));
        ctx.write_buffer(self.pixels.get(), 0, bytemuck::cast_slice(&pixels));
        let pos: Vec<[f32; 2]> = a.iter().chain(b).map(sanitize).collect();
        self.write_positions(&pos, na, 0);
        let mut enc = ctx.encoder();
        self.encode(&mut PassChain::new(ctx, &mut enc), na, nb, false);
        let best: Vec<Best> = ctx.read_buffer_after(enc, self.best.get(), na + nb)?;
        Ok(mutual(&best[..na], &best[na..], self.config.min_score))
    }
}

/// The two GPU-resident bands of a matching
/// ([`NccMatcher::match_resident`]'s arguments).
struct Bands<'i> {
    img_a: ResidentImage<'i>,
    a_rows: std::ops::Range<usize>,
    img_b: ResidentImage<'i>,
    b_rows: std::ops::Range<usize>,
    offset_b: [i32; 2],
}

/// Work recorded into a matching's passes before its own that writes
/// the exported side's positions into the buffer it is given
/// ([`NccMatcher::match_resident_exported`]).
pub type ExportFn<'a> = dyn FnMut(&mut PassChain, &wgpu::Buffer) -> Result<(), FeatureError> + 'a;

/// Where one side's features come from.
enum Side<'a> {
    /// Uploaded by the host.
    Host(&'a [Corner]),
    /// Written into this many positions on the GPU (A's first, B's after
    /// A's) by the matching's `export`.
    Exported(usize),
}

impl Side<'_> {
    fn len(&self) -> usize {
        match self {
            Side::Host(f) => f.len(),
            Side::Exported(slots) => *slots,
        }
    }
}

/// A matching whose readback is put off
/// ([`NccMatcher::match_resident_exported`]).
#[must_use = "a pending matching is only useful finished"]
pub struct PendingMatches {
    read: crate::gpu::PendingRead,
    /// A's rows read back.
    rows: usize,
    /// B's band's first row.
    y0: f64,
    refine: bool,
}
