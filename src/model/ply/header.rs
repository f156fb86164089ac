//! The PLY header: its encoding, elements and properties, read with a
//! cap on its size, and the element counts checked against the body.

use crate::model::error::ModelError;
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

/// The header may not be longer than this: real headers are a few hundred bytes.
const MAX_HEADER_BYTES: u64 = 1 << 20;
/// Longest body line accepted in ASCII files (a face with ~100k indices).
pub(super) const MAX_LINE_BYTES: u64 = 1 << 20;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    pub(super) fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
pub(crate) struct Property {
    pub name: String,
    pub kind: Kind,
}

#[derive(Debug, Clone)]
pub(crate) struct Element {
    pub name: String,
    pub count: usize,
    pub props: Vec<Property>,
}

impl Element {
    pub fn prop(&self, name: &str) -> Option<&Property> {
        self.props.iter().find(|p| p.name == name)
    }

    /// The fewest body bytes one element can take.
    fn min_bytes(&self, encoding: Encoding) -> u64 {
        match encoding {
            // Every token needs a character and a separator (space or newline).
            Encoding::Ascii => 2 * self.props.len() as u64,
            _ => self
                .props
                .iter()
                .map(|p| match p.kind {
                    Kind::Scalar(s) => s.size() as u64,
                    Kind::List { count, .. } => count.size() as u64,
                })
                .sum(),
        }
    }

    /// The name of the face element's vertex list, if it has one.
    pub fn face_list(&self) -> Option<&Property> {
        self.props.iter().find(|p| {
            (p.name == "vertex_indices" || p.name == "vertex_index")
                && matches!(p.kind, Kind::List { .. })
        })
    }
}

#[derive(Debug, Clone)]
pub(crate) struct Header {
    pub encoding: Encoding,
    pub elements: Vec<Element>,
    /// Bytes from the start of the file to the first body byte.
    pub body_offset: u64,
    /// Lines in the header, so that ASCII body errors give file line numbers.
    pub lines: usize,
}

impl Header {
    pub fn element(&self, name: &str) -> Option<&Element> {
        self.elements.iter().find(|e| e.name == name)
    }

    /// True when the file has a `face` element with a vertex index list.
    pub fn has_faces(&self) -> bool {
        self.element("face")
            .is_some_and(|f| f.face_list().is_some())
    }
}

fn header_err(path: &Path, line: usize, reason: impl Into<String>) -> ModelError {
    ModelError::Header {
        path: path.to_path_buf(),
        line,
        reason: reason.into(),
    }
}

pub(crate) fn io_err(path: &Path, action: &'static str, source: std::io::Error) -> ModelError {
    ModelError::Io {
        path: path.to_path_buf(),
        action,
        source,
    }
}

/// Reads one line (newline included) of at most `cap` bytes into `buf`.
/// Returns the number of bytes read, 0 at end of file.
pub(crate) fn read_line_capped<R: BufRead>(
    r: &mut R,
    buf: &mut Vec<u8>,
    cap: u64,
) -> std::io::Result<usize> {
    buf.clear();
    r.by_ref().take(cap).read_until(b'\n', buf)
}

fn trim_eol(line: &[u8]) -> &[u8] {
    let mut end = line.len();
    while end > 0 && matches!(line[end - 1], b'\n' | b'\r') {
        end -= 1;
    }
    &line[..end]
}

/// Opens `path` and reads its header; the reader is left at the first body byte.
pub(crate) fn open(path: &Path) -> Result<(Header, BufReader<File>, u64), ModelError> {
    let file = File::open(path).map_err(|e| io_err(path, "open", e))?;
    let file_len = file
        .metadata()
        .map_err(|e| io_err(path, "read metadata of", e))?
        .len();
    let mut reader = BufReader::with_capacity(1 << 16, file);
    let header = read_header(&mut reader, path)?;
    Ok((header, reader, file_len))
}

