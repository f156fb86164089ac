//! The PLY codec (Turk 1994; the format as documented by Paul Bourke, "PLY -
//! Polygon File Format"): headers, elements and properties, streamed body
//! values, and binary writing. What the elements mean (points, normals,
//! colours, radii, faces) is the `schema` module's business.
//!
//! How it works: the header is read line by line with a cap on its size (so a
//! garbage file cannot make us buffer gigabytes looking for a newline), then
//! every element count is checked against the bytes the body can possibly
//! hold *before* anything is allocated (at least one byte per binary value of
//! a fixed-size property, two per ASCII token): a count more than twice that
//! is refused as a lying header, and no array is ever reserved beyond what
//! the file can fill. The body is then streamed row by row ([`read_rows`]):
//! each value goes straight to the slot its reader assigned to the property,
//! so a million points cost one pass and no per-point allocation.
//!
//! Why not ply-rs-bw (4.0): its ASCII grammar rejects `nan` and `inf` (which
//! we must read, count and drop), its per-element property callbacks are
//! keyed by strings, its errors span several lines, and its header parser
//! silently merges two elements of the same name. (It does cap its own
//! pre-allocation at 65,536 elements, so it is not the gigabyte risk it could
//! be.) So this module reads PLY itself, and the tests use ply-rs-bw as an
//! independent check of the writer.

use super::Stage;
use super::error::ModelError;
use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

/// The header may not be longer than this: real headers are a few hundred bytes.
const MAX_HEADER_BYTES: u64 = 1 << 20;
/// Longest body line accepted in ASCII files (a face with ~100k indices).
const MAX_LINE_BYTES: u64 = 1 << 20;
/// Progress is reported every this many elements.
pub(crate) const PROGRESS_STEP: usize = 1 << 14;

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

    fn size(self) -> usize {
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

/// Why reading a value failed, before the element context is added.
pub(crate) enum Fault {
    Eof,
    Parse { line: usize, reason: String },
    Io(std::io::Error),
}

/// A stream of PLY body values, ASCII or binary.
pub(crate) trait Values {
    /// Starts the next element; ASCII reads its line.
    fn begin(&mut self) -> Result<(), Fault>;
    fn scalar(&mut self, t: Scalar) -> Result<f64, Fault>;
    /// Reads a list length and checks that the file can hold that many items.
    fn list_len(&mut self, count: Scalar, item: Scalar) -> Result<usize, Fault>;
    /// Ends the element; ASCII refuses leftover values.
    fn end(&mut self) -> Result<(), Fault>;
}

struct Binary<R> {
    reader: R,
    remaining: u64,
    big_endian: bool,
}

impl<R: Read> Binary<R> {
    fn bytes<const N: usize>(&mut self) -> Result<[u8; N], Fault> {
        let mut b = [0u8; N];
        if self.remaining < N as u64 {
            return Err(Fault::Eof);
        }
        self.reader.read_exact(&mut b).map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                Fault::Eof
            } else {
                Fault::Io(e)
            }
        })?;
        self.remaining -= N as u64;
        if self.big_endian {
            b.reverse();
        }
        Ok(b)
    }
}

impl<R: Read> Values for Binary<R> {
    fn begin(&mut self) -> Result<(), Fault> {
        Ok(())
    }

    #[inline]
    fn scalar(&mut self, t: Scalar) -> Result<f64, Fault> {
        // Bytes are put in little-endian order by `bytes`.
        Ok(match t {
            Scalar::I8 => f64::from(i8::from_le_bytes(self.bytes::<1>()?)),
            Scalar::U8 => f64::from(self.bytes::<1>()?[0]),
            Scalar::I16 => f64::from(i16::from_le_bytes(self.bytes::<2>()?)),
            Scalar::U16 => f64::from(u16::from_le_bytes(self.bytes::<2>()?)),
            Scalar::I32 => f64::from(i32::from_le_bytes(self.bytes::<4>()?)),
            Scalar::U32 => f64::from(u32::from_le_bytes(self.bytes::<4>()?)),
            Scalar::F32 => f64::from(f32::from_le_bytes(self.bytes::<4>()?)),
            Scalar::F64 => f64::from_le_bytes(self.bytes::<8>()?),
        })
    }

    fn list_len(&mut self, count: Scalar, item: Scalar) -> Result<usize, Fault> {
        let n = self.scalar(count)?;
        if n < 0.0 {
            return Err(Fault::Parse {
                line: 0,
                reason: format!("negative list length {n}"),
            });
        }
        // Integers up to 2^32 are exact in f64.
        let n = n as u64;
        if n.saturating_mul(item.size() as u64) > self.remaining {
            return Err(Fault::Eof);
        }
        Ok(n as usize)
    }

    fn end(&mut self) -> Result<(), Fault> {
        Ok(())
    }
}

struct Ascii<R> {
    reader: R,
    line: Vec<u8>,
    pos: usize,
    line_no: usize,
}

impl<R: BufRead> Ascii<R> {
    fn token(&mut self) -> Option<&str> {
        let bytes = &self.line;
        let mut i = self.pos;
        while i < bytes.len() && bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        let start = i;
        while i < bytes.len() && !bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        self.pos = i;
        if start == i {
            None
        } else {
            std::str::from_utf8(&bytes[start..i])
                .ok()
                .or(Some("\u{fffd}"))
        }
    }

    fn remaining_tokens(&self) -> usize {
        self.line[self.pos..]
            .split(|b| b.is_ascii_whitespace())
            .filter(|t| !t.is_empty())
            .count()
    }

    fn parse_err(&self, reason: String) -> Fault {
        Fault::Parse {
            line: self.line_no,
            reason,
        }
    }
}

