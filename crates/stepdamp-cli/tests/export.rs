//! `stepdamp export` / `import` / `sweep --table` end to end.

use std::process::{Command, Output};

fn stepdamp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs")
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr)
}

fn lines_of(path: &std::path::Path) -> Vec<String> {
    std::fs::read_to_string(path).unwrap().lines().map(str::to_string).collect()
}

/// The read-back a printer on firmware >= 6.3.1 prints for `M971 X F` and `M971 X B`
/// (`M971 X F I0 M0.00000 P0.00000`, 5 decimals), as an OctoPrint terminal shows it.
fn readback_of(gcode: &[String]) -> String {
    let mut t = String::from("Send: M971 X F\r\n");
    for l in gcode.iter().filter(|l| l.starts_with("M971 ")) {
        let f: Vec<&str> = l.split(' ').collect();
        let (m, p): (f64, f64) = (f[4][1..].parse().unwrap(), f[5][1..].parse().unwrap());
        t += &format!("Recv: M971 {} {} {} M{m:.5} P{p:.5}\r\n", f[1], f[2], f[3]);
    }
    t + "Recv: ok\r\n"
}

#[test]
fn prusa_export_writes_m970_m971_for_firmware_6_3_1_and_its_read_back_imports_to_the_profile() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.gcode");
    let o = stepdamp(&[
        "export",
        "prusa",
        "--motor",
        "patent-motor",
        "--current",
        "1.9",
        "--out",
        out.to_str().unwrap(),
        "--duration",
        "0.5",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("order  4 at"), "the prediction is printed: {}", text(&o));
    let g = lines_of(&out);
    let code: Vec<&String> = g.iter().filter(|l| !l.starts_with(';')).collect();
    assert_eq!(code[0], "M970 X0");
    assert_eq!(code[code.len() - 1], "M970 X1");
    assert_eq!(code.len(), 2 + 2 * 17, "every item of both directions: {g:?}");
    // 6.3.1's scale: A/(Km·I)/4 = 0.02/(0.3·1.9)/4 = 0.0087719 rad.
    assert!(g.contains(&"M971 X F I4 M0.008772 P0".to_string()), "{g:?}");
    assert!(g.contains(&"M971 X B I2 M0.005263 P0.7".to_string()), "{g:?}");
    let head = g[..6].join("\n");
    for want in
        [">= 6.3.1", "axis X", "patent-motor", "1.900 A peak", "1.344 A RMS", "F (forward) and B", "kept: 100.0 %"]
    {
        assert!(head.contains(want), "{want} missing in\n{head}");
    }
    assert_eq!(std::fs::read(dir.path().join("x.gcode.fwd.bin")).unwrap().len(), 168);
    // The printer's read-back of it, through a host's terminal, gives the profile again.
    for (dirs, keep) in [("F and B", ""), ("F only", " F "), ("B only", " B ")] {
        let rb: String = readback_of(&g)
            .lines()
            .filter(|l| !l.starts_with("Recv: M971") || keep.is_empty() || l.contains(keep))
            .map(|l| format!("{l}\n"))
            .collect();
        let rbf = dir.path().join("readback.txt");
        std::fs::write(&rbf, rb).unwrap();
        let prof = dir.path().join("p.toml");
        let o = stepdamp(&[
            "import",
            "prusa",
            "--readback",
            rbf.to_str().unwrap(),
            "--motor",
            "patent-motor",
            "--current",
            "1.9",
            "--out",
            prof.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o));
        assert!(text(&o).contains(dirs) && text(&o).contains("axis X"), "{}", text(&o));
        // Within the rounding of the exported (1e-6) and printed (1e-5) decimals, in 6.3.1's
        // scale 4: A within 4·(0.5e-6 + 0.5e-5)·Km·I = 1.3e-5 N·m, φ within 1e-5 rad (plus
        // the 5 decimals of stepdamp's own print).
        for (k, a, ph) in [(1, 0.008, -1.1), (2, 0.012, 0.7), (4, 0.02, 0.0)] {
            let l = text(&o).lines().find(|l| l.starts_with(&format!("order  {k}: A = "))).unwrap().to_string();
            let v: Vec<f64> = l.split(['=', ' ']).filter_map(|x| x.trim_start_matches('+').parse().ok()).collect();
            assert!((v[0] - a).abs() <= 1.3e-5 + 5e-6 && (v[1] - ph).abs() <= 1e-5 + 5e-5, "{k}: {l} {v:?}");
        }
    }
}

