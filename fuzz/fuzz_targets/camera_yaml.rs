#![no_main]
//! Fuzz target: arbitrary bytes into the camera_yaml reader
//! (splattrack::io::fuzz_entry). Run: `cargo fuzz run camera_yaml`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    splattrack::io::fuzz_entry::run("camera_yaml", data);
});
