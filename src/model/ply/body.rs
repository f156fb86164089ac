//! The PLY body: values streamed row by row from ASCII or binary, each to
//! the slot its reader assigned to the property.

use super::header::{
    Element, Encoding, Header, Kind, MAX_LINE_BYTES, Scalar, io_err, open, read_line_capped,
};
use crate::model::error::ModelError;
use crate::model::stage::Stage;
use std::io::{BufRead, Read};
use std::path::Path;

/// Progress is reported every this many elements.
pub(crate) const PROGRESS_STEP: usize = 1 << 14;

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
