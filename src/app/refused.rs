//! The refused estimates of a run (`splattrack track --refused FILE`,
//! docs/formats.md "Refused estimates"): a pose CSV with a row for each
//! `lost` frame that had an estimate ([`TrackResult::refused`]), the pose
//! refused and [`REFUSED_COLUMNS`] after it, written as the frames are
//! tracked.

use crate::io::poses::{PoseFileError, PoseRow, PoseWriter};
use crate::tracker::TrackResult;
use std::path::Path;

/// The columns of the refused file after the pose: where the estimate
/// came from ([`crate::tracker::Source::name`]), why it was refused
/// ([`crate::tracker::LostReason::code`]), the check's scores at it (`nan`
/// where the check did not run or had nothing to score), and its solve's
/// inliers and residual.
pub const REFUSED_COLUMNS: [&str; 6] = [
    "stage",
    "reason",
    "zncc",
    "edge_support",
    "inliers",
    "residual_px",
];

/// The refused file's row of a frame (`label`: its frame column), `None`
/// where the frame refused nothing (tracking, or lost without an
/// estimate).
pub fn refused_row(label: &str, r: &TrackResult) -> Option<PoseRow> {
    let refused = r.refused.as_ref()?;
    let num = |v: Option<f64>, digits: usize| match v.filter(|v| v.is_finite()) {
        Some(v) => format!("{v:.digits$}"),
        None => "nan".into(),
    };
    let scores = refused.scores.as_ref();
    let values = [
        refused.source.name().to_owned(),
        r.reason
            .as_ref()
            .map_or("unknown", |why| why.code())
            .to_owned(),
        num(scores.and_then(|s| s.zncc), 4),
        num(scores.and_then(|s| s.edge_support), 4),
        refused.inliers.to_string(),
        num(Some(refused.residual_px), 3),
    ];
    let mut row = PoseRow::new(label, refused.pose);
    row.extra = REFUSED_COLUMNS
        .iter()
        .zip(values)
        .map(|(k, v)| (k.to_string(), v))
        .collect();
    Some(row)
}

/// Writes the refused file row by row, crash-safe as the pose file
/// ([`PoseWriter`]: the rows in `FILE.partial` until [`Self::finish`]);
/// in a run of several objects, with the `object` column first
/// ([`Self::create_objects`], [`Self::object_frame`]).
pub struct RefusedWriter {
    file: PoseWriter,
    rows: usize,
}

impl RefusedWriter {
    /// Starts `path` with its header.
    pub fn create(path: &Path) -> Result<Self, PoseFileError> {
        Ok(Self {
            file: PoseWriter::create(path, &REFUSED_COLUMNS)?,
            rows: 0,
        })
    }

    /// Starts `path` with its header and the `object` column first.
    pub fn create_objects(path: &Path) -> Result<Self, PoseFileError> {
        Ok(Self {
            file: PoseWriter::create_objects(path, &REFUSED_COLUMNS)?,
            rows: 0,
        })
    }

    /// Writes object `name`'s row of frame `label`, if it refused an
    /// estimate (a file of [`Self::create_objects`]).
    pub fn object_frame(
        &mut self,
        name: &str,
        label: &str,
        r: &TrackResult,
    ) -> Result<(), PoseFileError> {
        if let Some(row) = refused_row(label, r) {
            self.file.row(&row.of_object(name))?;
            self.rows += 1;
        }
        Ok(())
    }

    /// Writes frame `label`'s row, if it refused an estimate.
    pub fn frame(&mut self, label: &str, r: &TrackResult) -> Result<(), PoseFileError> {
        if let Some(row) = refused_row(label, r) {
            self.file.row(&row)?;
            self.rows += 1;
        }
        Ok(())
    }

    /// The rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Puts the file in place.
    pub fn finish(self) -> Result<(), PoseFileError> {
        self.file.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use crate::tracker::{
        LostReason, Refused, Source, Status, TrackResult, Unverified, VerifyScores,
    };
    use nalgebra::{Matrix3, Vector3};

    fn lost(refused: Option<Refused>, reason: LostReason) -> TrackResult {
        TrackResult {
            pose: Pose::identity(),
            inliers: 0,
            residual_px: f64::NAN,
            status: Status::Lost,
            reason: Some(reason),
            keyframe: None,
            times: Default::default(),
            verify: None,
            texture_set_aside: false,
            cues: crate::tracker::Modalities::NONE,
            refused,
        }
    }

    #[test]
    fn a_refused_estimate_is_a_row_with_its_pose_stage_reason_and_scores() {
        let pose = Pose::new(Matrix3::identity(), Vector3::new(0.1, 0.0, 0.5)).unwrap();
        let scores = VerifyScores {
            zncc: Some(0.123456),
            edge_support: Some(0.5),
            ..Default::default()
        };
        let r = lost(
            Some(Refused {
                pose,
                source: Source::Contour,
                inliers: 31,
                residual_px: 1.25,
                scores: Some(scores),
            }),
            LostReason::Unverified(Unverified::Appearance {
                zncc: scores.zncc,
                edge_support: scores.edge_support,
            }),
        );
        let row = refused_row("000007", &r).unwrap();
        assert_eq!((row.frame.as_str(), row.pose), ("000007", pose));
        let values: Vec<&str> = row.extra.iter().map(|(_, v)| v.as_str()).collect();
        assert_eq!(
            values,
            ["contour", "appearance", "0.1235", "0.5000", "31", "1.250"]
        );
        let names: Vec<&str> = row.extra.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(names, REFUSED_COLUMNS);
        // Refused by the rules, before any check: no scores.
        let r = lost(
            Some(Refused {
                pose,
                source: Source::Kf,
                inliers: 5,
                residual_px: 0.8,
                scores: None,
            }),
            LostReason::NotFound,
        );
        let row = refused_row("x.png", &r).unwrap();
        let values: Vec<&str> = row.extra.iter().map(|(_, v)| v.as_str()).collect();
        assert_eq!(values, ["kf", "not_found", "nan", "nan", "5", "0.800"]);
        // Nothing refused: no row.
        assert!(refused_row("1", &lost(None, LostReason::NotFound)).is_none());
    }
}
