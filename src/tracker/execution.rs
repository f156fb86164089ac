//! How the tracker runs its steps ([`Execution`]): choices between code
//! paths that give the same poses (on the GPU or on the host, chained or
//! in turn, on a thread of their own or not), and GPU timing. The
//! defaults are the right ones for the adapter; the other paths are for
//! the tests and benches that compare them, and for profiling.

/// The tracker's code paths and GPU timing, given to
/// [`super::TrackerBuilder::execution`]. `None` (and the [`Default`]) keeps
/// what the tracker picks for its adapter. Every choice gives the same
/// poses (some within f32 rounding: see each field).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Execution {
    /// Match on GPU-resident images (`true`, the default on GPUs): the
    /// frames' grey levels uploaded once per frame, the novel view left on
    /// the GPU by Harris, the mutual check and the KF step's sub-pixel
    /// refinement on the GPU, so only a few values per feature come back;
    /// or (`false`, the default on CPU adapters) on host crops uploaded per
    /// call, with the view's grey levels read back and the refinement on
    /// the host. The same matches (refined points within f32 rounding).
    /// On lavapipe the host path measured faster (the real cube's KF
    /// matching about 10-14 ms a frame against 42-48 ms).
    pub resident_matching: Option<bool>,
    /// Chain the KF step's detection on the novel view, its matching and
    /// the gather at its corners on the GPU where matching is resident
    /// (`true`, the default): one wait for the three instead of two, the
    /// same corners, matches and samples. `false`: detect, then match.
    pub chained_kf: bool,
    /// Chain the frame's detection and IT's matching on the GPU where
    /// matching is resident (`true`, the default): one wait for both
    /// instead of two, the same corners and matches. Not with
    /// `it_interior_px` (its probes need the gather first). `false`:
    /// detect, then match.
    pub chained_it: bool,
    /// Score the pose check on the GPU (`true`, the default on GPUs) or
    /// read the view back and score it on the host (`false`, the default
    /// on CPU adapters, where that measured faster). The scores are the
    /// same to f32 rounding.
    pub resident_check: Option<bool>,
    /// Find the contour's outline on the GPU (`true`, the default on
    /// GPUs) or on the host from a readback of the window's depth (the
    /// default on CPU adapters). Only for depth-only contour renders; the
    /// points, and so the poses, are the same.
    pub resident_outline: Option<bool>,
    /// Learn the contour's colours from a tracked frame on a thread of
    /// their own while the next frame's texture steps run (`true`, the
    /// default), or on the calling thread before [`super::Tracker::track`]
    /// returns (for profiling, or an embedding that wants no thread). The
    /// colours, and so the poses, are the same either way.
    pub background_learning: bool,
    /// Time every GPU pass of every frame (where the adapter supports
    /// timestamp queries): [`super::StageTimes::gpu`]. Off by default;
    /// the timestamps come with the frame's own readbacks, so timing adds
    /// no wait.
    pub gpu_timing: bool,
    /// Every kernel choice between a GPU's (workgroup tiles, splits and
    /// groups: `true`) and a CPU adapter's (one thread an item: `false`),
    /// whatever the adapter: Harris's selection, the three matchers and
    /// the check. For tests that run the GPUs' kernels on lavapipe.
    pub gpu_kernels: Option<bool>,
    /// The corner selection's O(n^2) passes tiled in workgroup memory or
    /// one thread an item (the tracker's Harris; after
    /// [`Execution::gpu_kernels`]).
    pub harris_tiled_selection: Option<bool>,
    /// Where tiled, the corner selection in one workgroup a pass (`true`)
    /// or split over workgroups (`false`), in the tracker's Harris.
    pub harris_small_selection: Option<bool>,
    /// The most candidates the tracker's Harris selects among on the GPU
    /// (more are selected on the host, and the chained steps fall back to
    /// matching from the host's corners): for tests of those fallbacks.
    pub harris_select_limit: Option<usize>,
}

impl Default for Execution {
    fn default() -> Self {
        Self {
            resident_matching: None,
            chained_kf: true,
            chained_it: true,
            resident_check: None,
            resident_outline: None,
            background_learning: true,
            gpu_timing: false,
            gpu_kernels: None,
            harris_tiled_selection: None,
            harris_small_selection: None,
            harris_select_limit: None,
        }
    }
}
