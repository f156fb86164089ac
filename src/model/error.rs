//! The one error type of the model module. Every variant names the file (or
//! `<memory>` for in-memory input) and the fault, on one line, so that the CLI
//! can print it as is.

use std::path::{Path, PathBuf};

/// Why a model or mesh could not be loaded, built or saved.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The file could not be opened, read or written.
    #[error("{}: cannot {action}: {source}", path.display())]
    Io {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// What was being done (`open`, `read`, `create`, `write`...).
        action: &'static str,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },

    /// The file does not start with the PLY magic line `ply`.
    #[error("{}: not a PLY file (the first line is not 'ply')", path.display())]
    NotPly {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
    },

    /// The `format` line names an encoding or version this reader does not know.
    #[error(
        "{}: unsupported PLY format line '{line}' (expected 'format ascii|binary_little_endian|binary_big_endian 1.0')",
        path.display()
    )]
    UnsupportedFormat {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// The `format` line as found.
        line: String,
    },

    /// Any other fault in the PLY header.
    #[error("{}: PLY header line {line}: {reason}", path.display())]
    Header {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// The 1-based line number in the file.
        line: usize,
        /// What is wrong with the line.
        reason: String,
    },

    /// A required element (`vertex`, or `face` for meshes) is missing.
    #[error("{}: no '{element}' element in the PLY header", path.display())]
    MissingElement {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// The missing element's name.
        element: &'static str,
    },

    /// A required property (x, y, z; a face's vertex list) is missing or has the wrong kind.
    #[error("{}: element '{element}' {reason}", path.display())]
    MissingProperty {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// The element lacking the property.
        element: String,
        /// Which property is missing or wrong.
        reason: String,
    },

    /// The header declares more elements than the file's size can possibly hold:
    /// refused before anything is allocated.
    #[error(
        "{}: header declares {count} '{element}' elements, but the file is too small to hold more than {max_possible}",
        path.display()
    )]
    CountExceedsFile {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// The element whose count is too large.
        element: String,
        /// The count the header declares.
        count: usize,
        /// The most elements the file's remaining bytes could hold.
        max_possible: usize,
    },

    /// The body ends before every declared element was read.
    #[error(
        "{}: truncated: the file ends after {read} of {count} '{element}' elements",
        path.display()
    )]
    Truncated {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// The element being read when the file ended.
        element: String,
        /// How many of its rows were read completely.
        read: usize,
        /// How many rows the header declares.
        count: usize,
    },

    /// A value in the body (or a line of an OBJ file) could not be parsed.
    #[error("{}: line {line}: {reason}", path.display())]
    Parse {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// The 1-based line number in the file.
        line: usize,
        /// What could not be parsed.
        reason: String,
    },

    /// Structurally valid data that makes no sense (a face index out of range,
    /// a list longer than the file, an unsupported property type...).
    #[error("{}: {reason}", path.display())]
    Invalid {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// What makes no sense.
        reason: String,
    },

    /// The file holds no points (or a mesh no triangle of positive area).
    #[error("{}: no points: {reason}", path.display())]
    Empty {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// What is empty.
        reason: String,
    },

    /// Every point had a NaN or infinite coordinate.
    #[error(
        "{}: all {dropped} points have NaN or infinite coordinates",
        path.display()
    )]
    AllNonFinite {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// The number of points (all dropped).
        dropped: usize,
    },

    /// A loaded radius is negative, zero, NaN or infinite.
    #[error(
        "{}: point {index} has radius {value} (radii must be finite and > 0)",
        path.display()
    )]
    BadRadius {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// The 0-based index of the point in the file.
        index: usize,
        /// The offending radius, in model units.
        value: f32,
    },

    /// Normals or radii must be estimated but the points do not allow it
    /// (too few, all coincident, coordinates too large for the k-d tree).
    #[error("{}: cannot estimate {what}: {reason}", path.display())]
    Estimation {
        /// The file (`<memory>` for in-memory input).
        path: PathBuf,
        /// What was to be estimated (`normals`, `radii`).
        what: &'static str,
        /// Why it cannot be.
        reason: String,
    },
}

impl ModelError {
    /// The file the error is about (`<memory>` for in-memory input).
    pub fn path(&self) -> &Path {
        match self {
            Self::Io { path, .. }
            | Self::NotPly { path }
            | Self::UnsupportedFormat { path, .. }
            | Self::Header { path, .. }
            | Self::MissingElement { path, .. }
            | Self::MissingProperty { path, .. }
            | Self::CountExceedsFile { path, .. }
            | Self::Truncated { path, .. }
            | Self::Parse { path, .. }
            | Self::Invalid { path, .. }
            | Self::Empty { path, .. }
            | Self::AllNonFinite { path, .. }
            | Self::BadRadius { path, .. }
            | Self::Estimation { path, .. } => path,
        }
    }
}

/// The pseudo-path used in errors about in-memory data.
pub(crate) fn memory_path() -> PathBuf {
    PathBuf::from("<memory>")
}
