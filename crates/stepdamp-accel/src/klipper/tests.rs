//! The reader on hand-written logs: what it reads, and how it refuses what the logger does
//! not write.

use super::*;
use flate2::Compression;
use flate2::write::GzEncoder;
use std::f64::consts::TAU;
use std::io::Write;

/// `messages`, each followed by 0x03, in one gzip stream, as data_logger.py writes them.
fn gz(messages: &[String]) -> Vec<u8> {
    let mut e = GzEncoder::new(Vec::new(), Compression::default());
    for m in messages {
        e.write_all(m.as_bytes()).unwrap();
        e.write_all(&[0x03]).unwrap();
    }
    e.finish().unwrap()
}

/// The `objects/subscribe` answer of a printer with `kinematics`, 16 microsteps and a
/// TMC2209 on `stepper_x` at phase offset 5.
fn config(kinematics: &str) -> String {
    format!(
        r#"{{"id":"status","result":{{"eventtime":1.0,"status":{{"configfile":{{"settings":{{"printer":{{"kinematics":"{kinematics}"}},"stepper_x":{{"microsteps":16,"full_steps_per_rotation":200,"rotation_distance":40}},"stepper_y":{{"microsteps":16}},"tmc2209 stepper_x":{{"run_current":0.6}}}}}},"tmc2209 stepper_x":{{"mcu_phase_offset":5,"run_current":0.6}}}}}}}}"#
    )
}

/// 1000 steps up at 10 kHz from MCU position 100, clock 1 MHz, from print time 10 s.
fn steps() -> String {
    r#"{"q":"stepq:stepper_x","params":{"data":[[100,1000,0]],"start_position":0.0,"start_mcu_position":100,"step_distance":0.0125,"first_clock":10000000,"first_step_time":10.0,"last_clock":10099900,"last_step_time":10.0999}}"#.into()
}

