//! The accelerometer capture reader (`M973`/`M974` output through a host) on any bytes: never
//! a panic, finite samples from an accepted input, no control character from the input in a
//! message, and an accepted capture's reconstruction, lock-in and marker timing either
//! answer or refuse with a clean message.
#![no_main]

use libfuzzer_sys::fuzz_target;
use stepdamp_accel::capture::Reconstruction;
use stepdamp_accel::influence::harmonic_response;
use stepdamp_accel::read_captures;
use stepdamp_accel::timing::estimate_first_sample;

fuzz_target!(|data: &[u8]| {
    let clean = |s: String| assert!(!s.chars().any(char::is_control), "{s}");
    match read_captures(data, "fuzz.txt") {
        Ok(captures) => {
            let r = Reconstruction { periods_per_rev: 50, start_angle_rad: 0.0, first_sample_s: 0.0, mm_per_rev: 40.0 };
            for c in &captures {
                assert!(c.samples.iter().all(|v| v.is_finite()));
                // Bounded work: the lock-in runs on short captures only.
                if c.samples.len() <= 20_000 {
                    match harmonic_response(c, &r, 2, 5) {
                        Ok(y) => assert!(y.value.is_finite() && y.radius95.is_finite()),
                        Err(e) => clean(e.to_string()),
                    }
                    match estimate_first_sample(c, &r, 0.0, 0.05) {
                        Ok(t) => assert!(t.first_sample_s.is_finite() && (0.0..=1.0).contains(&t.score)),
                        Err(e) => clean(e.to_string()),
                    }
                }
            }
        }
        Err(e) => clean(e.to_string()),
    }
});
