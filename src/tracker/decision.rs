//! The decision of a frame (Dehais et al. 2010, section 5, and the rules
//! this crate adds): from what the IT and KF steps estimated, or why they
//! could not, whether the track holds and which estimate it keeps, or why
//! the frame is lost. A pure function, without a GPU: [`decide`].
//!
//! The rules, in order:
//! 1. The KF estimate, when it is trusted (enough inliers, small residual).
//! 2. Else the IT estimate, when it is trusted: KF+IT keeps tracking frame
//!    to frame through a frame the keyframes cannot explain, but only for
//!    [`TrackerConfig::max_it_only_frames`] frames in a row (IT alone drifts).
//! 3. Else the frame is lost, and the reason is the first of: KF's failure,
//!    KF's untrusted estimate, IT's failure, IT's untrusted estimate.
//! 4. The first frame in IT or KF+IT mode, with nothing to track against
//!    yet, is tracking at the initial pose.

use super::config::{Mode, TrackerConfig};
use super::result::{LostReason, Stage, Status, StepError};
use super::verify::Unverified;
use crate::geometry::Pose;

/// What a step that ran to the end estimates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// The pose after the step.
    pub pose: Pose,
    /// Inliers of the step's last robust solve (its own matches).
    pub inliers: usize,
    /// Their RMS residual, pixels.
    pub residual_px: f64,
    /// The robust scale of the residuals, pixels.
    pub scale_px: f64,
}

/// How a step of a frame ended; both empty when it did not run. KF may
/// run several times a frame: its estimate is the last one it gave, and
/// an error stops it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StepOutcome {
    /// The step's estimate.
    pub estimate: Option<Estimate>,
    /// Why it stopped, if it failed.
    pub error: Option<StepError>,
}

impl StepOutcome {
    /// An outcome from a step's result.
    pub fn from_result(r: Result<Estimate, StepError>) -> Self {
        match r {
            Ok(e) => Self {
                estimate: Some(e),
                error: None,
            },
            Err(e) => Self {
                estimate: None,
                error: Some(e),
            },
        }
    }
}

/// The settings the decision follows (from [`TrackerConfig`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rules {
    /// Which tracker runs.
    pub mode: Mode,
    /// [`TrackerConfig::min_inliers`].
    pub min_inliers: usize,
    /// [`TrackerConfig::max_residual_px`].
    pub max_residual_px: f64,
    /// [`TrackerConfig::max_it_only_frames`].
    pub max_it_only_frames: usize,
}

impl Rules {
    /// The rules of `config`.
    pub fn of(config: &TrackerConfig) -> Self {
        Self {
            mode: config.mode,
            min_inliers: config.min_inliers,
            max_residual_px: config.max_residual_px,
            max_it_only_frames: config.max_it_only_frames,
        }
    }

    /// Enough inliers with a small enough residual.
    pub fn trusted(&self, e: &Estimate) -> bool {
        e.inliers >= self.min_inliers && e.residual_px <= self.max_residual_px
    }

    /// Why `stage`'s outcome is not used: its failure, else its estimate
    /// (when it has one) measured against the rules.
    fn why_not(&self, stage: Stage, o: &StepOutcome) -> Option<LostReason> {
        o.error
            .clone()
            .map(|error| LostReason::Failed { stage, error })
            .or_else(|| {
                o.estimate.map(|e| LostReason::Untrusted {
                    stage,
                    inliers: e.inliers,
                    residual_px: e.residual_px,
                    min_inliers: self.min_inliers,
                    max_residual_px: self.max_residual_px,
                })
            })
    }
}

/// What the steps of a frame gave, and where the track stood.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameSteps {
    /// The frame-to-frame step.
    pub it: StepOutcome,
    /// The keyframe step.
    pub kf: StepOutcome,
    /// The contour step (it starts from the texture estimate and fuses the
    /// texture inliers: when trusted, it is the frame's best estimate).
    pub contour: StepOutcome,
    /// The first frame of the sequence (no previous frame, not recovering).
    pub first_frame: bool,
    /// KF+IT: frames in a row tracked by IT alone before this one.
    pub it_only_streak: usize,
}

/// The verdict on a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Decision {
    /// Whether the track holds.
    pub status: Status,
    /// The estimate kept: the new pose (`None`: keep the current one).
    pub pose: Option<Pose>,
    /// Inliers of the estimate kept, else of the last estimate (KF's
    /// before IT's); 0 without any.
    pub inliers: usize,
    /// Their RMS residual; 0 on a first frame without estimate, NaN on a
    /// lost frame without any.
    pub residual_px: f64,
    /// Why the frame is lost (only when it is).
    pub reason: Option<LostReason>,
    /// Why KF's outcome was passed over while IT's stood in.
    pub kf_passed_over: Option<LostReason>,
    /// The IT-only streak after this frame.
    pub it_only_streak: usize,
    /// The estimate the verdict is about and its step: the one kept when
    /// tracking, else the last one (the contour's, KF's, IT's), which a
    /// lost frame refuses; `None` without any (a first frame tracking at
    /// its initial pose).
    pub estimate: Option<(Stage, Estimate)>,
}

