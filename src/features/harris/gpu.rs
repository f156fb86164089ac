//! Harris corners on the GPU (`shaders/harris.wgsl`); the CPU reference is
//! [`super::cpu`], the shared host steps are in [`super`].

use super::host::{Scratch, detect_packed};
use super::{Corner, HarrisConfig, gaussian_taps, merge, pack_pixels, radius, selected_starts};
use crate::features::FeatureError;
use crate::features::gpu_data::{
    Candidate, Counters, ExportParams, FUSED_BYTES, FUSED_HALO, HARRIS_BLOCK, HarrisParams,
    MAX_TAPS, MERGE_LINKS, MERGE_ROUNDS, REFINE_GROUP_RADIUS, RefineCorner, SELECT_MAX,
    SELECT_MAX_CPU, pack_with_holes_into,
};
use crate::features::image::{GreyImage, check_mask};
use crate::features::resident::ResidentImage;
use crate::gpu::{
    BindCache, GpuContext, GpuTimer, GrowBuffer, PassChain, PendingRead, STORAGE_IN, STORAGE_OUT,
    TimerReport, Timings, Uniform, WORKGROUP_1D, WORKGROUP_2D, compute_entry, storage, workgroups,
};

/// Harris corners on the GPU. Pipelines are built once; buffers grow to the
/// largest image seen and are reused, so calling [`Harris::detect`] on
/// every frame allocates nothing in the steady state.
pub struct Harris {
    ctx: GpuContext,
    config: HarrisConfig,
    layout: wgpu::BindGroupLayout,
    passes: Vec<wgpu::ComputePipeline>,
    /// The four filter passes in one (`maps_fused`), where the adapter
    /// has its workgroup memory ([`Harris::set_fused_maps`]).
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
    /// Detect on the host ([`Harris::set_host`]), in these images.
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
    /// The most candidates selected on the GPU ([`Harris::set_select_limit`]).
    select_limit: usize,
    /// Whether the selection's O(n^2) passes share tiles of the items in
    /// workgroup memory ([`Harris::set_tiled_selection`]).
    tiled_select: bool,
    /// The selection in one workgroup forced on or off
    /// ([`Harris::set_small_selection`]); `None`: by the candidates of the
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
    pub origin: [f32; 2],
    pub clip: Option<[f32; 4]>,
    pub band_y0: f32,
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

const PASSES: [&str; 5] = ["deriv_h", "deriv_v", "integrate_h", "integrate_v", "nms"];

/// How a dispatch of the selection is sized.
#[derive(Clone, Copy, PartialEq)]
enum Size {
    /// One thread (`select_sizes`, which writes the sizes below).
    One,
    /// A thread a candidate (indirect, at byte 0 of the sizes).
    Candidates,
    /// A thread a selected corner (indirect, at byte 16).
    Selected,
    /// As `Selected`, [`MERGE_ROUNDS`] times.
    Rounds,
    /// A workgroup a selected corner (indirect, at byte 32).
    SelectedGroups,
    /// Workgroups of candidates by chunks of others (indirect, at byte 48).
    CandidatesSplit,
    /// Workgroups of selected corners by chunks of others (indirect, at
    /// byte 64).
    SelectedSplit,
    /// One workgroup (`select_small`, `merge_small`).
    Group,
}

// `select_sizes` writes the indirect dispatches' workgroups, wgpu no
// longer checking them (gpu::VALIDATE_INDIRECT_ENV): a thread a candidate
// or a workgroup a selected corner stays within a dimension's 65535.
const _: () = assert!(SELECT_MAX.div_ceil(WORKGROUP_1D) <= 65_535 && SELECT_MAX <= 65_535);

/// The Harris shader: the maps, the selection (split passes and one
/// workgroup), the export.
pub(crate) static SHADER: crate::shaders::Shader = crate::shaders::Shader {
    name: "harris",
    parts: &[
        super::super::gpu_data::PIXEL_WGSL,
        crate::wgsl_file!("harris_maps.wgsl"),
        crate::wgsl_file!("harris_select.wgsl"),
        crate::wgsl_file!("harris_select_small.wgsl"),
        crate::wgsl_file!("harris_export.wgsl"),
    ],
    constants: &[
        super::super::gpu_data::HARRIS_CONSTANTS,
        super::super::gpu_data::PIXEL_CONSTANTS,
        super::super::image::LUMA_CONSTANTS,
    ],
};

/// The selection's entry points (`shaders/harris.wgsl`, "The selection")
/// and their sizes.
const SELECT_ENTRIES: [(&str, Size); 19] = [
    ("select_sizes", Size::One),
    ("select_clear", Size::Candidates),
    ("select_rank", Size::CandidatesSplit),
    ("select_rank_finish", Size::Candidates),
    ("select_place", Size::CandidatesSplit),
    ("select_place_finish", Size::Candidates),
    ("select_refine", Size::Selected),
    ("select_refine_group", Size::SelectedGroups),
    ("merge_order", Size::SelectedSplit),
    ("merge_order_finish", Size::Selected),
    ("merge_links", Size::Selected),
    ("merge_round", Size::Rounds),
    // The compaction by a prefix sum in one workgroup.
    ("merge_compact_scan", Size::Group),
    // One thread an item, without workgroup tiles or splits.
    ("select_rank_direct", Size::Candidates),
    ("select_place_direct", Size::Candidates),
    ("merge_order_direct", Size::Selected),
    ("merge_links_direct", Size::Selected),
    // The selection in one workgroup (few candidates, GPUs).
    ("select_small", Size::Group),
    ("merge_small", Size::Group),
];

/// The most candidates of the last detection of a kind for the next one
/// to select in one workgroup ([`Harris::set_small_selection`]): the
/// frame loop's detections have a few hundred.
pub const SMALL_SELECT: usize = 512;

/// The most candidates a selection in one workgroup takes: with more (a
/// detection far busier than the last), the host selects, as beyond
/// [`Harris::set_select_limit`] (its loops stay within lavapipe's 65535
/// iterations an invocation; thousands are what the split passes are
/// for).
pub const SMALL_CAP: usize = 1024;

/// The selection's timed passes (their labels) and the entries each runs,
/// on GPUs (`tiled`): the O(n^2) counts tiled in workgroup memory and
/// split over the others, or (`small`) the selection one workgroup, and
/// the merge likewise, or (`small_merge`) the merge alone (its slots, at
/// most max_corners, fit one workgroup where the candidates do not); the
/// refinement a workgroup a corner (where its radius fits
/// [`REFINE_GROUP_RADIUS`]); else (CPU adapters) one thread an item
/// ([`Harris::set_tiled_selection`]).
fn select_passes(
    tiled: bool,
    small: bool,
    small_merge: bool,
    refine_radius: u32,
) -> [(&'static str, &'static [usize]); 3] {
    let refine: &'static [usize] = if tiled && refine_radius <= REFINE_GROUP_RADIUS {
        &[7]
    } else {
        &[6]
    };
    match (tiled, small, small_merge) {
        (true, true, _) => [("select", &[0, 17]), ("refine", refine), ("merge", &[18])],
        (true, false, true) => [
            ("select", &[0, 1, 2, 3, 4, 5]),
            ("refine", refine),
            ("merge", &[18]),
        ],
        (true, false, false) => [
            ("select", &[0, 1, 2, 3, 4, 5]),
            ("refine", refine),
            ("merge", &[8, 9, 10, 11, 12]),
        ],
        (false, ..) => [
            ("select", &[0, 13, 14]),
            ("refine", refine),
            ("merge", &[15, 16, 11, 12]),
        ],
    }
}

