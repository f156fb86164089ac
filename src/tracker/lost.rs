//! The search while the object is lost, in slices that fit a frame.
//!
//! How it works: the search for the object in a whole frame
//! ([`super::search`]: features, then templates) costs from half a second
//! to seconds on a CPU adapter, while a tracked frame costs tens of
//! milliseconds. Run in one go it stalls the frame it runs on, so while the
//! track is lost it runs in units, each small (a keyframe's features, the
//! frame's corners described, one keyframe matched, one candidate refined
//! and checked, one viewpoint's templates scored), as many a frame as the
//! frame's budget allows ([`InitConfig::lost_frame_budget`] times a
//! tracked frame's time, as measured on this sequence), resumed on the
//! next frame where it stopped.
//!
//! A round of features matches the corners of the frame it began on
//! against each keyframe, the keyframe closest to the last pose first,
//! each match's candidate tried as soon as it is found; a round of
//! templates scores the viewpoints on the frame it began on. Candidates are
//! refined and checked on the frame being tracked when their unit runs
//! (from a frame before it, the refinement's first step searches as far
//! as after a loss), so the pose the search finds has passed the check on
//! the current frame, as every pose of a whole search does. The tracker
//! then tracks that frame from it, where the frame's budget still allows,
//! else the next frame.
//!
//! [`InitConfig::lost_frame_budget`]: super::InitConfig::lost_frame_budget

use super::detect::{Candidate, DETECT_REFINE_STEPS, Described};
use super::error::TrackError;
use super::result::Refused;
use super::search::TemplateSearch;
use super::state::{Frame, Tracker};
use crate::geometry::Pose;
use std::time::{Duration, Instant};

/// The kinds of the search's units, each timed on its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Unit {
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
const UNITS: usize = 10;

/// Weight of the newest time in the running times.
const RUNNING: f64 = 0.25;

/// The search while lost, between frames, with the times its budget is
/// measured by.
#[derive(Default)]
pub(super) struct LostSearch {
    round: Option<Round>,
    /// Each unit kind's running time, seconds.
    costs: [Option<f64>; UNITS],
    /// A tracked frame's running time, seconds.
    tracked: Option<f64>,
    /// The running time of a lost frame's own steps (besides the search),
    /// seconds.
    steps: Option<f64>,
    /// Whether the last round was one of templates (a round of features
    /// comes next).
    after_templates: bool,
    /// The search found a pose that its frame had no time left to track
    /// from: the next frame tracks from it before the search goes on.
    pub(super) seeded: bool,
}

/// A round of the search, on the frame it began on.
enum Round {
    Features(Box<FeatureRound>),
    Templates(Box<TemplateRound>),
}

/// A round of features under way.
struct FeatureRound {
    /// The frame matched (its corners the detector's).
    frame: Frame,
    described: Option<Described>,
    /// Keyframes to match, the closest to the last pose first.
    order: Vec<usize>,
    next: usize,
    /// Candidates found and not yet tried, most inliers last.
    pending: Vec<Candidate>,
    /// The candidate being refined.
    active: Option<Active>,
    tried: usize,
    refused: Option<(f64, Refused)>,
}

/// A feature candidate being refined, a KF step a unit.
struct Active {
    candidate: Candidate,
    pose: Pose,
    steps: usize,
}

/// A round of templates under way.
struct TemplateRound {
    frame: Frame,
    search: Option<TemplateSearch>,
}

/// What a unit came to.
enum Step {
    More,
    Found(Pose),
    RoundOver,
}

impl LostSearch {
    /// A unit's running time, seconds; one not yet timed is taken as
    /// long as a tracked frame.
    fn cost(&self, u: Unit, reference: f64) -> f64 {
        self.costs[u as usize].unwrap_or(reference)
    }

    fn record(&mut self, u: Unit, secs: f64) {
        let c = &mut self.costs[u as usize];
        *c = Some(c.map_or(secs, |c| c + RUNNING * (secs - c)));
    }

    /// Counts a tracked frame's time.
    pub(super) fn tracked(&mut self, total: Duration) {
        let s = total.as_secs_f64();
        self.tracked = Some(self.tracked.map_or(s, |t| t + RUNNING * (s - t)));
    }

    /// Counts the time of a lost frame's own steps.
    pub(super) fn steps(&mut self, d: Duration) {
        let s = d.as_secs_f64();
        self.steps = Some(self.steps.map_or(s, |t| t + RUNNING * (s - t)));
    }