pub(crate) fn read_header<R: BufRead>(r: &mut R, path: &Path) -> Result<Header, ModelError> {
    let mut buf = Vec::with_capacity(128);
    let mut consumed: u64 = 0;
    let mut line_no = 0usize;

    // The magic line: anything else means this is not a PLY file at all.
    let n = read_line_capped(r, &mut buf, 16).map_err(|e| io_err(path, "read", e))?;
    consumed += n as u64;
    line_no += 1;
    if trim_eol(&buf).trim_ascii_end() != b"ply" || !buf.ends_with(b"\n") {
        return Err(ModelError::NotPly {
            path: path.to_path_buf(),
        });
    }

    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let remaining = MAX_HEADER_BYTES.saturating_sub(consumed);
        if remaining == 0 {
            return Err(header_err(
                path,
                line_no,
                format!("no 'end_header' in the first {MAX_HEADER_BYTES} bytes"),
            ));
        }
        let n = read_line_capped(r, &mut buf, remaining).map_err(|e| io_err(path, "read", e))?;
        if n == 0 {
            return Err(header_err(
                path,
                line_no,
                "the file ends before 'end_header'",
            ));
        }
        consumed += n as u64;
        line_no += 1;
        let text = String::from_utf8_lossy(trim_eol(&buf)).into_owned();
        let mut tokens = text.split_ascii_whitespace();
        let Some(keyword) = tokens.next() else {
            continue; // tolerate blank header lines
        };
        let rest: Vec<&str> = tokens.collect();
        match keyword {
            "format" => {
                if encoding.is_some() {
                    return Err(header_err(path, line_no, "a second 'format' line"));
                }
                let enc = match rest.first().copied() {
                    Some("ascii") => Some(Encoding::Ascii),
                    Some("binary_little_endian") => Some(Encoding::BinaryLittleEndian),
                    Some("binary_big_endian") => Some(Encoding::BinaryBigEndian),
                    _ => None,
                };
                let version_ok = rest.len() == 2
                    && rest[1].split_once('.').is_some_and(|(major, minor)| {
                        major == "1" && minor.bytes().all(|b| b.is_ascii_digit())
                    });
                match enc {
                    Some(e) if version_ok => encoding = Some(e),
                    _ => {
                        return Err(ModelError::UnsupportedFormat {
                            path: path.to_path_buf(),
                            line: text.trim().chars().take(120).collect(),
                        });
                    }
                }
            }
            "comment" | "obj_info" => {}
            "element" => {
                let [name, count] = rest[..] else {
                    return Err(header_err(
                        path,
                        line_no,
                        "expected 'element <name> <count>'",
                    ));
                };
                let count = count
                    .parse::<u64>()
                    .ok()
                    .and_then(|c| usize::try_from(c).ok())
                    .ok_or_else(|| {
                        header_err(path, line_no, format!("bad element count '{count}'"))
                    })?;
                if elements.iter().any(|e| e.name == name) {
                    return Err(header_err(
                        path,
                        line_no,
                        format!("element '{name}' declared twice"),
                    ));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(header_err(path, line_no, "a property before any element"));
                };
                let scalar = |s: &str| {
                    Scalar::parse(s).ok_or_else(|| {
                        header_err(path, line_no, format!("unknown property type '{s}'"))
                    })
                };
                let (kind, name) = match rest[..] {
                    ["list", count, item, name] => {
                        let count = scalar(count)?;
                        if !count.is_integer() {
                            return Err(header_err(
                                path,
                                line_no,
                                "a list count must have an integer type",
                            ));
                        }
                        (
                            Kind::List {
                                count,
                                item: scalar(item)?,
                            },
                            name,
                        )
                    }
                    [ty, name] => (Kind::Scalar(scalar(ty)?), name),
                    _ => {
                        return Err(header_err(
                            path,
                            line_no,
                            "expected 'property <type> <name>' or 'property list <type> <type> <name>'",
                        ));
                    }
                };
                if element.prop(name).is_some() {
                    return Err(header_err(
                        path,
                        line_no,
                        format!(
                            "property '{name}' declared twice in element '{}'",
                            element.name
                        ),
                    ));
                }
                element.props.push(Property {
                    name: name.to_string(),
                    kind,
                });
            }
            "end_header" => break,
            other => {
                let other: String = other.chars().take(40).collect();
                return Err(header_err(
                    path,
                    line_no,
                    format!("unknown keyword '{other}'"),
                ));
            }
        }
    }
    let Some(encoding) = encoding else {
        return Err(header_err(path, line_no, "no 'format' line"));
    };
    Ok(Header {
        encoding,
        elements,
        body_offset: consumed,
        lines: line_no,
    })
}

