//! BOP-style results (the BOP challenge's CSV): one row per frame,
//! `scene_id,im_id,obj_id,score,R,t,time`, R row-major and t in millimetres
//! (models in metres), space-separated; written row by row like the pose
//! CSV ([`PartialFile`]).

use super::atomic::{PartialFile, WriteError};
use crate::geometry::Pose;
use std::path::Path;

/// The header line of a BOP results file.
pub const BOP_HEADER: &str = "scene_id,im_id,obj_id,score,R,t,time";

/// One row: frame `im_id` of scene 0, its pose, a score (1 tracked, 0
/// lost) and the seconds it took.
pub fn format_bop_row(im_id: usize, obj_id: u32, pose: &Pose, score: f64, seconds: f64) -> String {
    let p = pose.to_row_major();
    let rot: Vec<String> = p[..9].iter().map(|v| format!("{v:.9}")).collect();
    let tr: Vec<String> = p[9..]
        .iter()
        .map(|v| format!("{:.6}", v * 1000.0))
        .collect();
    format!(
        "0,{im_id},{obj_id},{score:.4},{},{},{seconds:.4}",
        rot.join(" "),
        tr.join(" ")
    )
}

/// The BOP object id of object `name`, the `position`-th (from 1) of a
/// run: the number in a name of BOP's model naming (`obj_000005` -> 5),
/// else `position`.
pub fn bop_obj_id(name: &str, position: usize) -> u32 {
    name.strip_prefix("obj_")
        .filter(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
        .and_then(|n| n.parse().ok())
        .unwrap_or(position as u32)
}

/// A BOP results file written row by row into `OUT.partial`, renamed to
/// `OUT` by [`finish`](Self::finish).
pub struct BopWriter {
    file: PartialFile,
    obj_id: u32,
}

impl BopWriter {
    /// Starts `path` for object `obj_id`.
    pub fn create(path: &Path, obj_id: u32) -> Result<Self, WriteError> {
        let file = PartialFile::create(path, BOP_HEADER)?;
        Ok(Self { file, obj_id })
    }

    /// Appends the row of frame `im_id`.
    pub fn row(
        &mut self,
        im_id: usize,
        pose: &Pose,
        score: f64,
        seconds: f64,
    ) -> Result<(), WriteError> {
        self.file
            .line(&format_bop_row(im_id, self.obj_id, pose, score, seconds))
    }

    /// Appends the row of frame `im_id` for object `obj_id` (a file of
    /// several objects' rows).
    pub fn object_row(
        &mut self,
        im_id: usize,
        obj_id: u32,
        pose: &Pose,
        score: f64,
        seconds: f64,
    ) -> Result<(), WriteError> {
        self.file
            .line(&format_bop_row(im_id, obj_id, pose, score, seconds))
    }

    /// Syncs the file and renames it into place.
    pub fn finish(self) -> Result<(), WriteError> {
        self.file.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    #[test]
    fn object_ids_come_from_bop_names_else_positions() {
        assert_eq!(bop_obj_id("obj_000005", 1), 5);
        assert_eq!(bop_obj_id("obj_12", 3), 12);
        assert_eq!(bop_obj_id("gear", 2), 2);
        assert_eq!(bop_obj_id("obj_", 4), 4);
        assert_eq!(bop_obj_id("obj_5a", 1), 1);
        assert_eq!(bop_obj_id("my_obj_000005", 2), 2);
    }

    #[test]
    fn rows_are_in_millimetres_and_row_major() {
        let pose = Pose::new(Matrix3::identity(), Vector3::new(0.1, -0.02, 0.5)).unwrap();
        assert_eq!(
            format_bop_row(7, 3, &pose, 1.0, 0.0125),
            "0,7,3,1.0000,1.000000000 0.000000000 0.000000000 0.000000000 1.000000000 \
             0.000000000 0.000000000 0.000000000 1.000000000,100.000000 -20.000000 500.000000,0.0125"
        );
    }
}
