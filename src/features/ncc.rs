//! NCC matching on the GPU (`shaders/ncc.wgsl`); the CPU reference is
//! [`super::ncc_match_cpu`]. See the module docs of [`super`].

use super::FeatureError;
use super::gpu_data::{
    Best, MatchOut, NCC_TILE, NO_INDEX, NccParams, Pixel, REFINE_LOCAL_WINDOW,
    VECTORIZE_GROUP_WINDOW, pack_with_holes,
};
use super::harris::Corner;
use super::image::{GreyImage, check_mask};
use super::resident::{Refinement, ResidentImage, ResidentMatch};
use crate::gpu::{
    BindCache, GpuContext, GpuTimer, GrowBuffer, PassChain, STORAGE_IN, STORAGE_OUT, TimerReport,
    Timings, Uniform, WORKGROUP_1D, compute_entry, storage, workgroups,
};

/// A mutual best match: feature `a` of the first image and feature `b` of
/// the second, with their NCC score in [-1, 1].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Match {
    pub a: usize,
    pub b: usize,
    pub score: f32,
}

/// NCC matching parameters.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NccConfig {
    /// Window side in pixels, odd (the paper: 9).
    pub window: u32,
    /// Keep mutual best matches scoring at least this. Default 0.8.
    pub min_score: f32,
    /// Only pairs at most this far apart (pixels) may match; `None`: all
    /// pairs (the paper's GPU version). Default `None`.
    pub search_radius: Option<f32>,
    /// Windows whose standard deviation (grey 0..1) is below this are flat
    /// and get no match. Default 0.005 (about 1.3 grey levels of 255).
    pub min_std: f32,
    /// A window may have invalid (NaN) pixels: it matches when at least
    /// this fraction of its samples are valid, the NCC of a pair then being
    /// taken over the samples valid in both windows (which must hold this
    /// fraction too). 1: any invalid pixel voids the window. Windows that
    /// leave the image get no match either way. Default 0.8.
    #[serde(default = "default_min_valid")]
    pub min_valid: f32,
}

fn default_min_valid() -> f32 {
    0.8
}

impl Default for NccConfig {
    fn default() -> Self {
        Self {
            window: 9,
            min_score: 0.8,
            search_radius: None,
            min_std: 0.005,
            min_valid: default_min_valid(),
        }
    }
}

impl NccConfig {
    pub fn with_window(mut self, w: u32) -> Self {
        self.window = w;
        self
    }
    pub fn with_min_score(mut self, s: f32) -> Self {
        self.min_score = s;
        self
    }
    pub fn with_search_radius(mut self, r: Option<f32>) -> Self {
        self.search_radius = r;
        self
    }

    pub fn validate(&self) -> Result<(), FeatureError> {
        let bad = |m: String| Err(FeatureError::Config(m));
        if self.window.is_multiple_of(2) || self.window > 63 {
            return bad(format!(
                "window = {} is not odd and at most 63",
                self.window
            ));
        }
        if !(-1.0..=1.0).contains(&self.min_score) {
            return bad(format!("min_score = {} is not in [-1, 1]", self.min_score));
        }
        if let Some(r) = self.search_radius.filter(|r| !(*r >= 0.0 && r.is_finite())) {
            return bad(format!("search_radius = {r} is not a finite value >= 0"));
        }
        if !(self.min_std >= 0.0 && self.min_std.is_finite()) {
            return bad(format!("min_std = {} is not >= 0", self.min_std));
        }
        if !(self.min_valid > 0.0 && self.min_valid <= 1.0) {
            return bad(format!("min_valid = {} is not in (0, 1]", self.min_valid));
        }
        Ok(())
    }

    /// Descriptor row stride: w² padded with zeros to the score tile.
    pub(crate) fn stride(&self) -> u32 {
        (self.window * self.window).next_multiple_of(NCC_TILE)
    }
}

/// Positions as uploaded: non-finite or absurd coordinates become a point
/// far outside any image, whose window is then invalid.
pub(crate) fn sanitize(c: &Corner) -> [f32; 2] {
    let ok = |v: f32| v.is_finite() && v.abs() < 1.0e7;
    if ok(c.x) && ok(c.y) {
        [c.x, c.y]
    } else {
        [-1.0e9, -1.0e9]
    }
}

