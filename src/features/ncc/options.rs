//! How the matcher runs: code paths that give the same matches.

/// How [`super::NccMatcher`] runs. Every choice gives the same matches;
/// the defaults suit the adapter (`None`: the adapter's choice). Give it
/// to [`super::NccMatcher::with_options`] or
/// [`super::NccMatcher::set_options`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct NccOptions {
    /// Match host images on the host ([`super::ncc_match_cpu`], the
    /// reference the shaders are tested against; what
    /// [`crate::features::FeatureBackend::host_on`] says for the adapter):
    /// on a CPU adapter it measured faster than its shaders. Images
    /// resident on the GPU ([`super::NccMatcher::match_resident`]) are
    /// still matched there. Off by default: every test of the shaders
    /// runs them.
    pub host: bool,
    /// The kernels: a workgroup a window's descriptor, the score tiled in
    /// workgroup memory, a workgroup's reduction per row and column of
    /// bests and the refinement's samples in workgroup memory (`true`), or
    /// a thread a window, one thread per score and per row or column and
    /// the refinement sampling the images for every score (`false`).
    /// `None`: tiled on GPUs, not on CPU adapters, where workgroup
    /// barriers are slow (lavapipe's KF refinement took 16-19 ms more a
    /// frame of the real cube tiled). Both give the same descriptors,
    /// scores, bests and refined points.
    pub tiled: Option<bool>,
    /// Time every pass with GPU timestamp queries (where supported); see
    /// [`super::NccMatcher::last_timings`].
    pub timing: bool,
}
