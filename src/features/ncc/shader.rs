//! The NCC shader and its entry points.

pub(super) const PASSES: [&str; 3] = ["vectorize", "score", "bests"];
pub(super) const ENTRIES: [&str; 8] = [
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
        crate::features::gpu_data::PIXEL_WGSL,
        crate::wgsl_file!("ncc_score.wgsl"),
        crate::wgsl_file!("ncc_refine.wgsl"),
        crate::wgsl_file!("ncc_gate.wgsl"),
    ],
    constants: &[
        crate::features::gpu_data::NCC_CONSTANTS,
        crate::features::gpu_data::PIXEL_CONSTANTS,
    ],
};
