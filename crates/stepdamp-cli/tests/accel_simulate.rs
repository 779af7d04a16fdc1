//! `stepdamp accel simulate`: a simulated printer's capture, read back by the reader.

use std::path::Path;
use std::process::{Command, Output};

const REAL_MOTOR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles/patent-motor-real.toml");

/// `stepdamp accel simulate` of `gcode` on patent-motor-real at 0.9 A into `out`, with `extra`.
fn simulate(gcode: &str, out: &Path, extra: &[&str]) -> Output {
    let mut args =
        vec!["accel", "simulate", "--motor", REAL_MOTOR, "--current", "0.9", "--gcode", gcode, "--in-use", "none"];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--out", out.to_str().unwrap()]);
    Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs")
}

const GCODE: &str = "M973 X F2 R4 H4 A0.5 B0.5 C0.01 D0.01";

#[test]
fn accel_simulate_writes_a_capture_the_reader_reads_back_with_its_gcode() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("capture.txt");
    let o = simulate(GCODE, &out, &["--echo"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(said.starts_with("wrote ") && said.contains("M973 X F2 R4 H4") && said.contains("0.900 A peak"), "{said}");
    let captures = stepdamp_accel::prusa::read_file(&out).unwrap();
    assert_eq!(captures.len(), 1);
    let c = &captures[0];
    assert_eq!(c.gcode.unwrap().to_string(), GCODE);
    c.check_annotations().unwrap();
    assert!(c.annotations.is_valid() && (c.annotations.sampling_freq_hz - 1344.0).abs() < 1.5);
    // The move lasts 3.056 s (settle, marker, ramp, 2.4 s at 2 rev/s, ramp, settle, marker,
    // settle): as many samples at 1344 Hz ± 0.1 %.
    assert!((4100..=4114).contains(&c.samples.len()), "{}", c.samples.len());
    // The same seed repeats the capture byte for byte; the ideal sensor prints another.
    let again = dir.path().join("again.txt");
    assert!(simulate(GCODE, &again, &["--echo", "--sensor", "lis2dh12"]).status.success());
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&again).unwrap());
    assert!(simulate(GCODE, &again, &["--echo", "--sensor", "ideal"]).status.success());
    assert_ne!(std::fs::read(&out).unwrap(), std::fs::read(&again).unwrap());
}

#[test]
fn accel_simulate_refuses_a_gcode_the_firmware_refuses_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("capture.txt");
    let o = simulate("M973 X F2 R10 H40", &out, &[]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(e.contains("--gcode `M973 X F2 R10 H40`") && e.contains("H<1..16>"), "{e}");
    assert!(!out.exists());
    // A sweeping trial is refused by the printer, naming the G-code.
    let o = simulate("M973 X F2 R10 H4 A0 B1 C0 D0.02", &out, &[]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.lines().count() == 1 && e.contains("a constant trial"), "{e}");
}