    /// The time a lost frame aims at: `budget` times a tracked frame's,
    /// or before any frame was tracked, times a lost frame's own steps
    /// (or `fallback`, before those were timed either).
    pub(super) fn frame_target(&self, budget: f64, fallback: Duration) -> Duration {
        let reference = self
            .tracked
            .or(self.steps)
            .unwrap_or(fallback.as_secs_f64());
        Duration::from_secs_f64((budget * reference).max(0.0))
    }

    /// The expected time of a lost frame's own steps.
    pub(super) fn steps_time(&self) -> Duration {
        Duration::from_secs_f64(self.steps.unwrap_or(0.0))
    }

    /// Forgets the round under way (the object was found, by the search
    /// or by the steps).
    pub(super) fn reset(&mut self) {
        self.round = None;
        self.after_templates = false;
    }

    fn next_unit(&self, t: &Tracker) -> Unit {
        match &self.round {
            None => Unit::End,
            Some(Round::Features(r)) => {
                let cap = t.config.init.detect.candidates;
                if let Some(a) = &r.active {
                    if a.steps >= DETECT_REFINE_STEPS {
                        Unit::Check
                    } else {
                        Unit::Refine
                    }
                } else if !r.pending.is_empty() && r.tried < cap {
                    Unit::Refine
                } else if t.detector.is_none() {
                    Unit::Detector
                } else if r.described.is_none() {
                    Unit::Describe
                } else if r.tried >= cap {
                    Unit::End
                } else if let Some(&k) = r.order.get(r.next) {
                    let built = t
                        .detector
                        .as_ref()
                        .is_some_and(|d| d.built.get(k).copied().unwrap_or(true));
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
}

impl Tracker {
    /// One slice of the search while lost, on frame `rgb`, in `budget`
    /// (at least one unit): the pose found (checked on `rgb`), if any.
    pub(super) fn lost_search_slice(
        &mut self,
        rgb: &image::RgbImage,
        budget: Duration,
    ) -> Result<Option<Pose>, TrackError> {
        let t0 = Instant::now();
        let mut ls = std::mem::take(&mut self.lost);
        let reference = ls.frame_target(1.0, budget).as_secs_f64();
        let mut started = false;
        let mut units = 0;
        let out = loop {
            if ls.round.is_none() {
                if started {
                    break Ok(None);
                }
                started = true;
                ls.round = self.new_round(rgb, ls.after_templates);
                ls.after_templates = matches!(ls.round, Some(Round::Templates(_)));
            }
            let unit = ls.next_unit(self);
            let cost = Duration::from_secs_f64(ls.cost(unit, reference));
            if units > 0 && t0.elapsed() + cost > budget {
                break Ok(None);
            }
            let t = Instant::now();
            let step = self.lost_unit(&mut ls, unit);
            ls.record(unit, t.elapsed().as_secs_f64());
            log::trace!(
                "search unit {unit:?}: {:.1} ms",
                t.elapsed().as_secs_f64() * 1e3
            );
            units += 1;
            match step {
                Err(e) => {
                    ls.round = None;
                    break Err(e);
                }
                Ok(Step::More) => {}
                Ok(Step::Found(p)) => {
                    ls.round = None;
                    break Ok(Some(p));
                }
                Ok(Step::RoundOver) => ls.round = None,
            }
        };
        log::debug!(
            "search while lost: {units} units in {:.0} ms (budget {:.0} ms)",
            t0.elapsed().as_secs_f64() * 1e3,
            budget.as_secs_f64() * 1e3
        );
        self.lost = ls;
        out
    }

    /// A new round on frame `rgb`: features where the detector may find
    /// the object, templates where the features failed and
    /// [`super::detect::DetectConfig::templates_every`] asks for them (or
    /// without features), never two rounds of templates in a row where
    /// features run; `None` without keyframes to search with.
    fn new_round(&mut self, rgb: &image::RgbImage, after_templates: bool) -> Option<Round> {
        let store = self.store.as_ref()?;
        let cfg = &self.config.init.detect;
        let templates = !cfg.enabled
            || (!after_templates
                && self.detector.as_ref().is_some_and(|d| {
                    d.unbuilt().next().is_none() && d.misses > 0 && d.templates_now(cfg)
                }));
        let frame = Frame::new(rgb.clone());
        if templates {
            return Some(Round::Templates(Box::new(TemplateRound {
                frame,
                search: None,
            })));
        }
        let mut order: Vec<usize> = (0..store.keyframes.len()).collect();
        let pose = self.pose;
        order.sort_by(|&a, &b| {
            let d = |k: usize| store.keyframes[k].pose.rotation_error_deg(&pose);
            d(a).total_cmp(&d(b))
        });
        Some(Round::Features(Box::new(FeatureRound {
            frame,
            described: None,
            order,
            next: 0,
            pending: Vec::new(),
            active: None,
            tried: 0,
            refused: None,
        })))
    }

    /// Runs unit `unit` of the round under way.
    fn lost_unit(&mut self, ls: &mut LostSearch, unit: Unit) -> Result<Step, TrackError> {
        match (unit, ls.round.as_mut()) {
            (Unit::End, Some(Round::Features(r))) => {
                self.count_detection(false);
                if let Some(refused) = r.refused.take() {
                    self.search_refused = Some(refused.1);
                }
                Ok(Step::RoundOver)
            }
            (Unit::End, Some(Round::Templates(r))) => {
                let found = r.search.take().and_then(|s| self.template_result(s));
                Ok(found.map_or(Step::RoundOver, Step::Found))
            }
            (Unit::Detector, Some(Round::Features(_))) => {
                self.start_detector()?;
                Ok(Step::More)
            }
            (Unit::Describe, Some(Round::Features(r))) => {
                r.described = self.describe_frame(&mut r.frame)?;
                Ok(if r.described.is_some() {
                    Step::More
                } else {
                    Step::RoundOver
                })
            }
            (Unit::Keyframe, Some(Round::Features(r))) => {
                if let Some(&k) = r.order.get(r.next) {
                    self.build_detector_keyframe(k)?;
                }
                // Matched in the next unit.
                Ok(Step::More)
            }
            (Unit::Match, Some(Round::Features(r))) => {
                let k = r.order[r.next];
                r.next += 1;
                let cfg = self.config.init.detect.clone();
                if let Some(c) = r
                    .described
                    .as_ref()
                    .and_then(|d| self.keyframe_candidate(k, d, &cfg))
                {
                    r.pending.push(c);
                    r.pending.sort_by_key(|c| c.inliers);
                }
                Ok(Step::More)
            }
            (Unit::Refine, Some(Round::Features(r))) => {
                if r.active.is_none() {
                    let Some(c) = r.pending.pop() else {
                        return Ok(Step::More);
                    };
                    r.tried += 1;
                    r.active = Some(Active {
                        pose: c.pose,
                        candidate: c,
                        steps: 0,
                    });
                }
                let Some(a) = r.active.as_mut() else {
                    return Ok(Step::More);
                };
                match self.refine_detected(&r.frame, &a.pose)? {
                    Some(p) => {
                        a.pose = p;
                        a.steps += 1;
                    }
                    None => {
                        log::debug!(
                            "detect: keyframe {} candidate not refined",
                            a.candidate.keyframe
                        );
                        r.active = None;
                    }
                }
                Ok(Step::More)
            }
            (Unit::Check, Some(Round::Features(r))) => {
                let Some(a) = r.active.take() else {
                    return Ok(Step::More);
                };
                match self.check_candidate(&r.frame, &a.candidate, a.pose)? {
                    Ok(p) => {
                        self.count_detection(true);
                        Ok(Step::Found(p))
                    }
                    Err(Some((z, refused))) => {
                        if r.refused.as_ref().is_none_or(|b| z > b.0) {
                            r.refused = Some((z, refused));
                        }
                        Ok(Step::More)
                    }
                    Err(None) => Ok(Step::More),
                }
            }
            (Unit::Templates, Some(Round::Templates(r))) => {
                let mut frame = Frame::new(r.frame.rgb.clone());
                frame.corners = self.harris.detect(frame.grey(), None)?;
                r.search = Some(self.template_search(&frame)?);
                r.frame = frame;
                Ok(Step::More)
            }
            (Unit::View, Some(Round::Templates(r))) => {
                if let Some(s) = r.search.as_mut() {
                    self.template_hits(s)?;
                }
                Ok(Step::More)
            }
            (Unit::TemplateCandidate, Some(Round::Templates(r))) => {
                let Some(mut s) = r.search.take() else {
                    return Ok(Step::More);
                };
                let res = self.template_candidate(&mut s, &r.frame, &r.frame.rgb);
                r.search = Some(s);
                res.map(|_| Step::More)
            }
            _ => Ok(Step::RoundOver),
        }
    }
}
