//! The Prusa reader (M971 read-back, 6.2 M972 print, M973 lines, 168-byte files) on any
//! bytes: never a panic, finite items from an accepted input, no control character from the
//! input in a message, and an accepted correction replays to a table (or is refused when the
//! firmware's 32-bit arithmetic would overflow).
#![no_main]

use libfuzzer_sys::fuzz_target;
use stepdamp_export::prusa::{Firmware, parse_bytes};

fuzz_target!(|data: &[u8]| {
    // The first byte picks the axis asked for and the firmware scale of a binary file.
    let Some((&sel, text)) = data.split_first() else { return };
    let axis = [None, Some('X'), Some('Y')][usize::from(sel % 3)];
    let fw = if sel & 0x80 == 0 { Firmware::V6_3_1 } else { Firmware::V6_2 };
    match parse_bytes(text, axis, "fuzz.txt", fw) {
        Ok((c, kind)) => {
            assert!(!kind.chars().any(char::is_control));
            for s in [&c.forward, &c.backward] {
                assert!(s.mag.iter().chain(&s.pha).all(|v| v.is_finite()));
            }
            // Replayable or refused with a clean message; the table never panics either way.
            if let Err(e) = c.check_replay("fuzz.txt") {
                assert!(!e.to_string().chars().any(char::is_control), "{e}");
            }
            let _ = c.table();
        }
        Err(e) => assert!(!e.to_string().chars().any(char::is_control), "{e}"),
    }
});
