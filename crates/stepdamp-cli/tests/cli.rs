//! End-to-end tests of the `stepdamp` binary: outputs, and bad input ending in a one-line
//! error with a non-zero exit code, no panic, and nothing half-written.

use std::path::Path;
use std::process::{Command, Output};

fn stepdamp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A failed command: non-zero exit, one `error:` line naming `needle`, no panic.
fn assert_clean_error(o: &Output, needle: &str) {
    let err = stderr(o);
    assert!(!o.status.success(), "expected failure, got success: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "not one line: {err}");
    assert!(lines[0].starts_with("error:"), "{err}");
    assert!(err.contains(needle), "'{needle}' not in: {err}");
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

#[test]
fn sweep_writes_the_table_and_both_plots() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let o = stepdamp(&[
        "--quiet",
        "sweep",
        "--mode",
        "open-loop",
        "--compensation",
        "off,patent,estimated",
        "--from",
        "4",
        "--to",
        "9",
        "--points",
        "3",
        "--duration",
        "0.3",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(files_in(&out), ["sweep.csv", "sweep.png", "sweep.svg"]);
    let table = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    let mut lines = table.lines();
    assert_eq!(lines.next().unwrap(), "mode,compensation,speed_cmd_rad_s,vel_err_rms_rad_s,vel_err_pp_rad_s,lost_sync");
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 9);
    for comp in ["off", "patent", "estimated"] {
        assert_eq!(rows.iter().filter(|r| r.starts_with(&format!("open-loop,{comp},"))).count(), 3);
    }
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("resonance speeds") && stdout.contains("k=4 4.22"), "{stdout}");
}

#[test]
fn simulate_writes_a_run_log_with_the_documented_columns() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("run.csv");
    let o = stepdamp(&[
        "simulate",
        "--mode",
        "servo",
        "--compensation",
        "off",
        "--speed",
        "-2",
        "--duration",
        "0.2",
        "--log",
        log.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&log).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), "t_s,theta_cmd_rad,theta_fb_rad,omega_fb_rad_s,i_a_a,i_b_a,i_d_a,i_q_a,iq_cmd_a");
    // One row per 50 µs control period.
    assert_eq!(lines.count(), 4000);
}

#[test]
fn motor_check_names_the_file_the_key_and_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("m.toml");
    let good = stepdamp(&["motor", "show", "patent-motor"]);
    assert!(good.status.success());
    let text = String::from_utf8_lossy(&good.stdout).replace("resistance_ohm = 0.9", "resistance_ohm = -0.9");
    std::fs::write(&f, text).unwrap();
    let o = stepdamp(&["motor", "check", f.to_str().unwrap()]);
    assert_clean_error(&o, "motor.resistance_ohm");
    assert!(stderr(&o).contains("m.toml") && stderr(&o).contains("> 0"));
}

#[test]
fn bad_sweep_input_fails_cleanly_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let o = out.to_str().unwrap();
    for (args, needle) in [
        (vec!["--motor", "no-such-motor"], "no-such-motor"),
        (vec!["--from", "10", "--to", "5"], "--from"),
        (vec!["--points", "0"], "--points"),
        (vec!["--compensation", "sometimes"], "sometimes"),
        (vec!["--mode", "closed"], "closed"),
        (vec!["--load-torque", "-1"], "--load-torque"),
        (vec!["--duration", "nan"], "--duration"),
    ] {
        let mut all = vec!["sweep", "--out", o];
        all.extend(args);
        assert_clean_error(&stepdamp(&all), needle);
        assert!(!out.exists() || files_in(&out).is_empty(), "{all:?} left files behind");
    }
}

#[test]
fn unwritable_output_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let blocker = dir.path().join("file");
    std::fs::write(&blocker, b"x").unwrap();
    let out = blocker.join("sub");
    let o = stepdamp(&["sweep", "--points", "2", "--duration", "0.3", "--out", out.to_str().unwrap()]);
    assert_clean_error(&o, "output directory");
    let o = stepdamp(&["simulate", "--speed", "1", "--log", out.join("x.csv").to_str().unwrap()]);
    assert_clean_error(&o, "does not exist");
}

#[test]
fn argument_errors_are_one_line_too() {
    assert_clean_error(&stepdamp(&["sweep", "--points", "many"]), "many");
    assert_clean_error(&stepdamp(&["sweep", "--no-such-flag"]), "--no-such-flag");
    assert_clean_error(&stepdamp(&["simulate"]), "--speed");
}

#[test]
fn every_profile_the_readme_uses_passes_motor_check() {
    let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/profiles");
    let names = files_in(&docs);
    assert!(names.iter().any(|n| n == "patent-motor-identified.toml"), "{names:?}");
    for n in names.iter().filter(|n| n.ends_with(".toml")) {
        let o = stepdamp(&["motor", "check", docs.join(n).to_str().unwrap()]);
        assert!(o.status.success(), "{n}: {}", stderr(&o));
    }
}
