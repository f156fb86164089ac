//! Pose CSV files (docs/formats.md): a header line, then one row per pose,
//! `[object,]frame,r11,r12,r13,r21,r22,r23,r31,r32,r33,tx,ty,tz[,extra
//! columns]`, object-to-camera, R row-major; the leading `object` column
//! (the object's name) where the file holds several objects' poses.

use super::atomic::{PartialFile, WriteError, write_atomic};
use crate::geometry::{Pose, PoseError};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The columns every pose file starts with.
pub const POSE_COLUMNS: [&str; 13] = [
    "frame", "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33", "tx", "ty", "tz",
];

/// Errors of reading and writing pose CSV files.
#[derive(Debug, thiserror::Error)]
pub enum PoseFileError {
    /// The pose file could not be read.
    #[error("{path}: cannot read pose file: {source}")]
    Io {
        /// The pose file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The pose file could not be written.
    #[error(transparent)]
    Write(#[from] WriteError),
    /// The file as a whole is wrong: empty, a wrong header, or no pose rows.
    #[error("{path}: {reason}")]
    Format {
        /// The pose file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A row is malformed: wrong field count, a non-number, or an empty
    /// frame label.
    #[error("{path}, line {line}: {reason}")]
    Row {
        /// The pose file.
        path: PathBuf,
        /// The 1-based line number in the file.
        line: usize,
        /// What is wrong with the row.
        reason: String,
    },
    /// A row's numbers are not a rigid transform.
    #[error("{path}, line {line}: {source}")]
    BadPose {
        /// The pose file.
        path: PathBuf,
        /// The 1-based line number in the file.
        line: usize,
        /// Why the pose was rejected.
        #[source]
        source: PoseError,
    },
}

/// One row of a pose file: the object (in a file of several objects), the
/// frame label, the pose and any extra columns (by header name) that
/// followed `tz`.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseRow {
    /// The object's name, in a file with an `object` column (several
    /// objects' poses); `None` in a file of one object's.
    pub object: Option<String>,
    /// The frame label: an index (`000043`) or an image file name.
    pub frame: String,
    /// The object-to-camera pose.
    pub pose: Pose,
    /// Extra columns after `tz` as `(header name, value)`, in file order.
    pub extra: Vec<(String, String)>,
}

impl PoseRow {
    /// A row with no extra columns.
    pub fn new(frame: impl Into<String>, pose: Pose) -> Self {
        Self {
            object: None,
            frame: frame.into(),
            pose,
            extra: Vec::new(),
        }
    }

    /// This row, of object `name` (a row of a several-object file).
    pub fn of_object(mut self, name: impl Into<String>) -> Self {
        self.object = Some(name.into());
        self
    }

    /// The frame label as an index, if it is one (`"000043"` -> 43).
    pub fn frame_index(&self) -> Option<usize> {
        self.frame.parse().ok()
    }

    /// The label without an image extension (`kf00.png` -> `kf00`).
    pub fn frame_stem(&self) -> &str {
        Path::new(&self.frame)
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or(&self.frame)
    }
}

/// Reads a pose CSV. Rotations must be rotation matrices to 1e-4; they are
/// re-orthonormalised to full precision on load.
pub fn read_poses(path: &Path) -> Result<Vec<PoseRow>, PoseFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| PoseFileError::Io {
        path: path.to_owned(),
        source,
    })?;
    parse_poses(&text, path)
}

/// [`read_poses`] on text already in memory; `path` names it in errors.
pub fn parse_poses(text: &str, path: &Path) -> Result<Vec<PoseRow>, PoseFileError> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let fmt_err = |reason: String| PoseFileError::Format {
        path: path.to_owned(),
        reason,
    };
    let (_, header) = lines
        .next()
        .ok_or_else(|| fmt_err("empty file (expected a header line and pose rows)".into()))?;
    let mut cols: Vec<String> = header
        .trim_start_matches('\u{feff}')
        .split(',')
        .map(|c| c.trim().to_ascii_lowercase())
        .collect();
    // A leading `object` column: several objects' poses.
    let with_object = cols.first().is_some_and(|c| c == "object");
    if with_object {
        cols.remove(0);
    }
    if cols.len() < 13 || cols[..13] != POSE_COLUMNS {
        return Err(fmt_err(format!(
            "header must start with {:?} (or object,{0:?}), found {:?}",
            POSE_COLUMNS.join(","),
            header.trim()
        )));
    }
    let mut rows = Vec::new();
    for (i, line) in lines {
        let lineno = i + 1;
        let row_err = |reason: String| PoseFileError::Row {
            path: path.to_owned(),
            line: lineno,
            reason,
        };
        let mut fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let n_cols = cols.len() + usize::from(with_object);
        if fields.len() != n_cols {
            return Err(row_err(format!(
                "{} fields, the header has {n_cols}",
                fields.len(),
            )));
        }
        let object = if with_object {
            let name = fields.remove(0);
            if name.is_empty() {
                return Err(row_err("empty object name".into()));
            }
            Some(name.to_owned())
        } else {
            None
        };
        let mut v = [0.0f64; 12];
        for (k, f) in fields[1..13].iter().enumerate() {
            v[k] = f
                .parse()
                .map_err(|_| row_err(format!("{} = {f:?} is not a number", cols[k + 1])))?;
        }
        let pose = Pose::from_row_major(&v).map_err(|source| PoseFileError::BadPose {
            path: path.to_owned(),
            line: lineno,
            source,
        })?;
        if fields[0].is_empty() {
            return Err(row_err("empty frame label".into()));
        }
        rows.push(PoseRow {
            object,
            frame: fields[0].to_owned(),
            pose: pose.orthonormalized(),
            extra: cols[13..]
                .iter()
                .cloned()
                .zip(fields[13..].iter().map(|s| s.to_string()))
                .collect(),
        });
    }
    if rows.is_empty() {
        return Err(fmt_err("no pose rows after the header".into()));
    }
    Ok(rows)
}