impl Harris {
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
            select_limit: if ctx.is_cpu() {
                SELECT_MAX_CPU
            } else {
                SELECT_MAX
            } as usize,
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

    pub fn config(&self) -> &HarrisConfig {
        &self.config
    }

    /// Detects on the host from now on ([`super::harris_host`]: the CPU
    /// reference's corners, bit for bit) instead of in the shaders, where
    /// `on` (what [`crate::features::FeatureBackend::host_on`] says for the
    /// adapter).
    /// A view splatted on the GPU then comes back as colour (3 floats a
    /// pixel of its window) and a resident view is uploaded packed. Off
    /// by default: every test of the shaders runs them.
    pub fn set_host(&mut self, on: bool) {
        self.host = on;
    }

    /// Selects the corners on the GPU among at most `n` candidates (capped
    /// at [`SELECT_MAX`]); a detection finding more reads them back and
    /// selects on the host (the same corners, one or two waits more). By
    /// default [`SELECT_MAX`], and [`SELECT_MAX_CPU`] on CPU adapters,
    /// where the GPU's comparisons of every pair cost more than the
    /// host's sort.
    pub fn set_select_limit(&mut self, n: usize) {
        self.select_limit = n.min(SELECT_MAX as usize);
    }

    /// Chooses the selection's O(n^2) passes (each candidate's rank in its
    /// cell and place, each corner's place in the merge's order and its
    /// close earlier corners): tiles of the items shared in workgroup
    /// memory, each read once a workgroup (the default on GPUs), or one
    /// thread an item reading every other item itself (the default on CPU
    /// adapters, where the tiles' barriers cost more than they save). The
    /// same comparisons: the same corners, bit for bit.
    pub fn set_tiled_selection(&mut self, tiled: bool) {
        self.tiled_select = tiled;
    }

    /// Where the selection is tiled ([`Harris::set_tiled_selection`]):
    /// runs it in one workgroup a pass (`Some(true)`: the selection's
    /// ranks and places, then the merge, each one dispatch instead of
    /// six; with more than 1024 candidates, `SMALL_CAP`, the host
    /// selects, as beyond [`Harris::set_select_limit`]), split over
    /// workgroups (`Some(false)`), or (`None`, the default) in one
    /// workgroup when the last detection of the same kind (frame or
    /// view) had at most 512 candidates (`SMALL_SELECT`), and else the
    /// merge alone in one workgroup where `max_corners` is at most
    /// `SMALL_CAP` (its slots are at most `max_corners`: a whole image's
    /// thousands of candidates selected by the split passes, its 900
    /// corners merged by one dispatch instead of five and the rounds').
    /// The same corners, bit for bit.
    pub fn set_small_selection(&mut self, small: Option<bool>) {
        self.small_select = small;
    }

    /// The four filter passes (deriv_h, deriv_v, integrate_h,
    /// integrate_v) as one dispatch of tiles with their halos in workgroup
    /// memory (`Some(true)`; the default, `None`, on GPUs), or four
    /// (`Some(false)`; the default on CPU adapters). Only where
    /// radius(sigma_d) + radius(sigma_i) is at most 8 (the default sigmas'
    /// 3 + 5) and the adapter gives a workgroup 24 KB; else four passes
    /// whatever is asked. The same taps in the same order: the same
    /// responses and gradients.
    pub fn set_fused_maps(&mut self, fuse: Option<bool>) {
        self.fuse = fuse;
    }

    /// Whether the next detection's filter passes run as one.
    fn maps_fused(&self) -> bool {
        let halo = radius(self.config.sigma_d) + radius(self.config.sigma_i);
        self.fused.is_some()
            && halo <= FUSED_HALO as usize
            && self.fuse.unwrap_or(!self.ctx.is_cpu())
    }

    /// The most candidates the next selection takes on the GPU: the
    /// limit, at most [`SMALL_CAP`] in one workgroup.
    fn select_limit_now(&self) -> usize {
        if self.small_selection() {
            self.select_limit.min(SMALL_CAP)
        } else {
            self.select_limit
        }
    }

    /// Whether the next selection runs in one workgroup a pass.
    fn small_selection(&self) -> bool {
        self.tiled_select
            && self
                .small_select
                .unwrap_or(self.recent_candidates[self.kind] <= SMALL_SELECT)
    }

    /// Whether the next selection's merge runs in one workgroup (with
    /// the selection, or alone: [`Harris::set_small_selection`]).
    fn small_merge(&self) -> bool {
        self.small_selection()
            || (self.tiled_select
                && self.small_select.is_none()
                && self.config.max_corners <= SMALL_CAP)
    }

    /// Whether detection runs on the host ([`Harris::set_host`]).
    pub fn host(&self) -> bool {
        self.host
    }

