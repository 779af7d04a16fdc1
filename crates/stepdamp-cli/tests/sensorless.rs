//! `stepdamp identify` on the sensorless route, end to end through the binary.

use std::path::Path;
use std::process::{Command, Output};

fn stepdamp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs")
}

fn text(o: &Output) -> (String, String) {
    (String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

/// A failed command: non-zero exit, one `error:` line naming `needle`, no panic.
fn assert_clean_error(o: &Output, needle: &str) {
    let (_, err) = text(o);
    assert!(!o.status.success(), "expected failure: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert!(lines.len() == 1 && lines[0].starts_with("error:") && err.contains(needle), "{err}");
}

#[test]
fn the_sensorless_plan_as_csv_has_the_documented_columns() {
    let o = stepdamp(&["identify", "plan", "--sensorless", "--motor", "patent-motor", "--format", "csv"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let mut lines = out.lines();
    assert_eq!(
        lines.next(),
        Some(
            "run,mode,speed_rad_s,duration_s,standstill_s,ramp_s,holding_current_a,d_current_a,servo_bandwidth_hz,velocity_filter_hz"
        )
    );
    let rows: Vec<Vec<String>> = lines.map(|l| l.split(',').map(str::to_string).collect()).collect();
    // Two speeds in both directions, then the turn pair (docs/sensorless.md#the-split-from-a-fast-run).
    assert_eq!(rows.len(), 6);
    for r in &rows {
        assert_eq!(
            (r[1].as_str(), &r[7..]),
            ("open-loop", &[String::new(), String::new(), String::new()][..]),
            "{r:?}"
        );
        let v: Vec<f64> = r[2..7].iter().map(|x| x.parse().unwrap()).collect();
        assert!(v[0].abs() > 0.1 && v[1] > v[2] + v[3] && v[2] >= 0.02, "{r:?}");
        assert_eq!(v[4], 1.9, "the open-loop runs hold patent-motor's holding current");
    }
    // Both directions at two speeds; the turn pair both ways at twice patent-motor's open-loop
    // natural frequency (844 rad/s electrical, 50 pole pairs: 33.76 rad/s), far above the others.
    let speed = |i: usize| rows[i][2].parse::<f64>().unwrap();
    assert!(speed(0) > 0.0 && speed(1) < 0.0);
    assert!((speed(4) - 33.76).abs() < 0.01 && (speed(5) + 33.76).abs() < 0.01, "{rows:?}");
    assert!((0..4).all(|i| speed(i).abs() < 0.1 * speed(4)), "{rows:?}");
}

/// The plan asks for runs at the holding current only, and says why (a second current would
/// show the same sum of the third and fifth harmonics).
#[test]
fn the_sensorless_plan_says_why_one_current_is_enough() {
    let o = stepdamp(&["identify", "plan", "--sensorless", "--motor", "patent-motor"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        out.lines().any(|l| l.starts_with("one current:")
            && l.contains("same sum")
            && l.contains("docs/sensorless.md#the-flux-shape-without-a-sensor")),
        "{out}"
    );
}

fn logs_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path().display().to_string())
        .filter(|p| p.contains("sensorless-") && p.ends_with(".csv"))
        .collect();
    v.sort();
    v
}

#[test]
fn run_then_identify_without_an_encoder_recovers_the_detent_and_trims_r() {
    let dir = tempfile::tempdir().unwrap();
    let runs = dir.path().join("runs");
    let o = stepdamp(&[
        "--quiet",
        "identify",
        "run",
        "--sensorless",
        "--motor",
        "patent-motor",
        "--periods",
        "8",
        "--current-noise",
        "0.005",
        "--out",
        runs.to_str().unwrap(),
    ]);
    let (_, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let logs = logs_in(&runs);
    assert_eq!(logs.len(), 6, "the plan's four runs and its turn pair");
    // What a drive without an encoder logs: no theta_fb_rad.
    let head = std::fs::read_to_string(&logs[0]).unwrap();
    assert_eq!(head.lines().next(), Some("t_s,theta_cmd_rad,i_a_a,i_b_a,v_a_v,v_b_v"));
    for f in ["plan.txt", "plan.csv", "base.toml", "identified.toml"] {
        assert!(runs.join(f).is_file(), "{f}");
    }
    // A datasheet base: R 10 % high, no detent.
    let base = dir.path().join("datasheet.toml");
    let toml = std::fs::read_to_string(runs.join("base.toml")).unwrap();
    let toml = toml.replace("resistance_ohm = 0.9", "resistance_ohm = 0.99");
    assert!(toml.contains("0.99"), "{toml}");
    std::fs::write(&base, toml).unwrap();
    let out = dir.path().join("id.toml");
    let mut args = vec!["identify", "--motor", base.to_str().unwrap(), "--out", out.to_str().unwrap()];
    for l in &logs {
        args.extend(["--log", l]);
    }
    let o = stepdamp(&args);
    let (stdout, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(stdout.contains("route: sensorless") && stdout.contains("R trimmed at standstill"), "{stdout}");
    // The turn pair is named and left out of the fit; patent-motor's flux is a sine, so its
    // X5 - X3 has nothing to split (not "the 88 % split stands": no split was written).
    assert!(
        stdout
            .lines()
            .any(|l| l.starts_with("turn runs, left out of the torque fit") && l.contains("sensorless-6-rev")),
        "{stdout}"
    );
    assert!(stdout.contains("nothing to split: the flux section has no third or fifth"), "{stdout}");
    let id = std::fs::read_to_string(&out).unwrap();
    let value = |key: &str| -> f64 {
        id.lines()
            .find_map(|l| l.strip_prefix(key))
            .and_then(|v| v.trim_start_matches([' ', '=']).split_whitespace().next())
            .unwrap()
            .parse()
            .unwrap()
    };
    assert!((value("resistance_ohm") / 0.9 - 1.0).abs() < 1e-3, "{id}");
    assert!(id.matches("[[motor.detent]]").count() == 3, "{id}");
    // The JSON report says which route ran.
    args.extend(["--format", "json"]);
    let (stdout, _) = text(&stepdamp(&args));
    assert!(stdout.starts_with("{\"route\":\"sensorless\""), "{stdout}");
}

#[test]
fn sensorless_misuse_fails_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let enc = d.join("enc.csv");
    let sl = d.join("sl.csv");
    std::fs::write(&enc, "t_s,theta_fb_rad,i_q_a\n0,0,0\n").unwrap();
    std::fs::write(&sl, "t_s,theta_cmd_rad,i_a_a,i_b_a,v_a_v,v_b_v\n0,0,1,0,0.9,0\n").unwrap();
    let out = d.join("id.toml");
    let o = |extra: &[&str]| {
        let mut a = vec!["identify", "--motor", "patent-motor", "--out", out.to_str().unwrap()];
        a.extend_from_slice(extra);
        stepdamp(&a)
    };
    // A mixed set is refused naming a log of each route (from their headers alone: the
    // one-row encoder log is too short to fit, and that is not what is said).
    let (e, s) = (enc.to_str().unwrap(), sl.to_str().unwrap());
    let mixed = format!(
        "{s} has no theta_fb_rad (a sensorless log), but {e} has theta_fb_rad (an encoder log): give logs of one route"
    );
    assert_clean_error(&o(&["--log", e, "--log", s]), &mixed);
    assert_clean_error(&o(&["--log", sl.to_str().unwrap(), "--ff-on"]), "--ff-on");
    // A sensorless log missing a voltage names it.
    std::fs::write(&sl, "t_s,theta_cmd_rad,i_a_a,i_b_a,v_a_v\n0,0,1,0,0.9\n").unwrap();
    assert_clean_error(&o(&["--log", sl.to_str().unwrap()]), "v_b_v");
    let r = stepdamp(&[
        "identify",
        "run",
        "--sensorless",
        "--refine",
        "--motor",
        "patent-motor",
        "--out",
        d.join("r").to_str().unwrap(),
    ]);
    assert_clean_error(&r, "--refine");
    assert!(!d.join("id.toml").exists() && !d.join("r").exists());
}
