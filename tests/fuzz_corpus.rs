//! Replays every committed fuzz input (fuzz/corpus/TARGET: the minimised
//! corpora; fuzz/regressions/TARGET: inputs that once crashed a reader)
//! through the same entry points the `cargo fuzz` targets call
//! (`splattrack::io::fuzz_entry`). Each must return, accepted or refused,
//! never panic: CI's stand-in for the fuzzing itself.

use splattrack::io::fuzz_entry::{TARGETS, run};
use std::path::Path;

fn inputs(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    v.retain(|p| p.is_file());
    v.sort();
    v
}

#[test]
fn every_corpus_and_crash_input_is_refused_or_accepted_without_panic() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    for target in TARGETS {
        let corpus = inputs(&root.join("corpus").join(target));
        // Every target has a corpus, and its seeds include valid files the
        // reader accepts (so the replay exercises the whole reader).
        assert!(!corpus.is_empty(), "fuzz/corpus/{target} is empty");
        let mut accepted = 0;
        for p in corpus
            .iter()
            .chain(&inputs(&root.join("regressions").join(target)))
        {
            let data = std::fs::read(p).unwrap();
            let r = std::panic::catch_unwind(|| run(target, &data));
            match r {
                Ok(true) => accepted += 1,
                Ok(false) => {}
                Err(_) => panic!("{target}: {} panics the reader", p.display()),
            }
        }
        assert!(accepted > 0, "{target}: no corpus input is accepted");
    }
}
