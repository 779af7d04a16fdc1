//! End-to-end tests of the `stepdamp` binary: outputs, and bad input ending in a one-line
//! error with a non-zero exit code, no panic, and nothing half-written.

use std::path::Path;
use std::process::{Command, Output};

fn stepdamp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs")
}

/// `stepdamp` with the words of `args` (split at spaces) followed by `--out out`.
fn stepdamp_out(args: &str, out: &Path) -> Output {
    let mut all: Vec<&str> = args.split_whitespace().collect();
    all.extend(["--out", out.to_str().expect("temporary paths are UTF-8")]);
    stepdamp(&all)
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
    let o = stepdamp_out(
        "--quiet sweep --mode open-loop --compensation off,patent,estimated --from 4 --to 9 --points 3 --duration 0.3",
        &out,
    );
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
        "0.3",
        "--log",
        log.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&log).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t_s,theta_cmd_rad,theta_fb_rad,omega_fb_rad_s,i_a_a,i_b_a,i_d_a,i_q_a,iq_cmd_a,v_a_v,v_b_v"
    );
    // One row per 50 µs control period.
    assert_eq!(lines.count(), 6000);
    assert_eq!(files_in(dir.path()), ["run.csv"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("(6000 rows)"));
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
    assert!(
        stderr(&o).contains("m.toml") && stderr(&o).contains("= -0.9: must be in [1e-3, 1000] Ω"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn bad_sweep_input_fails_cleanly_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let o = out.to_str().unwrap();
    for (args, needle) in [
        (vec!["--motor", "no-such-motor"], "no-such-motor"),
        (vec!["--from", "10", "--to", "5"], "--from"),
        (vec!["--from", "5", "--to", "5"], "--from 5 must be below --to 5"),
        (vec!["--to", "20000"], "±628.3 rad/s"),
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
    let o = stepdamp(&["sweep", "--points", "2", "--duration", "0.4", "--out", out.to_str().unwrap()]);
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

/// A sweep that fails its checks after its arguments parse leaves no output directory.
#[test]
fn sweep_checks_everything_before_it_creates_the_output_directory() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("new/o");
    let o = out.to_str().unwrap();
    let ctl = dir.path().join("ctl.toml");
    let shown = stepdamp(&["motor", "show", "patent-motor"]);
    std::fs::write(
        &ctl,
        String::from_utf8_lossy(&shown.stdout).replace("counts_per_rev = 4000", "counts_per_rev = 1000"),
    )
    .unwrap();
    let c = ctl.to_str().unwrap();
    for (args, needles) in [
        (vec!["--controller-motor", c], vec!["patent-motor", "ctl.toml", "encoder.counts_per_rev", "4000", "1000"]),
        (vec!["--from", "1", "--duration", "0.25"], vec!["--duration", "at least 0.326 s"]),
        (vec!["--mode", "servo", "--compensation", "estimated"], vec!["estimated applies to open loop"]),
    ] {
        let mut all = vec!["sweep", "--points", "2", "--out", o];
        all.extend(args);
        let r = stepdamp(&all);
        for n in &needles {
            assert_clean_error(&r, n);
        }
        assert!(!dir.path().join("new").exists(), "{all:?} created the output directory");
    }
}

#[test]
fn a_controller_profile_for_other_hardware_is_rejected_by_simulate_too() {
    let dir = tempfile::tempdir().unwrap();
    let ctl = dir.path().join("ctl.toml");
    let shown = stepdamp(&["motor", "show", "patent-motor"]);
    let text = String::from_utf8_lossy(&shown.stdout).replace("pwm_hz = 20000.0", "pwm_hz = 25000.0");
    std::fs::write(&ctl, text).unwrap();
    let o = stepdamp(&["simulate", "--speed", "5", "--controller-motor", ctl.to_str().unwrap()]);
    assert_clean_error(&o, "drive.pwm_hz (20000 vs 25000)");
    assert!(stderr(&o).contains("ctl.toml") && stderr(&o).contains("patent-motor"));
    // A mis-identified motor model (R, Km) on the same hardware is what it is for.
    let text = String::from_utf8_lossy(&shown.stdout).replace("resistance_ohm = 0.9", "resistance_ohm = 1.1");
    std::fs::write(&ctl, text).unwrap();
    let o = stepdamp(&["simulate", "--speed", "5", "--duration", "0.4", "--controller-motor", ctl.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn estimated_compensation_is_open_loop_only() {
    let o = stepdamp(&["simulate", "--mode", "servo", "--compensation", "estimated", "--speed", "5"]);
    assert_clean_error(&o, "estimated applies to open loop; servo uses the encoder angle");
    // In a sweep of both modes it runs in open loop only, and says so on one line.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let o = stepdamp_out(
        "--quiet sweep --mode both --compensation off,estimated --from 5 --to 9 --points 2 --duration 0.3",
        &out,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with("note:") && err.contains("open loop only"), "{err}");
    let table = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    assert_eq!(table.lines().filter(|l| l.starts_with("open-loop,estimated,")).count(), 2, "{table}");
    assert_eq!(table.lines().filter(|l| l.starts_with("servo,estimated,")).count(), 0, "{table}");
    assert_eq!(table.lines().filter(|l| l.starts_with("servo,off,")).count(), 2, "{table}");
    // The help lists it.
    let help = String::from_utf8_lossy(&stepdamp(&["simulate", "--help"]).stdout).into_owned();
    assert!(help.contains("estimated"), "{help}");
}

#[test]
fn simulate_rejects_a_run_too_short_to_measure() {
    let o = stepdamp(&["simulate", "--speed", "2", "--duration", "0.2"]);
    assert_clean_error(&o, "--duration");
    assert!(stderr(&o).contains("at least 0.263 s"), "{}", stderr(&o));
    assert_clean_error(
        &stepdamp(&["simulate", "--speed", "700"]),
        "--speed 700 rad/s must be non-zero, finite and within ±628.3 rad/s",
    );
}

#[test]
fn resonance_prints_the_natural_frequency_and_the_three_speeds() {
    let o = stepdamp(&["resonance", "--motor", "patent-motor"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(s.starts_with("patent-motor\n"), "{s}");
    assert!(s.contains("natural frequency ω_n       844.1 rad/s"), "{s}");
    for (k, w) in [(4, "4.220"), (2, "8.441"), (1, "16.882")] {
        assert!(s.lines().any(|l| l.starts_with(&format!("resonance k={k}")) && l.contains(w)), "k={k} {w}: {s}");
    }
}

#[test]
fn malformed_toml_names_the_file_and_the_line_on_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("broken.toml");
    std::fs::write(&f, "name = \"x\"\n[motor\nkm_nm_per_a = 0.3\n").unwrap();
    for cmd in [vec!["motor", "check"], vec!["resonance", "--motor"]] {
        let mut all = cmd.clone();
        all.push(f.to_str().unwrap());
        let o = stepdamp(&all);
        assert_clean_error(&o, "broken.toml");
        assert!(stderr(&o).contains("line 2"), "{}", stderr(&o));
    }
}

#[test]
fn without_quiet_a_sweep_not_on_a_terminal_prints_no_progress_bar() {
    // The test's stdout and stderr are pipes, not terminals.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let o = stepdamp_out("sweep --mode open-loop --compensation off --from 5 --to 9 --points 2 --duration 0.3", &out);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(o.stderr.is_empty(), "stderr: {:?}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(!stdout.contains('\r') && !stdout.contains('\x1b'), "{stdout:?}");
    assert!(stdout.contains("median rms") && stdout.contains("wrote"), "{stdout}");
}

/// `stepdamp … | head -1`: the reader goes away; the command ends quietly with status 0.
#[test]
fn a_closed_stdout_ends_the_command_quietly() {
    use std::process::Stdio;
    // A pipe whose reader has exited: the write end of `true`'s standard input.
    let mut reader = Command::new("true").stdin(Stdio::piped()).spawn().expect("runs true");
    let closed = reader.stdin.take().unwrap();
    reader.wait().unwrap();
    for args in [
        vec!["motor", "show", "patent-motor"],
        vec!["resonance"],
        vec!["motor", "list"],
        vec!["identify", "plan", "--motor", "patent-motor"],
    ] {
        let closed = closed.try_clone_as_stdio();
        let o = Command::new(env!("CARGO_BIN_EXE_stepdamp"))
            .args(&args)
            .stdout(closed)
            .stderr(Stdio::piped())
            .output()
            .expect("runs");
        assert!(o.status.success(), "{args:?}: {:?} {}", o.status, stderr(&o));
        assert!(o.stderr.is_empty(), "{args:?}: {}", stderr(&o));
    }
}

trait TryCloneAsStdio {
    fn try_clone_as_stdio(&self) -> std::process::Stdio;
}

impl TryCloneAsStdio for std::process::ChildStdin {
    fn try_clone_as_stdio(&self) -> std::process::Stdio {
        use std::os::fd::AsFd;
        std::process::Stdio::from(self.as_fd().try_clone_to_owned().unwrap())
    }
}
