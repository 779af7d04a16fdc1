//! `identify` (the fit) prints the fit's decisions and its validation exactly as the library
//! computes them, honours `--inertia`, and `--report` plots the validation; it reads each log
//! once (a FIFO and standard input give the file's profile) and refuses a file given twice.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};
use stepdamp_identify::conditions::InertiaMode;
use stepdamp_identify::fit::FitOptions;
use stepdamp_identify::from_logs::{IdentifyOptions, encoder_route};
use stepdamp_identify::log::{LogOptions, read_log};
use stepdamp_identify::plan::{PlanOptions, plan};
use stepdamp_identify::validation::{default_max_order, validate};
use stepdamp_profile::Profile;

fn stepdamp(args: &[&str]) -> Output {
    let o = Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs");
    assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
    o
}

/// Simulated logs of the plan for patent-motor (short runs) and the profile they were
/// recorded with.
fn logs(dir: &Path) -> (Vec<PathBuf>, PathBuf) {
    let out = dir.join("runs");
    let o = out.to_str().unwrap();
    stepdamp(&["--quiet", "identify", "run", "--motor", "patent-motor", "--periods", "5", "--out", o]);
    let mut csv: Vec<PathBuf> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "csv"))
        .collect();
    csv.sort();
    (csv, out.join("base.toml"))
}

/// What the library says for these logs with `--inertia mode`: the decisions, then the
/// validation (its `Display`).
fn library_lines(csv: &[PathBuf], base: &Path, mode: InertiaMode) -> (Vec<String>, String) {
    let base = Profile::from_file(base).unwrap();
    let opts = LogOptions::new(base.motor.pole_pairs);
    let logs: Vec<_> = csv.iter().map(|p| read_log(p, &opts).unwrap()).collect();
    let o = IdentifyOptions { inertia: mode, ..IdentifyOptions::new(&[1, 2, 4]) };
    let f = encoder_route(&logs, &base, &o).unwrap().0.fit;
    let decisions = f.decisions.iter().map(ToString::to_string).collect();
    (decisions, validate(&f, default_max_order(&f)).to_string())
}

#[test]
fn the_fit_prints_its_decisions_then_the_library_validation_and_honours_inertia() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, base) = logs(dir.path());
    assert!(csv.len() >= 2, "{csv:?}");
    for &mode in InertiaMode::ALL {
        let mut args = vec!["identify".to_string()];
        for c in &csv {
            args.extend(["--log".to_string(), c.display().to_string()]);
        }
        let out = dir.path().join(format!("id-{}.toml", mode.name()));
        args.extend(
            ["--motor", base.to_str().unwrap(), "--out", out.to_str().unwrap(), "--inertia", mode.name()]
                .map(String::from),
        );
        let report = dir.path().join(format!("report-{}", mode.name()));
        if mode == InertiaMode::Auto {
            args.extend(["--report".to_string(), report.display().to_string()]);
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let text = String::from_utf8(stepdamp(&args).stdout).unwrap();
        let (decisions, validation) = library_lines(&csv, &base, mode);
        assert!(!decisions.is_empty());
        let mut expected = decisions.join("\n");
        expected.push('\n');
        expected.push_str(&format!("validation (orders 1–8):\n{validation}\n"));
        assert!(text.contains(&expected), "{mode:?}: want\n{expected}\nin\n{text}");
        if mode == InertiaMode::Base {
            assert!(
                text.contains("J held at the base profile's") && text.contains("as asked (--inertia base)"),
                "{text}"
            );
        }
        if mode == InertiaMode::Fit {
            assert!(text.contains("J fitted") && text.contains("as asked (--inertia fit)"), "{text}");
        }
        if mode == InertiaMode::Auto {
            for f in ["validation.svg", "validation.png"] {
                let len = std::fs::metadata(report.join(f)).map(|m| m.len()).unwrap_or(0);
                assert!(len > 1000, "{f}: {len} bytes");
            }
        }
    }
}

