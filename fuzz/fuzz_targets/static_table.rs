//! The static-table reader and analysis on any bytes: never a panic, finite harmonics
//! from an accepted table, no control character from the input in a message.
#![no_main]

use libfuzzer_sys::fuzz_target;
use stepdamp_identify::static_curve::{TorqueSign, analyse, parse_table};

fuzz_target!(|data: &[u8]| {
    // The first byte picks the pole pairs and sign, the rest is the table.
    let Some((&sel, table)) = data.split_first() else { return };
    let pole_pairs = u16::from(sel % 64) + 1;
    let sign = if sel & 0x80 == 0 { TorqueSign::OnRotor } else { TorqueSign::Holding };
    match parse_table(table, "fuzz.csv") {
        Ok(points) => match analyse(&points, pole_pairs, sign, 8, "fuzz.csv") {
            Ok(c) => {
                assert!(c.mean_nm.is_finite() && c.rest_rms_nm.is_finite());
                assert!(c.harmonics.iter().all(|h| h.amplitude_nm.is_finite() && h.phase_rad.is_finite()));
            }
            Err(e) => assert!(!e.to_string().chars().any(char::is_control)),
        },
        Err(e) => assert!(!e.to_string().chars().any(char::is_control), "{e}"),
    }
});