/// Formats one row (no newline) with enough digits to round-trip poses;
/// the object's name first where the row has one.
pub fn format_row(row: &PoseRow) -> String {
    let mut s = match &row.object {
        Some(name) => format!("{name},{}", row.frame),
        None => row.frame.clone(),
    };
    for v in row.pose.to_row_major() {
        s.push(',');
        s.push_str(&format!("{v:.9}"));
    }
    for (_, v) in &row.extra {
        s.push(',');
        s.push_str(v);
    }
    s
}

/// The header line for rows with these extra columns.
pub fn header(extra_columns: &[&str]) -> String {
    header_of(false, extra_columns)
}

/// The header line for rows with these extra columns, and an `object`
/// column first where `objects` (rows of several objects).
pub fn header_of(objects: bool, extra_columns: &[&str]) -> String {
    let mut h = if objects {
        "object,".to_string()
    } else {
        String::new()
    };
    h.push_str(&POSE_COLUMNS.join(","));
    for c in extra_columns {
        h.push(',');
        h.push_str(c);
    }
    h
}

/// Writes a pose CSV atomically ([`write_atomic`]), so a crash never
/// leaves a truncated file. Rows must all have the same extra columns,
/// and all an object or none (the `object` column).
pub fn write_poses(path: &Path, rows: &[PoseRow]) -> Result<(), PoseFileError> {
    let extra: Vec<&str> = rows
        .first()
        .map(|r| r.extra.iter().map(|(k, _)| k.as_str()).collect())
        .unwrap_or_default();
    let objects = rows.first().is_some_and(|r| r.object.is_some());
    write_atomic(path, |f| {
        writeln!(f, "{}", header_of(objects, &extra))?;
        for r in rows {
            writeln!(f, "{}", format_row(r))?;
        }
        Ok(())
    })
    .map_err(|source| {
        PoseFileError::Write(WriteError {
            path: path.to_owned(),
            source,
        })
    })
}

/// A pose CSV written row by row while a sequence is tracked: each row is
/// flushed to `OUT.partial` as it is written, and the file is renamed to
/// `OUT` only by [`finish`](Self::finish), so a crash leaves every finished
/// row on disk and never a file that looks complete.
pub struct PoseWriter {
    file: PartialFile,
}

impl PoseWriter {
    /// Starts `path` with the header for rows with these extra columns.
    pub fn create(path: &Path, extra_columns: &[&str]) -> Result<Self, PoseFileError> {
        let file = PartialFile::create(path, &header(extra_columns))?;
        Ok(Self { file })
    }

    /// [`PoseWriter::create`] for rows of several objects (an `object`
    /// column first: every row must name its object).
    pub fn create_objects(path: &Path, extra_columns: &[&str]) -> Result<Self, PoseFileError> {
        let file = PartialFile::create(path, &header_of(true, extra_columns))?;
        Ok(Self { file })
    }

    /// Appends one row and flushes it.
    pub fn row(&mut self, row: &PoseRow) -> Result<(), PoseFileError> {
        Ok(self.file.line(&format_row(row))?)
    }

