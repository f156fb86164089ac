//! Outputs never overwrite inputs: [`check_output`] and
//! [`check_output_dir`] refuse, before anything is written, an output file
//! that is one of a command's inputs and an output directory that holds
//! them (overlays written into the frames folder would replace the frames).

use std::path::{Path, PathBuf};

/// An output would overwrite an input.
#[derive(Debug, thiserror::Error)]
#[error("{}: the {what} would overwrite the input {}; choose another path", output.display(), input.display())]
pub struct ClobberError {
    /// The output path.
    pub output: PathBuf,
    /// What the output is ("--out", "overlays").
    pub what: String,
    /// The input it would overwrite (or the directory holding inputs).
    pub input: PathBuf,
}

/// `p` made absolute and free of `..` and links as far as it exists: the
/// existing part canonicalised, the rest appended.
pub fn resolve(p: &Path) -> PathBuf {
    if let Ok(c) = p.canonicalize() {
        return c;
    }
    match (p.parent(), p.file_name()) {
        (Some(parent), Some(name)) => {
            let parent = if parent.as_os_str().is_empty() {
                Path::new(".")
            } else {
                parent
            };
            resolve(parent).join(name)
        }
        _ => std::env::current_dir()
            .map(|d| d.join(p))
            .unwrap_or_else(|_| p.to_owned()),
    }
}

/// True when `a` and `b` name the same file (or would).
pub fn same_path(a: &Path, b: &Path) -> bool {
    resolve(a) == resolve(b)
}

/// Refuses the output file `output` when it is one of `inputs`.
pub fn check_output(output: &Path, what: &str, inputs: &[&Path]) -> Result<(), ClobberError> {
    let out = resolve(output);
    for input in inputs {
        if resolve(input) == out {
            return Err(ClobberError {
                output: output.to_owned(),
                what: what.to_owned(),
                input: input.to_path_buf(),
            });
        }
    }
    Ok(())
}

/// Refuses the output directory `dir` when it is `protected` directory
/// (a folder of input frames or keyframe images) or the folder of one of
/// `inputs`.
pub fn check_output_dir(
    dir: &Path,
    what: &str,
    protected: &[&Path],
    inputs: &[&Path],
) -> Result<(), ClobberError> {
    let d = resolve(dir);
    let parents: Vec<&Path> = inputs.iter().filter_map(|p| p.parent()).collect();
    for input in protected.iter().chain(&parents) {
        if resolve(input) == d {
            return Err(ClobberError {
                output: dir.to_owned(),
                what: what.to_owned(),
                input: input.to_path_buf(),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_that_are_inputs_are_refused() {
        let d = std::env::temp_dir().join(format!("splattrack-guard-{}", std::process::id()));
        std::fs::create_dir_all(d.join("frames")).unwrap();
        std::fs::write(d.join("init.csv"), "x").unwrap();
        let init = d.join("init.csv");
        // The same file by another spelling.
        let other = d.join("frames/../init.csv");
        let e = check_output(&other, "--out", &[&init])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("would overwrite the input") && e.contains("init.csv"),
            "{e}"
        );
        assert!(check_output(&d.join("out.csv"), "--out", &[&init]).is_ok());
        // Not yet existing outputs resolve too.
        assert!(same_path(&d.join("frames/../new.csv"), &d.join("new.csv")));
        let frames = d.join("frames");
        let e = check_output_dir(&d.join("frames/"), "--overlay", &[&frames], &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("frames"), "{e}");
        assert!(check_output_dir(&d, "--overlay", &[&frames], &[&init]).is_err());
        assert!(check_output_dir(&d.join("ov"), "--overlay", &[&frames], &[&init]).is_ok());
        std::fs::remove_dir_all(&d).unwrap();
    }
}