#[test]
fn prusa_export_keeps_the_6_2_form_on_request_and_imports_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.gcode");
    let o = stepdamp(&[
        "export",
        "prusa",
        "--motor",
        "patent-motor",
        "--current",
        "1.9",
        "--firmware",
        "6.2",
        "--out",
        out.to_str().unwrap(),
        "--duration",
        "0",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let g = lines_of(&out);
    assert!(g[0].contains("6.2 (M973)"), "{g:?}");
    assert_eq!(g[6], "M973 XF0,0 0.014035,-1.1 0.021053,0.7 0,0 0.035088,0");
    assert!(g[7].starts_with("M973 XB0,0 "));
    let fwd = dir.path().join("x.gcode.fwd.bin");
    let prof = dir.path().join("p.toml");
    let o = stepdamp(&[
        "import",
        "prusa",
        "--m972",
        fwd.to_str().unwrap(),
        "--firmware",
        "6.2",
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
        "--current",
        "1.9",
        "--firmware",
        "6.2",
        "--out",
        again.to_str().unwrap(),
        "--duration",
        "0",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(std::fs::read(dir.path().join("y.gcode.fwd.bin")).unwrap(), std::fs::read(&fwd).unwrap());
}

/// Presets (from `stepdamp motor list`) and the profiles in docs/profiles.
fn every_profile() -> Vec<(String, f64)> {
    let list = stepdamp(&["motor", "list"]);
    assert!(list.status.success());
    let mut out: Vec<(String, f64)> = String::from_utf8(list.stdout)
        .unwrap()
        .lines()
        .filter_map(|l| {
            let name = l.split_whitespace().next()?;
            let i = l.split(", I ").nth(1)?.split(' ').next()?.parse().ok()?;
            Some((name.to_string(), i))
        })
        .collect();
    assert!(out.len() >= 4, "{out:?}");
    let docs = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles");
    for e in std::fs::read_dir(docs).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            out.push((p.display().to_string(), 1.9));
        }
    }
    out
}

#[test]
fn no_exported_prusa_line_is_longer_than_95_characters_with_a_hosts_line_number_and_checksum() {
    let dir = tempfile::tempdir().unwrap();
    for (motor, peak) in every_profile() {
        for (flag, i, fw) in [
            ("--current", peak.to_string(), "6.3.1"),
            ("--current-rms", "0.55".to_string(), "6.3.1"),
            ("--current", peak.to_string(), "6.2"),
        ] {
            let out = dir.path().join("l.gcode");
            let _ = std::fs::remove_file(&out);
            let o = stepdamp(&[
                "export",
                "prusa",
                "--motor",
                &motor,
                flag,
                &i,
                "--firmware",
                fw,
                "--out",
                out.to_str().unwrap(),
                "--duration",
                "0",
            ]);
            if fw == "6.2" && !o.status.success() {
                // The 6.2 form has one line per direction: refused when too long, never cut.
                assert!(text(&o).contains("the printer keeps 95"), "{motor}: {}", text(&o));
                assert!(!out.exists());
                continue;
            }
            assert!(o.status.success(), "{motor} {flag} {i} {fw}: {}", text(&o));
            for l in lines_of(&out) {
                // "N12345 " + line + "*123": what a host sends.
                let sent = format!("N12345 {l}*123");
                assert!(sent.len() <= 95, "{motor} {fw}: {} characters sent: {sent}", sent.len());
            }
        }
    }
}

#[test]
fn current_is_the_peak_and_current_rms_the_rms_root_two_apart() {
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &[&str], name: &str| {
        let out = dir.path().join(name);
        let mut a =
            vec!["export", "prusa", "--motor", "patent-motor", "--out", out.to_str().unwrap(), "--duration", "0"];
        a.extend_from_slice(args);
        let o = stepdamp(&a);
        (o, out)
    };
    let (o, peak) = run(&["--current", "1.9"], "peak.gcode");
    assert!(o.status.success(), "{}", text(&o));
    let rms = std::f64::consts::SQRT_2.recip() * 1.9;
    let (o, r) = run(&["--current-rms", &rms.to_string()], "rms.gcode");
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(std::fs::read(&peak).unwrap(), std::fs::read(&r).unwrap(), "1.9 A peak is 1.9/√2 A RMS");
    // The same number as RMS is √2 more current: √2 less correction per ampere.
    let (o, r2) = run(&["--current-rms", "1.9"], "rms2.gcode");
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("2.687 A peak (current vector) = 1.900 A RMS per phase"), "{}", text(&o));
    let mag = |p: &std::path::Path| -> f64 {
        let g = lines_of(p);
        let l = g.iter().find(|l| l.starts_with("M971 X F I4 ")).unwrap().clone();
        l.split(' ').nth(4).unwrap()[1..].parse().unwrap()
    };
    let ratio = mag(&peak) / mag(&r2);
    assert!((ratio - std::f64::consts::SQRT_2).abs() < 2e-4, "{ratio}");
    // Exactly one of the two: neither is refused (export simplefoc alone takes none: its
    // feed-forward does not depend on the current), both is a usage error.
    let (o, none) = run(&[], "none.gcode");
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("the run current is needed: --current A (peak"), "{}", text(&o));
    assert!(!none.exists());
    let (o, _) = run(&["--current", "1", "--current-rms", "1"], "both.gcode");
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let help = text(&stepdamp(&["export", "--help"]));
    assert!(help.contains("PEAK of the current vector") && help.contains("RMS of each phase"), "{help}");
}

