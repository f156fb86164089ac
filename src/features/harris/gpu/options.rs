//! How the GPU detector runs: code paths that give the same corners.

/// How [`super::Harris`] runs. Every choice gives the same corners, bit
/// for bit; the defaults suit the adapter (`None`: the adapter's choice).
/// Give it to [`super::Harris::with_options`] or
/// [`super::Harris::set_options`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct HarrisGpuOptions {
    /// Detect on the host ([`crate::features::harris_host`]: the CPU
    /// reference's corners, bit for bit) instead of in the shaders (what
    /// [`crate::features::FeatureBackend::host_on`] says for the adapter).
    /// A view splatted on the GPU then comes back as colour (3 floats a
    /// pixel of its window) and a resident view is uploaded packed. Off by
    /// default: every test of the shaders runs them.
    pub host: bool,
    /// Select the corners on the GPU among at most this many candidates
    /// (capped at [`crate::features::SELECT_MAX`]); a detection finding
    /// more reads them back and selects on the host (the same corners,
    /// one or two waits more). `None`: [`crate::features::SELECT_MAX`],
    /// and [`crate::features::SELECT_MAX_CPU`] on CPU adapters, where the
    /// GPU's comparisons of every pair cost more than the host's sort.
    pub select_limit: Option<usize>,
    /// The selection's O(n^2) passes (each candidate's rank in its cell
    /// and place, each corner's place in the merge's order and its close
    /// earlier corners): tiles of the items shared in workgroup memory,
    /// each read once a workgroup (`true`), or one thread an item reading
    /// every other item itself (`false`). `None`: tiled on GPUs, not on
    /// CPU adapters (where the tiles' barriers cost more than they save).
    pub tiled_selection: Option<bool>,
    /// Where the selection is tiled: in one workgroup a pass (`Some(true)`:
    /// the selection's ranks and places, then the merge, each one
    /// dispatch instead of six; with more than 1024 candidates, the host
    /// selects, as beyond `select_limit`), split over workgroups
    /// (`Some(false)`), or (`None`) in one workgroup when the last
    /// detection of the same kind (frame or view) had at most 512
    /// candidates, and else the merge alone in one workgroup where
    /// `max_corners` is at most 1024 (its slots are at most
    /// `max_corners`: a whole image's thousands of candidates selected by
    /// the split passes, its 900 corners merged by one dispatch instead of
    /// five and the rounds').
    pub small_selection: Option<bool>,
    /// The four filter passes (deriv_h, deriv_v, integrate_h,
    /// integrate_v) as one dispatch of tiles with their halos in
    /// workgroup memory (`Some(true)`), or four (`Some(false)`). `None`:
    /// one on GPUs, four on CPU adapters. Only where radius(sigma_d) +
    /// radius(sigma_i) is at most 8 (the default sigmas' 3 + 5) and the
    /// adapter gives a workgroup 24 KB; else four passes whatever is
    /// asked. The same taps in the same order: the same responses and
    /// gradients.
    pub fused_maps: Option<bool>,
    /// Time every pass with GPU timestamp queries (where the adapter
    /// supports them); see [`super::Harris::last_timings`].
    pub timing: bool,
}