#[test]
fn an_unknown_inertia_mode_is_refused_with_the_allowed_values() {
    let o = Command::new(env!("CARGO_BIN_EXE_stepdamp"))
        .args(["identify", "--log", "x.csv", "--motor", "patent-motor", "--out", "y.toml", "--inertia", "guess"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("guess") && e.contains("fit") && e.contains("base") && e.contains("auto"), "{e}");
}

#[test]
fn identify_format_json_is_the_library_fit_report_alone() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, base) = logs(dir.path());
    let mut args = vec!["identify".to_string()];
    for c in &csv {
        args.extend(["--log".to_string(), c.display().to_string()]);
    }
    let out = dir.path().join("id.toml");
    args.extend(
        ["--motor", base.to_str().unwrap(), "--out", out.to_str().unwrap(), "--format", "json"].map(String::from),
    );
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let text = String::from_utf8(stepdamp(&args).stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "one line of JSON: {text}");
    assert!(out.exists(), "the profile is written with --format json too");
    let got: serde_json::Value = serde_json::from_str(&text).unwrap();

    let profile = Profile::from_file(&base).unwrap();
    let opts = LogOptions::new(profile.motor.pole_pairs);
    let logs: Vec<_> = csv.iter().map(|p| read_log(p, &opts).unwrap()).collect();
    let report = encoder_route(&logs, &profile, &IdentifyOptions::new(&[1, 2, 4])).unwrap().0;
    let want = serde_json::to_value(report).unwrap();
    assert_close(&got, &want);
}

#[test]
fn identify_ff_on_json_carries_the_library_feed_forward_check() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, base) = logs(dir.path());
    let mut args = vec!["identify".to_string()];
    for c in &csv {
        args.extend(["--log".to_string(), c.display().to_string()]);
    }
    let out = dir.path().join("ff.toml");
    args.extend(
        ["--motor", base.to_str().unwrap(), "--out", out.to_str().unwrap(), "--ff-on", "--format", "json"]
            .map(String::from),
    );
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let text = String::from_utf8(stepdamp(&args).stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "one line of JSON: {text}");
    let got: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert!(got["feed_forward"]["remaining_ripple_nm"].is_number(), "{got}");

    let profile = Profile::from_file(&base).unwrap();
    let opts = LogOptions::new(profile.motor.pole_pairs);
    let logs: Vec<_> = csv.iter().map(|p| read_log(p, &opts).unwrap()).collect();
    let o = IdentifyOptions { feed_forward_on: true, ..IdentifyOptions::new(&[1, 2, 4]) };
    let report = encoder_route(&logs, &profile, &o).unwrap().0;
    assert!(report.feed_forward.is_some());
    let want = serde_json::to_value(report).unwrap();
    assert_close(&got, &want);
}

/// Equal, numbers to the last digit or two (serde_json's default parser rounds the last bit).
fn assert_close(got: &serde_json::Value, want: &serde_json::Value) {
    use serde_json::Value;
    match (got, want) {
        (Value::Number(a), Value::Number(b)) => {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            assert!((a - b).abs() <= 1e-14 * a.abs().max(b.abs()), "{a} vs {b}");
        }
        (Value::Array(a), Value::Array(b)) => {
            assert_eq!(a.len(), b.len(), "{got} vs {want}");
            a.iter().zip(b).for_each(|(x, y)| assert_close(x, y));
        }
        (Value::Object(a), Value::Object(b)) => {
            assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
            a.iter().for_each(|(k, x)| assert_close(x, &b[k]));
        }
        _ => assert_eq!(got, want),
    }
}