/// Refuses headers whose element counts the body cannot hold, before any
/// allocation sized by a count, and returns for each of the first `upto`
/// elements the number of rows it is safe to reserve. A count more than twice
/// what the body can hold is a lying or corrupted header and is refused here;
/// a smaller excess is a cut file, read until the data runs out so that the
/// error says where (`Truncated`).
pub(crate) fn check_counts(
    header: &Header,
    upto: usize,
    body_len: u64,
    path: &Path,
) -> Result<Vec<usize>, ModelError> {
    let mut budget = body_len;
    let mut reserve = Vec::with_capacity(upto);
    for e in header.elements.iter().take(upto) {
        let per = e.min_bytes(header.encoding);
        if per == 0 {
            reserve.push(0);
            continue;
        }
        // The last ASCII element may lack its final newline.
        let slack = u64::from(header.encoding == Encoding::Ascii);
        let max_possible = (budget + slack) / per;
        let count = e.count as u64;
        if count > max_possible.saturating_mul(2) {
            return Err(ModelError::CountExceedsFile {
                path: path.to_path_buf(),
                element: e.name.clone(),
                count: e.count,
                max_possible: usize::try_from(max_possible).unwrap_or(usize::MAX),
            });
        }
        let fits = count.min(max_possible);
        reserve.push(usize::try_from(fits).unwrap_or(usize::MAX));
        budget = budget.saturating_sub(per * fits);
    }
    Ok(reserve)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(text: &str) -> Result<Header, ModelError> {
        read_header(&mut text.as_bytes(), Path::new("t.ply"))
    }

    #[test]
    fn header_parses_types_lists_and_offsets() {
        let text = "ply\r\nformat binary_big_endian 1.0\r\ncomment hi\r\nelement vertex 3\r\n\
                    property float64 x\r\nproperty float y\r\nproperty float z\r\n\
                    element face 1\r\nproperty list uint8 int32 vertex_indices\r\nend_header\r\n";
        let h = header(text).expect("valid header");
        assert_eq!(h.encoding, Encoding::BinaryBigEndian);
        assert_eq!(h.body_offset as usize, text.len());
        assert_eq!(h.elements.len(), 2);
        assert_eq!(h.elements[0].props[0].kind, Kind::Scalar(Scalar::F64));
        assert!(h.has_faces());
        assert_eq!(h.elements[1].min_bytes(h.encoding), 1);
        assert_eq!(h.elements[0].min_bytes(Encoding::Ascii), 6);
    }

    #[test]
    fn header_faults_are_classified() {
        assert!(matches!(header("plx\n"), Err(ModelError::NotPly { .. })));
        assert!(matches!(header(""), Err(ModelError::NotPly { .. })));
        assert!(matches!(
            header("ply\nformat binary_middle_endian 1.0\nend_header\n"),
            Err(ModelError::UnsupportedFormat { .. })
        ));
        assert!(matches!(
            header("ply\nformat ascii 2.0\nend_header\n"),
            Err(ModelError::UnsupportedFormat { .. })
        ));
        for bad in [
            "ply\nformat ascii 1.0\nproperty float x\nend_header\n",
            "ply\nformat ascii 1.0\nelement vertex -1\nend_header\n",
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n",
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty list float int x\nend_header\n",
            "ply\nformat ascii 1.0\nelement vertex 1\nbogus\nend_header\n",
            "ply\nformat ascii 1.0\nelement vertex 1\n",
            "ply\nelement vertex 1\nend_header\n",
        ] {
            match header(bad) {
                Err(ModelError::Header { line, .. }) => assert!(line >= 2, "{bad}"),
                other => panic!("{bad:?} gave {other:?}"),
            }
        }
    }

    #[test]
    fn count_guard_uses_minimum_sizes() {
        let h = header("ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\nproperty float y\nproperty float z\nend_header\n").expect("header");
        assert_eq!(
            check_counts(&h, 1, 120, Path::new("t")).ok(),
            Some(vec![10])
        );
        // A cut file is read (and reported truncated where the data ends)...
        assert_eq!(check_counts(&h, 1, 119, Path::new("t")).ok(), Some(vec![9]));
        // ...a count far beyond the file is refused up front.
        match check_counts(&h, 1, 59, Path::new("t")) {
            Err(ModelError::CountExceedsFile { max_possible, .. }) => assert_eq!(max_possible, 4),
            other => panic!("{other:?}"),
        }
    }
}