impl<R: BufRead> Values for Ascii<R> {
    fn begin(&mut self) -> Result<(), Fault> {
        loop {
            let n = read_line_capped(&mut self.reader, &mut self.line, MAX_LINE_BYTES)
                .map_err(Fault::Io)?;
            if n == 0 {
                return Err(Fault::Eof);
            }
            self.line_no += 1;
            if n as u64 == MAX_LINE_BYTES && !self.line.ends_with(b"\n") {
                return Err(self.parse_err(format!("line longer than {MAX_LINE_BYTES} bytes")));
            }
            self.pos = 0;
            // Blank lines carry no element; skipping them costs nothing.
            if self.line.iter().any(|b| !b.is_ascii_whitespace()) {
                return Ok(());
            }
        }
    }

    fn scalar(&mut self, _t: Scalar) -> Result<f64, Fault> {
        let line_no = self.line_no;
        // A short last line without its newline is where the file was cut.
        let cut = !self.line.ends_with(b"\n");
        let Some(tok) = self.token() else {
            if cut {
                return Err(Fault::Eof);
            }
            return Err(Fault::Parse {
                line: line_no,
                reason: "too few values on the line".into(),
            });
        };
        // f64 parsing accepts integers, exponents, "nan" and "inf" alike.
        tok.parse::<f64>().map_err(|_| {
            let shown: String = tok.chars().take(32).collect();
            Fault::Parse {
                line: line_no,
                reason: format!("'{shown}' is not a number"),
            }
        })
    }

    fn list_len(&mut self, count: Scalar, _item: Scalar) -> Result<usize, Fault> {
        let n = self.scalar(count)?;
        let left = self.remaining_tokens();
        if !(n >= 0.0 && n.fract() == 0.0 && n <= left as f64) {
            return Err(self.parse_err(format!(
                "list length {n} but {left} values follow on the line"
            )));
        }
        Ok(n as usize)
    }

    fn end(&mut self) -> Result<(), Fault> {
        let left = self.remaining_tokens();
        if left > 0 {
            return Err(self.parse_err(format!("{left} more values than the header declares")));
        }
        Ok(())
    }
}

/// Where a property's value goes: into the row's values at an index, into
/// the row's list, or nowhere.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Slot {
    Value(usize),
    List,
    Skip,
}

/// Streams the `count` rows of `element`, one slot per property, calling
/// `row(index, values, list)` for each and advancing `progress` every
/// [`PROGRESS_STEP`] rows.
pub(crate) fn read_rows<V: Values, const N: usize>(
    src: &mut V,
    element: &Element,
    slots: &[Slot],
    path: &Path,
    progress: &Stage,
    mut row: impl FnMut(usize, &[f64; N], &[f64]) -> Result<(), ModelError>,
) -> Result<(), ModelError> {
    let mut values = [0.0f64; N];
    let mut list: Vec<f64> = Vec::new();
    let fault = |f: Fault, i: usize| match f {
        Fault::Eof => ModelError::Truncated {
            path: path.to_path_buf(),
            element: element.name.clone(),
            read: i,
            count: element.count,
        },
        Fault::Parse { line: 0, reason } => ModelError::Invalid {
            path: path.to_path_buf(),
            reason: format!("'{}' element {i}: {reason}", element.name),
        },
        Fault::Parse { line, reason } => ModelError::Parse {
            path: path.to_path_buf(),
            line,
            reason,
        },
        Fault::Io(e) => io_err(path, "read", e),
    };
    if element.props.is_empty() {
        return Ok(()); // nothing to read, however large the count
    }
    for i in 0..element.count {
        src.begin().map_err(|f| fault(f, i))?;
        for (prop, &slot) in element.props.iter().zip(slots) {
            match prop.kind {
                Kind::Scalar(t) => {
                    let v = src.scalar(t).map_err(|f| fault(f, i))?;
                    if let Slot::Value(s) = slot {
                        values[s] = v;
                    }
                }
                Kind::List { count, item } => {
                    let n = src.list_len(count, item).map_err(|f| fault(f, i))?;
                    if slot == Slot::List {
                        list.clear();
                        for _ in 0..n {
                            list.push(src.scalar(item).map_err(|f| fault(f, i))?);
                        }
                    } else {
                        for _ in 0..n {
                            src.scalar(item).map_err(|f| fault(f, i))?;
                        }
                    }
                }
            }
        }
        src.end().map_err(|f| fault(f, i))?;
        row(i, &values, &list)?;
        if i % PROGRESS_STEP == PROGRESS_STEP - 1 {
            progress.advance(PROGRESS_STEP as u64);
        }
    }
    Ok(())
}

/// A reader of one PLY schema: given the header and the body's value stream
/// (whatever its encoding), it reads the elements it needs.
pub(crate) trait BodyReader {
    type Output;
    fn read<V: Values>(
        self,
        src: &mut V,
        header: &Header,
        body_len: u64,
    ) -> Result<Self::Output, ModelError>;
}

/// Opens `path`, reads its header and hands the body, decoded as the header
/// says, to `reader`.
pub(crate) fn read<B: BodyReader>(path: &Path, reader: B) -> Result<B::Output, ModelError> {
    let (header, file, file_len) = open(path)?;
    let body_len = file_len.saturating_sub(header.body_offset);
    match header.encoding {
        Encoding::Ascii => {
            let mut src = Ascii {
                reader: file,
                line: Vec::with_capacity(256),
                pos: 0,
                line_no: header.lines,
            };
            reader.read(&mut src, &header, body_len)
        }
        enc => {
            let mut src = Binary {
                reader: file,
                remaining: body_len,
                big_endian: enc == Encoding::BinaryBigEndian,
            };
            reader.read(&mut src, &header, body_len)
        }
    }
}

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
