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

mod body;
mod header;
mod write;

pub(crate) use body::{BodyReader, Slot, Values, read, read_rows};
pub(crate) use header::{
    Element, Header, Kind, Property, Scalar, check_counts, open, read_line_capped,
};
pub(crate) use write::write;
