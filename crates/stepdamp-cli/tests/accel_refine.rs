//! `stepdamp accel refine` on a session log written as the firmware and a host print it.

use std::f64::consts::TAU;
use std::fmt::Write as _;
use std::process::{Command, Output};
use stepdamp_accel::capture::{Annotations, PlannedTimes};
use stepdamp_accel::{AccelCapture, Axis, Gcode, Reconstruction, TrialSweep};

fn stepdamp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs")
}

/// Rounds like the firmware's `Print::printFloat(x, 2)`: add 0.005, truncate.
fn printed(x: f64) -> f64 {
    ((x + 0.005) * 100.0).floor() / 100.0
}

fn m973(revs: f64, mag: f64, pha: f64) -> Gcode {
    let trial = TrialSweep { harmonic: 4, pha_start: pha, pha_end: pha, mag_start: mag, mag_end: mag };
    Gcode::ParamSweep { axis: Axis::X, speed: 2.0, revs, trial }
}

/// One capture of `g` as OctoPrint logs it: the command sent, then the samples
/// (`"%d, %.5f\n"`) of a head whose harmonic 4 is `y` (m/s², `Im(y·e^{4iθ})`) plus a
/// harmonic 1 and an offset, then the seven annotations with CR LF.
fn capture_text(g: Gcode, y: (f64, f64)) -> String {
    let t = g.planned_times().unwrap();
    let times = PlannedTimes {
        start_marker: printed(t.start_marker),
        end_marker: printed(t.end_marker),
        signal_start: printed(t.signal_start),
        signal_end: printed(t.signal_end),
    };
    let fs = 1344.37;
    let annotations = Annotations { sampling_freq_hz: fs, movement_ok: true, accel_error: 0, times };
    let n = ((t.end_marker + 0.3) * fs) as usize;
    let c = AccelCapture { source: "gen".into(), line: 1, gcode: Some(g), samples: vec![0.0; n], annotations };
    let r = Reconstruction { periods_per_rev: 50, start_angle_rad: 0.0, first_sample_s: 0.0, mm_per_rev: 32.0 };
    let mut s = format!("Send: N7 {g}*33\r\n");
    for (i, st) in c.commanded(&r).unwrap().iter().enumerate() {
        let th = st.electrical_rad;
        let v = 0.2 + y.0 * (4.0 * th + y.1).sin() + 0.3 * (th - 0.4).sin();
        let _ = write!(s, "Recv: {i}, {v:.5}\r\n");
    }
    let _ = write!(
        s,
        "Recv: sampling_freq: {fs:.2}\r\nRecv: movement_ok: true\r\nRecv: accel_error: 0\r\n\
         Recv: start_marker: {:.2}\r\nRecv: end_marker: {:.2}\r\nRecv: signal_start: {:.2}\r\nRecv: signal_end: {:.2}\r\nRecv: ok\r\n",
        times.start_marker, times.end_marker, times.signal_start, times.signal_end
    );
    s
}

#[test]
fn refine_writes_the_m971_table_that_cancels_what_the_captures_measured() {
    // The head's harmonic 4: Y0 = 0.8·e^{1.2i} m/s² forward, 0.5·e^{-0.3i} backward, and a
    // known influence C = 20·e^{-0.5i} m/s² per rad of shift; the trial (0.004, 0.6) is
    // U = 4·0.004·e^{0.6i} rad.
    let c = |u: (f64, f64)| (20.0 * 4.0 * u.0, -0.5 + u.1);
    let add = |a: (f64, f64), b: (f64, f64)| {
        let (x, y) = (a.0 * a.1.cos() + b.0 * b.1.cos(), a.0 * a.1.sin() + b.0 * b.1.sin());
        (x.hypot(y), y.atan2(x))
    };
    let (y_fwd, y_bwd, trial) = ((0.8, 1.2), (0.5, -0.3), (0.004, 0.6));
    let mut log = String::new();
    for (revs, y0) in [(-8.0, y_fwd), (8.0, y_bwd)] {
        log += &capture_text(m973(revs, 0.0, 0.0), y0);
        log += &capture_text(m973(revs, trial.0, trial.1), add(y0, c(trial)));
    }
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("serial.log");
    std::fs::write(&session, log).unwrap();
    let out = dir.path().join("x.gcode");
    let o = stepdamp(&[
        "accel",
        "refine",
        "--log",
        session.to_str().unwrap(),
        "--motor",
        "patent-motor",
        "--in-use",
        "none",
        "--axis",
        "X",
        "--current-rms",
        "0.55",
        "--timing",
        "planned",
        "--out",
        out.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}{text}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("not simulated: a measured correction"), "{text}");
    let gcode = std::fs::read_to_string(&out).unwrap();
    let (table, _) = stepdamp_export::prusa::parse_text(&gcode, Some('X'), "x.gcode").unwrap();
    // U* = −Y0/C, as a table item (mag = |U*|/4, pha = arg U*).
    for (s, y0) in [(table.forward, y_fwd), (table.backward, y_bwd)] {
        let (mag, pha) = (y0.0 / 20.0 / 4.0, (y0.1 + 0.5 + std::f64::consts::PI).rem_euclid(TAU));
        let got = (f64::from(s.mag[4]), f64::from(s.pha[4]).rem_euclid(TAU));
        assert!(
            (got.0 - mag).abs() < 1e-3 * mag + 1e-6 && (got.1 - pha).abs() < 2e-3,
            "{got:?} against {:?}",
            (mag, pha)
        );
        assert!(s.mag.iter().enumerate().all(|(n, &m)| n == 4 || m == 0.0), "only harmonic 4 changes");
    }
}

