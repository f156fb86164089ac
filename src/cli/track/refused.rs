//! `--refused FILE`: the refused estimates, written frame by frame beside
//! the run ([`splattrack::app::refused`]); the first write error is kept
//! and reported after the run.

use splattrack::app::refused::RefusedWriter;
use splattrack::io::poses::PoseFileError;
use splattrack::io::sequence::Frame;
use splattrack::tracker::TrackResult;
use std::path::{Path, PathBuf};

/// The refused file of a run, if asked for.
pub struct Refused {
    file: Option<(PathBuf, RefusedWriter)>,
    error: Option<PoseFileError>,
    /// The objects' names in a run of several (the object column).
    names: Vec<String>,
}

impl Refused {
    /// Starts `path`'s file (`None`: nothing to write), with the object
    /// column when `names` holds several objects' names.
    pub fn create(path: Option<&Path>, names: Vec<String>) -> anyhow::Result<Self> {
        let file = match (path, names.len() > 1) {
            (Some(p), false) => Some((p.to_owned(), RefusedWriter::create(p)?)),
            (Some(p), true) => Some((p.to_owned(), RefusedWriter::create_objects(p)?)),
            (None, _) => None,
        };
        Ok(Self {
            file,
            error: None,
            names,
        })
    }

    /// Writes a frame's rows (one per object that refused an estimate,
    /// in the objects' order).
    pub fn frame(&mut self, frame: &Frame, results: &[TrackResult]) {
        if let (Some((_, w)), None) = (self.file.as_mut(), &self.error) {
            self.error = if self.names.len() > 1 {
                results
                    .iter()
                    .zip(&self.names)
                    .try_for_each(|(r, name)| w.object_frame(name, &frame.label, r))
                    .err()
            } else {
                w.frame(&frame.label, &results[0]).err()
            };
        }
    }

    /// After a failed run: no file, not even a partial one.
    pub fn discard(self) {
        if let Some((path, w)) = self.file {
            drop(w);
            let _ = std::fs::remove_file(splattrack::io::atomic::partial_path(&path));
        }
    }

    /// Puts the file in place and says how many rows it holds, or reports
    /// the first write error.
    pub fn finish(self) -> anyhow::Result<()> {
        if let Some(e) = self.error {
            return Err(e.into());
        }
        if let Some((path, w)) = self.file {
            let rows = w.rows();
            w.finish()?;
            println!("{rows} refused estimates in {}", path.display());
        }
        Ok(())
    }
}
