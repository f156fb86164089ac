#![no_main]
//! Fuzz target: arbitrary bytes into the STL reader
//! (splattrack::io::fuzz_entry). Run: `cargo fuzz run stl`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    splattrack::io::fuzz_entry::run("stl", data);
});