    /// Syncs the file and renames it into place.
    pub fn finish(self) -> Result<(), PoseFileError> {
        Ok(self.file.finish()?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::rotation_exp;
    use nalgebra::Vector3;

    fn p() -> &'static Path {
        Path::new("test.csv")
    }

    #[test]
    fn object_column_roundtrips_and_is_checked() {
        let pose = Pose::new(rotation_exp(&Vector3::new(0.1, 0.2, 0.3)), Vector3::z()).unwrap();
        let mut rows = Vec::new();
        for (i, name) in ["gear", "housing"].into_iter().enumerate() {
            let mut r = PoseRow::new(format!("{i:06}"), pose).of_object(name);
            r.extra = vec![("status".into(), "tracking".into())];
            rows.push(r);
        }
        let text: String = std::iter::once(header_of(true, &["status"]))
            .chain(rows.iter().map(format_row))
            .map(|l| l + "\n")
            .collect();
        assert!(text.starts_with("object,frame,r11,"));
        let back = parse_poses(&text, p()).unwrap();
        assert_eq!(back.len(), 2);
        assert_eq!(back[0].object.as_deref(), Some("gear"));
        assert_eq!(back[1].object.as_deref(), Some("housing"));
        assert_eq!(back[1].frame, "000001");
        assert_eq!(back[1].extra, rows[1].extra);
        // A file of one object has none.
        let plain = format!(
            "{}\n{}\n",
            header(&[]),
            format_row(&PoseRow::new("0", pose))
        );
        assert_eq!(parse_poses(&plain, p()).unwrap()[0].object, None);
        // An empty name, or a row without the object's field, is refused
        // naming the line.
        let empty = text.replace("gear,", ",");
        let e = parse_poses(&empty, p()).unwrap_err().to_string();
        assert!(
            e.contains("line 2") && e.contains("empty object name"),
            "{e}"
        );
        let short = text.replace("housing,", "");
        let e = parse_poses(&short, p()).unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("fields"), "{e}");
    }

    #[test]
    fn roundtrip_with_extra_columns() {
        let mut rng = crate::rng::Rng::new(11);
        let rows: Vec<PoseRow> = (0..20)
            .map(|i| {
                let r = rotation_exp(&(rng.unit_vector() * rng.uniform(0.0, 3.0)));
                let t = Vector3::new(rng.normal(), rng.normal(), rng.uniform(0.2, 2.0));
                PoseRow {
                    object: None,
                    frame: format!("{i:06}"),
                    pose: Pose::new(r, t).unwrap(),
                    extra: vec![("inliers".into(), format!("{}", i * 3))],
                }
            })
            .collect();
        let dir = std::env::temp_dir().join(format!("splattrack-poses-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("poses.csv");
        write_poses(&path, &rows).unwrap();
        let back = read_poses(&path).unwrap();
        assert_eq!(back.len(), rows.len());
        for (a, b) in rows.iter().zip(&back) {
            assert_eq!(a.frame, b.frame);
            assert_eq!(a.extra, b.extra);
            assert!((a.pose.to_matrix4() - b.pose.to_matrix4()).amax() < 1e-8);
        }
        assert!(!path.with_extension("csv.partial").exists());
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn pose_writer_is_crash_safe() {
        let dir =
            std::env::temp_dir().join(format!("splattrack-posewriter-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("poses.csv");
        let partial = dir.join("poses.csv.partial");
        let row = |i: usize| {
            let mut r = PoseRow::new(i.to_string(), Pose::identity());
            r.extra = vec![("status".into(), "tracking".into())];
            r
        };
        // Dropped without finish: the rows so far in .partial, no final file.
        let mut w = PoseWriter::create(&path, &["status"]).unwrap();
        w.row(&row(0)).unwrap();
        w.row(&row(1)).unwrap();
        drop(w);
        assert!(!path.exists());
        let text = std::fs::read_to_string(&partial).unwrap();
        assert_eq!(text.lines().count(), 3, "{text}");
        assert_eq!(parse_poses(&text, &partial).unwrap(), vec![row(0), row(1)]);
        // Finished: the whole file in place, no .partial.
        let mut w = PoseWriter::create(&path, &["status"]).unwrap();
        for i in 0..3 {
            w.row(&row(i)).unwrap();
        }
        w.finish().unwrap();
        assert!(!partial.exists());
        assert_eq!(read_poses(&path).unwrap().len(), 3);
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn formats_md_example_parses() {
        let rows = parse_poses(
            "frame,r11,r12,r13,r21,r22,r23,r31,r32,r33,tx,ty,tz\n0,1,0,0,0,1,0,0,0,1,0,0,0.5\n",
            p(),
        )
        .unwrap();
        assert_eq!(rows[0].frame_index(), Some(0));
        assert_eq!(rows[0].pose.translation.z, 0.5);
        let kf = PoseRow::new("kf00.png", Pose::identity());
        assert_eq!(kf.frame_stem(), "kf00");
    }

    #[test]
    fn bad_files_name_the_problem() {
        let h = "frame,r11,r12,r13,r21,r22,r23,r31,r32,r33,tx,ty,tz\n";
        let cases = [
            ("", "empty file"),
            ("a,b,c\n", "header must start"),
            (h, "no pose rows"),
            (&format!("{h}0,1,0,0,0,1,0,0,0,1,0,0\n") as &str, "line 2"),
            (&format!("{h}0,1,0,0,0,1,0,0,0,x,0,0,1\n"), "r33"),
            (&format!("{h}0,2,0,0,0,1,0,0,0,1,0,0,1\n"), "not a rotation"),
            (&format!("{h}0,1,0,0,0,1,0,0,0,1,0,NaN,1\n"), "non-finite"),
        ];
        for (text, want) in cases {
            let e = parse_poses(text, p()).unwrap_err().to_string();
            assert!(e.contains(want) && e.contains("test.csv"), "{text:?}: {e}");
        }
    }
}
