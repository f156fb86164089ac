//! What the search while lost ([`super`]) keeps between frames: the
//! round under way and the times its budget is measured by.

use crate::geometry::Pose;
use crate::tracker::detect::cache::Detector;
use crate::tracker::detect::{Candidate, DETECT_REFINE_STEPS, Described};
use crate::tracker::frames::Frame;
use crate::tracker::result::Refused;
use crate::tracker::templates::TemplateSearch;
use std::time::Duration;

/// The kinds of the search's units, each timed on its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Unit {
    /// One keyframe's features made (the first round only).
    Keyframe,
    /// The round's frame: the detector's corners, described.
    Describe,
    /// One keyframe's features matched to the frame's, a pose by PnP.
    Match,
    /// The detector made (its Harris, without keyframe features).
    Detector,
    /// One KF step refining a feature candidate.
    Refine,
    /// A refined feature candidate checked.
    Check,
    /// The template search made ready (the frame shrunk, the model thinned).
    Templates,
    /// One viewpoint's templates scored over the frame.
    View,
    /// A template candidate refined and checked.
    TemplateCandidate,
    /// The round is over (no work).
    End,
}

/// Unit kinds timed.
pub(super) const UNITS: usize = 10;

/// Weight of the newest time in the running times.
pub(super) const RUNNING: f64 = 0.25;

/// The search while lost, between frames, with the times its budget is
/// measured by.
#[derive(Default)]
pub(in crate::tracker) struct LostSearch {
    pub(super) round: Option<Round>,
    /// Each unit kind's running time, seconds.
    pub(super) costs: [Option<f64>; UNITS],
    /// A tracked frame's running time, seconds.
    pub(super) tracked: Option<f64>,
    /// The running time of a lost frame's own steps (besides the search),
    /// seconds.
    pub(super) steps: Option<f64>,
    /// A round of templates beside the rounds of features (their units
    /// take turns), where the features failed.
    pub(super) templates: Option<Round>,
    /// The search found a pose that its frame had no time left to track
    /// from: the next frame tracks from it before the search goes on.
    pub(in crate::tracker) seeded: bool,
}

/// A round of the search, on the frame it began on.
pub(super) enum Round {
    Features(Box<FeatureRound>),
    Templates(Box<TemplateRound>),
}

/// A round of features under way.
pub(super) struct FeatureRound {
    /// The frame matched (its corners the detector's).
    pub(super) frame: Frame,
    /// Slices since it began.
    pub(super) age: usize,
    pub(super) described: Option<Described>,
    /// Keyframes to match, the closest to the last pose first.
    pub(super) order: Vec<usize>,
    pub(super) next: usize,
    /// Candidates found and not yet tried, most inliers last.
    pub(super) pending: Vec<Candidate>,
    /// The candidate being refined.
    pub(super) active: Option<Active>,
    pub(super) tried: usize,
    pub(super) refused: Option<(f64, Refused)>,
}

/// A feature candidate being refined, a KF step a unit.
pub(super) struct Active {
    pub(super) candidate: Candidate,
    pub(super) pose: Pose,
    pub(super) steps: usize,
}

/// A round of templates under way.
pub(super) struct TemplateRound {
    pub(super) frame: Frame,
    pub(super) search: Option<TemplateSearch>,
}

/// What a unit came to.
pub(super) enum Step {
    More,
    Found(Pose),
    RoundOver,
}

impl LostSearch {
    /// A unit's running time, seconds; one not yet timed is taken as
    /// long as a tracked frame.
    pub(super) fn cost(&self, u: Unit, reference: f64) -> f64 {
        self.costs[u as usize].unwrap_or(reference)
    }

    pub(super) fn record(&mut self, u: Unit, secs: f64) {
        let c = &mut self.costs[u as usize];
        *c = Some(c.map_or(secs, |c| c + RUNNING * (secs - c)));
    }

    /// Counts a tracked frame's time.
    pub(in crate::tracker) fn tracked(&mut self, total: Duration) {
        let s = total.as_secs_f64();
        self.tracked = Some(self.tracked.map_or(s, |t| t + RUNNING * (s - t)));
    }

    /// Counts the time of a lost frame's own steps.
    pub(in crate::tracker) fn steps(&mut self, d: Duration) {
        let s = d.as_secs_f64();
        self.steps = Some(self.steps.map_or(s, |t| t + RUNNING * (s - t)));
    }

    /// The time a lost frame aims at: `budget` times a tracked frame's,
    /// or before any frame was tracked, times a lost frame's own steps
    /// (or `fallback`, before those were timed either).
    pub(in crate::tracker) fn frame_target(&self, budget: f64, fallback: Duration) -> Duration {
        let reference = self
            .tracked
            .or(self.steps)
            .unwrap_or(fallback.as_secs_f64());
        Duration::from_secs_f64((budget * reference).max(0.0))
    }

    /// The expected time of a lost frame's own steps.
    pub(in crate::tracker) fn steps_time(&self) -> Duration {
        Duration::from_secs_f64(self.steps.unwrap_or(0.0))
    }

    /// Forgets the round under way (the object was found, by the search
    /// or by the steps).
    pub(in crate::tracker) fn reset(&mut self) {
        self.round = None;
        self.templates = None;
    }
}

/// The next unit of `round` (`cap`: candidates a round of features
/// tries).
pub(super) fn next_unit(round: Option<&Round>, cap: usize, detector: Option<&Detector>) -> Unit {
    match round {
        None => Unit::End,
        Some(Round::Features(r)) => {
            if let Some(a) = &r.active {
                if a.steps >= DETECT_REFINE_STEPS {
                    Unit::Check
                } else {
                    Unit::Refine
                }
            } else if !r.pending.is_empty() && r.tried < cap {
                Unit::Refine
            } else if detector.is_none() {
                Unit::Detector
            } else if r.described.is_none() {
                Unit::Describe
            } else if r.tried >= cap {
                Unit::End
            } else if let Some(&k) = r.order.get(r.next) {
                let built = detector.is_some_and(|d| d.built.get(k).copied().unwrap_or(true));
                if built { Unit::Match } else { Unit::Keyframe }
            } else {
                Unit::End
            }
        }
        Some(Round::Templates(r)) => match &r.search {
            None => Unit::Templates,
            Some(s) if !s.views_done() => Unit::View,
            Some(s) if !s.candidates_done() => Unit::TemplateCandidate,
            Some(_) => Unit::End,
        },
    }
}
