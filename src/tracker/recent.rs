//! The track's recent scores and the rules that hold a frame to them
//! (`tracker/steady.rs` says why): the edge support and the shading's RMS
//! of the last tracked frames, and the shading's level from before a
//! loss.

use super::verify::{Unverified, VerifyScores};

/// The tracked frames whose scores the medians are taken over.
const HISTORY: usize = 10;

/// Tracked frames needed before the rules apply.
const LEAST_HISTORY: usize = 5;

/// Lost frames after which the shading's level from before a loss no
/// longer holds ([`History::shading_level`]): a lasting change (a hand
/// over the object, another light) refuses no longer than this.
const LEVEL_KEPT_FRAMES: usize = 30;

/// The last tracked frames' scores, oldest first (cleared by a lost
/// frame), and the shading's level from before the last loss.
#[derive(Debug, Clone, Default)]
pub(super) struct History {
    edges: Vec<f64>,
    shading: Vec<f64>,
    /// The shading's recent level when the last loss began, and the lost
    /// frames since.
    before_loss: Option<(f64, usize)>,
}

impl History {
    /// Forgets every frame (a loss, or the object hidden), keeping the
    /// shading's level for the frames that end the loss.
    pub fn clear(&mut self) {
        if let Some(level) = recent(&self.shading) {
            self.before_loss = Some((level, 0));
        }
        if let Some((_, frames)) = self.before_loss.as_mut() {
            *frames += 1;
            if *frames > LEVEL_KEPT_FRAMES {
                self.before_loss = None;
            }
        }
        self.edges.clear();
        self.shading.clear();
    }

    /// Keeps a tracked frame's scores (those it has), the last
    /// [`HISTORY`] of each.
    pub fn push(&mut self, s: &VerifyScores) {
        let keep = |v: &mut Vec<f64>, x: Option<f64>| {
            if let Some(x) = x {
                if v.len() == HISTORY {
                    v.remove(0);
                }
                v.push(x);
            }
        };
        keep(&mut self.edges, s.edge_support);
        keep(&mut self.shading, s.shading_rms);
    }

    /// The shading's level a frame is held to: the recent frames' median,
    /// or, until enough frames are tracked again, the level from before a
    /// loss of at most [`LEVEL_KEPT_FRAMES`] frames. A near-symmetric
    /// object that slipped is refused, and its recovery from the last
    /// pose finds the same slip: without the level from before, the
    /// history would start again at the wrong pose.
    fn shading_level(&self) -> Option<f64> {
        recent(&self.shading).or(self.before_loss.map(|(level, _)| level))
    }

    /// Whether a shading RMS of `rms` is over `ratio` times the level
    /// ([`History::shading_level`], floored at [`SHADING_FLOOR`]); never
    /// without a level or with the rule off (`ratio` 0).
    fn refuses(&self, rms: f64, ratio: f64) -> bool {
        self.shading_level()
            .is_some_and(|level| ratio > 0.0 && rms > ratio * level.max(SHADING_FLOOR))
    }

    /// [`History::refuses`] under `cfg`'s rule.
    pub fn refuses_shading(&self, rms: f64, cfg: &super::VerifyConfig) -> bool {
        cfg.enabled && self.refuses(rms, cfg.shading_drop)
    }
}

