//! Writing a binary little-endian PLY of one element, through a temporary
//! file renamed into place.

use super::header::io_err;
use crate::model::error::ModelError;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writes a binary little-endian PLY of one element, `count` rows of the
/// scalar properties `props` (`(type, name)`), each row's bytes appended by
/// `row(index, bytes)`. The file is written through a temporary file renamed
/// into place, so that a failed write never leaves a plausible-looking file
/// behind.
pub(crate) fn write(
    path: &Path,
    comments: &[String],
    element: &str,
    count: usize,
    props: &[(&str, &str)],
    row: impl FnMut(usize, &mut Vec<u8>),
) -> Result<(), ModelError> {
    let mut tmp_name = path.file_name().unwrap_or_default().to_os_string();
    tmp_name.push(format!(".tmp{}", std::process::id()));
    let tmp: PathBuf = path.with_file_name(tmp_name);
    let result = write_to(&tmp, comments, element, count, props, row).and_then(|()| {
        std::fs::rename(&tmp, path).map_err(|e| io_err(path, "rename the temporary file to", e))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn write_to(
    path: &Path,
    comments: &[String],
    element: &str,
    count: usize,
    props: &[(&str, &str)],
    mut row: impl FnMut(usize, &mut Vec<u8>),
) -> Result<(), ModelError> {
    let file = File::create(path).map_err(|e| io_err(path, "create", e))?;
    let mut w = BufWriter::with_capacity(1 << 16, file);
    let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
    for c in comments {
        // A newline in a comment would end the header line early.
        header.push_str(&format!("comment {}\n", c.replace(['\n', '\r'], " ")));
    }
    header.push_str(&format!("element {element} {count}\n"));
    for (ty, name) in props {
        header.push_str(&format!("property {ty} {name}\n"));
    }
    header.push_str("end_header\n");
    let werr = |e| io_err(path, "write", e);
    w.write_all(header.as_bytes()).map_err(werr)?;
    let mut rec = Vec::with_capacity(64);
    for i in 0..count {
        rec.clear();
        row(i, &mut rec);
        w.write_all(&rec).map_err(werr)?;
    }
    w.flush().map_err(werr)?;
    w.into_inner()
        .map_err(|e| werr(e.into_error()))?
        .sync_all()
        .map_err(werr)?;
    Ok(())
}