    /// Times every pass with GPU timestamp queries from now on (where the
    /// adapter supports them); see [`Harris::last_timings`].
    pub fn enable_timing(&mut self) {
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

    fn params(&self, w: usize, h: usize, n_corners: u32) -> HarrisParams {
        let c = &self.config;
        let (gd, dd) = gaussian_taps(c.sigma_d);
        let (gi, _) = gaussian_taps(c.sigma_i);
        let mut flat = [0f32; MAX_TAPS];
        for (slot, v) in flat.iter_mut().zip(gd.iter().chain(&dd).chain(&gi)) {
            *slot = *v;
        }
        let mut weights = [[0f32; 4]; MAX_TAPS / 4];
        for (i, v) in flat.iter().enumerate() {
            weights[i / 4][i % 4] = *v;
        }
        HarrisParams {
            width: w as u32,
            height: h as u32,
            rd: radius(c.sigma_d) as u32,
            ri: radius(c.sigma_i) as u32,
            k: c.k,
            rel_threshold: c.relative_threshold,
            min_response: c.min_response,
            capacity: capacity(w, h) as u32,
            refine_radius: c.refine_radius,
            refine_iterations: c.refine_iterations,
            refine_inv_2s2: c.refine_inv_2s2(),
            n_corners,
            max_shift: c.max_shift(),
            min_weight: c.min_valid_weight,
            max_corners: c.max_corners.min(u32::MAX as usize) as u32,
            grid_cell: c.grid_cell,
            merge_r2: c.merge_radius * c.merge_radius,
            refine: c.refine as u32,
            select_limit: self.select_limit_now() as u32,
            _pad2: 0,
            weights,
        }
    }

    /// Checks sizes against the device's limits and (re)allocates buffers.
    fn prepare(&mut self, w: usize, h: usize) -> Result<(), FeatureError> {
        let limit = self
            .ctx
            .limits
            .max_storage_buffer_binding_size
            .min(self.ctx.limits.max_buffer_size);
        let too_large = |reason: String| FeatureError::TooLarge {
            width: w,
            height: h,
            reason,
        };
        let max_dim =
            self.ctx.limits.max_compute_workgroups_per_dimension as usize * WORKGROUP_2D as usize;
        if w > max_dim || h > max_dim {
            return Err(too_large(format!("a side exceeds {max_dim} pixels")));
        }
        // Shader indices are u32.
        if w * h >= 1 << 28 {
            return Err(too_large("more than 2^28 pixels".into()));
        }
        let big = (w * h * 16) as u64;
        if big > limit {
            return Err(too_large(format!(
                "needs {big}-byte buffers, limit {limit}"
            )));
        }
        let ctx = &self.ctx.clone();
        let mut changed = false;
        changed |= self.pixels.ensure(ctx, (w * h * 8) as u64);
        changed |= self.rgba.ensure(ctx, (w * h * 12) as u64);
        self.grey_out.ensure(ctx, (w * h * 4) as u64);
        // The fused filter pass keeps its lines in workgroup memory: no
        // `tmp` (its binding takes the smallest buffer).
        changed |= self
            .tmp
            .ensure(ctx, if self.maps_fused() { 16 } else { big });
        changed |= self.grad.ensure(ctx, big);
        changed |= self.response.ensure(ctx, (w * h * 4) as u64);
        changed |= self.counters.ensure(ctx, 16);
        changed |= self.candidates.ensure(ctx, (capacity(w, h) * 16) as u64);
        // The selected corners (by the GPU or the host).
        let cap = capacity(w, h);
        changed |= self
            .corners
            .ensure(ctx, (self.config.max_corners.min(cap).max(1) * 16) as u64);
        let max = SELECT_MAX as u64;
        let mut select_changed = changed;
        select_changed |= self
            .select_index
            .ensure(ctx, (1 + MERGE_LINKS as u64) * max * 4);
        select_changed |= self.select_state.ensure(ctx, max * 4);
        select_changed |= self.ordered.ensure(ctx, max * 16);
        select_changed |= self.select_args.ensure(ctx, 80);
        if select_changed || self.select_bind.is_none() {
            let bufs = [
                (0, self.params.buffer()),
                (3, self.grad.get()),
                (5, self.counters.get()),
                (6, self.candidates.get()),
                (7, self.corners.get()),
                (9, self.select_index.get()),
                (10, self.select_state.get()),
                (11, self.ordered.get()),
            ];
            self.select_bind =
                Some(ctx.bind_buffers_at("harris select", &self.select_layout, &bufs)?);
            let bufs = [
                (0, self.params.buffer()),
                (5, self.counters.get()),
                (12, self.select_args.get()),
            ];
            self.sizes_bind =
                Some(ctx.bind_buffers_at("harris select sizes", &self.sizes_layout, &bufs)?);
        }
        if changed || self.bind.is_none() {
            let bufs = [
                self.params.buffer(),
                self.pixels.get(),
                self.tmp.get(),
                self.grad.get(),
                self.response.get(),
                self.counters.get(),
                self.candidates.get(),
                self.corners.get(),
                self.rgba.get(),
            ];
            self.bind = Some(ctx.bind_buffers("harris", &self.layout, &bufs)?);
        }
        Ok(())
    }

    /// Records the map passes and NMS over `input`, its uploads queued,
    /// and with `select` the selection behind them
    /// ([`Harris::encode_select`]), in one compute pass where untimed (two
    /// where a resolved view's grey levels are kept: a copy between), for
    /// the caller to submit: with a readback behind them, one
    /// submission.
    fn encode_maps(
        &mut self,
        input: Input,
        mask: Option<&[bool]>,
        select: bool,
    ) -> Result<crate::gpu::Encoder, FeatureError> {
        let (w, h) = input.size();
        self.prepare(w, h)?;
        let ctx = &self.ctx.clone();
        let p = self.params(w, h, 0);
        self.params.write(ctx, bytemuck::bytes_of(&p));
        match input {
            Input::Grey(img) => ctx.write_buffer(
                self.pixels.get(),
                0,
                bytemuck::cast_slice(&pack_pixels(img, mask)),
            ),
            Input::Rgb(img) => {
                // RGBA8 with the mask in the alpha byte; little-endian, so
                // unpack4x8unorm reads red first.
                let packed: Vec<u32> = img
                    .pixels()
                    .enumerate()
                    .map(|(i, p)| {
                        let alpha = if mask.is_none_or(|m| m[i]) { 255 } else { 0 };
                        u32::from_le_bytes([p[0], p[1], p[2], alpha])
                    })
                    .collect();
                ctx.write_buffer(self.rgba.get(), 0, bytemuck::cast_slice(&packed));
            }
            // Already on the GPU (Harris::colour_target,
            // Harris::input_target).
            Input::Resolved { .. } | Input::Packed { .. } => {}
        }
        let bind = self.bind.as_ref().expect("prepared");
        let (gx, gy) = (
            workgroups(w as u32, WORKGROUP_2D),
            workgroups(h as u32, WORKGROUP_2D),
        );
        let mut enc = ctx.encoder();
        // The counters start at zero: cleared in the command stream (no
        // upload of its own, and in order with any earlier work of a
        // batch that still reads them).
        enc.clear_buffer(
            self.counters.get(),
            0,
            Some(std::mem::size_of::<Counters>() as u64),
        );
        let mut passes = PassChain::new(ctx, &mut enc);
        if let Input::Rgb(_) = input {
            let pass = passes.stage("grey", self.timer.as_mut());
            pass.set_pipeline(&self.grey);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        if let Input::Resolved { keep_grey, .. } = input {
            let pass = passes.stage("grey", self.timer.as_mut());
            pass.set_pipeline(&self.grey_pack_f32);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
            // The grey levels, before the integration passes reuse
            // `response`.
            if keep_grey {
                passes.encoder().copy_buffer_to_buffer(
                    self.response.get(),
                    0,
                    self.grey_out.get(),
                    0,
                    (w * h * 4) as u64,
                );
            }
        }
        // The filter passes run one invocation per HARRIS_BLOCK pixels
        // along their direction (x for *_h, y for *_v).
        let (bw, bh) = (
            workgroups((w as u32).div_ceil(HARRIS_BLOCK), WORKGROUP_2D),
            workgroups((h as u32).div_ceil(HARRIS_BLOCK), WORKGROUP_2D),
        );
        let groups = [(bw, gy), (gx, bh), (bw, gy), (gx, bh), (gx, gy)];
        let fused = self.maps_fused().then_some(self.fused.as_ref()).flatten();
        if let Some(pipeline) = fused {
            // A tile of WORKGROUP_2D^2 outputs a workgroup.
            let pass = passes.stage("maps", self.timer.as_mut());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        let skip = if fused.is_some() { 4 } else { 0 };
        for ((pipeline, label), (x, y)) in self.passes.iter().zip(PASSES).zip(groups).skip(skip) {
            let pass = passes.stage(label, self.timer.as_mut());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
        if select {
            self.encode_select(&mut passes);
        }
        drop(passes);
        Ok(enc)
    }

    /// Records the selection of the corners behind the map passes
    /// (`shaders/harris.wgsl`, "The selection") into `chain`: three
    /// stages (selection, refinement, merge), several dispatches each, one thread an item
    /// (the O(n^2) ones tiled or not: [`Harris::set_tiled_selection`]),
    /// sized on the GPU (`select_sizes`, then indirect dispatches).
    fn encode_select(&mut self, chain: &mut PassChain) {
        let bind = self.select_bind.as_ref().expect("prepared");
        let sizes = self.sizes_bind.as_ref().expect("prepared");
        let args = self.select_args.get();
        let (small, small_merge) = (self.small_selection(), self.small_merge());
        if small {
            log::trace!("harris: the selection in one workgroup a pass");
        }
        let stages = select_passes(
            self.tiled_select,
            small,
            small_merge,
            self.config.refine_radius,
        );
        for (label, entries) in stages {
            let pass = chain.stage(label, self.timer.as_mut());
            for &e in entries {
                let size = SELECT_ENTRIES[e].1;
                pass.set_pipeline(&self.select[e]);
                pass.set_bind_group(0, if size == Size::One { sizes } else { bind }, &[]);
                match size {
                    Size::One => pass.dispatch_workgroups(1, 1, 1),
                    Size::Candidates => pass.dispatch_workgroups_indirect(args, 0),
                    Size::Selected => pass.dispatch_workgroups_indirect(args, 16),
                    Size::SelectedGroups => pass.dispatch_workgroups_indirect(args, 32),
                    Size::CandidatesSplit => pass.dispatch_workgroups_indirect(args, 48),
                    Size::SelectedSplit => pass.dispatch_workgroups_indirect(args, 64),
                    Size::Group => pass.dispatch_workgroups(1, 1, 1),
                    Size::Rounds => {
                        for _ in 0..self.merge_rounds {
                            pass.dispatch_workgroups_indirect(args, 16);
                        }
                    }
                }
            }
        }
    }

    /// The corners of a selection on the GPU from its counters and the
    /// first `part` of them read back (bytes of [`RefineCorner`]s): the
    /// rest read back where it kept more; where its merge left corners
    /// undecided, the selected corners (in the merge's order) read back
    /// and merged on the host.
    fn selected_corners(
        &mut self,
        counters: &Counters,
        part: &[u8],
        slots: usize,
    ) -> Result<Detected, FeatureError> {
        let ctx = &self.ctx.clone();
        let corner = |r: &RefineCorner| Corner {
            x: r.x,
            y: r.y,
            score: r.score,
        };
        if counters.undecided > 0 {
            log::trace!(
                "harris: {} corners left to the host's merge",
                counters.undecided
            );
            let ordered: Vec<RefineCorner> = ctx.read_buffer(self.ordered.get(), slots)?;
            let corners = merge(
                ordered.iter().map(corner).collect(),
                self.config.merge_radius,
            );
            self.note_kept(corners.len());
            return Ok(Detected {
                corners,
                exported: false,
            });
        }
        let size = std::mem::size_of::<RefineCorner>();
        let kept = (counters.selected as usize).min(slots);
        self.note_kept(kept);
        let exported = kept * size <= part.len();
        let refined: Vec<RefineCorner> = if exported {
            bytemuck::pod_collect_to_vec(&part[..kept * size])
        } else {
            ctx.read_buffer(self.corners.get(), kept)?
        };
        Ok(Detected {
            corners: refined.iter().map(corner).collect(),
            exported,
        })
    }

    /// The response map (row-major, [`crate::features::INVALID_RESPONSE`] where the
    /// support leaves the image or touches an invalid pixel), for tests and
    /// visualisation.
    pub fn response(&mut self, img: &GreyImage) -> Result<Vec<f32>, FeatureError> {
        check_mask(img, None)?;
        if img.is_empty() {
            return Ok(Vec::new());
        }
        if self.host {
            return super::harris_response_host(img, &self.config);
        }
        let enc = self.encode_maps(Input::Grey(img), None, false)?;
        let response = self
            .ctx
            .read_buffer_after(enc, self.response.get(), img.data.len())?;
        self.finish_timing()?;
        Ok(response)
    }

    /// Harris corners of `img`, strongest first. `mask` (row-major, one
    /// flag per pixel) restricts where corners may be reported; NaN pixels
    /// are invalid and no corner's support touches one.
    pub fn detect(
        &mut self,
        img: &GreyImage,
        mask: Option<&[bool]>,
    ) -> Result<Vec<Corner>, FeatureError> {
        check_mask(img, mask)?;
        self.detect_input(Input::Grey(img), mask)
    }

    /// Harris corners of an 8-bit RGB frame, converted to grey on the GPU
    /// (Rec. 601 luma, as [`GreyImage::from_rgb8`] on the CPU): uploads 4
    /// bytes a pixel instead of 8.
    pub fn detect_rgb8(
        &mut self,
        img: &image::RgbImage,
        mask: Option<&[bool]>,
    ) -> Result<Vec<Corner>, FeatureError> {
        let n = img.width() as usize * img.height() as usize;
        if let Some(m) = mask.filter(|m| m.len() != n) {
            return Err(FeatureError::MaskSize {
                expected: n,
                got: m.len(),
            });
        }
        self.detect_input(Input::Rgb(img), mask)
    }

    /// The buffer of packed pixels (8 bytes each: grey value and flags,
    /// as [`crate::features::FrameIntake::pack_window`] writes
    /// them) that [`Harris::detect_packed`] reads, sized for a
    /// `width x height` image.
    pub fn input_target(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<wgpu::Buffer, FeatureError> {
        self.prepare(width.max(1), height.max(1))?;
        Ok(self.pixels.get().clone())
    }

    /// Harris corners of the `width x height` pixels packed into
    /// [`Harris::input_target`] on the GPU (corners only where a pixel is
    /// allowed): the image never comes to the host. Not in host mode.
    pub fn detect_packed(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<Vec<Corner>, FeatureError> {
        self.detect_input(Input::Packed { width, height }, None)
    }

    /// The buffer to resolve a splatted view's colour into (3 f32 a
    /// pixel, NaN where empty: [`crate::splat::Splatter::resolve_into`]) for
    /// [`Harris::detect_resolved`] on a `width x height` view.
    pub fn colour_target(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<wgpu::Buffer, FeatureError> {
        self.prepare(width.max(1), height.max(1))?;
        Ok(self.rgba.get().clone())
    }

    /// Harris corners of the view resolved into [`Harris::colour_target`]:
    /// grey conversion (as [`GreyImage::from_rgb_f32`]) and packing (as
    /// the host packs a [`GreyImage`], pinholes included) on the GPU, so
    /// the view's colour never comes back. Returns the corners (as
    /// [`Harris::detect`] of that grey image without a mask) and the grey
    /// image (one float a pixel, read back for NCC windows and refinement).
    pub fn detect_resolved(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<(Vec<Corner>, GreyImage), FeatureError> {
        if width == 0 || height == 0 {
            return Ok((Vec::new(), GreyImage::filled(width, height, 0.0)));
        }
        if self.host {
            let grey = self.resolved_grey(width, height)?;
            pack_with_holes_into(&grey, None, true, &mut self.scratch.pixels);
            let corners = detect_packed(&mut self.scratch, width, height, &self.config);
            return Ok((corners, grey));
        }
        let input = Input::Resolved {
            width,
            height,
            keep_grey: true,
        };
        let corners = self.detect_input(input, None)?;
        let data = self.ctx.read_buffer(self.grey_out.get(), width * height)?;
        Ok((corners, GreyImage::new(width, height, data)?))
    }

    /// [`Harris::detect_resolved`] without the grey image coming back: the
    /// view stays on the GPU, packed (grey levels, pinholes flagged) as
    /// NCC reads it, in [`Harris::resident_view`] until the next detection.
    pub fn detect_resolved_resident(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<Vec<Corner>, FeatureError> {
        if width == 0 || height == 0 {
            return Ok(Vec::new());
        }
        if self.host {
            // Detected on the host, then packed on the GPU as NCC reads
            // it (the packing the shaders would have left there).
            let grey = self.resolved_grey(width, height)?;
            pack_with_holes_into(&grey, None, true, &mut self.scratch.pixels);
            self.ctx.write_buffer(
                self.pixels.get(),
                0,
                bytemuck::cast_slice(&self.scratch.pixels),
            );
            return Ok(detect_packed(
                &mut self.scratch,
                width,
                height,
                &self.config,
            ));
        }
        let input = Input::Resolved {
            width,
            height,
            keep_grey: false,
        };
        self.detect_input(input, None)
    }

    /// The grey levels of the view resolved into [`Harris::colour_target`]
    /// (`width x height`), converted on the host as the `grey_pack_f32` pass
    /// converts them ([`GreyImage::from_rgb_f32`]).
    fn resolved_grey(&mut self, width: usize, height: usize) -> Result<GreyImage, FeatureError> {
        self.prepare(width, height)?;
        let rgb: Vec<f32> = self.ctx.read_buffer(self.rgba.get(), width * height * 3)?;
        self.timings = Default::default();
        GreyImage::from_rgb_f32(width, height, &rgb)
    }

    /// The view of the last [`Harris::detect_resolved_resident`] (or
    /// [`Harris::detect_resolved`]) of a `width x height` view, as packed
    /// on the GPU (the pixels of [`GreyImage`] the host would pack with
    /// its pinholes, every pixel allowed): valid until the next detection.
    pub fn resident_view(
        &self,
        width: usize,
        height: usize,
    ) -> Result<ResidentImage<'_>, FeatureError> {
        if self.pixels.size() == 0 {
            return Err(FeatureError::Config("no view detected yet".into()));
        }
        Ok(ResidentImage {
            pixels: self.pixels.get(),
            width,
            height,
        })
    }

    fn detect_input(
        &mut self,
        input: Input,
        mask: Option<&[bool]>,
    ) -> Result<Vec<Corner>, FeatureError> {
        let (w, h) = input.size();
        if w == 0 || h == 0 {
            return Ok(Vec::new());
        }
        if self.host {
            self.timings = Default::default();
            let pixels = &mut self.scratch.pixels;
            match input {
                Input::Grey(img) => pack_with_holes_into(img, mask, true, pixels),
                Input::Rgb(img) => {
                    pack_with_holes_into(&GreyImage::from_rgb8(img), mask, true, pixels)
                }
                // detect_resolved* detect these on the host themselves.
                Input::Resolved { .. } => {
                    return Err(FeatureError::Config(
                        "a resolved view in host mode: use detect_resolved".into(),
                    ));
                }
                Input::Packed { .. } => {
                    return Err(FeatureError::Config(
                        "pixels packed on the GPU in host mode".into(),
                    ));
                }
            }
            return Ok(detect_packed(&mut self.scratch, w, h, &self.config));
        }
        // The maps, the candidates and their selection in one submission,
        // and one readback: the counts and the corners, as many as recent
        // detections kept and a quarter more (the rest, when there are
        // more, in a second). With more candidates than the GPU selects
        // among (Harris::set_select_limit), they come back in a second readback, the
        // host selects, and the selected are refined on the GPU after it
        // (a third).
        self.kind = matches!(input, Input::Resolved { .. }) as usize;
        let limit = self.select_limit_now();
        let rows = self.readback_rows(w, h);
        let enc = self.encode_maps(input, mask, true)?;
        let ctx = &self.ctx.clone();
        let size = std::mem::size_of::<RefineCorner>();
        let counters_size = std::mem::size_of::<Counters>() as u64;
        let reads = [
            (self.counters.get(), counters_size),
            (self.corners.get(), (rows * size) as u64),
        ];
        let parts = ctx.read_buffers_after(enc, &reads)?;
        let counters: Counters = bytemuck::pod_read_unaligned(&parts[0]);
        let detected = self.finish_detection(w, h, &counters, &parts[1], rows, limit)?;
        self.finish_timing()?;
        Ok(detected.corners)
    }

    /// The corners read back with a detection's counters in a `w x h`
    /// image: as many as the last two detections of its kind kept and a
    /// quarter more, at most as many as it can keep.
    fn readback_rows(&self, w: usize, h: usize) -> usize {
        let cap = self.config.max_corners.min(capacity(w, h));
        let recent = self.recent_corners[self.kind]
            .iter()
            .max()
            .copied()
            .unwrap_or(0);
        (recent * 5 / 4 + 64).min(cap)
    }

    /// Records the corners a detection of the current kind kept.
    fn note_kept(&mut self, n: usize) {
        let r = &mut self.recent_corners[self.kind];
        *r = [r[1], n];
    }

    /// The corners of a detection in a `w x h` image from its counters
    /// and the first `rows` corners read back with them: selected on the
    /// GPU, or (more candidates than it selects among) read back and
    /// selected on the host.
    fn finish_detection(
        &mut self,
        w: usize,
        h: usize,
        counters: &Counters,
        part: &[u8],
        rows: usize,
        limit: usize,
    ) -> Result<Detected, FeatureError> {
        let room = capacity(w, h);
        let cap = self.config.max_corners.min(room);
        let count = (counters.count as usize).min(room);
        self.recent_candidates[self.kind] = count;
        if count <= limit {
            log::trace!(
                "harris: {count} candidates, {} corners, {rows} read back",
                counters.selected
            );
            return self.selected_corners(counters, part, count.min(cap));
        }
        log::trace!("harris: {count} candidates, selected on the host");
        let ctx = &self.ctx.clone();
        let cands: Vec<Candidate> = ctx.read_buffer(self.candidates.get(), count)?;
        let starts = selected_starts(&cands, &self.config);
        self.note_kept(starts.len());
        let corners = if self.config.refine && !starts.is_empty() {
            self.refine(w, h, &starts)?
        } else {
            starts
        };
        Ok(Detected {
            corners: merge(corners, self.config.merge_radius),
            exported: false,
        })
    }

    /// [`Harris::detect_resolved_resident`] whose corners come back with
    /// a later readback: the detection is recorded and submitted (within
    /// a batch, put off with it) and the reads of its counters and first
    /// corners put off ([`GpuContext::read_buffer_later`]), so that work
    /// fed from its corners on the GPU ([`Harris::export_corners`]) goes
    /// before the one wait. Finish it with [`Harris::finish_later`]. Not
    /// in host mode, nor for an empty view.
    pub fn detect_resolved_resident_later(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<PendingCorners, FeatureError> {
        let input = Input::Resolved {
            width,
            height,
            keep_grey: false,
        };
        self.detect_later(input, 1)
    }

    /// [`Harris::detect_packed`] whose corners come back with a later
    /// readback, as [`Harris::detect_resolved_resident_later`] (a frame's
    /// window: its readback sized by recent frames' detections). Not in
    /// host mode, nor for an empty window.
    pub fn detect_packed_later(
        &mut self,
        width: usize,
        height: usize,
    ) -> Result<PendingCorners, FeatureError> {
        self.detect_later(Input::Packed { width, height }, 0)
    }

    /// A detection of `input` (of `kind`: frames 0, views 1) recorded and
    /// submitted, its readbacks put off.
    fn detect_later(&mut self, input: Input, kind: usize) -> Result<PendingCorners, FeatureError> {
        let (width, height) = input.size();
        if self.host {
            return Err(FeatureError::Config(
                "a detection read back later in host mode".into(),
            ));
        }
        if width == 0 || height == 0 {
            return Err(FeatureError::Config(format!(
                "a detection read back later in an empty {width}x{height} image"
            )));
        }
        self.kind = kind;
        let limit = self.select_limit_now();
        let rows = self.readback_rows(width, height);
        let enc = self.encode_maps(input, None, true)?;
        let ctx = &self.ctx.clone();
        let size = std::mem::size_of::<RefineCorner>();
        let counters_size = std::mem::size_of::<Counters>() as u64;
        let counters = ctx.read_buffer_later(enc, self.counters.get(), counters_size)?;
        let corners =
            ctx.read_buffer_later(ctx.encoder(), self.corners.get(), (rows * size) as u64)?;
        Ok(PendingCorners {
            counters,
            corners,
            rows,
            slots: self.config.max_corners.min(capacity(width, height)),
            width,
            height,
            kind,
            limit,
        })
    }

    /// Records into `enc` the export of `pending`'s corners (behind its
    /// detection; [`PendingCorners::slots`] slots): slot `i` of `points`
    /// gets corner `i` (its position in the detection's pixels, a
    /// gather's point; with `None`, a scratch buffer of the detector's)
    /// and slot `place.first + i` of `positions` the same placed as
    /// [`ExportPlace`] says (as NCC reads its positions); slots past the
    /// corners kept, or all where the host is to finish the selection, get
    /// a point far outside any image (a void NCC window, an empty sample).
    /// `shaders/harris.wgsl`, "The export".
    pub fn export_corners(
        &mut self,
        passes: &mut PassChain,
        pending: &PendingCorners,
        place: ExportPlace,
        positions: &wgpu::Buffer,
        points: Option<&wgpu::Buffer>,
    ) -> Result<(), FeatureError> {
        let n = pending.slots;
        let points = match points {
            Some(p) => p.clone(),
            None => {
                self.export_scratch.ensure(&self.ctx, (n.max(1) * 8) as u64);
                self.export_scratch.get().clone()
            }
        };
        let need = [((place.first + n) * 8) as u64, (n * 8) as u64];
        for ((what, b), need) in [("positions", positions), ("points", &points)]
            .into_iter()
            .zip(need)
        {
            if b.size() < need {
                return Err(FeatureError::Config(format!(
                    "the export's {what} buffer holds {} bytes, {need} needed",
                    b.size()
                )));
            }
        }
        let clip = place.clip.unwrap_or([0.0; 4]);
        let params = ExportParams {
            origin_x: place.origin[0],
            origin_y: place.origin[1],
            band_y0: place.band_y0,
            n: n as u32,
            first: place.first as u32,
            clip: place.clip.is_some() as u32,
            _pad0: 0,
            _pad1: 0,
            clip_x0: clip[0],
            clip_y0: clip[1],
            clip_x1: clip[2],
            clip_y1: clip[3],
        };
        self.export_params
            .write(&self.ctx, bytemuck::bytes_of(&params));
        let bufs = [
            self.counters.get().clone(),
            self.corners.get().clone(),
            positions.clone(),
            points,
        ];
        let (ctx, layout) = (&self.ctx, &self.export_layout);
        let (params, export_params) = (self.params.buffer(), self.export_params.buffer());
        let bind = self.export_bind.get(bufs, |b| {
            let at = [
                (0, params),
                (5, &b[0]),
                (7, &b[1]),
                (13, export_params),
                (14, &b[2]),
                (15, &b[3]),
            ];
            ctx.bind_buffers_at("harris export", layout, &at)
        })?;
        let pass = passes.stage("export", self.timer.as_mut());
        pass.set_pipeline(&self.export);
        pass.set_bind_group(0, bind, &[]);
        pass.dispatch_workgroups(workgroups(n as u32, WORKGROUP_1D), 1, 1);
        Ok(())
    }

    /// The corners of a detection from
    /// [`Harris::detect_resolved_resident_later`]: its readback (one wait,
    /// which brings every readback put off since with it), and where the
    /// host finishes the selection, its waits.
    pub fn finish_later(&mut self, pending: PendingCorners) -> Result<Detected, FeatureError> {
        let ctx = &self.ctx.clone();
        let counters = pending.counters.wait(ctx)?;
        let part = pending.corners.wait(ctx)?;
        let counters: Counters = bytemuck::pod_read_unaligned(&counters);
        self.kind = pending.kind;
        let detected = self.finish_detection(
            pending.width,
            pending.height,
            &counters,
            &part,
            pending.rows,
            pending.limit,
        )?;
        self.finish_timing()?;
        Ok(detected)
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

    fn refine(
        &mut self,
        w: usize,
        h: usize,
        corners: &[Corner],
    ) -> Result<Vec<Corner>, FeatureError> {
        let ctx = &self.ctx.clone();
        let n = corners.len();
        let p = self.params(w, h, n as u32);
        self.params.write(ctx, bytemuck::bytes_of(&p));
        let input: Vec<RefineCorner> = corners
            .iter()
            .map(|c| RefineCorner {
                x: c.x,
                y: c.y,
                score: c.score,
                status: 0.0,
            })
            .collect();
        ctx.write_buffer(self.corners.get(), 0, bytemuck::cast_slice(&input));
        let mut enc = ctx.encoder();
        {
            let mut passes = PassChain::new(ctx, &mut enc);
            let pass = passes.stage("refine", self.timer.as_mut());
            pass.set_pipeline(&self.refine);
            pass.set_bind_group(0, self.bind.as_ref().expect("prepared"), &[]);
            pass.dispatch_workgroups(workgroups(n as u32, WORKGROUP_1D), 1, 1);
        }
        let out: Vec<RefineCorner> = ctx.read_buffer_after(enc, self.corners.get(), n)?;
        Ok(out
            .iter()
            .map(|c| Corner {
                x: c.x,
                y: c.y,
                score: c.score,
            })
            .collect())
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    impl Harris {
        /// The GPU's selection among `cands` in a `w x h` image whose
        /// gradients are all zero (a refinement keeps every corner at its
        /// start): the candidates written as NMS writes them, the
        /// selection's passes, the corners read back.
        fn select_candidates(
            &mut self,
            w: usize,
            h: usize,
            cands: &[Candidate],
        ) -> Result<Vec<Corner>, FeatureError> {
            self.prepare(w, h)?;
            let ctx = &self.ctx.clone();
            let p = self.params(w, h, 0);
            self.params.write(ctx, bytemuck::bytes_of(&p));
            let counters = Counters {
                max_bits: 0,
                count: cands.len() as u32,
                selected: 0,
                undecided: 0,
            };
            ctx.write_buffer(self.counters.get(), 0, bytemuck::bytes_of(&counters));
            if !cands.is_empty() {
                ctx.write_buffer(self.candidates.get(), 0, bytemuck::cast_slice(cands));
            }
            let mut enc = ctx.encoder();
            enc.clear_buffer(self.grad.get(), 0, None);
            self.encode_select(&mut PassChain::new(ctx, &mut enc));
            let counters: Counters = ctx.read_buffer_after(enc, self.counters.get(), 1)?[0];
            // The merge in one workgroup runs its rounds to the end.
            assert!(
                !self.small_merge() || counters.undecided == 0,
                "{} corners left undecided in one workgroup",
                counters.undecided
            );
            let slots = cands.len().min(self.config.max_corners);
            self.selected_corners(&counters, &[], slots)
                .map(|d| d.corners)
        }
    }

    /// `n` candidates at distinct pixels of `w x h`, clustered (so that
    /// merges chain and cells fill) where `dense`; scores drawn from four
    /// values where `ties`.
    fn candidates(
        rng: &mut Rng,
        n: usize,
        w: u32,
        h: u32,
        dense: bool,
        ties: bool,
    ) -> Vec<Candidate> {
        let mut seen = std::collections::HashSet::new();
        let mut out = Vec::new();
        let (cw, ch) = if dense {
            (w.min(24), h.min(24))
        } else {
            (w, h)
        };
        while out.len() < n && seen.len() < (cw * ch) as usize {
            let x = (rng.next_f64() * cw as f64) as u32 % cw;
            let y = (rng.next_f64() * ch as f64) as u32 % ch;
            if !seen.insert((x, y)) {
                continue;
            }
            let score = if ties {
                [0.25f32, 0.5, 0.75, 1.0][(rng.next_f64() * 4.0) as usize % 4]
            } else {
                (rng.next_f64() as f32).max(1e-6)
            };
            out.push(Candidate {
                x,
                y,
                score,
                _pad: 0,
            });
        }
        out
    }

    /// The host's selection and merge (the CPU reference's) of `cands`
    /// kept at their pixels.
    fn host_selection(cands: &[Candidate], cfg: &HarrisConfig) -> Vec<Corner> {
        merge(selected_starts(cands, cfg), cfg.merge_radius)
    }

    #[test]
    fn gpu_selection_is_the_hosts_bit_for_bit_on_random_candidates() {
        let ctx = crate::gpu::shared_test_context();
        let mut rng = Rng::new(7);
        let (w, h) = (200, 150);
        let (mut cases, mut smalls, mut small_merges) = (0, 0, 0);
        // One detector (its pipelines built once), its configuration set
        // for each case.
        let mut harris = Harris::new(ctx, HarrisConfig::default()).unwrap();
        for (case, (n, dense)) in [
            (0, false),
            (1, false),
            (37, false),
            (500, false),
            (400, true),
            (3000, false),
        ]
        .into_iter()
        .enumerate()
        {
            for grid in [0, 1, 16, 32] {
                for max in [1, 25, 900, 5000] {
                    for radius in [0.0, 1.5, 4.0] {
                        for ties in [false, true] {
                            // A sample of the combinations, every value of
                            // each parameter seen with each other's.
                            let key = n + grid as usize + max + (radius * 2.0) as usize;
                            if !(key + ties as usize).is_multiple_of(3) {
                                continue;
                            }
                            let cfg = HarrisConfig {
                                max_corners: max,
                                grid_cell: grid,
                                merge_radius: radius,
                                ..HarrisConfig::default()
                            };
                            harris.config = cfg.clone();
                            harris.set_select_limit(SELECT_MAX as usize);
                            // The four selections in turn: one thread an
                            // item, split over workgroups, one workgroup a
                            // pass (up to SMALL_SELECT candidates: beyond,
                            // its loops pass lavapipe's 65535 iterations),
                            // split with the merge in one workgroup (the
                            // default after a busy detection, where
                            // max_corners <= SMALL_CAP).
                            let mode = cases % 4;
                            let small = mode == 2 && n <= SMALL_SELECT;
                            harris.set_tiled_selection(mode > 0);
                            harris.set_small_selection(Some(small));
                            if mode == 3 {
                                harris.set_small_selection(None);
                                harris.recent_candidates[harris.kind] = usize::MAX;
                                assert!(!harris.small_selection());
                                assert_eq!(harris.small_merge(), max <= SMALL_CAP);
                                small_merges += harris.small_merge() as usize;
                            }
                            // Every other case without the parallel rounds:
                            // the host finishes the whole merge.
                            harris.merge_rounds = if (case + cases) % 2 == 0 {
                                0
                            } else {
                                MERGE_ROUNDS
                            };
                            let cands = candidates(&mut rng, n, w, h, dense, ties);
                            let got = harris
                                .select_candidates(w as usize, h as usize, &cands)
                                .unwrap();
                            let want = host_selection(&cands, &cfg);
                            let first = got.iter().zip(&want).position(|(g, w)| g != w);
                            assert!(
                                got == want,
                                "{n} candidates (dense {dense}, ties {ties}), grid {grid}, max {max}, radius {radius}, {} rounds, mode {mode}, small {small}: {} corners against the host's {}, first difference at {first:?}",
                                harris.merge_rounds,
                                got.len(),
                                want.len()
                            );
                            cases += 1;
                            smalls += small as usize;
                        }
                    }
                }
            }
        }
        assert!(cases > 100, "{cases} cases");
        assert!(smalls > 20, "{smalls} cases in one workgroup");
        assert!(
            small_merges > 20,
            "{small_merges} merges alone in one workgroup"
        );
    }
}