#[test]
fn a_table_too_large_for_the_int8_shifts_is_refused_with_the_current_where_it_would_fit() {
    // Harmonic 4 forward: Y0 = 6 m/s², C = 20 m/s² per rad: the cancelling shift is 0.3 rad,
    // past the table's 0.195 rad at 0.55 A RMS (0.778 A peak). A detent's shift falls as 1/I:
    // it fits from 0.778·0.3/0.195 ≈ 1.2 A peak, 0.85 A RMS.
    // The trial (0.004, 0.6) adds C·U = 20·e^{-0.5i}·4·0.004·e^{0.6i} to Y0.
    let (y, u) = ((6.0f64, 1.2f64), (20.0 * 4.0 * 0.004, 0.1f64));
    let sum = (y.0 * y.1.cos() + u.0 * u.1.cos(), y.0 * y.1.sin() + u.0 * u.1.sin());
    let with_trial = (sum.0.hypot(sum.1), sum.1.atan2(sum.0));
    let log = capture_text(m973(-8.0, 0.0, 0.0), y) + &capture_text(m973(-8.0, 0.004, 0.6), with_trial);
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("serial.log");
    std::fs::write(&session, log).unwrap();
    let out = dir.path().join("x.gcode");
    let o = stepdamp(&[
        "accel",
        "refine",
        "--log",
        session.to_str().unwrap(),
        "--motor",
        "patent-motor",
        "--in-use",
        "none",
        "--axis",
        "X",
        "--current-rms",
        "0.55",
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.lines().count() == 1, "{err}");
    assert!(
        err.contains("past Prusa's int8 shifts") && err.contains("too large for the table at this run current"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written");
    // The advice: M906 X<mA RMS>, within 2 % of the closed form (0.3 rad as 4096ths, rounded).
    let ma: f64 = err.split("`M906 X").nth(1).and_then(|t| t.split('`').next()).unwrap().parse().unwrap();
    let want_peak = 0.55 * std::f64::consts::SQRT_2 * (0.3 * 4096.0 / TAU) / 127.0;
    let want_ma = 1e3 * want_peak / std::f64::consts::SQRT_2;
    assert!((ma - want_ma).abs() < 0.02 * want_ma, "{ma} mA against {want_ma:.0}: {err}");
}

#[test]
fn refine_refuses_what_it_cannot_use_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("serial.log");
    std::fs::write(&session, capture_text(m973(8.0, 0.0, 0.0), (0.5, 0.1))).unwrap();
    let out = dir.path().join("x.gcode");
    let base =
        ["accel", "refine", "--log", session.to_str().unwrap(), "--motor", "patent-motor", "--current-rms", "0.55"];
    for (extra, needle) in [
        (vec!["--in-use", "none", "--axis", "X"], "has no constant trial"),
        (vec!["--in-use", "none", "--axis", "Y"], "moved the other axis than --axis"),
        (vec!["--in-use", "none", "--axis", "Z"], "--axis Z: Prusa phase stepping has axes X and Y"),
        (vec!["--in-use", "none", "--axis", "X", "--mm-per-rev", "1000"], "--mm-per-rev 1e3: must be in 6.3..=314 mm"),
        (vec!["--in-use", "/nonexistent/t.gcode", "--axis", "X"], "/nonexistent/t.gcode"),
    ] {
        let mut a: Vec<&str> = base.to_vec();
        a.extend(extra);
        a.extend(["--out", out.to_str().unwrap()]);
        let o = stepdamp(&a);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(needle) && err.lines().count() == 1, "{a:?}: {err}");
        assert!(!out.exists(), "nothing written on an error");
    }
}

/// The printed baseline response of `accel refine`'s output, m/s².
fn baseline(text: &str) -> f64 {
    let l = text.lines().find(|l| l.contains(": baseline ")).expect("a refined harmonic");
    l.split(": baseline ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap()
}

/// `patent-motor-real`, the docs' profile.
const REAL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles/patent-motor-real.toml");
/// Harmonic 4's baseline and a trial, at 2 rev/s backward.
const BASE: &str = "M973 X F2 R10 H4 A0 B0 C0 D0";
const TRIAL: &str = "M973 X F2 R10 H4 A0 B0 C0.01 D0.01";

/// `gcode` captured by `accel simulate` on [`REAL`] at `current` A peak with `table` in use,
/// written to `out`; returns the text.
fn simulated(gcode: &str, current: &str, table: &str, seed: &str, out: &str) -> String {
    let a = ["accel", "simulate", "--motor", REAL, "--current", current, "--gcode", gcode, "--in-use", table];
    let o = stepdamp(&[&a[..], &["--echo", "--seed", seed, "--out", out]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read_to_string(out).unwrap()
}

/// `accel refine` of `log` on [`REAL`] at `current` A peak with `table` in use, writing `out`,
/// with `extra` arguments; returns its standard output.
fn refined(log: &str, current: &str, table: &str, out: &str, extra: &[&str]) -> String {
    let a = ["accel", "refine", "--log", log, "--motor", REAL, "--in-use", table, "--axis", "X", "--current", current];
    let o = stepdamp(&[&a[..], extra, &["--out", out]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).to_string()
}

#[test]
fn simulate_refine_and_simulate_again_cancel_harmonic_4_on_the_simulated_printer() {
    // The route from the command line: the simulated printer's baseline and trial captures,
    // refined into a table, loaded, captured again: harmonic 4 must fall at least 10×
    // (measured 23×: 1.473 → 0.0645 m/s²).
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let session = |text: String| {
        std::fs::write(p("session.log"), text).unwrap();
        p("session.log")
    };
    let first = simulated(BASE, "0.9", "none", "1", &p("b.txt")) + &simulated(TRIAL, "0.9", "none", "2", &p("t.txt"));
    let before = baseline(&refined(&session(first), "0.9", "none", &p("new.gcode"), &[]));
    let new = p("new.gcode");
    let second = simulated(BASE, "0.9", &new, "3", &p("b2.txt")) + &simulated(TRIAL, "0.9", &new, "4", &p("t2.txt"));
    let after = baseline(&refined(&session(second), "0.9", &new, &p("new2.gcode"), &[]));
    eprintln!("harmonic 4: {before} -> {after} m/s² ({:.1}x)", before / after);
    assert!(before / after >= 10.0, "{before} -> {after}");
}

#[test]
fn a_second_step_without_a_trial_takes_the_first_sessions_influence_and_lowers_the_residual() {
    // docs/accelerometer.md#a-step-without-a-trial: the first session (baseline and trial)
    // refined; the baseline alone again with that table loaded, refined with the first
    // session's influence: harmonic 4 must fall at least 3× further (measured at 0.44 A:
    // 1.15 → 0.112 → 0.0188 m/s², 20.2 then 35.7 dB), with no second trial.
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let (current, new) = ("0.44", p("new.gcode"));
    let first =
        simulated(BASE, current, "none", "3", &p("b.txt")) + &simulated(TRIAL, current, "none", "4", &p("t.txt"));
    std::fs::write(p("session.log"), first).unwrap();
    let start = baseline(&refined(&p("session.log"), current, "none", &new, &[]));
    simulated(BASE, current, &new, "5", &p("b2.txt"));
    let carried = ["--influence-from", &p("session.log"), "--influence-current", current];
    let text = refined(&p("b2.txt"), current, &new, &p("new2.gcode"), &carried);
    assert!(text.contains("no trial: the earlier session's influence ×1.0000"), "{text}");
    let first_step = baseline(&text);
    simulated(BASE, current, &p("new2.gcode"), "7", &p("b3.txt"));
    let second_step = baseline(&refined(&p("b3.txt"), current, &p("new2.gcode"), &p("new3.gcode"), &carried));
    eprintln!("harmonic 4: {start} -> {first_step} -> {second_step} m/s²");
    assert!(start / first_step >= 5.0, "the first step: {start} -> {first_step}");
    assert!(first_step / second_step >= 3.0, "the step without a trial: {first_step} -> {second_step}");
}

#[test]
fn an_influence_from_another_session_needs_its_current_and_a_matching_step() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let (backward, forward, out) = (p("b.txt"), p("f.txt"), p("x.gcode"));
    std::fs::write(&backward, capture_text(m973(8.0, 0.0, 0.0), (0.5, 0.1))).unwrap();
    std::fs::write(&forward, capture_text(m973(-8.0, 0.0, 0.0), (0.5, 0.1))).unwrap();
    let a = ["accel", "refine", "--log", &backward, "--motor", "patent-motor", "--in-use", "none", "--axis", "X"];
    let a = [&a[..], &["--current", "0.6", "--out", &out]].concat();
    for (extra, needle) in [
        (vec!["--influence-from", &backward], "--influence-from needs the run current that session was recorded at"),
        (vec!["--influence-current", "0.5"], "--influence-current(-rms) without --influence-from"),
        (vec!["--influence-from", &backward, "--influence-current", "0.2"], "at most 2× either way"),
        (vec!["--influence-from", &backward, "--influence-current=-1"], "--influence-current (peak) -1e0 A: must be"),
        (vec!["--influence-from", &backward, "--influence-current-rms=0"], "--influence-current-rms 0e0 A: must be"),
        // The earlier session must have its own trial: a baseline alone gives no influence.
        (vec!["--influence-from", &forward, "--influence-current", "0.5"], "has no constant trial"),
    ] {
        let o = stepdamp(&[&a[..], &extra[..]].concat());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(needle) && err.lines().count() == 1, "{extra:?}: {err}");
        assert!(!std::path::Path::new(&out).exists(), "nothing written on an error");
    }
}