#[test]
fn identify_plan_prints_the_library_plan_and_its_json() {
    let motor = Profile::preset("patent-motor").unwrap();
    let po = PlanOptions { orders: vec![1, 2, 4], electrical_periods: 12.0, ..PlanOptions::default() };
    let want = plan(&motor, &po).unwrap();
    let args = ["identify", "plan", "--motor", "patent-motor", "--periods", "12"];
    let text = String::from_utf8(stepdamp(&args).stdout).unwrap();
    assert_eq!(text, format!("{want}\n"));
    assert!(text.contains("run-4-rev") && text.contains("total "), "{text}");
    let mut json = args.to_vec();
    json.extend(["--format", "json"]);
    let text = String::from_utf8(stepdamp(&json).stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "one line of JSON: {text}");
    let got: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_close(&got, &serde_json::to_value(&want).unwrap());
}

#[test]
fn identify_static_prints_the_library_report_and_its_json() {
    use stepdamp_identify::static_curve::{StaticReport, TorqueSign, analyse, read_table};
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("curve.csv");
    let mut s = String::from("theta_rad,torque_nm\n");
    for i in 0..400 {
        let th = i as f64 / 400.0 * 2.0 * std::f64::consts::TAU / 50.0;
        let tq = -0.02 * (200.0 * th + 0.2).sin() - 0.005 * (50.0 * th - 1.0).sin() + 0.001;
        s.push_str(&format!("{th},{tq}\n"));
    }
    std::fs::write(&table, s).unwrap();
    let (t, out) = (table.to_str().unwrap(), dir.path().join("s.toml"));
    let args = ["identify", "static", "--table", t, "--sign", "on-rotor", "--motor", "patent-motor"];
    let pts = read_table(&table).unwrap();
    let curve = analyse(&pts, 50, TorqueSign::OnRotor, 4, t).unwrap();
    let want = StaticReport::new(t, pts.len(), &curve, &[1, 2, 4]);
    assert_eq!(want.harmonics.len(), 3);

    let mut text_args = args.to_vec();
    text_args.extend(["--out", out.to_str().unwrap()]);
    let text = String::from_utf8(stepdamp(&text_args).stdout).unwrap();
    assert!(text.starts_with(&format!("{want}\n")), "want\n{want}\nin\n{text}");

    let json_out = dir.path().join("j.toml");
    let mut json_args = args.to_vec();
    json_args.extend(["--out", json_out.to_str().unwrap(), "--format", "json"]);
    let text = String::from_utf8(stepdamp(&json_args).stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "one line of JSON: {text}");
    assert!(json_out.exists(), "the profile is written with --format json too");
    let got: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_close(&got, &serde_json::to_value(&want).unwrap());
}

