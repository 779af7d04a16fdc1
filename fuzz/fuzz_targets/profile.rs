//! The profile parser on any text: never a panic; a profile it accepts is written back
//! as TOML that it accepts again, unchanged.
#![no_main]

use libfuzzer_sys::fuzz_target;
use stepdamp_sim::Profile;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(p) = Profile::from_toml_str(text, "fuzz.toml") {
        let again = Profile::from_toml_str(&p.to_toml_string(), "again.toml").expect("a valid profile round-trips");
        assert_eq!(again.to_toml_string(), p.to_toml_string());
    }
});
