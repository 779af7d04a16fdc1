//! `stepdamp export` / `import` / `sweep --table` end to end.

use std::process::{Command, Output};

fn stepdamp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs")
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr)
}

#[test]
fn prusa_export_writes_m973_and_files_that_import_back_to_the_profile() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.gcode");
    let o =
        stepdamp(&["export", "prusa", "--motor", "patent-motor", "--out", out.to_str().unwrap(), "--duration", "0.5"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("order  4 at"), "the prediction is printed: {}", text(&o));
    let g = std::fs::read_to_string(&out).unwrap();
    assert!(g.starts_with("M973 XF0,0 0.014035088,-1.1 "), "{g}");
    let fwd = dir.path().join("x.gcode.fwd.bin");
    assert_eq!(std::fs::read(&fwd).unwrap().len(), 168);
    let prof = dir.path().join("p.toml");
    let o = stepdamp(&[
        "import",
        "prusa",
        "--m972",
        fwd.to_str().unwrap(),
        "--motor",
        "patent-motor",
        "--current",
        "1.9",
        "--out",
        prof.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("order  4: A = 0.02000 N·m"), "{}", text(&o));
    // Exporting the imported profile gives the same bytes.
    let again = dir.path().join("y.gcode");
    let o = stepdamp(&[
        "export",
        "prusa",
        "--motor",
        prof.to_str().unwrap(),
        "--out",
        again.to_str().unwrap(),
        "--duration",
        "0",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(std::fs::read(dir.path().join("y.gcode.fwd.bin")).unwrap(), std::fs::read(&fwd).unwrap());
}

#[test]
fn klipper_export_reports_coverage_and_refuses_a_model_it_cannot_carry() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tmc.cfg");
    let o = stepdamp(&[
        "export",
        "klipper-tmc",
        "--motor",
        "patent-motor",
        "--out",
        out.to_str().unwrap(),
        "--duration",
        "0",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("order  2: wanted 0.0400 A, not expressible"), "{}", text(&o));
    assert!(std::fs::read_to_string(&out).unwrap().contains("driver_START_SIN90: "));
    // A profile with only orders 1 and 2: nothing fits, exit 1, no file.
    let base = std::fs::read_to_string(dir.path().join("tmc.cfg")).unwrap();
    assert!(!base.is_empty());
    let prof = dir.path().join("no4.toml");
    let show = stepdamp(&["motor", "show", "patent-motor"]);
    let toml = String::from_utf8(show.stdout).unwrap();
    let cut = toml.replacen("order = 4\namplitude_nm = 0.02\n", "order = 3\namplitude_nm = 0.02\n", 1);
    assert_ne!(cut, toml, "the preset's order-4 term is where the test expects it:\n{toml}");
    std::fs::write(&prof, cut).unwrap();
    let bad = dir.path().join("bad.cfg");
    let o = stepdamp(&["export", "klipper-tmc", "--motor", prof.to_str().unwrap(), "--out", bad.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("nothing fits"), "{}", text(&o));
    assert!(!bad.exists());
}

#[test]
fn sweep_replays_an_exported_table_next_to_the_other_laws() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("tmc.cfg");
    assert!(
        stepdamp(&[
            "export",
            "klipper-tmc",
            "--motor",
            "patent-motor",
            "--out",
            cfg.to_str().unwrap(),
            "--duration",
            "0"
        ])
        .status
        .success()
    );
    let out = dir.path().join("sweep");
    let o = stepdamp(&[
        "-q",
        "sweep",
        "--mode",
        "open-loop",
        "--compensation",
        "off,patent,angle,table",
        "--table",
        cfg.to_str().unwrap(),
        "--from",
        "4",
        "--to",
        "5",
        "--points",
        "2",
        "--duration",
        "0.6",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    for c in ["off", "patent", "angle", "table"] {
        assert!(csv.contains(&format!("open-loop,{c},")), "{c} missing:\n{csv}");
    }
    let o =
        stepdamp(&["-q", "sweep", "--mode", "open-loop", "--compensation", "table", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o).contains("--table"), "{}", text(&o));
}