/// Applies the rules (module docs) to the steps of a frame.
pub fn decide(rules: &Rules, steps: &FrameSteps) -> Decision {
    let trusted = |o: &StepOutcome| o.estimate.filter(|e| rules.trusted(e));
    let it_may_stand = rules.mode != Mode::KfIt || steps.it_only_streak < rules.max_it_only_frames;
    let mut it_only_streak = steps.it_only_streak;
    let mut kf_passed_over = None;
    let mut reason = None;
    let chosen = if let Some(e) = trusted(&steps.contour) {
        // Drift-free like KF: against the model's silhouette.
        it_only_streak = 0;
        Some((Stage::Contour, e))
    } else if let Some(e) = trusted(&steps.kf) {
        it_only_streak = 0;
        Some((Stage::Kf, e))
    } else if let Some(e) = trusted(&steps.it).filter(|_| it_may_stand) {
        if rules.mode == Mode::KfIt {
            it_only_streak += 1;
        }
        kf_passed_over = rules.why_not(Stage::Kf, &steps.kf);
        Some((Stage::It, e))
    } else {
        reason = rules
            .why_not(Stage::Contour, &steps.contour)
            .or_else(|| rules.why_not(Stage::Kf, &steps.kf))
            .or_else(|| rules.why_not(Stage::It, &steps.it));
        if !it_may_stand && trusted(&steps.it).is_some() {
            reason = Some(LostReason::ItOnlyTooLong {
                kf: reason.map(Box::new),
                frames: rules.max_it_only_frames,
            });
        }
        it_only_streak = 0;
        None
    };
    // The first frame of a sequence has nothing to track against in IT
    // mode: it is the initial pose, by definition tracking.
    let first_it_frame = matches!(rules.mode, Mode::It | Mode::KfIt)
        && steps.it == StepOutcome::default()
        && steps.first_frame;
    let last = (steps.contour.estimate.map(|e| (Stage::Contour, e)))
        .or(steps.kf.estimate.map(|e| (Stage::Kf, e)))
        .or(steps.it.estimate.map(|e| (Stage::It, e)));
    let (status, pose, inliers, residual_px) = match (chosen, last) {
        (Some((_, e)), _) => (Status::Tracking, Some(e.pose), e.inliers, e.residual_px),
        (None, _) if first_it_frame => (Status::Tracking, None, 0, 0.0),
        (None, Some((_, e))) => (Status::Lost, None, e.inliers, e.residual_px),
        (None, None) => (Status::Lost, None, 0, f64::NAN),
    };
    let estimate = match status {
        Status::Tracking => chosen,
        Status::Lost => last,
    };
    let reason =
        (status == Status::Lost).then(|| reason.unwrap_or(LostReason::NothingToTrackAgainst));
    Decision {
        status,
        pose,
        inliers,
        residual_px,
        reason,
        kf_passed_over,
        it_only_streak,
        estimate,
    }
}

