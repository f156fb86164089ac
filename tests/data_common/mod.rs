//! The real data (the ViSP cube and dragon sequences, docs/testing.md): the
//! folder named by `SPLATTRACK_DATA` (CI sets it). Unset, a test that needs
//! it says in one line that it did not run and passes; set, a missing file
//! fails the test.
#![allow(dead_code)]

use std::io::Write;
use std::path::PathBuf;

/// How to get the data, for the line a test prints when it does not run.
pub const HOW: &str =
    "set SPLATTRACK_DATA to the real data folder; scripts/get_real_data.sh makes one";

/// `rel` under the real data folder, or `None` (said on the terminal) when
/// `SPLATTRACK_DATA` is unset.
pub fn real_data(rel: &str) -> Option<PathBuf> {
    let Some(root) = std::env::var_os("SPLATTRACK_DATA") else {
        // Straight to the terminal: the test harness captures eprintln!.
        let test = match std::thread::current().name() {
            Some(name) if !name.is_empty() && name != "main" => name.to_owned(),
            _ => "a test".to_owned(),
        };
        let _ = writeln!(
            std::io::stderr(),
            "{test}: not run, it needs the real data ({HOW})"
        );
        return None;
    };
    let path = PathBuf::from(root).join(rel);
    assert!(
        path.exists(),
        "{} not found: SPLATTRACK_DATA names the real data folder ({HOW})",
        path.display()
    );
    Some(path)
}
