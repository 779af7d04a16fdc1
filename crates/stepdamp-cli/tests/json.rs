//! `--format json` prints exactly the library's result types: each test computes the result
//! with the library and compares it with what the binary printed.

use serde_json::Value;
use std::process::Command;
use stepdamp_core::Mode;
use stepdamp_profile::{MotorFigures, MotorShow, Profile};
use stepdamp_sim::{Compensation, RunSpec, SimOptions, SweepSpec, SweepSummary, linear_grid, sweep};

fn json_of(args: &[&str]) -> Value {
    let o = Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8(o.stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "one line of JSON: {text}");
    serde_json::from_str(&text).unwrap()
}

/// Equal, numbers to the last digit or two (serde_json's default parser rounds the last bit).
fn assert_same(got: &Value, want: &Value) {
    match (got, want) {
        (Value::Number(a), Value::Number(b)) => {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            assert!((a - b).abs() <= 1e-14 * a.abs().max(b.abs()), "{a} vs {b}");
        }
        (Value::Array(a), Value::Array(b)) => {
            assert_eq!(a.len(), b.len(), "{got} vs {want}");
            a.iter().zip(b).for_each(|(x, y)| assert_same(x, y));
        }
        (Value::Object(a), Value::Object(b)) => {
            assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
            a.iter().for_each(|(k, x)| assert_same(x, &b[k]));
        }
        _ => assert_eq!(got, want),
    }
}

#[test]
fn resonance_json_is_the_library_motor_figures() {
    let got = json_of(&["resonance", "--motor", "nema23-57mm", "--format", "json"]);
    let want = serde_json::to_value(MotorFigures::of(&Profile::preset("nema23-57mm").unwrap())).unwrap();
    assert_same(&got, &want);
    assert!(got["resonances"][0]["order"] == 4, "{got}");
}

#[test]
fn motor_show_json_is_the_profile_and_its_figures() {
    let got = json_of(&["motor", "show", "patent-motor", "--format", "json"]);
    let p = Profile::preset("patent-motor").unwrap();
    let want = serde_json::to_value(MotorShow { figures: MotorFigures::of(&p), profile: p }).unwrap();
    assert_same(&got, &want);
}

#[test]
fn sweep_json_is_the_library_sweep_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let args = "--quiet sweep --mode open-loop --compensation off,patent --from 4 --to 9 --points 3 --duration 0.3 \
                --format json --out";
    let mut all: Vec<&str> = args.split_whitespace().collect();
    all.push(out.to_str().unwrap());
    let got = json_of(&all);
    // The same sweep through the library: the CLI's run shape for --duration 0.3.
    let motor = Profile::preset("patent-motor").unwrap();
    let spec = SweepSpec {
        speeds_rad_s: linear_grid(4.0, 9.0, 3).unwrap(),
        modes: vec![Mode::OpenLoop],
        compensations: vec![Compensation::Off, Compensation::Patent],
        run: RunSpec::for_duration(4.0, 0.3),
        options: SimOptions::default(),
        table: None,
    };
    let rows = sweep(&motor, &motor, &spec, &|| {}).unwrap();
    let want = serde_json::to_value(SweepSummary::new(&motor, &rows)).unwrap();
    assert_same(&got, &want);
    assert_eq!(got["modes"][0]["mode"], "open-loop");
    assert_eq!(got["modes"][0]["compensations"][1]["compensation"], "patent");
}
