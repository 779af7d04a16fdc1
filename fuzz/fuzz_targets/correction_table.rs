//! The correction-table reader of `sweep --table` ([`stepdamp_export::load_table`]: a
//! Klipper block with `driver_MSLUT0…`, or any Prusa form) on any bytes: never a panic, no
//! control character from the input in a message, and an accepted table has a positive full scale.
#![no_main]

use libfuzzer_sys::fuzz_target;
use stepdamp_export::load_table;

fuzz_target!(|data: &[u8]| {
    // The first byte picks the axis asked for.
    let Some((&sel, bytes)) = data.split_first() else { return };
    let axis = [None, Some('X'), Some('Y')][usize::from(sel % 3)];
    match load_table(bytes, "fuzz.cfg", axis) {
        Ok((table, kind)) => {
            assert!(table.full_scale > 0, "full scale {}", table.full_scale);
            assert!(!kind.chars().any(char::is_control), "{kind}");
        }
        Err(e) => assert!(!e.to_string().chars().any(char::is_control), "{e}"),
    }
});
