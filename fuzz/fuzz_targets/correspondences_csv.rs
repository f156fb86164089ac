#![no_main]
//! Fuzz target: arbitrary bytes into the correspondences_csv readers
//! (splattrack::io::fuzz_entry). Run: `cargo fuzz run correspondences_csv`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    splattrack::io::fuzz_entry::run("correspondences_csv", data);
});
