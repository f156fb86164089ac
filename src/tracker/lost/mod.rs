//! The search while the object is lost, in slices that fit a frame.
//!
//! How it works: the search for the object in a whole frame
//! ([`super::search`]: features, then templates) costs from half a second
//! to seconds on a CPU adapter, while a tracked frame costs tens of
//! milliseconds. Run in one go it stalls the frame it runs on, so while the
//! track is lost it runs in units, each small (a keyframe's features, the
//! frame's corners described, one keyframe matched, one KF step of a
//! candidate, its check, one viewpoint's templates scored), as many a frame as the
//! frame's budget allows ([`InitConfig::lost_frame_budget`] times a
//! tracked frame's time, as measured on this sequence), resumed on the
//! next frame where it stopped.
//!
//! A round of features matches the corners of the frame it began on
//! against each keyframe, the keyframe closest to the last pose first,
//! each match's candidate tried as soon as it is found; one still running
//! after a few frames starts again on the newest. A round of templates
//! scores the viewpoints on the frame it began on, beside the rounds of
//! features (their units take turns). Candidates are refined and checked
//! on their round's frame, as in a whole search; the pose found seeds the
//! frame being tracked, which starts from it with the recovery's wide KF
//! step and the check, in the same frame where its budget allows, else in
//! the next.
//!
//! [`InitConfig::lost_frame_budget`]: super::InitConfig::lost_frame_budget

mod rounds;

use super::error::TrackError;
use super::state::{Frame, Tracker};
use crate::geometry::Pose;
pub(super) use rounds::LostSearch;
use rounds::{Active, FeatureRound, Round, Step, TemplateRound, Unit, next_unit};
use std::time::{Duration, Instant};

/// Slices a round of features may run before it starts again on a newer
/// frame.
const MAX_AGE: usize = 3;

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
        // A round of features on a frame a few frames old starts again on
        // this one (the keyframes' features made so far are kept): the
        // object may have come back since (the first round makes the
        // features, a frame or so each).
        if let Some(Round::Features(r)) = ls.round.as_mut() {
            r.age += 1;
            if r.age > MAX_AGE && r.active.is_none() {
                ls.round = None;
            }
        }
        let mut started = false;
        let mut units = 0;
        let out = loop {
            // The templates' units take turns with the features'.
            let templates_turn =
                ls.templates.is_some() && (units % 2 == 1 || (ls.round.is_none() && started));
            if !templates_turn && ls.round.is_none() {
                if started {
                    break Ok(None);
                }
                started = true;
                ls.round = self.new_round(rgb);
                if ls.round.is_none() {
                    break Ok(None);
                }
            }
            let slot = if templates_turn {
                &mut ls.templates
            } else {
                &mut ls.round
            };
            let unit = next_unit(
                slot.as_ref(),
                self.config.init.detect.candidates,
                self.detector.as_ref(),
            );
            let cost = Duration::from_secs_f64(ls.cost(unit, reference));
            if units > 0 && t0.elapsed() + cost > budget {
                break Ok(None);
            }
            let t = Instant::now();
            let slot = if templates_turn {
                &mut ls.templates
            } else {
                &mut ls.round
            };
            let step = self.lost_unit(slot, unit);
            ls.record(unit, t.elapsed().as_secs_f64());
            log::trace!(
                "search unit {unit:?}: {:.1} ms",
                t.elapsed().as_secs_f64() * 1e3
            );
            units += 1;
            match step {
                Err(e) => {
                    ls.reset();
                    break Err(e);
                }
                Ok(Step::More) => {}
                Ok(Step::Found(p)) => {
                    ls.reset();
                    break Ok(Some(p));
                }
                Ok(Step::RoundOver) if templates_turn => ls.templates = None,
                Ok(Step::RoundOver) => {
                    let features = matches!(ls.round, Some(Round::Features(_)));
                    ls.round = None;
                    if features && ls.templates.is_none() && self.templates_wanted() {
                        ls.templates = Some(Round::Templates(Box::new(TemplateRound {
                            frame: Frame::new(rgb.clone()),
                            search: None,
                        })));
                    }
                }
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

    /// A new round on frame `rgb`: features, or templates where the
    /// detection by features is off; `None` without keyframes to search
    /// with.
    fn new_round(&mut self, rgb: &image::RgbImage) -> Option<Round> {
        let store = self.store.as_ref()?;
        let frame = Frame::new(rgb.clone());
        if !self.config.init.detect.enabled {
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
            age: 0,
            described: None,
            order,
            next: 0,
            pending: Vec::new(),
            active: None,
            tried: 0,
            refused: None,
        })))
    }

    /// Whether a round of templates should follow the features' failure
    /// ([`super::detect::DetectConfig::templates_every`]; every keyframe's
    /// features made).
    fn templates_wanted(&self) -> bool {
        let cfg = &self.config.init.detect;
        self.detector
            .as_ref()
            .is_some_and(|d| d.unbuilt().next().is_none() && d.misses > 0 && d.templates_now(cfg))
    }

    /// Runs unit `unit` of the round under way.
    fn lost_unit(&mut self, round: &mut Option<Round>, unit: Unit) -> Result<Step, TrackError> {
        match (unit, round.as_mut()) {
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
                let mask = self.search_mask();
                frame.corners = self.harris.detect(frame.grey(), mask.as_deref())?;
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
