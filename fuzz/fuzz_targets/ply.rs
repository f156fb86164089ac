#![no_main]
//! Fuzz target: arbitrary bytes into the ply reader
//! (splattrack::io::fuzz_entry). Run: `cargo fuzz run ply`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    splattrack::io::fuzz_entry::run("ply", data);
});
