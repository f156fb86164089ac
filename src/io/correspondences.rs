//! The inputs of `splattrack init` (docs/formats.md): 2-D/3-D
//! correspondences (`corr.csv`: `u,v,x,y,z`) and named model points to click
//! (`pts.csv`: `name,x,y,z`). Columns are found by their header names, in
//! any order; other columns are ignored, except an optional `name` column in
//! `corr.csv` that labels the points in messages. Blank lines and lines
//! starting with `#` are skipped.

use nalgebra::{Vector2, Vector3};
use std::path::{Path, PathBuf};

/// Errors reading a correspondence or model-point file; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum CorrespondenceError {
    /// The file could not be read.
    #[error("{}: cannot read: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The reason.
        source: std::io::Error,
    },
    /// The header is missing or lacks a column.
    #[error("{}: {reason}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A row is malformed.
    #[error("{}: line {line}: {reason}", path.display())]
    Row {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
}

/// A model point and the pixel that shows it.
#[derive(Debug, Clone, PartialEq)]
pub struct PointPair {
    /// A label for messages: the `name` column, else the 1-based row number.
    pub name: String,
    /// The point, model coordinates.
    pub point: Vector3<f64>,
    /// Where the frame shows it, pixels (OpenCV convention: centre of the
    /// top-left pixel at 0,0).
    pub pixel: Vector2<f64>,
}

/// A named model point, to be clicked.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedPoint {
    /// What the user is asked to click.
    pub name: String,
    /// The point, model coordinates.
    pub point: Vector3<f64>,
}

/// The header's column names and the data rows (1-based line, fields).
struct Table {
    columns: Vec<String>,
    rows: Vec<(usize, Vec<String>)>,
}

fn read_text(path: &Path) -> Result<String, CorrespondenceError> {
    std::fs::read_to_string(path).map_err(|source| CorrespondenceError::Io {
        path: path.to_owned(),
        source,
    })
}

fn table(text: &str, path: &Path, what: &str) -> Result<Table, CorrespondenceError> {
    let mut lines = text.lines().enumerate().filter(|(_, l)| {
        let t = l.trim();
        !t.is_empty() && !t.starts_with('#')
    });
    let (_, header) = lines.next().ok_or_else(|| CorrespondenceError::Format {
        path: path.to_owned(),
        reason: format!("empty file (expected a header line and {what})"),
    })?;
    let columns = header
        .trim_start_matches('\u{feff}')
        .split(',')
        .map(|c| c.trim().to_ascii_lowercase())
        .collect();
    let rows = lines
        .map(|(i, l)| (i + 1, l.split(',').map(|f| f.trim().to_owned()).collect()))
        .collect();
    Ok(Table { columns, rows })
}

impl Table {
    /// Indices of `names` in the header, or an error naming the missing ones.
    fn find(&self, names: &[&str], path: &Path) -> Result<Vec<usize>, CorrespondenceError> {
        let missing: Vec<&str> = names
            .iter()
            .copied()
            .filter(|n| !self.columns.iter().any(|c| c == n))
            .collect();
        if !missing.is_empty() {
            return Err(CorrespondenceError::Format {
                path: path.to_owned(),
                reason: format!(
                    "missing column{} {} (the header must name {}; found {:?})",
                    if missing.len() > 1 { "s" } else { "" },
                    missing.join(", "),
                    names.join(","),
                    self.columns.join(",")
                ),
            });
        }
        Ok(names
            .iter()
            .map(|n| self.columns.iter().position(|c| c == n).unwrap_or(0))
            .collect())
    }

    fn numbers<const N: usize>(
        &self,
        fields: &[String],
        idx: &[usize],
        line: usize,
        path: &Path,
    ) -> Result<[f64; N], CorrespondenceError> {
        let mut out = [0.0; N];
        for (k, &i) in idx.iter().enumerate() {
            let f = &fields[i];
            out[k] = f
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| CorrespondenceError::Row {
                    path: path.to_owned(),
                    line,
                    reason: format!("{} = {f:?} is not a finite number", self.columns[i]),
                })?;
        }
        Ok(out)
    }

    fn check_width(
        &self,
        fields: &[String],
        line: usize,
        path: &Path,
    ) -> Result<(), CorrespondenceError> {
        if fields.len() != self.columns.len() {
            return Err(CorrespondenceError::Row {
                path: path.to_owned(),
                line,
                reason: format!(
                    "{} fields, the header has {}",
                    fields.len(),
                    self.columns.len()
                ),
            });
        }
        Ok(())
    }
}

/// Reads `corr.csv`: columns `u,v,x,y,z` (any order, an optional `name`).
pub fn read_point_pairs(path: &Path) -> Result<Vec<PointPair>, CorrespondenceError> {
    parse_point_pairs(&read_text(path)?, path)
}

