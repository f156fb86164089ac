//! The Harris shader, its entry points and the selection's passes.

use crate::features::gpu_data::{REFINE_GROUP_RADIUS, SELECT_MAX};
use crate::gpu::WORKGROUP_1D;

pub(super) const PASSES: [&str; 5] = ["deriv_h", "deriv_v", "integrate_h", "integrate_v", "nms"];

/// How a dispatch of the selection is sized.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Size {
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
        crate::features::gpu_data::PIXEL_WGSL,
        crate::wgsl_file!("harris_maps.wgsl"),
        crate::wgsl_file!("harris_select.wgsl"),
        crate::wgsl_file!("harris_select_small.wgsl"),
        crate::wgsl_file!("harris_export.wgsl"),
    ],
    constants: &[
        crate::features::gpu_data::HARRIS_CONSTANTS,
        crate::features::gpu_data::PIXEL_CONSTANTS,
        crate::features::image::LUMA_CONSTANTS,
    ],
};

/// The selection's entry points (`shaders/harris_select.wgsl`)
/// and their sizes.
pub(super) const SELECT_ENTRIES: [(&str, Size); 19] = [
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
/// to select in one workgroup ([`super::HarrisGpuOptions::small_selection`]): the
/// frame loop's detections have a few hundred.
pub(super) const SMALL_SELECT: usize = 512;

/// The most candidates a selection in one workgroup takes: with more (a
/// detection far busier than the last), the host selects, as beyond
/// [`super::HarrisGpuOptions::select_limit`] (its loops stay within lavapipe's 65535
/// iterations an invocation; thousands are what the split passes are
/// for).
pub(super) const SMALL_CAP: usize = 1024;

/// The selection's timed passes (their labels) and the entries each runs,
/// on GPUs (`tiled`): the O(n^2) counts tiled in workgroup memory and
/// split over the others, or (`small`) the selection one workgroup, and
/// the merge likewise, or (`small_merge`) the merge alone (its slots, at
/// most max_corners, fit one workgroup where the candidates do not); the
/// refinement a workgroup a corner (where its radius fits
/// [`REFINE_GROUP_RADIUS`]); else (CPU adapters) one thread an item
/// ([`super::HarrisGpuOptions::tiled_selection`]).
pub(super) fn select_passes(
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
