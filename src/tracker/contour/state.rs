//! What the contour step keeps between frames and within one.

use super::learner::Colours;
use super::normals::ModelNormals;

/// The contour's state in the tracker: the colours it learns, the
/// coverage of its last render, the model's normals and the frame's
/// counts.
pub(crate) struct ContourState {
    /// The object's and the background's colours, learnt online.
    pub(crate) colours: Colours,
    /// The coverage of its last render, to learn the colours from (the
    /// frame's size; a buffer kept between frames).
    pub(crate) mask: Vec<bool>,
    /// Whether `mask` is this frame's (a render of this frame's contour
    /// step; cleared when the frame starts and once learnt).
    pub(crate) mask_fresh: bool,
    /// The model's normals for limbs of depth-only renders (made on first
    /// use).
    pub(crate) normals: Option<ModelNormals>,
    /// The model's median splat radius and its sampling radius
    /// ([`ModelNormals::sampling_radius`]), model units (found on first
    /// use): how far the coverage reaches past a crease depends on them.
    pub(crate) crease_radii: Option<(f64, f64)>,
    /// Whether the last contour step converged (a round moved its outline
    /// less than [`super::ContourConfig::converged_px`]) before its last
    /// round.
    pub(crate) converged: bool,
    /// Whether the check's last view showed no texture of its own
    /// (shading only, or no texture at all): where a view a pixel off
    /// scores alike, so the contour's renders may stand for the check's
    /// (`Tracker::contour_view_serves_check`).
    pub(crate) plain_view: bool,
    /// The rounds of the frame being tracked.
    pub(crate) rounds: usize,
    /// The renders of the frame being tracked.
    pub(crate) renders: usize,
}

impl ContourState {
    /// Nothing learnt yet: colour histograms of `bins` bins a channel,
    /// with `sectors` sectors.
    pub(crate) fn new(bins: u32, sectors: usize) -> Self {
        Self {
            colours: Colours::new(bins, sectors),
            mask: Vec::new(),
            mask_fresh: false,
            normals: None,
            crease_radii: None,
            converged: false,
            plain_view: false,
            rounds: 0,
            renders: 0,
        }
    }

    /// A frame starts: no rounds, no renders, no mask of its own yet.
    pub(crate) fn begin_frame(&mut self) {
        self.rounds = 0;
        self.renders = 0;
        self.mask_fresh = false;
    }
}