/// B's features (`b`: their uploaded positions) in the order the
/// one-thread-per-score kernel visits them: by bands of rows as tall as the
/// search radius (at least 8 px), then by x, so that consecutive threads
/// hold nearby features and skip together the pairs beyond the radius.
/// Without a radius, B's own order. Every index once.
pub(crate) fn spatial_order(b: &[[f32; 2]], radius: Option<f32>) -> Vec<u32> {
    let mut order: Vec<u32> = (0..b.len() as u32).collect();
    if let Some(r) = radius.filter(|r| r.is_finite() && *r > 0.0) {
        let band = r.max(8.0);
        let key = |j: &u32| {
            let [x, y] = b[*j as usize];
            ((y / band).floor() as i64, x)
        };
        order.sort_by(|p, q| {
            let ((bp, xp), (bq, xq)) = (key(p), key(q));
            bp.cmp(&bq).then(xp.total_cmp(&xq))
        });
    }
    order
}

/// Mutual best matches from the best entry per row and per column.
pub(crate) fn mutual(rows: &[Best], cols: &[Best], min_score: f32) -> Vec<Match> {
    rows.iter()
        .enumerate()
        .filter_map(|(a, r)| {
            let b = r.index as usize;
            (r.index != NO_INDEX
                && r.score >= min_score
                && cols.get(b).is_some_and(|c| c.index as usize == a))
            .then_some(Match {
                a,
                b,
                score: r.score,
            })
        })
        .collect()
}

/// NCC matching on the GPU. Pipelines are built once and buffers grow to
/// the largest problem seen, so per-frame calls allocate nothing in the
/// steady state.
pub struct NccMatcher {
    ctx: GpuContext,
    config: NccConfig,
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
    /// Match host images on the host ([`NccMatcher::set_host`]).
    host: bool,
}

const PASSES: [&str; 3] = ["vectorize", "score", "bests"];
const ENTRIES: [&str; 8] = [
    "vectorize",
    "score_tiled",
    "bests",
    "score_direct",
    "bests_direct",
    "mutual_refine",
    "mutual_refine_wide",
    "vectorize_group",
];

/// The NCC shader: vectorisation, scores and bests, the refinement of
/// the mutual bests, the gate.
pub(crate) static SHADER: crate::shaders::Shader = crate::shaders::Shader {
    name: "ncc",
    parts: &[
        super::gpu_data::PIXEL_WGSL,
        crate::wgsl_file!("ncc_score.wgsl"),
        crate::wgsl_file!("ncc_refine.wgsl"),
        crate::wgsl_file!("ncc_gate.wgsl"),
    ],
    constants: &[
        super::gpu_data::NCC_CONSTANTS,
        super::gpu_data::PIXEL_CONSTANTS,
    ],
};

