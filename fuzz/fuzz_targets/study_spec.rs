//! The study spec reader on any text: never a panic. A spec names its motor by preset or
//! path; paths are resolved against a directory that does not exist, so the target reads no
//! file there (an absolute path is read bounded, as a profile).
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;
use stepdamp_study::Study;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let _ = Study::from_toml_str(text, "fuzz.toml", Path::new("/nonexistent-fuzz-dir"));
});