/// [`read_point_pairs`] on text in memory; `path` names it in errors.
pub fn parse_point_pairs(text: &str, path: &Path) -> Result<Vec<PointPair>, CorrespondenceError> {
    let t = table(text, path, "rows u,v,x,y,z")?;
    let idx = t.find(&["u", "v", "x", "y", "z"], path)?;
    let name = t.columns.iter().position(|c| c == "name");
    let mut out = Vec::new();
    for (line, fields) in &t.rows {
        t.check_width(fields, *line, path)?;
        let [u, v, x, y, z] = t.numbers::<5>(fields, &idx, *line, path)?;
        out.push(PointPair {
            name: name
                .map(|i| fields[i].clone())
                .filter(|n| !n.is_empty())
                .unwrap_or_else(|| format!("#{}", out.len() + 1)),
            point: Vector3::new(x, y, z),
            pixel: Vector2::new(u, v),
        });
    }
    if out.is_empty() {
        return Err(CorrespondenceError::Format {
            path: path.to_owned(),
            reason: "no rows after the header".into(),
        });
    }
    Ok(out)
}

/// Reads `pts.csv`: columns `name,x,y,z` (any order).
pub fn read_named_points(path: &Path) -> Result<Vec<NamedPoint>, CorrespondenceError> {
    parse_named_points(&read_text(path)?, path)
}

/// [`read_named_points`] on text in memory; `path` names it in errors.
pub fn parse_named_points(text: &str, path: &Path) -> Result<Vec<NamedPoint>, CorrespondenceError> {
    let t = table(text, path, "rows name,x,y,z")?;
    let idx = t.find(&["name", "x", "y", "z"], path)?;
    let mut out: Vec<NamedPoint> = Vec::new();
    for (line, fields) in &t.rows {
        t.check_width(fields, *line, path)?;
        let [x, y, z] = t.numbers::<3>(fields, &idx[1..], *line, path)?;
        let name = fields[idx[0]].clone();
        let row_err = |reason: String| CorrespondenceError::Row {
            path: path.to_owned(),
            line: *line,
            reason,
        };
        if name.is_empty() {
            return Err(row_err("empty name".into()));
        }
        if out.iter().any(|p| p.name == name) {
            return Err(row_err(format!("the name {name:?} appears twice")));
        }
        out.push(NamedPoint {
            name,
            point: Vector3::new(x, y, z),
        });
    }
    if out.is_empty() {
        return Err(CorrespondenceError::Format {
            path: path.to_owned(),
            reason: "no rows after the header".into(),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("corr.csv")
    }

    #[test]
    fn pairs_by_header_name_in_any_order() {
        let text =
            "# clicked by hand\nx,y,z,u,v,name\n0.1,0.2,0.3,10,20,corner\n\n-1,0,1e-3,5.5,6.5,\n";
        let r = parse_point_pairs(text, p()).unwrap();
        assert_eq!(r.len(), 2);
        assert_eq!(r[0].name, "corner");
        assert_eq!(r[0].point, Vector3::new(0.1, 0.2, 0.3));
        assert_eq!(r[0].pixel, Vector2::new(10.0, 20.0));
        assert_eq!(r[1].name, "#2");
        assert_eq!(r[1].pixel, Vector2::new(5.5, 6.5));
        let r = parse_point_pairs("u,v,x,y,z\n1,2,3,4,5\n", p()).unwrap();
        assert_eq!(r[0].point, Vector3::new(3.0, 4.0, 5.0));
    }

    #[test]
    fn bad_pairs_name_the_file_and_the_problem() {
        let e = |t: &str| parse_point_pairs(t, p()).unwrap_err().to_string();
        assert!(e("u,v,x,y\n1,2,3,4\n").contains("corr.csv: missing column z"));
        assert!(e("").contains("corr.csv: empty file"));
        assert!(e("u,v,x,y,z\n").contains("no rows"));
        assert!(e("u,v,x,y,z\n1,2,3,4\n").contains("corr.csv: line 2: 4 fields"));
        assert!(e("u,v,x,y,z\n1,2,3,nan,5\n").contains("y = \"nan\" is not a finite number"));
        assert!(e("u,v,x,y,z\n1,2,3,a,5\n").contains("line 2"));
    }

    #[test]
    fn named_points() {
        let q = Path::new("pts.csv");
        let r = parse_named_points("name,x,y,z\ntop left,0,0,0\nright,1,0,0\n", q).unwrap();
        assert_eq!(r[0].name, "top left");
        assert_eq!(r[1].point, Vector3::new(1.0, 0.0, 0.0));
        let e = |t: &str| parse_named_points(t, q).unwrap_err().to_string();
        assert!(e("x,y,z\n0,0,0\n").contains("pts.csv: missing column name"));
        assert!(
            e("name,x,y,z\na,0,0,0\na,1,0,0\n").contains("line 3: the name \"a\" appears twice")
        );
        assert!(e("name,x,y,z\n,0,0,0\n").contains("empty name"));
    }
}
