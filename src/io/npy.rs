//! NumPy `.npy` files (format version 1.0) for raw float images: `<f4`,
//! C order, shape `(height, width, channels)` (docs/formats.md).

use std::io::Write;
use std::path::{Path, PathBuf};

/// Errors of reading and writing `.npy` files.
#[derive(Debug, thiserror::Error)]
pub enum NpyError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The `.npy` file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a `<f4` C-order `.npy` array, or the data to write do
    /// not match the given shape.
    #[error("{path}: not a supported .npy file: {reason}")]
    Format {
        /// The `.npy` file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

fn header_for(shape: &[usize]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut dict = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
    // Magic (6) + version (2) + length (2) + dict + '\n' is a multiple of 64.
    let total = 10 + dict.len() + 1;
    dict.push_str(&" ".repeat(total.next_multiple_of(64) - total));
    dict.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out
}

/// Writes `data` (row-major, `height * width * channels` values) as an
/// `(height, width, channels)` array.
pub fn write_npy(
    path: &Path,
    data: &[f32],
    height: usize,
    width: usize,
    channels: usize,
) -> Result<(), NpyError> {
    let io = |source| NpyError::Io {
        path: path.to_owned(),
        source,
    };
    if data.len() != height * width * channels {
        return Err(NpyError::Format {
            path: path.to_owned(),
            reason: format!(
                "{} values for shape ({height}, {width}, {channels})",
                data.len()
            ),
        });
    }
    // Crash-safe, like every result file: complete or absent.
    crate::io::write_atomic(path, |f| {
        f.write_all(&header_for(&[height, width, channels]))?;
        for v in data {
            f.write_all(&v.to_le_bytes())?;
        }
        Ok(())
    })
    .map_err(io)
}

/// Reads a `<f4` C-order array; returns its shape and values.
pub fn read_npy(path: &Path) -> Result<(Vec<usize>, Vec<f32>), NpyError> {
    let bytes = std::fs::read(path).map_err(|source| NpyError::Io {
        path: path.to_owned(),
        source,
    })?;
    let bad = |reason: &str| NpyError::Format {
        path: path.to_owned(),
        reason: reason.to_owned(),
    };
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(bad("missing NUMPY magic"));
    }
    let (hlen, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        _ => return Err(bad("unknown version")),
    };
    let header = bytes
        .get(start..start + hlen)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or_else(|| bad("truncated header"))?;
    if !header.contains("'<f4'") {
        return Err(bad("dtype is not <f4"));
    }
    if header.contains("'fortran_order': True") {
        return Err(bad("Fortran order"));
    }
    let open = header.find("'shape': (").ok_or_else(|| bad("no shape"))? + 10;
    let close = header[open..].find(')').ok_or_else(|| bad("bad shape"))? + open;
    let shape: Vec<usize> = header[open..close]
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().map_err(|_| bad("bad shape")))
        .collect::<Result<_, _>>()?;
    let n: usize = shape.iter().product();
    let body = &bytes[start + hlen..];
    if body.len() != n * 4 {
        return Err(bad("body size does not match the shape"));
    }
    let data = body
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok((shape, data))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roundtrip_keeps_shape_values_and_nan() {
        let mut rng = crate::rng::Rng::new(3);
        let (h, w, c) = (7, 5, 12);
        let mut data: Vec<f32> = (0..h * w * c).map(|_| rng.normal() as f32).collect();
        data[4] = f32::NAN;
        let path = std::env::temp_dir().join(format!("splattrack-npy-{}.npy", std::process::id()));
        write_npy(&path, &data, h, w, c).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(
            (10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize) % 64,
            0
        );
        let (shape, back) = read_npy(&path).unwrap();
        assert_eq!(shape, vec![h, w, c]);
        assert!(back[4].is_nan());
        assert!(
            data.iter()
                .zip(&back)
                .enumerate()
                .all(|(i, (a, b))| i == 4 || a == b)
        );
        assert!(write_npy(&path, &data[1..], h, w, c).is_err());
        std::fs::remove_file(path).unwrap();
    }
}