/// Samples at 3200 Hz from 10.02 s with x = 1000·k, y = 7 mm/s².
fn accel(n: usize) -> String {
    let rows: Vec<String> =
        (0..n).map(|k| format!("[{},{},7.0,9806.65]", 10.02 + k as f64 / 3200.0, 1000.0 * k as f64)).collect();
    format!(r#"{{"q":"accelerometer:adxl345","params":{{"data":[{}],"errors":0,"overflows":0}}}}"#, rows.join(","))
}

fn opts() -> KlipperOptions {
    KlipperOptions { axis: Axis::X, accelerometer: None, trial: None }
}

fn read(messages: &[String]) -> Result<Log, KlipperError> {
    read_log(gz(messages).as_slice(), "t.json.gz", &opts())
}

#[test]
fn each_sample_gets_its_time_its_projection_and_the_commanded_electrical_angle() {
    let log = read(&[config("cartesian"), steps(), accel(100)]).unwrap();
    assert_eq!((log.microsteps, log.full_steps_per_rotation, log.mcu_phase_offset), (16, 200, Some(5)));
    assert_eq!(log.times_s.len(), 100);
    assert_eq!(log.accel_m_s2[3], 3.0, "x in mm/s², read in m/s²");
    for (k, c) in log.commanded.iter().enumerate() {
        // Step j (to 100 + j + 1) at 10 + j·1e-4 s: the position passes 100.5 + j then.
        let p = 100.5 + (c.t_s - 10.0) / 1e-4;
        let want = TAU * (p + 5.0) / 64.0;
        assert!((c.electrical_rad - want).abs() < 1e-6, "{k}: {} vs {want}", c.electrical_rad);
        assert!((c.speed_rev_s - 1e4 / 3200.0).abs() < 1e-6 && c.accel_rev_s2.abs() < 1e-3, "{c:?}");
    }
}

#[test]
fn corexy_projects_the_belt_of_a_on_x_plus_y_and_of_b_on_x_minus_y() {
    let log = read(&[config("corexy"), steps(), accel(4)]).unwrap();
    assert_eq!(log.accel_m_s2[2], (2000.0 + 7.0) * 1e-3);
    assert_eq!(Kinematics::CoreXy.projection(Axis::Y), (1.0, -1.0));
}

#[test]
fn count_and_add_expand_into_steps_as_readlog_does() {
    let mut s = motion::Steps::default();
    let p: serde_json::Value = serde_json::from_str(
        r#"{"data":[[100,3,10],[500,-2,0]],"start_mcu_position":0,"first_clock":1000,"first_step_time":1.0,"last_clock":2330,"last_step_time":1.00133}"#,
    )
    .unwrap();
    s.add_block(&p, &motion::At { file: "t", record: 1, key: "k" }).unwrap();
    // Clocks 1000, 1110, 1230 (up), then 1730, 2230 (down); 1 µs per clock.
    assert_eq!(s.len(), 5);
    let at = |clock: f64| 1.0 + (clock - 1000.0) * 1e-6;
    assert_eq!(s.position(at(1110.0)).0, 1.5, "at a step's time, half-way through it");
    assert_eq!(s.position(at(1730.0)).0, 2.5, "down from 3");
    assert_eq!(s.position(5.0).0, 1.0, "after the last step, its position");
}

#[test]
fn a_trial_out_of_range_or_not_finite_is_refused_naming_its_values_and_the_ranges() {
    let log = gz(&[config("cartesian"), steps(), accel(400)]);
    for (t, shown) in [
        ((4, f64::NAN, 0.0), "(4, NaN, 0)"),
        ((4, 0.1, f64::INFINITY), "(4, 0.1, inf)"),
        ((0, 0.1, 0.0), "(0, 0.1, 0)"),
    ] {
        let (harmonic, amplitude_rad, phase_rad) = t;
        let o = KlipperOptions { trial: Some(TrialShift { harmonic, amplitude_rad, phase_rad }), ..opts() };
        let e = read_log(&log[..], "LOG.json.gz", &o).unwrap_err().to_string();
        let want =
            format!("LOG.json.gz: trial (H, U, PHI) = {shown}: harmonic 1..=16, amplitude 0..=1 rad, a finite phase");
        assert_eq!(e, want);
    }
}

#[test]
fn a_cut_gzip_stream_is_refused_with_how_to_stop_the_logger() {
    let bytes = gz(&[config("cartesian"), steps(), accel(100)]);
    let e = read_log(&bytes[..bytes.len() - 30], "t.json.gz", &opts()).unwrap_err().to_string();
    assert!(e.starts_with("t.json.gz: after ") && e.contains("cut") && !e.contains('\n'), "{e}");
    let e = read_log(&b"{\"id\":\"status\"} is text, not gzip"[..], "t.json.gz", &opts()).unwrap_err().to_string();
    assert!(e.contains("not a gzip stream"), "{e}");
}

#[test]
fn a_missing_key_names_the_record_the_key_and_the_value_as_written() {
    let bad = steps().replace(r#""first_clock":10000000,"#, "");
    let e = read(&[config("cartesian"), bad, accel(10)]).unwrap_err().to_string();
    assert_eq!(
        e,
        "t.json.gz: record 2: stepq:stepper_x.params.first_clock = null: expected an integer in 0..=2305843009213693951"
    );
}

#[test]
fn nan_in_a_read_subscription_is_refused_and_elsewhere_skipped() {
    let bad = accel(3).replace("7.0", "NaN");
    let e = read(&[config("cartesian"), steps(), bad]).unwrap_err().to_string();
    assert!(e.contains("record 3: (JSON at column") && e.contains("NaN"), "{e}");
    let other = r#"{"q":"status","params":{"status":{"extruder":{"temperature":NaN}}}}"#.to_string();
    let log = read(&[config("cartesian"), other, steps(), accel(3)]).unwrap();
    assert_eq!(log.skipped_records, 1);
}

#[test]
fn huge_declared_counts_and_messages_stop_at_the_bounds() {
    let entries = vec!["[1,65535,0]"; 65].join(",");
    let big = format!(
        r#"{{"q":"stepq:stepper_x","params":{{"data":[{entries}],"start_mcu_position":0,"first_clock":1,"first_step_time":1.0,"last_clock":9000000,"last_step_time":9.0}}}}"#
    );
    let e = read(&[config("cartesian"), big]).unwrap_err().to_string();
    assert!(e.contains("more than 4194304 steps"), "{e}");
    let e = read(&[config("cartesian"), steps().replace("[100,1000,0]", "[100,70000,0]")]).unwrap_err().to_string();
    assert!(e.contains("data[0] = [100,70000,0]: expected [interval, count, add]"), "{e}");
    let e = read(&[" ".repeat(MAX_RECORD_BYTES + 1)]).unwrap_err().to_string();
    assert!(e.contains("record 1: more than 4194304 bytes in one message"), "{e}");
}

#[test]
fn a_phase_offset_that_changes_mid_log_is_refused() {
    let moved = r#"{"q":"status","params":{"status":{"tmc2209 stepper_x":{"mcu_phase_offset":9}}}}"#.to_string();
    let e = read(&[config("cartesian"), steps(), moved, accel(3)]).unwrap_err().to_string();
    assert!(e.contains("mcu_phase_offset = 9: expected 5, its value at the start"), "{e}");
}

#[test]
fn a_log_without_what_the_route_needs_says_what_to_record() {
    let e = read(&[config("cartesian"), steps()]).unwrap_err().to_string();
    assert!(e.contains("log with `-s accelerometer:<name>`"), "{e}");
    let e = read(&[config("delta"), steps()]).unwrap_err().to_string();
    assert!(e.contains("printer.kinematics = \"delta\": expected cartesian or corexy"), "{e}");
    let e = read(&[steps(), accel(3)]).unwrap_err().to_string();
    assert!(e.contains("accelerometer data before"), "{e}");
}

#[test]
fn a_steady_move_is_one_segment_less_the_settle_time_at_each_end() {
    // 1.5 s at 10 kHz (3.125 rev/s) from 10 s, sampled from 9.5 s to 12 s.
    let steps = r#"{"q":"stepq:stepper_x","params":{"data":[[100,15000,0]],"start_mcu_position":0,"first_clock":10000000,"first_step_time":10.0,"last_clock":11499900,"last_step_time":11.4999}}"#;
    let rows: Vec<String> = (0..8000).map(|k| format!("[{},0,0,0]", 9.5 + k as f64 / 3200.0)).collect();
    let a = format!(r#"{{"q":"accelerometer:adxl345","params":{{"data":[{}]}}}}"#, rows.join(","));
    let log = read(&[config("cartesian"), steps.into(), a]).unwrap();
    let s = log.segments();
    assert_eq!(s.len(), 1);
    let (t0, t1) = s[0].span_s();
    // The acceleration's estimate spans ±10 ms (`ACCEL_SPAN_S`): the ends move by as much.
    assert!((t0 - 10.2).abs() < 0.015 && (t1 - 11.3).abs() < 0.015, "{t0} {t1}");
    assert_eq!(s[0].direction, crate::ripple::Direction::Forward);
}

#[test]
fn control_characters_from_the_log_are_escaped_in_every_message() {
    let no_control = |e: &str| assert!(!e.chars().any(char::is_control), "{e:?}");
    // DEL in a key (JSON writes it raw): found by the klipper_log fuzz target.
    let e = read(&[config("cartesian").replace("\"settings\"", "\"setti\u{7f}gs\"")]).unwrap_err().to_string();
    no_control(&e);
    assert!(e.contains(r"setti\u{7f}gs"), "{e}");
    // A C1 control in the driver's section name, quoted in the key of a refused offset.
    let driver = config("cartesian").replace("tmc2209 stepper_x", "tmc\u{85}2209 stepper_x");
    let moved = r#"{"q":"status","params":{"status":{"tmc\u0085 stepper_x":{"mcu_phase_offset":-1}}}}"#;
    let bad = driver.replace("\"mcu_phase_offset\":5", "\"mcu_phase_offset\":-1");
    for e in [
        read(&[bad]).unwrap_err().to_string(),
        read(&[driver, moved.into()]).map(|_| ()).map_or_else(|e| e.to_string(), |_| String::new()),
    ] {
        no_control(&e);
    }
    // Two accelerometers, one named with DEL: the message names both, escaped.
    let other = accel(3).replace("accelerometer:adxl345", "accelerometer:a\u{7f}b");
    let e = read(&[config("cartesian"), steps(), accel(3), other]).unwrap_err().to_string();
    no_control(&e);
    assert!(e.contains(r"a\u{7f}b"), "{e}");
}

/// A log of one steady forward move (1.5 s from 10 s, a step every `interval` µs) with
/// noise-free zero samples, carrying `trial`.
fn steady_log(interval: u32, trial: Option<TrialShift>) -> Log {
    let n = 1_500_000 / interval;
    let steps = format!(
        r#"{{"q":"stepq:stepper_x","params":{{"data":[[{interval},{n},0]],"start_mcu_position":0,"first_clock":10000000,"first_step_time":10.0,"last_clock":{},"last_step_time":{}}}}}"#,
        10_000_000 + interval * (n - 1),
        10.0 + f64::from(interval * (n - 1)) * 1e-6
    );
    let rows: Vec<String> = (0..8000).map(|k| format!("[{},0,0,0]", 9.5 + k as f64 / 3200.0)).collect();
    let a = format!(r#"{{"q":"accelerometer:adxl345","params":{{"data":[{}]}}}}"#, rows.join(","));
    let o = KlipperOptions { trial, ..opts() };
    read_log(gz(&[config("cartesian"), steps, a]).as_slice(), "t.json.gz", &o).unwrap()
}

#[test]
fn the_table_step_refuses_logs_that_cannot_measure_an_influence() {
    use super::table_step::table_step;
    let t = |h, u, phi| Some(TrialShift { harmonic: h, amplitude_rad: u, phase_rad: phi });
    let base = steady_log(100, None);
    let err = |b: &[Log], tr: &[Log], in_use: f64| table_step(b, tr, 4, in_use, 20).unwrap_err().to_string();
    let e = err(&[steady_log(100, t(4, 0.1, 0.0))], &[steady_log(100, t(4, 0.1, 0.0))], 0.0);
    assert!(e.contains("a baseline log with a trial"), "{e}");
    assert!(err(std::slice::from_ref(&base), &[steady_log(100, None)], 0.0).contains("a trial log without its trial"));
    assert!(err(std::slice::from_ref(&base), &[steady_log(100, t(8, 0.1, 0.0))], 0.0).contains("sine phase only"));
    assert!(err(std::slice::from_ref(&base), &[steady_log(100, t(4, 0.1, 1.0))], 0.0).contains("sine phase only"));
    assert!(err(std::slice::from_ref(&base), &[steady_log(100, t(4, 0.1, 0.0))], 0.1).contains("no change to measure"));
    // A trial at another speed has no baseline to pair with.
    let e = err(std::slice::from_ref(&base), &[steady_log(125, t(4, 0.1, 0.0))], 0.0);
    assert!(e.contains("no steady stretch of a trial log"), "{e}");
    // Paired, but the samples are all 0: the trial changed nothing measurable.
    let e = err(&[base], &[steady_log(100, t(4, 0.1, std::f64::consts::PI))], 0.0);
    assert!(e.contains("within the noise"), "{e}");
}
