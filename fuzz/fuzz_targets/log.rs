//! The run-log reader on any bytes: never a panic, an accepted log is consistent (equal
//! column lengths, finite values, increasing time), and an error message never carries a
//! control character from the input. The same bytes as a sensorless log: never a panic,
//! and the angle estimate of an accepted one never panics either (any finite values).
#![no_main]

use libfuzzer_sys::fuzz_target;
use stepdamp_identify::log::{LogOptions, parse_log};
use stepdamp_identify::sensorless::flux::{FluxOptions, Winding};
use stepdamp_identify::sensorless::{estimate, log::parse_sensorless_log};

fuzz_target!(|data: &[u8]| {
    let mut opts = LogOptions::new(50);
    opts.min_electrical_periods = 0.0;
    match parse_log(data, "fuzz.csv", &opts) {
        Ok(log) => {
            assert!(!log.is_empty());
            assert_eq!(log.t_s.len(), log.theta_fb_rad.len());
            assert_eq!(log.t_s.len(), log.i_q_a.len());
            assert!(log.t_s.windows(2).all(|w| w[1] > w[0]));
            assert!(log.theta_fb_rad.iter().chain(&log.i_q_a).all(|v| v.is_finite()));
            assert!(log.ignored_columns.iter().all(|c| !c.chars().any(char::is_control)));
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(!msg.chars().any(|c| c.is_control() && c != '\n'), "{msg:?}");
        }
    }
    match parse_sensorless_log(data, "fuzz.csv") {
        Ok(log) => {
            let w = Winding { pole_pairs: 50, resistance_ohm: 0.9, inductance_h: 2.5e-3, shape: None };
            if let Ok(e) = estimate(std::slice::from_ref(&log), &w, &FluxOptions::default()) {
                assert_eq!(e.logs[0].t_s.len(), log.t_s.len());
                assert_eq!(e.logs[0].theta_fb_rad.len(), log.t_s.len());
            }
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(!msg.chars().any(|c| c.is_control() && c != '\n'), "{msg:?}");
        }
    }
});
