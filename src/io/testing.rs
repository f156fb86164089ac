//! What the unit tests of the readers share.

/// The real data for the unit tests: `rel` in the folder `SPLATTRACK_DATA`
/// names, or `None` (said on the terminal, which the harness does not
/// capture) when it is unset; a missing file fails the test.
pub(crate) fn test_data(rel: &str) -> Option<std::path::PathBuf> {
    use std::io::Write;
    let Some(root) = std::env::var_os("SPLATTRACK_DATA") else {
        let test = match std::thread::current().name() {
            Some(name) if !name.is_empty() && name != "main" => name.to_owned(),
            _ => "a test".to_owned(),
        };
        let _ = writeln!(
            std::io::stderr(),
            "{test}: not run, it needs the real data (set SPLATTRACK_DATA to the real data folder; scripts/get_real_data.sh makes one)"
        );
        return None;
    };
    let path = std::path::PathBuf::from(root).join(rel);
    assert!(
        path.exists(),
        "{} not found (SPLATTRACK_DATA)",
        path.display()
    );
    Some(path)
}
