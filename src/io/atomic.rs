//! Crash-safe file writing, the one way every output file is written: to a
//! temporary beside the target (`NAME.partial`), flushed and synced, then
//! renamed over the target. A crash (or an error) never leaves a file that
//! looks complete: at most the `.partial` one.
//!
//! [`write_atomic`] writes a whole file at once; [`PartialFile`] writes line
//! by line (flushed per line, so a crash keeps every finished line on disk)
//! and renames only when [`PartialFile::finish`] is called.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// A file could not be written.
#[derive(Debug, thiserror::Error)]
#[error("{}: cannot write: {source}", path.display())]
pub struct WriteError {
    /// The file.
    pub path: PathBuf,
    /// Why.
    #[source]
    pub source: std::io::Error,
}

/// The temporary beside `path` that holds its content until it is complete:
/// `poses.csv` -> `poses.csv.partial`.
pub fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_owned();
    name.push(".partial");
    path.with_file_name(name)
}

/// Writes `path` atomically: `body` writes the content into the temporary
/// [`partial_path`], which is then flushed, synced and renamed over `path`.
/// On error the temporary is removed and `path` is untouched.
pub fn write_atomic(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let tmp = partial_path(path);
    keep_previous_partial(&tmp)?;
    let result = File::create(&tmp).and_then(|f| {
        let mut w = BufWriter::new(f);
        body(&mut w)?;
        commit(w, &tmp, path)
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Flushes and syncs `w` (the file `tmp`), then renames it to `path`.
fn commit(w: BufWriter<File>, tmp: &Path, path: &Path) -> std::io::Result<()> {
    let f = w.into_inner().map_err(|e| e.into_error())?;
    f.sync_all()?;
    drop(f);
    std::fs::rename(tmp, path)?;
    // The rename itself is durable once the directory is synced (where the
    // platform allows opening a directory; elsewhere this is best effort).
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
    }
    Ok(())
}

/// A `.partial` file left at `tmp` by an earlier run that did not finish
/// (a crash, a lost device) may be the only record of that run: it is
/// moved aside to `NAME.partial.1` (the first free number) rather than
/// truncated, with a warning. Returns where it went.
pub fn keep_previous_partial(tmp: &Path) -> std::io::Result<Option<PathBuf>> {
    if std::fs::symlink_metadata(tmp).is_err() {
        return Ok(None);
    }
    for n in 1..10_000u32 {
        let mut name = tmp.file_name().unwrap_or_default().to_owned();
        name.push(format!(".{n}"));
        let kept = tmp.with_file_name(name);
        if std::fs::symlink_metadata(&kept).is_err() {
            std::fs::rename(tmp, &kept)?;
            log::warn!(
                "{} was left by an unfinished run: kept as {}",
                tmp.display(),
                kept.display()
            );
            eprintln!(
                "note: {} was left by an unfinished run: kept as {}",
                tmp.display(),
                kept.display()
            );
            return Ok(Some(kept));
        }
    }
    Err(std::io::Error::other(format!(
        "{}: too many unfinished runs kept beside it (.partial.1 to .partial.9999); remove some",
        tmp.display()
    )))
}

/// A text file written line by line into its [`partial_path`], each line
/// flushed as it is written, and renamed into place by
/// [`finish`](Self::finish). Dropped without `finish` (a crash, an error), it leaves
/// the `.partial` file with the lines written so far and no file at `path`.
pub struct PartialFile {
    w: BufWriter<File>,
    tmp: PathBuf,
    path: PathBuf,
}

impl PartialFile {
    /// Creates `path`'s temporary, starting with the line `header`.
    pub fn create(path: &Path, header: &str) -> Result<Self, WriteError> {
        let tmp = partial_path(path);
        keep_previous_partial(&tmp).map_err(|source| WriteError {
            path: tmp.clone(),
            source,
        })?;
        let f = File::create(&tmp).map_err(|source| WriteError {
            path: tmp.clone(),
            source,
        })?;
        let mut file = Self {
            w: BufWriter::new(f),
            tmp,
            path: path.to_owned(),
        };
        file.line(header)?;
        Ok(file)
    }

    /// Appends one line (without its newline) and flushes it.
    pub fn line(&mut self, line: &str) -> Result<(), WriteError> {
        writeln!(self.w, "{line}")
            .and_then(|_| self.w.flush())
            .map_err(|source| WriteError {
                path: self.tmp.clone(),
                source,
            })
    }

    /// The file being written (the temporary).
    pub fn partial(&self) -> &Path {
        &self.tmp
    }

    /// The file it becomes.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Syncs the temporary and renames it to the final path.
    pub fn finish(self) -> Result<(), WriteError> {
        commit(self.w, &self.tmp, &self.path).map_err(|source| WriteError {
            path: self.path,
            source,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("splattrack-atomic-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn whole_file_replaces_the_target_only_when_complete() {
        let d = dir("whole");
        let path = d.join("out.csv");
        assert_eq!(partial_path(&path), d.join("out.csv.partial"));
        std::fs::write(&path, "old\n").unwrap();
        // A body that fails leaves the old file and no temporary.
        let e = write_atomic(&path, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("disk full"))
        });
        assert!(e.is_err());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old\n");
        assert!(!partial_path(&path).exists());
        write_atomic(&path, |w| w.write_all(b"new\n")).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new\n");
        assert!(!partial_path(&path).exists());
        std::fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn line_by_line_keeps_finished_lines_and_no_final_file_until_finish() {
        let d = dir("lines");
        let path = d.join("rows.csv");
        let mut f = PartialFile::create(&path, "a,b").unwrap();
        f.line("1,2").unwrap();
        f.line("3,4").unwrap();
        // Every line is on disk already, and nothing at the final path.
        assert_eq!(
            std::fs::read_to_string(f.partial()).unwrap(),
            "a,b\n1,2\n3,4\n"
        );
        assert!(!path.exists());
        f.finish().unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "a,b\n1,2\n3,4\n");
        assert!(!partial_path(&path).exists());
        // Dropped without finish (a crash): the partial file stays.
        let mut f = PartialFile::create(&d.join("crash.csv"), "h").unwrap();
        f.line("x").unwrap();
        drop(f);
        assert!(!d.join("crash.csv").exists());
        assert_eq!(
            std::fs::read_to_string(d.join("crash.csv.partial")).unwrap(),
            "h\nx\n"
        );
        // A rerun keeps the crashed run's partial output, never truncates it.
        let mut f = PartialFile::create(&d.join("crash.csv"), "h2").unwrap();
        f.line("y").unwrap();
        f.finish().unwrap();
        assert_eq!(
            std::fs::read_to_string(d.join("crash.csv.partial.1")).unwrap(),
            "h\nx\n"
        );
        assert_eq!(
            std::fs::read_to_string(d.join("crash.csv")).unwrap(),
            "h2\ny\n"
        );
        std::fs::write(d.join("whole.bin.partial"), "left").unwrap();
        write_atomic(&d.join("whole.bin"), |w| w.write_all(b"ok")).unwrap();
        assert_eq!(
            std::fs::read_to_string(d.join("whole.bin.partial.1")).unwrap(),
            "left"
        );
        std::fs::remove_dir_all(d).unwrap();
    }
}