#[test]
fn an_out_of_range_correction_is_scaled_never_wrapped_with_the_share_kept_and_its_prediction() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("big.gcode");
    let o = stepdamp(&[
        "export",
        "prusa",
        "--motor",
        "patent-motor",
        "--current",
        "0.5",
        "--out",
        out.to_str().unwrap(),
        "--duration",
        "0.5",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let t = text(&o);
    assert!(t.contains("beyond the ±0.195 rad") && t.contains("scaled to 7"), "{t}");
    assert!(t.contains("simulated: open loop, table replay") && t.contains("order  4 at"), "{t}");
    let g = lines_of(&out);
    assert!(g.iter().any(|l| l.starts_with("; correction kept: 7")), "{g:?}");
    // It says from which run current the whole correction fits, and exported there it does.
    let at = t
        .lines()
        .find_map(|l| l.split("fits the table at a run current of ").nth(1))
        .and_then(|r| r.split(" A peak").next())
        .unwrap_or_else(|| panic!("no run current at which it fits: {t}"));
    let rms = t
        .lines()
        .find_map(|l| l.split("(current vector) = ").nth(1).filter(|_| l.contains("fits the table")))
        .and_then(|r| r.split(" A RMS").next())
        .unwrap_or_else(|| panic!("no RMS current at which it fits: {t}"));
    for (flag, value) in [("--current", at), ("--current-rms", rms)] {
        let whole = stepdamp(&[
            "export",
            "prusa",
            "--motor",
            "patent-motor",
            flag,
            value,
            "--out",
            out.to_str().unwrap(),
            "--duration",
            "0",
        ]);
        assert!(whole.status.success(), "{}", text(&whole));
        assert!(text(&whole).contains("correction kept: 100 %"), "{flag} {value}: {}", text(&whole));
    }
}

#[test]
fn import_prusa_refuses_an_endless_input_within_its_size_cap() {
    let dir = tempfile::tempdir().unwrap();
    let prof = dir.path().join("p.toml");
    let o = stepdamp(&[
        "import",
        "prusa",
        "--readback",
        "/dev/zero",
        "--motor",
        "patent-motor",
        "--current-rms",
        "0.65",
        "--out",
        prof.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("/dev/zero: more than 1048576 bytes"), "{}", text(&o));
    assert!(!prof.exists());
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
        "--current",
        "1.9",
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
    let o = stepdamp(&[
        "export",
        "klipper-tmc",
        "--motor",
        prof.to_str().unwrap(),
        "--current",
        "1.9",
        "--out",
        bad.to_str().unwrap(),
    ]);
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
            "--current",
            "1.9",
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

#[test]
fn accel_klipper_trial_writes_a_block_that_reads_back_and_names_its_trial_argument() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("trial.cfg");
    let o = stepdamp(&["accel", "klipper-trial", "--axis", "tmc2240 stepper_y", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let block = std::fs::read_to_string(&out).unwrap();
    let arg = text(&o).split("--klipper-trial TRIAL_LOG=").nth(1).unwrap().trim().to_string();
    assert!(arg.starts_with("4,0.12") && arg.ends_with(",0"), "{arg}");
    assert!(block.contains(&format!("TRIAL_LOG={arg}\n")) && block.contains("[tmc2240 stepper_y]\n"), "{block}");
    // `sweep --table` reads the block as it reads an exported correction.
    let t = stepdamp_export::tmc::parse_klipper(&block, "trial.cfg").unwrap();
    assert_eq!(t, stepdamp_export::tmc::ShiftTable::trial(4, 0.12).unwrap().registers);
    // A driver without a table, an order or a shift the table cannot turn: exit 1, one line, no file.
    for bad in [
        &["--axis", "tmc2209 stepper_x"][..],
        &["--axis", "tmc5160 stepper_x", "--harmonic", "2"],
        &["--axis", "tmc5160 stepper_x", "--shift-rad", "-0.4"],
        &["--axis", "tmc5160 stepper_x", "--harmonic", "8", "--shift-rad", "0.1"],
    ] {
        let none = dir.path().join("none.cfg");
        let o = stepdamp(&[&["accel", "klipper-trial", "--out", none.to_str().unwrap()][..], bad].concat());
        assert_eq!(o.status.code(), Some(1), "{bad:?}: {}", text(&o));
        assert_eq!(text(&o).trim().lines().count(), 1, "{bad:?}: {}", text(&o));
        assert!(!none.exists(), "{bad:?}");
    }
}
