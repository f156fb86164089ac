#![no_main]
//! Fuzz target: arbitrary bytes into the poses_csv reader
//! (splattrack::io::fuzz_entry). Run: `cargo fuzz run poses_csv`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    splattrack::io::fuzz_entry::run("poses_csv", data);
});
