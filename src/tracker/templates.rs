//! A template search under way ([`super::search`]): what it keeps
//! between its viewpoints and candidates.

use super::init::{EdgeMap, Hit};
use super::result::Refused;
use crate::geometry::Pose;
use crate::splat::{GpuModel, SplatTargets};
use std::collections::HashMap;

/// The thinned model on the GPU and its copies textured by keyframes.
pub(super) struct TemplateModels {
    pub(super) geometry: GpuModel,
    pub(super) idx: Vec<usize>,
    pub(super) textured: HashMap<usize, GpuModel>,
}

/// A template search under way (`Tracker::template_search`): the frame
/// shrunk and its edges, the viewpoints, the hits so far and the
/// candidates judged so far.
pub(super) struct TemplateSearch {
    /// Whether the object shows shading only (its candidates refined by
    /// the outline are judged strictly).
    pub(super) shading_only: bool,
    /// Hits closer than this (full-size pixels) are at one place.
    pub(super) near: f64,
    /// Where candidates were refined (full-size pixels).
    pub(super) places: Vec<(f64, f64)>,
    /// Candidates refined at most.
    pub(super) cap: usize,
    pub(super) views: Vec<Pose>,
    /// The shrink factor of the frame.
    pub(super) f: usize,
    pub(super) coarse: Vec<f32>,
    pub(super) cw: usize,
    pub(super) ch: usize,
    pub(super) edges: EdgeMap,
    pub(super) small: crate::geometry::Intrinsics,
    pub(super) targets: SplatTargets,
    pub(super) models: TemplateModels,
    pub(super) hits: Vec<Hit>,
    pub(super) next_view: usize,
    /// The next hit to refine (`None`: the hits are not ranked yet).
    pub(super) next_hit: Option<usize>,
    /// The best candidate that passed: score, pose, refined by the outline.
    pub(super) best: Option<(f64, Pose, bool)>,
    pub(super) refused: Option<(f64, Refused)>,
}

impl TemplateSearch {
    /// Whether every viewpoint has been scored.
    pub(super) fn views_done(&self) -> bool {
        self.next_view >= self.views.len()
    }

    /// Whether every candidate has been judged (the viewpoints first).
    pub(super) fn candidates_done(&self) -> bool {
        self.views_done()
            && (self.places.len() >= self.cap
                || self.next_hit.is_some_and(|n| n >= self.hits.len()))
    }
}

/// A view's grey levels and coverage (0/1).
pub(super) type ViewAndCover = (Vec<f32>, Vec<f32>);