impl NccMatcher {
    pub fn new(ctx: &GpuContext, config: NccConfig) -> Result<Self, FeatureError> {
        config.validate()?;
        // Parameters in a storage buffer, not a uniform: see shaders/ncc.wgsl.
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

    pub fn config(&self) -> &NccConfig {
        &self.config
    }

    /// Matches host images on the host from now on ([`super::ncc_match_cpu`],
    /// the reference the shaders are tested against) where `on` (what
    /// [`super::FeatureBackend::host_on`] says for the adapter): on a CPU
    /// adapter it measured faster than its shaders. Images resident on
    /// the GPU ([`NccMatcher::match_resident`]) are still matched there.
    /// Off by default: every test of the shaders runs them.
    pub fn set_host(&mut self, on: bool) {
        self.host = on;
    }

    /// Whether host images are matched on the host ([`NccMatcher::set_host`]).
    pub fn host(&self) -> bool {
        self.host
    }

    /// Chooses the kernels: a workgroup a window's descriptor, the score
    /// tiled in workgroup memory, a workgroup's reduction per row and
    /// column of bests and the refinement's samples in workgroup memory
    /// (the default on GPUs), or a thread a window, one thread per score
    /// and per row or column and the refinement sampling the images for
    /// every score (the default on CPU adapters,
    /// where workgroup barriers are slow: lavapipe's KF refinement took
    /// 16-19 ms more a frame of the real cube tiled). Both give the same
    /// descriptors, scores, bests and refined points.
    pub fn set_tiled(&mut self, tiled: bool) {
        self.tiled = tiled;
    }

    /// Times every pass with GPU timestamp queries from now on (where
    /// supported); see [`NccMatcher::last_timings`].
    pub fn enable_timing(&mut self) {
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
            return super::ncc_match_cpu(img_a, a, img_b, b, &self.config);
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

    /// Mutual best NCC matches between the features `a` of rows `a_rows`
    /// of the GPU-resident image `img_a` and `b` of rows `b_rows` of
    /// `img_b` (positions in each whole image's pixels; a window leaving
    /// its rows leaves its image; `offset_b`: where B's pixel (0, 0) lies
    /// in A's pixels, for the search radius): what [`NccMatcher::match_features`]
    /// gives on those rows as host images, without uploading or reading
    /// back any image. Both bands are copied on the GPU into the matcher's
    /// buffer. With `refine`, B's point of each match is moved to the
    /// sub-pixel NCC peak on the GPU, as [`super::refine_match`] does on
    /// the host. One readback of [`ResidentMatch`]'s few values per
    /// feature of `a`. Sorted by `a`.
    #[allow(clippy::too_many_arguments)]
    pub fn match_resident(
        &mut self,
        img_a: ResidentImage,
        a_rows: std::ops::Range<usize>,
        a: &[Corner],
        img_b: ResidentImage,
        b_rows: std::ops::Range<usize>,
        b: &[Corner],
        offset_b: [i32; 2],
        refine: Option<Refinement>,
    ) -> Result<Vec<ResidentMatch>, FeatureError> {
        if a.is_empty() || b.is_empty() || a_rows.is_empty() || b_rows.is_empty() {
            img_a.check(&a_rows)?;
            img_b.check(&b_rows)?;
            return Ok(Vec::new());
        }
        let y0 = b_rows.start as f64;
        let na = a.len();
        let bands = Bands {
            img_a,
            a_rows,
            img_b,
            b_rows,
            offset_b,
        };
        let enc = self.record_resident(bands, Side::Host(a), Side::Host(b), None, None, refine)?;
        let ctx = &self.ctx.clone();
        let out: Vec<MatchOut> = ctx.read_buffer_after(enc, self.matched.get(), na)?;
        Ok(resident_matches(&out, y0, refine.is_some()))
    }

    /// [`NccMatcher::match_resident`] with A's features written on the GPU
    /// by `export` (recorded into the matching's encoder before its passes,
    /// [`crate::features::Harris::export_corners`]) into the `slots` first
    /// positions of the buffer it is given, in A's band's pixels (slots
    /// without a feature far outside any image), and the matches' readback
    /// put off: the first `rows` rows come back with the next readback.
    /// [`NccMatcher::finish_exported`] returns the matches.
    #[allow(clippy::too_many_arguments)]
    pub fn match_resident_exported(
        &mut self,
        img_a: ResidentImage,
        a_rows: std::ops::Range<usize>,
        slots: usize,
        export: &mut ExportFn,
        img_b: ResidentImage,
        b_rows: std::ops::Range<usize>,
        b: &[Corner],
        offset_b: [i32; 2],
        refine: Option<Refinement>,
        rows: usize,
    ) -> Result<PendingMatches, FeatureError> {
        if slots == 0 || b.is_empty() || a_rows.is_empty() || b_rows.is_empty() {
            return Err(FeatureError::Config(format!(
                "an exported matching of {slots} slots and {} features in bands of {} and {} rows",
                b.len(),
                a_rows.len(),
                b_rows.len()
            )));
        }
        let bands = Bands {
            img_a,
            a_rows,
            img_b,
            b_rows,
            offset_b,
        };
        let sides = (Side::Exported(slots), Side::Host(b));
        self.record_later(bands, sides, export, None, refine, rows.min(slots))
    }

    /// [`NccMatcher::match_resident`] with B's features written on the
    /// GPU by `export` (recorded into the matching's encoder before its
    /// passes: [`crate::features::Harris::export_corners`] placed from
    /// slot `a.len()` on) into the `slots` positions after A's, in B's
    /// band's pixels (slots without a feature far outside any image: those
    /// outside the crop too, where the host leaves them out); with `gate`
    /// (a gather's samples at A's features, [`crate::gpu::GATHER_STRIDE`]
    /// floats each, its validity last, left on the GPU by
    /// [`crate::splat::Splatter::gather_later`]), A's features whose
    /// sample is empty left out as if not given. The matches' readback is
    /// put off (every row of A); [`NccMatcher::finish_exported`] with
    /// `a.len()` returns them, B's indices those of the slots. The same
    /// matches as [`NccMatcher::match_resident`] on the kept features.
    #[allow(clippy::too_many_arguments)]
    pub fn match_resident_exported_b(
        &mut self,
        img_a: ResidentImage,
        a_rows: std::ops::Range<usize>,
        a: &[Corner],
        gate: Option<&wgpu::Buffer>,
        img_b: ResidentImage,
        b_rows: std::ops::Range<usize>,
        slots: usize,
        export: &mut ExportFn,
        offset_b: [i32; 2],
        refine: Option<Refinement>,
    ) -> Result<PendingMatches, FeatureError> {
        if slots == 0 || a.is_empty() || a_rows.is_empty() || b_rows.is_empty() {
            return Err(FeatureError::Config(format!(
                "an exported matching of {} features and {slots} slots in bands of {} and {} rows",
                a.len(),
                a_rows.len(),
                b_rows.len()
            )));
        }
        let bands = Bands {
            img_a,
            a_rows,
            img_b,
            b_rows,
            offset_b,
        };
        let sides = (Side::Host(a), Side::Exported(slots));
        self.record_later(bands, sides, export, gate, refine, a.len())
    }

    /// Records an exported matching ([`NccMatcher::record_resident`]) and
    /// puts off the readback of its first `rows` rows of A.
    fn record_later(
        &mut self,
        bands: Bands,
        (a, b): (Side, Side),
        export: &mut ExportFn,
        gate: Option<&wgpu::Buffer>,
        refine: Option<Refinement>,
        rows: usize,
    ) -> Result<PendingMatches, FeatureError> {
        let y0 = bands.b_rows.start as f64;
        let enc = self.record_resident(bands, a, b, Some(export), gate, refine)?;
        let size = std::mem::size_of::<MatchOut>();
        let read = self
            .ctx
            .read_buffer_later(enc, self.matched.get(), (rows * size) as u64)?;
        Ok(PendingMatches {
            read,
            rows,
            y0,
            refine: refine.is_some(),
        })
    }

    /// The matches of [`NccMatcher::match_resident_exported`] among the
    /// first `kept` features of A (at most the rows read back), as
    /// [`NccMatcher::match_resident`] gives them for those features.
    pub fn finish_exported(
        &mut self,
        pending: PendingMatches,
        kept: usize,
    ) -> Result<Vec<ResidentMatch>, FeatureError> {
        if kept > pending.rows {
            return Err(FeatureError::Config(format!(
                "{kept} features asked of an exported matching, {} read back",
                pending.rows
            )));
        }
        let bytes = pending.read.wait(&self.ctx)?;
        let size = std::mem::size_of::<MatchOut>();
        let out: Vec<MatchOut> = bytemuck::pod_collect_to_vec(&bytes[..kept * size]);
        Ok(resident_matches(&out, pending.y0, pending.refine))
    }

    /// Records a matching on GPU-resident bands (checked), each side's
    /// features from the host or written on the GPU by `export`, A's
    /// gated by `gate`, into an encoder for the caller to read from.
    fn record_resident(
        &mut self,
        bands: Bands,
        a: Side,
        b: Side,
        export: Option<&mut ExportFn>,
        gate: Option<&wgpu::Buffer>,
        refine: Option<Refinement>,
    ) -> Result<crate::gpu::Encoder, FeatureError> {
        let Bands {
            img_a,
            a_rows,
            img_b,
            b_rows,
            offset_b,
        } = bands;
        img_a.check(&a_rows)?;
        img_b.check(&b_rows)?;
        if let Some(r) = &refine {
            r.validate()?;
        }
        let (na, nb) = (a.len(), b.len());
        if let Some(g) = gate {
            let need = (na * crate::gpu::GATHER_STRIDE * 4) as u64;
            if g.size() < need {
                return Err(FeatureError::Config(format!(
                    "a gate of {} bytes for {na} features ({need} needed)",
                    g.size()
                )));
            }
        }
        let sizes = [(img_a.width, a_rows.len()), (img_b.width, b_rows.len())];
        // B's band origin in A's band's pixels.
        let shift = [
            offset_b[0],
            offset_b[1] + b_rows.start as i32 - a_rows.start as i32,
        ];
        // B exported: its features in their own order (no spatial order).
        let b_in_order = matches!(b, Side::Exported(_));
        self.prepare(na, nb, sizes, shift, refine, b_in_order)?;
        let ctx = &self.ctx.clone();
        // Positions in the bands: y less the first row (exact in f32 for
        // image coordinates).
        let band = |c: &Corner, y0: usize| Corner {
            y: c.y - y0 as f32,
            ..*c
        };
        let in_band = |f: &[Corner], y0: usize| -> Vec<[f32; 2]> {
            f.iter().map(|c| sanitize(&band(c, y0))).collect()
        };
        match (&a, &b) {
            (Side::Host(a), Side::Host(b)) => {
                let mut pos = in_band(a, a_rows.start);
                pos.extend(in_band(b, b_rows.start));
                self.write_positions(&pos, na, 0);
            }
            // A's positions are the export's.
            (Side::Exported(_), Side::Host(b)) => {
                self.write_positions(&in_band(b, b_rows.start), 0, na);
            }
            // B's positions are the export's, in no spatial order
            // (`b_in_order`: nothing to upload for it).
            (Side::Host(a), Side::Exported(_)) => {
                let pos = in_band(a, a_rows.start);
                ctx.write_buffer(self.positions.get(), 0, bytemuck::cast_slice(&pos));
            }
            (Side::Exported(_), Side::Exported(_)) => {
                return Err(FeatureError::Config(
                    "a matching of two exported sides".into(),
                ));
            }
        }
        let px = std::mem::size_of::<Pixel>();
        let (len_a, len_b) = (img_a.width * a_rows.len(), img_b.width * b_rows.len());
        let mut enc = ctx.encoder();
        enc.copy_buffer_to_buffer(
            img_a.pixels,
            (a_rows.start * img_a.width * px) as u64,
            self.pixels.get(),
            0,
            (len_a * px) as u64,
        );
        enc.copy_buffer_to_buffer(
            img_b.pixels,
            (b_rows.start * img_b.width * px) as u64,
            self.pixels.get(),
            (len_a * px) as u64,
            (len_b * px) as u64,
        );
        // The export, the gate and the matching's passes: one compute
        // pass where untimed.
        let mut passes = PassChain::new(ctx, &mut enc);
        if let Some(export) = export {
            export(&mut passes, self.positions.get())?;
        }
        if let Some(g) = gate {
            self.record_gate(&mut passes, g, na)?;
        }
        self.encode(&mut passes, na, nb, true);
        drop(passes);
        Ok(enc)
    }

    /// Records the gate of A's `na` positions (the parameters' `na`,
    /// written by [`NccMatcher::prepare`]) by the gather's samples
    /// `samples` (`shaders/ncc.wgsl`, "The gate").
    fn record_gate(
        &mut self,
        passes: &mut PassChain,
        samples: &wgpu::Buffer,
        na: usize,
    ) -> Result<(), FeatureError> {
        let bufs = [samples.clone(), self.positions.get().clone()];
        let (ctx, layout, params) = (&self.ctx, &self.gate_layout, self.params.buffer());
        let bind = self.gate_bind.get(bufs, |b| {
            ctx.bind_buffers_at("ncc gate", layout, &[(0, params), (20, &b[0]), (22, &b[1])])
        })?;
        let pass = passes.stage("gate", self.timer.as_mut());
        pass.set_pipeline(&self.gate);
        pass.set_bind_group(0, bind, &[]);
        pass.dispatch_workgroups(workgroups(na as u32, WORKGROUP_1D), 1, 1);
        Ok(())
    }

    /// Uploads the positions `pos` (A's first `na`, then B's) from slot
    /// `skip` on (the slots before are A's, written on the GPU) and B's
    /// [`spatial_order`] after the window flags in `ok`.
    fn write_positions(&self, pos: &[[f32; 2]], na: usize, skip: usize) {
        let ctx = &self.ctx;
        ctx.write_buffer(
            self.positions.get(),
            (skip * 8) as u64,
            bytemuck::cast_slice(pos),
        );
        let order = spatial_order(&pos[na..], self.config.search_radius);
        ctx.write_buffer(
            self.ok.get(),
            ((skip + pos.len()) * 4) as u64,
            bytemuck::cast_slice(&order),
        );
    }

    /// Checks a problem of `na` and `nb` features in two images of
    /// `sizes` (width, height) against the device's limits, grows the
    /// buffers and writes the parameters.
    fn prepare(
        &mut self,
        na: usize,
        nb: usize,
        sizes: [(usize, usize); 2],
        shift_b: [i32; 2],
        refine: Option<Refinement>,
        b_in_order: bool,
    ) -> Result<(), FeatureError> {
        let ctx = &self.ctx.clone();
        let lim = &ctx.limits;
        let max_groups = lim.max_compute_workgroups_per_dimension as usize;
        if na.max(nb) > max_groups {
            return Err(FeatureError::TooManyFeatures {
                n: na.max(nb),
                max: max_groups,
            });
        }
        let limit = lim.max_storage_buffer_binding_size.min(lim.max_buffer_size);
        if (na * nb * 4) as u64 > limit {
            return Err(FeatureError::TooManyFeatures {
                n: na.max(nb),
                max: ((limit / 4) as f64).sqrt() as usize,
            });
        }
        let [(wa, ha), (wb, hb)] = sizes;
        let n_pix = wa * ha + wb * hb;
        // Shader indices are u32.
        if (n_pix * 8) as u64 > limit || n_pix >= 1 << 28 {
            return Err(FeatureError::TooLarge {
                width: wa.max(wb),
                height: ha + hb,
                reason: format!("two images need {} bytes, limit {limit}", n_pix * 8),
            });
        }
        let stride = self.config.stride() as usize;
        let mut changed = self.pixels.ensure(ctx, (n_pix * 8) as u64);
        changed |= self.positions.ensure(ctx, ((na + nb) * 8) as u64);
        // Unit rows, then raw rows (windows with holes).
        changed |= self.desc.ensure(ctx, ((na + nb) * stride * 8) as u64);
        // The window flags, then B's spatial order.
        changed |= self.ok.ensure(ctx, ((na + 2 * nb) * 4) as u64);
        changed |= self.scores.ensure(ctx, (na * nb * 4) as u64);
        changed |= self.best.ensure(ctx, ((na + nb) * 8) as u64);
        changed |= self
            .matched
            .ensure(ctx, (na * std::mem::size_of::<MatchOut>()) as u64);
        if changed || self.bind.is_none() {
            let bufs = [
                self.params.buffer(),
                self.pixels.get(),
                self.positions.get(),
                self.desc.get(),
                self.ok.get(),
                self.scores.get(),
                self.best.get(),
                self.matched.get(),
            ];
            self.bind = Some(ctx.bind_buffers("ncc", &self.layout, &bufs)?);
        }
        self.refine_wide = refine.is_some_and(|r| 2 * (r.window / 2) + 1 > REFINE_LOCAL_WINDOW);
        let c = &self.config;
        let r = refine.unwrap_or(Refinement {
            window: 1,
            max_shift: 0,
            min_score: 0.0,
        });
        let params = NccParams {
            na: na as u32,
            nb: nb as u32,
            stride: stride as u32,
            window: c.window,
            wa: wa as u32,
            ha: ha as u32,
            wb: wb as u32,
            hb: hb as u32,
            offset_b: (wa * ha) as u32,
            radius2: c.search_radius.map_or(-1.0, |r| r * r),
            min_std: c.min_std,
            min_valid: c.min_valid,
            min_score: c.min_score,
            refine_on: refine.is_some() as u32,
            refine_half: r.window / 2,
            max_shift: r.max_shift,
            refine_min: r.min_score,
            shift_bx: shift_b[0] as f32,
            shift_by: shift_b[1] as f32,
            b_in_order: b_in_order as u32,
        };
        self.params.write(ctx, bytemuck::bytes_of(&params));
        Ok(())
    }

    /// Records the stages (vectorize, scores, bests; with `mutual`, the
    /// mutual check and refinement) into `passes`.
    fn encode(&mut self, passes: &mut PassChain, na: usize, nb: usize, mutual: bool) {
        // The bests: a workgroup a line (rows, then columns), or on CPU
        // adapters a thread a line, in rows of at most 65535 workgroups.
        let lines = (na + nb) as u32;
        let groups = [
            (workgroups(lines, WORKGROUP_1D), 1),
            (
                workgroups(nb as u32, NCC_TILE),
                workgroups(na as u32, NCC_TILE),
            ),
            split_groups(lines),
        ];
        let bind = self.bind.as_ref().expect("bind group built in prepare");
        for ((pipeline, label), (gx, gy)) in self.passes.iter().zip(PASSES).zip(groups) {
            let pass = passes.stage(label, self.timer.as_mut());
            pass.set_bind_group(0, bind, &[]);
            if label == "vectorize" && self.tiled && self.config.window <= VECTORIZE_GROUP_WINDOW {
                pass.set_pipeline(&self.vectorize_group);
                // A workgroup a window (they stride over any beyond).
                pass.dispatch_workgroups(((na + nb) as u32).clamp(1, 65535), 1, 1);
            } else if label == "score" && !self.tiled {
                pass.set_pipeline(&self.score_direct);
                // Four columns per thread.
                pass.dispatch_workgroups(workgroups(nb as u32, 4 * NCC_TILE), gy, 1);
            } else if label == "bests" && !self.tiled {
                pass.set_pipeline(&self.bests_direct);
                let (x, y) = split_groups(workgroups(lines, WORKGROUP_1D));
                pass.dispatch_workgroups(x, y, 1);
            } else {
                pass.set_pipeline(pipeline);
                pass.dispatch_workgroups(gx, gy, 1);
            }
        }
        if mutual {
            let pass = passes.stage("mutual_refine", self.timer.as_mut());
            pass.set_bind_group(0, bind, &[]);
            pass.set_pipeline(if self.refine_wide || !self.tiled {
                &self.mutual_refine_wide
            } else {
                &self.mutual_refine
            });
            // One workgroup per feature of A.
            pass.dispatch_workgroups(na as u32, 1, 1);
        }
        if let Some(t) = self.timer.as_mut() {
            // The timestamps come with this matching's readback.
            match t.resolve_later(&self.ctx, passes.encoder()) {
                Ok(read) => self.timings.append(read),
                Err(e) => log::warn!("GPU timer: {e}"),
            }
        }
    }
}

/// `n` workgroups as a grid of rows of at most 65535 (a dispatch's most
/// in x), x first; the last row's surplus does nothing.
fn split_groups(n: u32) -> (u32, u32) {
    let x = n.clamp(1, 65_535);
    (x, n.div_ceil(x).max(1))
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

/// The matches among `mutual_refine`'s rows (one a feature of A), B's
/// points moved from its band (first row `y0`) into its image.
fn resident_matches(out: &[MatchOut], y0: f64, refine: bool) -> Vec<ResidentMatch> {
    out.iter()
        .enumerate()
        .filter(|(_, m)| m.b != NO_INDEX)
        .map(|(i, m)| ResidentMatch {
            a: i,
            b: m.b as usize,
            score: m.score,
            at: (!refine || m.refined == 1).then_some([m.x as f64, m.y as f64 + y0]),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{spatial_order, split_groups};

    #[test]
    fn workgroups_beyond_a_dispatch_row_wrap_into_rows() {
        for n in [0u32, 1, 64, 65_535, 65_536, 200_000] {
            let (x, y) = split_groups(n);
            assert!((1..=65_535).contains(&x) && y >= 1, "{n}: {x} x {y}");
            assert!(x as u64 * y as u64 >= n as u64, "{n}: {x} x {y} too few");
            assert!(
                (x as u64 * (y as u64 - 1)) < n.max(1) as u64,
                "{n}: {x} x {y}: a whole row too many"
            );
        }
    }

    #[test]
    fn spatial_order_is_a_permutation_by_bands_then_x() {
        let b = [
            [50.0, 3.0],
            [10.0, 25.0],
            [5.0, 9.9],
            [7.0, 0.0],
            [-1.0e9, -1.0e9],
            [30.0, 19.0],
        ];
        // Bands of 10 px: y in [0, 10) holds 0, 2, 3; [10, 20) holds 5;
        // [20, 30) holds 1; the far point first.
        assert_eq!(spatial_order(&b, Some(10.0)), vec![4, 2, 3, 0, 5, 1]);
        // Bands are at least 8 px tall.
        assert_eq!(spatial_order(&b, Some(1.0)), spatial_order(&b, Some(8.0)));
        // No radius (or a meaningless one): B's own order.
        for r in [None, Some(0.0), Some(f32::NAN), Some(f32::INFINITY)] {
            assert_eq!(spatial_order(&b, r), vec![0, 1, 2, 3, 4, 5]);
        }
        let mut sorted = spatial_order(&b, Some(10.0));
        sorted.sort();
        assert_eq!(sorted, vec![0, 1, 2, 3, 4, 5]);
    }
}
