//! `splattrack init --click`: the live view's window shows the frame and
//! asks for each named model point in turn; when every point is answered
//! it shows the solved pose for confirmation. What each event means is
//! [`splattrack::view::clicks`]'s (pure, unit-tested); this file only pumps
//! the window.

use super::solve::{Fit, ModelView, fit};
use anyhow::{Context, bail};
use image::{RgbImage, RgbaImage};
use nalgebra::Vector2;
use splattrack::geometry::Intrinsics;
use splattrack::io::correspondences::{NamedPoint, PointPair};
use splattrack::view::clicks::{ClickSession, Phase, compose_band, frame_pixel};
use splattrack::view::{DisplaySink, ViewError};
use std::time::Duration;

/// How long one pump of the window waits for events.
const WAIT: Duration = Duration::from_millis(30);

/// The clicked points and their accepted fit; an error when the user
/// cancels or there is no window.
pub fn collect(
    cam: &Intrinsics,
    frame: &RgbImage,
    named: &[NamedPoint],
    view: &ModelView<'_>,
    max_rms: f64,
    threshold: f64,
) -> anyhow::Result<(Vec<PointPair>, Fit)> {
    let ctx = view
        .context()
        .context("--click: the window needs a GPU adapter, and none opened")?;
    let mut window = match DisplaySink::open(ctx, "splattrack init") {
        Ok(w) => w,
        Err(ViewError::NoDisplay(reason)) => {
            let reason = reason.split(" (run it").next().unwrap_or(&reason);
            bail!("--click needs a display: {reason} (or give the pixels with --points corr.csv)")
        }
        Err(ViewError::Open(reason)) => bail!("--click: cannot open a window: {reason}"),
        Err(e) => return Err(e).context("--click"),
    };
    let source = "the clicked points";
    let mut session = ClickSession::new(named.iter().map(|p| p.name.clone()).collect());
    // The review picture and fit of the current clicks, once solved.
    let mut review: Option<(RgbaImage, Option<Fit>)> = None;
    loop {
        let phase = session.phase();
        let picture = match phase {
            Phase::Asking(_) => {
                review = None;
                session.picture(frame)
            }
            Phase::Review => {
                if review.is_none() {
                    let pairs = pairs_from_clicks(named, &session.clicked());
                    review = Some(match fit(&pairs, cam, max_rms, threshold, source) {
                        Ok(f) => {
                            let img = view.overlay(frame, cam, &pairs, &f)?;
                            let mut lines = session.prompt();
                            lines[0] = format!(
                                "RMS {:.2} px over {} of {} points",
                                f.solution.rms_px,
                                f.solution.inliers.len(),
                                pairs.len()
                            );
                            (compose_band(&img, &lines, [40, 230, 60]), Some(f))
                        }
                        Err(e) => {
                            let lines = [
                                format!("{e:#}"),
                                "Backspace: back to the last point   Esc or q: cancel".into(),
                                String::new(),
                            ];
                            (
                                compose_band(
                                    &session_frame(&session, frame),
                                    &lines,
                                    [240, 40, 40],
                                ),
                                None,
                            )
                        }
                    });
                }
                review.as_ref().map(|r| r.0.clone()).unwrap_or_default()
            }
            Phase::Accepted => {
                let pairs = pairs_from_clicks(named, &session.clicked());
                if let Some((_, Some(f))) = review.take() {
                    return Ok((pairs, f));
                }
                bail!("{source}: accepted without a pose");
            }
            Phase::Cancelled => bail!("--click: cancelled in the window; nothing written"),
        };
        let events = window.show(&picture, WAIT)?;
        let size = window.inner_size();
        for e in events {
            let to_frame =
                |x, y| frame_pixel((x, y), size, picture.dimensions(), frame.dimensions());
            let Some(input) = session.translate(e, to_frame) else {
                continue;
            };
            // A refused fit cannot be accepted.
            let refused = matches!(review, Some((_, None)));
            if session.phase() == Phase::Review
                && refused
                && input == splattrack::view::clicks::Input::Accept
            {
                continue;
            }
            session.apply(input);
        }
    }
}

/// The frame with the placed points marked (the review of a refused fit).
fn session_frame(session: &ClickSession, frame: &RgbImage) -> RgbImage {
    let mut shown = frame.clone();
    for (_, p) in session.clicked() {
        splattrack::view::clicks::mark(&mut shown, p, [240, 40, 40], "");
    }
    shown
}

/// The clicked points as correspondences, for [`fit`].
fn pairs_from_clicks(named: &[NamedPoint], clicked: &[(usize, Vector2<f64>)]) -> Vec<PointPair> {
    clicked
        .iter()
        .map(|&(i, pixel)| PointPair {
            name: named[i].name.clone(),
            point: named[i].point,
            pixel,
        })
        .collect()
}
