//! End-to-end tests of `stepdamp study`.

use std::process::Command;

const SPEC: &str = r#"
motor = "patent-motor"
variants = 6
seed = 3
[sweep]
compensations = ["patent", "estimated"]
orders = [4]
points = 1
duration_s = 0.4
[plant]
inertia_kg_m2 = { scale = [0.8, 1.5] }
detent_phase_rad = { add = [-0.2, 0.2] }
"#;

#[test]
fn study_writes_the_table_the_summary_and_the_cdf_plot() {
    let dir = tempfile::tempdir().unwrap();
    let spec = dir.path().join("study.toml");
    std::fs::write(&spec, SPEC).unwrap();
    let out = dir.path().join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_stepdamp"))
        .args(["study", "--spec", spec.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("6 variants of patent-motor"), "{stdout}");
    assert!(stdout.contains("open-loop estimated: holds ≥ 10x at every resonance in"), "{stdout}");
    let csv = std::fs::read_to_string(out.join("study.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 7, "header + one row per variant");
    assert!(lines[0].starts_with("variant,resistance_ohm,"), "{}", lines[0]);
    assert!(lines[0].contains("reduction_open-loop_patent_k4"), "{}", lines[0]);
    assert!(lines[1].starts_with("0,") && lines[6].starts_with("5,"));
    for f in ["study-cdf.png", "study-cdf.svg", "study-summary.json"] {
        assert!(out.join(f).metadata().unwrap().len() > 100, "{f}");
    }
}

#[test]
fn a_bad_spec_is_one_line_naming_the_file_and_the_key_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let spec = dir.path().join("bad.toml");
    std::fs::write(&spec, "motor = \"patent-motor\"\nvariants = 4\n[plant]\ninertia_kg_m2 = { scale = [0.0, 1.0] }\n")
        .unwrap();
    let out = dir.path().join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_stepdamp"))
        .args(["study", "--spec", spec.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("bad.toml") && err.contains("plant.inertia_kg_m2"), "{err}");
    assert!(!out.exists());
}