/// The median of the last [`HISTORY`] values of `history`; `None` where
/// fewer than [`LEAST_HISTORY`] are known.
fn recent(history: &[f64]) -> Option<f64> {
    if history.len() < LEAST_HISTORY {
        return None;
    }
    let mut v: Vec<f64> = history[history.len().saturating_sub(HISTORY)..].to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// The least level of the shading's RMS the rule compares with (grey
/// levels 0..1). Under about three grey levels of noise a level says more
/// about the lighting than about the pose: the untextured box's right
/// poses rose from 0.008 to 0.017 over eight frames as a face turned to
/// grazing light (1.89 times the median before it; 1.46 against this
/// floor), where a slip's pose left 2.4-4.9 times a level of 0.017-0.023.
const SHADING_FLOOR: f64 = 3.0 / 255.0;

/// The rules alone: `Err` where the edge support is below `edge_drop`
/// times the median of the recent frames', or the shading's RMS above
/// `shading_drop` times theirs (each rule off at 0).
pub(super) fn judge_steady(
    s: &VerifyScores,
    history: &History,
    edge_drop: f64,
    shading_drop: f64,
) -> Result<(), Unverified> {
    if let (Some(edges), Some(recent)) = (s.edge_support, recent(&history.edges)) {
        if edge_drop > 0.0 && edges < edge_drop * recent {
            return Err(Unverified::EdgeDrop {
                edge_support: edges,
                recent,
                ratio: edge_drop,
            });
        }
    }
    if let (Some(rms), Some(recent)) = (s.shading_rms, history.shading_level()) {
        if history.refuses(rms, shading_drop) {
            return Err(Unverified::ShadingDrop {
                shading_rms: rms,
                recent,
                ratio: shading_drop,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn history(edges: &[f64], shading: &[f64]) -> History {
        History {
            edges: edges.to_vec(),
            shading: shading.to_vec(),
            before_loss: None,
        }
    }

    fn scores(edges: Option<f64>, shading: Option<f64>) -> VerifyScores {
        VerifyScores {
            edge_support: edges,
            shading_rms: shading,
            ..Default::default()
        }
    }

    #[test]
    fn the_median_needs_five_frames_and_takes_the_last_ten() {
        assert_eq!(recent(&[0.9; 4]), None);
        assert_eq!(recent(&[0.9, 0.5, 0.7, 0.8, 0.6]), Some(0.7));
        assert_eq!(recent(&[0.9, 0.5, 0.7, 0.8, 0.6, 1.0]), Some(0.75));
        let mut h = vec![0.1; 5];
        h.extend([0.9; 10]);
        assert_eq!(recent(&h), Some(0.9));
        // The history keeps ten of each, and only the scores a frame has.
        let mut h = History::default();
        for k in 0..12 {
            h.push(&scores(Some(k as f64), (k % 2 == 0).then_some(0.02)));
        }
        assert_eq!(h.edges, (2..12).map(|k| k as f64).collect::<Vec<_>>());
        assert_eq!(h.shading, vec![0.02; 6]);
        h.clear();
        assert!(h.edges.is_empty() && h.shading.is_empty());
    }

    #[test]
    fn a_sudden_drop_is_refused_and_a_steady_track_is_not() {
        let steady = history(&[0.95, 0.97, 0.99, 1.0, 0.96, 0.98], &[]);
        // The wrong pose measured on the box: 0.52 after 0.95-1.0.
        let err = judge_steady(&scores(Some(0.522), None), &steady, 0.7, 2.0).expect_err("a drop");
        assert!(
            matches!(err, Unverified::EdgeDrop { recent, .. } if (recent - 0.975).abs() < 1e-12)
        );
        // The lowest right pose measured: 0.79 of its median.
        assert!(judge_steady(&scores(Some(0.79 * 0.975), None), &steady, 0.7, 2.0).is_ok());
        // Too little history, no edges, or the rule off: no verdict.
        let short = history(&[0.95, 0.97, 0.99, 1.0], &[]);
        assert!(judge_steady(&scores(Some(0.1), None), &short, 0.7, 2.0).is_ok());
        assert!(judge_steady(&scores(None, None), &steady, 0.7, 2.0).is_ok());
        assert!(judge_steady(&scores(Some(0.1), None), &steady, 0.0, 2.0).is_ok());
    }

    #[test]
    fn shading_far_above_its_level_is_refused_and_its_spread_is_not() {
        // The slipping `plain` (a sampling of its model): 0.017 a frame,
        // then 0.035 at 6 degrees off.
        let level = history(&[0.9; 6], &[0.017, 0.016, 0.018, 0.017, 0.017, 0.016]);
        let err =
            judge_steady(&scores(Some(0.9), Some(0.036)), &level, 0.7, 2.0).expect_err("a slip");
        assert!(
            matches!(err, Unverified::ShadingDrop { recent, .. } if (recent - 0.017).abs() < 1e-12)
        );
        // The most a right pose measured: 1.47 times the level.
        assert!(judge_steady(&scores(Some(0.9), Some(1.47 * 0.017)), &level, 0.7, 2.0).is_ok());
        // A clean frame's level is floored at three grey levels.
        let clean = history(&[0.9; 6], &[0.002; 6]);
        assert!(judge_steady(&scores(Some(0.9), Some(0.023)), &clean, 0.7, 2.0).is_ok());
        assert!(judge_steady(&scores(Some(0.9), Some(0.024)), &clean, 0.7, 2.0).is_err());
        // No fit, too little history, or the rule off: no verdict.
        assert!(judge_steady(&scores(Some(0.9), None), &level, 0.7, 2.0).is_ok());
        let short = history(&[0.9; 6], &[0.017; 4]);
        assert!(judge_steady(&scores(Some(0.9), Some(0.1)), &short, 0.7, 2.0).is_ok());
        assert!(judge_steady(&scores(Some(0.9), Some(0.1)), &level, 0.7, 0.0).is_ok());
    }

    #[test]
    fn the_level_from_before_a_loss_holds_its_recovery_for_a_while() {
        let slipped = scores(None, Some(0.05));
        let mut h = history(&[], &[0.017; 6]);
        // The loss: the history goes, the level stays for the frames that
        // end it, tracked ones included, until five are known again.
        h.clear();
        assert!(h.edges.is_empty() && h.shading.is_empty());
        assert!(matches!(
            judge_steady(&slipped, &h, 0.7, 2.0),
            Err(Unverified::ShadingDrop { .. })
        ));
        for _ in 0..4 {
            h.push(&slipped);
        }
        assert!(judge_steady(&slipped, &h, 0.7, 2.0).is_err());
        h.push(&slipped);
        assert!(judge_steady(&slipped, &h, 0.7, 2.0).is_ok());
        // A loss that lasts: the level from before goes after
        // LEVEL_KEPT_FRAMES lost frames, so a lasting change cannot lock
        // the track out.
        let mut h = history(&[], &[0.017; 6]);
        for _ in 0..LEVEL_KEPT_FRAMES {
            h.clear();
        }
        assert!(judge_steady(&slipped, &h, 0.7, 2.0).is_err());
        h.clear();
        assert!(judge_steady(&slipped, &h, 0.7, 2.0).is_ok());
    }
}
