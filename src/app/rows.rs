//! The rows of the tracker output: a frame's pose and result columns.

use crate::io::poses::PoseRow;
use crate::tracker::TrackResult;

/// The columns the tracker output adds after the pose (FORMATS.md
/// "Tracker output"; `cues`: [`cues_name`] of [`TrackResult::cues`]).
pub const RESULT_COLUMNS: [&str; 4] = ["inliers", "residual_px", "status", "cues"];

/// The column a run over a video or a camera adds after [`RESULT_COLUMNS`]:
/// the frame's timestamp in seconds (FORMATS.md, `track --video`).
pub const TIME_COLUMN: &str = "time_s";

/// The tracker output row of a frame.
pub fn result_row(label: &str, r: &TrackResult) -> PoseRow {
    let mut row = PoseRow::new(label, r.pose);
    let residual = if r.residual_px.is_finite() {
        format!("{:.3}", r.residual_px)
    } else {
        "nan".into()
    };
    row.extra = [
        r.inliers.to_string(),
        residual,
        r.status.name().into(),
        cues_name(r.cues),
    ]
    .into_iter()
    .zip(RESULT_COLUMNS)
    .map(|(v, k)| (k.to_string(), v))
    .collect();
    row
}

/// The cues of a frame as the `cues` column writes them: `texture`,
/// `contour`, `texture+contour` (no comma inside a CSV field) or `none`.
pub fn cues_name(m: crate::tracker::Modalities) -> String {
    m.name().replace(',', "+")
}
