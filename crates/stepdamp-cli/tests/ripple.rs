//! `stepdamp motor ripple`: the ripple of a profile at an operating point, as the library
//! computes it (stepdamp_profile::ripple), in text, JSON and CSV.

use std::process::{Command, Output};

fn stepdamp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs")
}

fn stdout(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The patent motor with a 1.5 % third flux harmonic and a 4 % phase imbalance.
fn real_motor(dir: &std::path::Path) -> String {
    let base = stdout(&stepdamp(&["motor", "show", "patent-motor"]));
    let toml: String = base.lines().filter(|l| !l.starts_with('#')).collect::<Vec<_>>().join("\n");
    let toml = toml.replacen(
        "\n[drive]",
        "\n[motor.flux]\nphase_b_gain = 0.04\n\n[[motor.flux.harmonic]]\norder = 3\nratio = 0.015\nphase_rad = 0.5\n\n[drive]",
        1,
    );
    let path = dir.join("real.toml");
    std::fs::write(&path, toml).unwrap();
    path.to_str().unwrap().to_string()
}

fn harmonic(v: &serde_json::Value, part: &str, order: u64) -> (f64, f64) {
    let h = v[part].as_array().unwrap().iter().find(|h| h["order"] == order).unwrap();
    (h["amplitude_nm"].as_f64().unwrap(), h["phase_rad"].as_f64().unwrap())
}

#[test]
fn ripple_json_of_a_real_motor_grows_with_current_and_keeps_the_detent() {
    let dir = tempfile::tempdir().unwrap();
    let m = real_motor(dir.path());
    let at = |id: &str| -> serde_json::Value {
        serde_json::from_str(&stdout(&stepdamp(&[
            "motor", "ripple", "--motor", &m, "--id", id, "--iq", "0", "--format", "json",
        ])))
        .unwrap()
    };
    let (full, half) = (at("1.9"), at("0.95"));
    // Detent: patent-motor's 20 mN·m at order 4, the same at both currents.
    assert!((harmonic(&full, "detent", 4).0 - 0.020).abs() < 1e-12);
    assert_eq!(full["detent"], half["detent"]);
    // Current part at order 4: 3·h3·Km·I, order 2: g·Km·I/2 (docs/design.md, to first order:
    // the cross terms are within g·3h3·Km·I), and exactly proportional to I.
    let (km, i, h3, g) = (0.3, 1.9, 0.015, 0.04);
    let second_order = g * 3.0 * h3 * km * i;
    assert!((harmonic(&full, "current", 4).0 - 3.0 * h3 * km * i).abs() < second_order, "{full}");
    assert!((harmonic(&full, "current", 2).0 - g * km * i / 2.0).abs() < second_order, "{full}");
    for k in [2, 4] {
        assert!((harmonic(&half, "current", k).0 - harmonic(&full, "current", k).0 / 2.0).abs() < 1e-12);
    }
    assert!(full["harmonics"].as_array().unwrap().len() >= 8);
}

#[test]
fn ripple_csv_has_units_in_the_header_and_one_row_per_order() {
    let o = stepdamp(&["motor", "ripple", "--motor", "patent-motor", "--id", "1.9", "--iq", "0", "--format", "csv"]);
    let text = stdout(&o);
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "order,total_amplitude_nm,total_phase_rad,detent_amplitude_nm,detent_phase_rad,current_amplitude_nm,current_phase_rad"
    );
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 8);
    assert!(rows[3].starts_with("4,0.02,"), "{}", rows[3]);
}

#[test]
fn ripple_text_names_the_operating_point_and_refuses_currents_beyond_the_limit() {
    let text = stdout(&stepdamp(&["motor", "ripple", "--motor", "patent-motor", "--id", "0", "--iq", "-0.5"]));
    assert!(text.contains("i_d = 0 A, i_q = -0.5 A"), "{text}");
    let o = stepdamp(&["motor", "ripple", "--motor", "patent-motor", "--id", "1e9", "--iq", "0"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && !err.contains("panicked"), "{err}");
    assert!(err.contains("--id 1e9 A: must be in [-"), "{err}");
    assert_eq!(err.lines().filter(|l| !l.is_empty()).count(), 1, "{err}");
}

#[test]
fn a_flux_profile_exported_at_the_run_current_cancels_the_ripple_that_grows_with_it() {
    // docs/profiles/patent-motor-real.toml: at 1.9 A the 4th-order ripple is 47 mN·m, 27 of
    // them from the flux harmonics. The exported table carries the total ripple at the run
    // current; the prediction simulates the motor with its flux.
    let dir = tempfile::tempdir().unwrap();
    let motor = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles/patent-motor-real.toml");
    let out = dir.path().join("x.gcode");
    let o = stepdamp(&["export", "prusa", "--motor", motor, "--current", "1.9", "--out", out.to_str().unwrap()]);
    let text = stdout(&o);
    let line = text.lines().find(|l| l.trim_start().starts_with("order  4")).expect("order 4 predicted");
    let db: f64 = line.split('(').nth(1).unwrap().split(" dB").next().unwrap().parse().unwrap();
    assert!(db >= 20.0, "order 4: {db} dB lower, expected at least 20: {text}");
}

#[test]
fn an_export_for_a_flux_motor_is_predicted_in_both_directions_and_reports_the_worse() {
    // The flux harmonics make the motor asymmetric in the direction of travel: on
    // patent-motor-real the backward order-4 resonance is the larger (12.84 against
    // 12.58 rad/s p-p without correction), so the row must come from a negative speed.
    let dir = tempfile::tempdir().unwrap();
    let motor = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles/patent-motor-real.toml");
    let out = dir.path().join("x.gcode");
    let o = stepdamp(&["export", "prusa", "--motor", motor, "--current", "1.9", "--out", out.to_str().unwrap()]);
    let text = stdout(&o);
    let line = text.lines().find(|l| l.trim_start().starts_with("order  4")).expect("order 4 predicted");
    let speed: f64 = line.split(" at ").nth(1).unwrap().split(" rad/s").next().unwrap().trim().parse().unwrap();
    assert!(speed < 0.0, "the worse direction is backward: {text}");
    // Without flux the motor is symmetric: forward runs only, as before.
    let o =
        stepdamp(&["export", "prusa", "--motor", "patent-motor", "--current", "1.9", "--out", out.to_str().unwrap()]);
    let text = stdout(&o);
    assert!(text.lines().filter(|l| l.trim_start().starts_with("order")).all(|l| !l.contains(" at  -")), "{text}");
}
