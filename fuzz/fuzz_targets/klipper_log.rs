//! Klipper's motion-analysis log reader on any message stream: the fuzz bytes are the
//! decompressed `.json.gz` content (JSON messages, each ended by `0x03`), gzipped here so the
//! record and JSON rules are what is fuzzed, not the inflater. Never a panic, finite values
//! and steady stretches from an accepted log, no control character from the input in a
//! message.
#![no_main]

use flate2::Compression;
use flate2::write::GzEncoder;
use libfuzzer_sys::fuzz_target;
use std::io::Write;
use stepdamp_accel::Axis;
use stepdamp_accel::klipper::{KlipperOptions, read_log};

fuzz_target!(|data: &[u8]| {
    let mut gz = GzEncoder::new(Vec::new(), Compression::fast());
    gz.write_all(data).unwrap();
    let bytes = gz.finish().unwrap();
    let clean = |s: String| assert!(!s.chars().any(char::is_control), "{s}");
    for axis in [Axis::X, Axis::Y] {
        let o = KlipperOptions { axis, accelerometer: None, trial: None };
        match read_log(bytes.as_slice(), "fuzz.json.gz", &o) {
            Ok(log) => {
                for s in log.segments() {
                    let (a, b) = s.span_s();
                    assert!(a.is_finite() && b.is_finite() && a <= b);
                }
            }
            Err(e) => clean(e.to_string()),
        }
    }
});
