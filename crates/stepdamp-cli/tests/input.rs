//! Bad numbers and motor names on the command line: our message, naming the option and the
//! value as written, never clap's "unexpected argument"; preset and file names by one rule.

use std::path::Path;
use std::process::{Command, Output};

fn stepdamp_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).current_dir(dir).output().expect("runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Fails with one `error:` line that contains every needle, and writes no `out` directory.
fn assert_refused(dir: &Path, args: &[&str], needles: &[&str]) {
    let o = stepdamp_in(dir, args);
    let err = stderr(&o);
    assert!(!o.status.success() && !err.contains("panicked"), "{args:?}: {err}");
    assert_eq!(err.lines().filter(|l| !l.trim().is_empty()).count(), 1, "{args:?}: {err}");
    assert!(!err.contains("unexpected argument"), "{args:?}: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: '{n}' not in {err}");
        // Said once: an error chain must not repeat its cause.
        assert_eq!(err.matches(n).count(), 1, "{args:?}: '{n}' said twice in {err}");
    }
    assert!(!dir.join("out").exists(), "{args:?} created out/");
}

#[test]
fn negative_numbers_are_range_checked_with_our_messages() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert_refused(d, &["sweep", "--points", "-5"], &["--points -5", "at least 2"]);
    assert_refused(d, &["sweep", "--substeps", "-1"], &["--substeps -1", "1..=1000"]);
    assert_refused(d, &["sweep", "--from", "-3"], &["--from -3"]);
    assert_refused(d, &["simulate", "--speed", "5", "--dwell", "-1"], &["--dwell -1"]);
    assert_refused(d, &["simulate", "--speed", "5", "--ramp", "-0.5"], &["--ramp -0.5"]);
    assert_refused(d, &["identify", "plan", "--motor", "patent-motor", "--periods", "-3"], &["--periods -3"]);
    assert_refused(
        d,
        &["identify", "run", "--motor", "patent-motor", "--out", "out", "--iterations", "-2", "--refine"],
        &["--iterations -2", "1..=20"],
    );
}

#[test]
fn a_bare_name_is_a_preset_a_path_is_a_file_and_both_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let shown = stepdamp_in(d, &["motor", "show", "nema23-57mm"]);
    assert!(shown.status.success(), "{}", stderr(&shown));
    let text = String::from_utf8_lossy(&shown.stdout).replace("name = \"nema23-57mm\"", "name = \"mine\"");
    // A file named like a preset: the bare name is ambiguous, ./name is the file.
    std::fs::write(d.join("patent-motor"), &text).unwrap();
    assert_refused(d, &["resonance", "--motor", "patent-motor"], &["both a preset and a file", "./patent-motor"]);
    let o = stepdamp_in(d, &["resonance", "--motor", "./patent-motor"]);
    assert!(o.status.success() && String::from_utf8_lossy(&o.stdout).starts_with("mine"), "{}", stderr(&o));
    // A bare name that is only a file is not a preset; the message says how to name the file.
    std::fs::write(d.join("mymotor"), &text).unwrap();
    assert_refused(d, &["motor", "check", "mymotor"], &["unknown motor 'mymotor'", "./mymotor"]);
    // A .toml name is a file even without a slash, and a missing one says so.
    std::fs::write(d.join("m.toml"), &text).unwrap();
    let o = stepdamp_in(d, &["motor", "check", "m.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_refused(d, &["motor", "check", "gone.toml"], &["gone.toml: no such profile file"]);
}

#[test]
fn implausible_profiles_are_refused_naming_file_key_value_and_range() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let shown = stepdamp_in(d, &["motor", "show", "patent-motor"]);
    let text = String::from_utf8_lossy(&shown.stdout).into_owned();
    for (from, to, want) in [
        ("km_nm_per_a = 0.3", "km_nm_per_a = 1e308", "m.toml: motor.km_nm_per_a = 1e308: must be in [1e-3, 50] N·m/A"),
        (
            "inertia_kg_m2 = 0.00004",
            "inertia_kg_m2 = 1e-308",
            "motor.inertia_kg_m2 = 1e-308: must be in [1e-8, 1] kg·m²",
        ),
        ("holding_current_a = 1.9", "holding_current_a = 0.0", "drive.holding_current_a = 0: must be in (0, 100] A"),
    ] {
        assert!(text.contains(from), "{from} not in {text}");
        std::fs::write(d.join("m.toml"), text.replace(from, to)).unwrap();
        for cmd in [
            &["motor", "check", "m.toml"][..],
            &["resonance", "--motor", "m.toml"],
            &["identify", "plan", "--motor", "m.toml"],
        ] {
            assert_refused(d, cmd, &[want]);
            let err = stderr(&stepdamp_in(d, cmd));
            assert_eq!(err.matches("m.toml").count(), 1, "{err}");
            assert!(!err.contains("inf") && !err.contains("NaN"), "{err}");
        }
    }
}

#[test]
fn every_file_argument_refuses_an_endless_input_with_one_line() {
    // `/dev/zero` as any file argument: refused after reading at most the kind's limit
    // (docs/files.md#size-limits), not read until memory runs out.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let z = "/dev/zero";
    assert_refused(d, &["study", "--spec", z, "--out", "out"], &["/dev/zero", "1048576 bytes"]);
    assert_refused(d, &["sweep", "--table", z, "--points", "2", "--out", "out"], &["--table", "/dev/zero", "1048576"]);
    for form in ["--readback", "--m972"] {
        let args =
            ["import", "prusa", form, z, "--motor", "patent-motor", "--current-rms", "0.65", "--out", "out/p.toml"];
        assert_refused(d, &args, &["/dev/zero", "1048576"]);
    }
    assert_refused(d, &["sweep", "--motor", z, "--out", "out"], &["/dev/zero", "1048576"]);
    assert_refused(d, &["sweep", "--controller-motor", z, "--out", "out"], &["/dev/zero", "1048576"]);
    assert_refused(
        d,
        // `--out` in a folder that exists: a bad `--out` is refused before any log is read.
        &["identify", "--log", z, "--motor", "patent-motor", "--out", "x.toml"],
        &["/dev/zero", "longer than"],
    );
    let args = ["identify", "static", "--table", z, "--sign", "on-rotor", "--motor", "patent-motor", "--out", "x.toml"];
    assert_refused(d, &args, &["/dev/zero", "longer than"]);
}