/// A decision after the check of its pose: a `tracking` decision whose
/// check failed becomes `lost` (the pose not kept), with the failure as
/// its reason; anything else is unchanged.
pub fn verified(d: Decision, check: Result<(), Unverified>) -> Decision {
    match check {
        Err(why) if d.status == Status::Tracking => Decision {
            status: Status::Lost,
            pose: None,
            reason: Some(LostReason::Unverified(why)),
            it_only_streak: 0,
            ..d
        },
        _ => d,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::SolveError;
    use nalgebra::{Matrix3, Vector3};

    const RULES: Rules = Rules {
        mode: Mode::KfIt,
        min_inliers: 8,
        max_residual_px: 3.0,
        max_it_only_frames: 5,
    };

    fn pose(z: f64) -> Pose {
        Pose::new(Matrix3::identity(), Vector3::new(0.0, 0.0, z)).unwrap()
    }

    fn est(z: f64, inliers: usize, residual_px: f64) -> StepOutcome {
        StepOutcome::from_result(Ok(Estimate {
            pose: pose(z),
            inliers,
            residual_px,
            scale_px: 0.5,
        }))
    }

    fn failed(got: usize) -> StepOutcome {
        StepOutcome::from_result(Err(StepError::Solve(SolveError::TooFewMatches {
            got,
            need: 6,
        })))
    }

    fn steps(it: StepOutcome, kf: StepOutcome) -> FrameSteps {
        FrameSteps {
            it,
            kf,
            ..Default::default()
        }
    }

    /// [`steps`] after `it_only_streak` frames tracked by IT alone.
    fn after_it_only(it_only_streak: usize, it: StepOutcome, kf: StepOutcome) -> FrameSteps {
        FrameSteps {
            it_only_streak,
            ..steps(it, kf)
        }
    }

    #[test]
    fn a_trusted_kf_estimate_wins_and_ends_the_it_only_streak() {
        let d = decide(
            &RULES,
            &after_it_only(3, est(1.0, 50, 0.5), est(2.0, 20, 1.0)),
        );
        assert_eq!(d.status, Status::Tracking);
        assert_eq!(d.pose, Some(pose(2.0)));
        assert_eq!((d.inliers, d.residual_px), (20, 1.0));
        assert_eq!(
            (d.reason, d.kf_passed_over, d.it_only_streak),
            (None, None, 0)
        );
    }

    #[test]
    fn a_trusted_contour_estimate_wins_and_an_untrusted_one_is_named() {
        let steps = FrameSteps {
            contour: est(0.7, 40, 0.5),
            it_only_streak: 3,
            ..steps(est(0.6, 30, 0.4), est(0.5, 20, 0.3))
        };
        let d = decide(&RULES, &steps);
        assert_eq!((d.status, d.pose), (Status::Tracking, Some(pose(0.7))));
        assert_eq!(d.it_only_streak, 0);
        let lost = FrameSteps {
            contour: failed(3),
            ..Default::default()
        };
        let d = decide(&RULES, &lost);
        assert_eq!(d.status, Status::Lost);
        assert!(d.reason.unwrap().to_string().starts_with("contour:"));
    }

    #[test]
    fn a_trusted_it_estimate_stands_in_for_an_untrusted_kf_one() {
        let d = decide(&RULES, &steps(est(1.0, 50, 0.5), est(2.0, 5, 0.8)));
        assert_eq!(d.status, Status::Tracking);
        assert_eq!(d.pose, Some(pose(1.0)));
        assert_eq!((d.inliers, d.it_only_streak, d.reason), (50, 1, None));
        assert_eq!(
            d.kf_passed_over.unwrap().to_string(),
            "KF: 5 inliers, residual 0.80 px (need >= 8 and <= 3.0 px)"
        );
        // Too large a residual is not trusted either.
        let d = decide(&RULES, &steps(est(1.0, 50, 0.5), est(2.0, 50, 3.5)));
        assert_eq!(d.pose, Some(pose(1.0)));
    }

    #[test]
    fn it_alone_stands_in_only_so_many_frames_in_kf_it() {
        let d = decide(
            &RULES,
            &after_it_only(5, est(1.0, 50, 0.5), est(2.0, 5, 0.8)),
        );
        assert_eq!(d.status, Status::Lost);
        assert_eq!((d.pose, d.inliers, d.residual_px), (None, 5, 0.8));
        assert_eq!(d.it_only_streak, 0);
        assert_eq!(
            d.reason.unwrap().to_string(),
            "KF: 5 inliers, residual 0.80 px (need >= 8 and <= 3.0 px); IT alone has stood in for 5 frames and drifts"
        );
        // In IT mode the streak neither grows nor limits.
        let it = Rules {
            mode: Mode::It,
            ..RULES
        };
        let d = decide(
            &it,
            &after_it_only(9, est(1.0, 50, 0.5), StepOutcome::default()),
        );
        assert_eq!((d.status, d.it_only_streak), (Status::Tracking, 9));
    }

    #[test]
    fn a_lost_frame_names_kf_before_it_and_failures_before_estimates() {
        let d = decide(&RULES, &steps(failed(3), failed(4)));
        assert_eq!(d.status, Status::Lost);
        assert_eq!((d.inliers, d.pose), (0, None));
        assert!(d.residual_px.is_nan());
        assert_eq!(
            d.reason.unwrap().to_string(),
            "KF: too few matches for a pose update: 4 (need at least 6)"
        );
        let d = decide(&RULES, &steps(failed(3), est(2.0, 5, 0.8)));
        assert_eq!((d.inliers, d.residual_px), (5, 0.8));
        assert!(d.reason.unwrap().to_string().starts_with("KF: 5 inliers"));
        // A KF step that failed after an estimate: the failure is the reason,
        // the estimate gives the figures.
        let kf = StepOutcome {
            error: Some(StepError::Gpu("device lost".into())),
            ..est(2.0, 5, 0.8)
        };
        let d = decide(&RULES, &steps(est(1.0, 4, 0.5), kf));
        assert_eq!(d.reason.unwrap().to_string(), "KF: device lost");
        assert_eq!(d.inliers, 5);
        let d = decide(&RULES, &steps(failed(3), StepOutcome::default()));
        assert_eq!(
            d.reason.unwrap().to_string(),
            "IT: too few matches for a pose update: 3 (need at least 6)"
        );
        let d = decide(&RULES, &steps(est(1.0, 4, 0.5), StepOutcome::default()));
        assert_eq!(
            d.reason.unwrap().to_string(),
            "IT: 4 inliers, residual 0.50 px (need >= 8 and <= 3.0 px)"
        );
    }

    #[test]
    fn the_first_frame_is_tracking_and_nothing_at_all_is_lost() {
        let first = FrameSteps {
            first_frame: true,
            ..Default::default()
        };
        let d = decide(&RULES, &first);
        assert_eq!((d.status, d.pose, d.inliers), (Status::Tracking, None, 0));
        assert_eq!((d.residual_px, d.reason), (0.0, None));
        // In KF mode there is no such thing as a first IT frame.
        let kf = Rules {
            mode: Mode::Kf,
            ..RULES
        };
        let d = decide(&kf, &first);
        assert_eq!(d.status, Status::Lost);
        assert_eq!(
            d.reason.as_ref().map(ToString::to_string).as_deref(),
            Some("nothing to track against")
        );
        let d = decide(&RULES, &FrameSteps::default());
        assert_eq!(d.reason, Some(LostReason::NothingToTrackAgainst));
    }

    #[test]
    fn a_failed_check_turns_tracking_into_lost_and_nothing_else() {
        let d = decide(&RULES, &steps(est(1.0, 50, 0.5), est(2.0, 20, 1.0)));
        let why = Unverified::Appearance {
            zncc: Some(0.05),
            edge_support: Some(0.2),
        };
        let v = verified(d.clone(), Err(why.clone()));
        assert_eq!((v.status, v.pose, v.inliers), (Status::Lost, None, 20));
        // The refused estimate stays: KF's, at z = 2.
        let (stage, e) = v.estimate.unwrap();
        assert_eq!((stage, e.pose, e.inliers), (Stage::Kf, pose(2.0), 20));
        assert_eq!(
            v.reason.unwrap().to_string(),
            "verification: model does not match the image: ZNCC 0.05, contour edge support 0.20"
        );
        assert_eq!(verified(d.clone(), Ok(())), d);
        // The first frame is tracking only when its pose passes.
        let first = decide(
            &RULES,
            &FrameSteps {
                first_frame: true,
                ..Default::default()
            },
        );
        assert_eq!(
            verified(first, Err(Unverified::FrozenFrame)).status,
            Status::Lost
        );
        // A lost frame keeps its own reason, and its last estimate (KF's,
        // untrusted) as the one refused; a first frame has none.
        let lost = decide(&RULES, &steps(failed(3), est(2.0, 5, 0.8)));
        assert_eq!(
            lost.estimate.map(|(s, e)| (s, e.inliers)),
            Some((Stage::Kf, 5))
        );
        assert_eq!(
            decide(
                &RULES,
                &FrameSteps {
                    first_frame: true,
                    ..Default::default()
                }
            )
            .estimate,
            None
        );
        assert_eq!(verified(lost.clone(), Err(why)), lost);
    }

    #[test]
    fn reasons_and_statuses_serialise() {
        let reasons = [
            LostReason::ItOnlyTooLong {
                kf: Some(Box::new(LostReason::Failed {
                    stage: Stage::Kf,
                    error: StepError::Solve(SolveError::Degenerate {
                        reason: "tx".into(),
                    }),
                })),
                frames: 5,
            },
            LostReason::Untrusted {
                stage: Stage::It,
                inliers: 3,
                residual_px: 1.25,
                min_inliers: 8,
                max_residual_px: 3.0,
            },
            LostReason::Failed {
                stage: Stage::It,
                error: StepError::Gpu("out of memory".into()),
            },
            LostReason::NothingToTrackAgainst,
            LostReason::NotFound,
            LostReason::Confirming { left: 2 },
            LostReason::Unconfirmed {
                turn_deg: 19.5,
                check: Some(Unverified::Appearance {
                    zncc: Some(0.7),
                    edge_support: Some(0.5),
                }),
            },
            LostReason::Unverified(Unverified::NotInView {
                visible: 0.25,
                min: 0.5,
            }),
            LostReason::Unverified(Unverified::Appearance {
                zncc: None,
                edge_support: Some(0.5),
            }),
        ];
        for r in reasons {
            let json = serde_json::to_string(&r).unwrap();
            assert_eq!(
                serde_json::from_str::<LostReason>(&json).unwrap(),
                r,
                "{json}"
            );
        }
        for s in [Status::Tracking, Status::Lost] {
            let json = serde_json::to_string(&s).unwrap();
            assert_eq!(json, format!("\"{s}\""));
            assert_eq!(serde_json::from_str::<Status>(&json).unwrap(), s);
        }
        assert_eq!(serde_json::to_string(&Stage::Kf).unwrap(), "\"kf\"");
        assert_eq!(serde_json::from_str::<Stage>("\"it\"").unwrap(), Stage::It);
    }
}
