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
}

impl Refused {
    /// Starts `path`'s file (`None`: nothing to write).
    pub fn create(path: Option<&Path>) -> anyhow::Result<Self> {
        let file = match path {
            Some(p) => Some((p.to_owned(), RefusedWriter::create(p)?)),
            None => None,
        };
        Ok(Self { file, error: None })
    }

    /// Writes a frame's row, if it refused an estimate.
    pub fn frame(&mut self, frame: &Frame, r: &TrackResult) {
        if let (Some((_, w)), None) = (self.file.as_mut(), &self.error) {
            self.error = w.frame(&frame.label, r).err();
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