#[test]
fn identify_run_refine_json_is_the_library_run_report_and_the_summary_its_rows() {
    use stepdamp_identify::model::Model;
    use stepdamp_identify::refine::{RefineOptions, RefinementReport, RunReport, refine};
    let dir = tempfile::tempdir().unwrap();
    let cli_dir = dir.path().join("cli");
    let o = cli_dir.to_str().unwrap();
    let args = ["identify", "run", "--motor", "patent-motor", "--out", o, "--periods", "6", "--refine"];
    let mut json = args.to_vec();
    json.extend(["--iterations", "1", "--format", "json"]);
    let text = String::from_utf8(stepdamp(&json).stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "one line of JSON: {text}");
    let got: serde_json::Value = serde_json::from_str(&text).unwrap();

    let motor = Profile::preset("patent-motor").unwrap();
    let po = PlanOptions { orders: vec![1, 2, 4], electrical_periods: 6.0, ..PlanOptions::default() };
    let p = plan(&motor, &po).unwrap();
    // The CLI's logs (the fit report names them), in the plan's order.
    let files: Vec<PathBuf> = p.runs.iter().map(|r| cli_dir.join(format!("{}.csv", r.name))).collect();
    let opts = LogOptions::new(motor.motor.pole_pairs);
    let logs: Vec<_> = files.iter().map(|f| read_log(f, &opts).unwrap()).collect();
    let fo = FitOptions::for_profile(&p.profile, &[1, 2, 4]);
    let report = encoder_route(&logs, &p.profile, &IdentifyOptions::new(&[1, 2, 4])).unwrap().0;
    let f0 = report.fit.clone();
    let ro = RefineOptions { max_iterations: 1, ..RefineOptions::default() };
    let r = refine(&motor, &p, &Model::from_fit(&f0), Some(&f0), &fo, &ro, &|| {}).unwrap();
    let refinement = RefinementReport::new(&motor, &f0, &r);
    let want = RunReport { plan: p, fit: Some(report), refinement: Some(refinement) };
    assert_close(&got, &serde_json::to_value(&want).unwrap());

    // refine-summary.csv holds the report's summary rows.
    let csv = std::fs::read_to_string(cli_dir.join("refine-summary.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("quantity,order,unit,motor,identified,refined"));
    let rows = &want.refinement.as_ref().unwrap().summary;
    assert_eq!(lines.clone().count(), rows.len(), "{csv}");
    let num = |c: &str| (!c.is_empty()).then(|| c.parse::<f64>().unwrap());
    for (line, row) in lines.zip(rows) {
        let c: Vec<&str> = line.split(',').collect();
        assert_eq!(c.len(), 6, "{line}");
        assert_eq!((c[0], c[1].parse().ok(), c[2]), (row.quantity, row.order, row.unit), "{line}");
        assert_eq!([num(c[3]), num(c[4]), num(c[5])], [row.motor, row.identified, row.refined], "{line}");
    }
}

/// Runs the binary with `stdin`, killed (and the test failed) after two minutes: reading a
/// log twice used to wait forever on a FIFO.
fn stepdamp_with(args: &[&str], stdin: Stdio) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_stepdamp"))
        .args(args)
        .stdin(stdin)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("runs");
    let t0 = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t0.elapsed() > Duration::from_secs(120) {
            child.kill().unwrap();
            panic!("{args:?}: still running after 120 s (waiting on a log it opened twice?)");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn ok(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout.clone()).unwrap()
}

/// The one-line error of a failed run.
fn error(o: &Output) -> String {
    assert!(!o.status.success(), "succeeded: {}", String::from_utf8_lossy(&o.stdout));
    let e = String::from_utf8(o.stderr.clone()).unwrap();
    assert_eq!(e.trim_end().lines().count(), 1, "{e}");
    e
}

/// `identify` of `first` (as given) and the other logs, the profile it wrote.
fn identified(first: &str, rest: &[PathBuf], base: &Path, out: &Path, stdin: Stdio) -> String {
    let mut args = vec!["identify", "--log", first];
    for l in rest {
        args.extend(["--log", l.to_str().unwrap()]);
    }
    args.extend(["--motor", base.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    ok(&stepdamp_with(&args, stdin));
    std::fs::read_to_string(out).unwrap()
}

#[cfg(target_os = "linux")]
#[test]
fn a_fifo_and_standard_input_give_the_profile_the_file_gives() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (csv, base) = logs(d);
    let from_file = identified(csv[0].to_str().unwrap(), &csv[1..], &base, &d.join("file.toml"), Stdio::null());

    let fifo = d.join("log.fifo");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let writer = {
        let (fifo, src) = (fifo.clone(), csv[0].clone());
        // Opens the FIFO once and writes the log once; an error (the reader gone) ends it.
        std::thread::spawn(move || {
            let _ = std::fs::write(&fifo, std::fs::read(src).unwrap());
        })
    };
    let from_fifo = identified(fifo.to_str().unwrap(), &csv[1..], &base, &d.join("fifo.toml"), Stdio::null());
    if !writer.is_finished() {
        // A writer still waiting for a reader: release it (O_NONBLOCK, 0o4000 on Linux).
        use std::os::unix::fs::OpenOptionsExt;
        let _ = std::fs::OpenOptions::new().read(true).custom_flags(0o4000).open(&fifo);
    }
    writer.join().unwrap();
    assert_eq!(from_fifo, from_file);

    let stdin = Stdio::from(std::fs::File::open(&csv[0]).unwrap());
    let from_stdin = identified("-", &csv[1..], &base, &d.join("stdin.toml"), stdin);
    assert_eq!(from_stdin, from_file);
}

#[test]
fn a_log_given_twice_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = d.join("a.csv");
    std::fs::write(&log, "t_s,theta_fb_rad,i_q_a\n0,0,0\n").unwrap();
    let out = d.join("id.toml");
    let run = |logs: &[&str], stdin: Stdio| {
        let mut a = vec!["identify", "--motor", "patent-motor", "--out", out.to_str().unwrap()];
        for l in logs {
            a.extend(["--log", l]);
        }
        stepdamp_with(&a, stdin)
    };
    let l = log.to_str().unwrap();
    let again = d.join(".").join("a.csv");
    for second in [l, again.to_str().unwrap()] {
        let e = error(&run(&[l, second], Stdio::null()));
        assert!(e.contains(&format!("{second}: given twice (first as {l})")), "{e}");
    }
    let e = error(&run(&["-", "-"], Stdio::null()));
    assert!(e.contains("standard input (-) is given twice"), "{e}");
    #[cfg(unix)]
    {
        // Standard input redirected from a file given by name too.
        let e = error(&run(&[l, "-"], Stdio::from(std::fs::File::open(&log).unwrap())));
        assert!(e.contains("<stdin>: given twice") && e.contains(l), "{e}");
    }
    assert!(!out.exists());
}

#[test]
fn a_missing_log_is_one_line_naming_it_with_the_reason_once() {
    let dir = tempfile::tempdir().unwrap();
    let (log, out) = (dir.path().join("none.csv"), dir.path().join("id.toml"));
    let (l, o) = (log.to_str().unwrap(), out.to_str().unwrap());
    let e = error(&stepdamp_with(&["identify", "--log", l, "--motor", "patent-motor", "--out", o], Stdio::null()));
    assert!(e.starts_with(&format!("error: {l}: cannot read: ")), "{e}");
    assert_eq!(e.matches("os error").count(), 1, "{e}");
}

#[test]
fn the_accelerometer_plan_prints_runnable_m973_pairs_sized_by_the_model_and_a_sweep_per_direction() {
    let o =
        stepdamp(&["identify", "plan", "--accel", "--motor", "patent-motor", "--current-rms", "0.55", "--axis", "Y"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lines: Vec<&str> = out.lines().filter(|l| !l.starts_with(';')).collect();
    assert_eq!(lines.len(), 12 + 2, "{out}");
    assert!(lines[..12].iter().all(|l| l.starts_with("M973 Y F")), "{out}");
    // The sweeps `identify --accel` needs for the head and the ripple in N·m.
    assert_eq!(lines[12..], ["M974 Y A2 B4 R-8", "M974 Y A2 B4 R8"], "{out}");
    // patent-motor at 0.55 A RMS: order 2 is 12 mN·m at phase 0.7, so its trial is
    // 0.012/(0.3·0.778·4) = 0.01286 at A0.7.
    assert!(out.contains("M973 Y F2 R-6 H2 A0.7 B0.7 C0.01286 D0.01286"), "{out}");
    for (args, needle) in [
        (vec!["--current-rms", "0.55", "--axis", "Z"], "--axis Z: Prusa phase stepping has axes X and Y"),
        (vec!["--current-rms", "0.55", "--orders", "17"], "--orders 17"),
        (vec![], "the run current is needed"),
        (vec!["--current-rms", "0.55", "--format", "csv"], "does nothing with --accel"),
    ] {
        let mut a = vec!["identify", "plan", "--accel", "--motor", "patent-motor"];
        a.extend(args);
        let o = Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(&a).output().expect("runs");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(needle), "{a:?}: {err}");
    }
    let o = Command::new(env!("CARGO_BIN_EXE_stepdamp"))
        .args(["identify", "plan", "--motor", "patent-motor", "--axis", "X"])
        .output()
        .expect("runs");
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("do nothing without --accel"));
}
