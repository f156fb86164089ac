#![no_main]
//! Fuzz target: arbitrary bytes into the keyframe_store reader
//! (splattrack::io::fuzz_entry). Run: `cargo fuzz run keyframe_store`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    splattrack::io::fuzz_entry::run("keyframe_store", data);
});
