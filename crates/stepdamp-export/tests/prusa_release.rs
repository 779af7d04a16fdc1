//! The Prusa export against the firmware users run (≥ 6.3.1), checked by a printer model
//! written here from the firmware's rules, not by the exporter's own code:
//!
//! - the grammar (tag v6.3.1: `lib/Marlin/Marlin/src/gcode/feature/phase_stepping/M97x.cpp`,
//!   `src/common/gcode/gcode_parser.cpp`, `gcode_basic_parser.cpp`): `;` starts a comment; a
//!   command letter and number; parameters are an upper-case letter, optional spaces, and a
//!   value of `0123456789+-.,` (each letter once); `M970 X0|X1` turns phase stepping off/on;
//!   `M971 X|Y F|B I<n> M<mag> P<pha>` writes item n only while the axis is off ("Phase-stepping
//!   must be disabled to modify its parameters.");
//! - the line length (`MAX_CMD_SIZE 96` on Core One, iX, MK4: 95 characters kept);
//! - the table arithmetic (`lut.cpp`, `common.hpp`, `phase_stepping_opts.h`): `mag_fixed =
//!   lround(mag·4096·256/2π)`, `pha_fixed = lround(pha·4096/2π)`, a 2¹⁵ quarter sine,
//!   `raw = Σ 4·mag_fixed·sin(n·4i + pha_fixed)`, shift = raw/2²³ rounded half away from
//!   zero, stored as `int8_t`.

use std::f64::consts::TAU;
use stepdamp_core::Compensation;
use stepdamp_export::{Correction, RunCurrent, predict, prusa};
use stepdamp_sim::Profile;

const UNIT: f64 = TAU / 4096.0;

/// The printer, as far as phase-stepping G-code goes.
struct Printer {
    enabled: [bool; 2],
    items: [[[(f32, f32); 17]; 2]; 2],
    written: [[[bool; 17]; 2]; 2],
    errors: Vec<String>,
}

impl Printer {
    fn new() -> Self {
        Printer {
            enabled: [true; 2],
            items: [[[(0.0, 0.0); 17]; 2]; 2],
            written: [[[false; 17]; 2]; 2],
            errors: vec![],
        }
    }

    fn feed(&mut self, text: &str) {
        for line in text.lines() {
            assert!(line.len() <= 95 - "N12345 ".len() - "*123".len(), "{} characters: {line}", line.len());
            let body = line.split(';').next().unwrap().trim();
            if body.is_empty() {
                continue;
            }
            let (cmd, rest) = body.split_at(body.find(' ').unwrap_or(body.len()));
            let mut p: [Option<String>; 26] = Default::default();
            let b = rest.as_bytes();
            let mut i = 0;
            while i < b.len() {
                if b[i] == b' ' {
                    i += 1;
                    continue;
                }
                assert!(b[i].is_ascii_uppercase(), "{line}: parameter letter expected");
                let k = usize::from(b[i] - b'A');
                i += 1;
                while i < b.len() && b[i] == b' ' {
                    i += 1;
                }
                let s = i;
                while i < b.len() && b"0123456789+-.,".contains(&b[i]) {
                    i += 1;
                }
                assert!(p[k].is_none(), "{line}: a letter twice");
                assert!(i - s < 32, "{line}: value too long");
                p[k] = Some(rest[s..i].to_string());
            }
            let flag = |c: u8| match p[usize::from(c - b'A')].as_deref() {
                None | Some("0") => false,
                Some("" | "1") => true,
                Some(v) => panic!("{line}: {v} is no bool"),
            };
            match cmd {
                "M970" => {
                    for (ax, c) in [(0, b'X'), (1, b'Y')] {
                        if p[usize::from(c - b'A')].is_some() {
                            self.enabled[ax] = flag(c);
                        }
                    }
                }
                "M971" => {
                    let get = |c: u8| p[usize::from(c - b'A')].clone();
                    let (Some(n), Some(m), Some(ph)) = (get(b'I'), get(b'M'), get(b'P')) else {
                        panic!("{line}: the export only writes items")
                    };
                    let ax = match (flag(b'X'), flag(b'Y')) {
                        (true, false) => 0,
                        (false, true) => 1,
                        _ => panic!("{line}: Syntax."),
                    };
                    let d = match (flag(b'F'), flag(b'B')) {
                        (true, false) => 0,
                        (false, true) => 1,
                        _ => panic!("{line}: Syntax."),
                    };
                    if self.enabled[ax] {
                        self.errors.push(format!("{line}: Phase-stepping must be disabled to modify its parameters."));
                        continue;
                    }
                    let n: usize = n.parse().unwrap();
                    assert!(n < 17, "{line}: Syntax.");
                    self.items[ax][d][n] = (m.parse().unwrap(), ph.parse().unwrap());
                    self.written[ax][d][n] = true;
                }
                other => panic!("{line}: {other} is not a phase-stepping write (M973 is a sweep since 6.3.1)"),
            }
        }
    }
}

/// `round_fixed` of `lut.cpp`.
fn round_fixed(v: i64, bits: u32) -> i64 {
    let h = 1i64 << (bits - 1);
    if v < 0 { -((-v + h) >> bits) } else { (v + h) >> bits }
}

/// The 2¹⁵ sine of `lut.cpp` over the 4096-unit period.
fn sin15(x: i64) -> i64 {
    let q = |i: i64| (32768.0 * f64::from(std::f32::consts::PI / 2.0 * i as f32 / 1024.0).sin()).round() as i64;
    let x = x.rem_euclid(4096);
    match x {
        0..=1024 => q(x),
        1025..=2048 => q(2048 - x),
        2049..=3072 => -q(x - 2048),
        _ => -q(4096 - x),
    }
}

/// The firmware's table of a spectrum: `(shift before the int8 store, stored int8)` per tick.
fn table(items: &[(f32, f32); 17]) -> Vec<(i64, i8)> {
    let fixed: Vec<(i64, i64)> = items
        .iter()
        .map(|&(m, p)| {
            let mf = (m * 4096.0 * 256.0 / (2.0 * std::f32::consts::PI)).round() as i64;
            let pf = (p * 4096.0 / (2.0 * std::f32::consts::PI)).round() as i64;
            (mf, pf)
        })
        .collect();
    (0..1024i64)
        .map(|i| {
            let mut raw = 0i64;
            for (n, &(mf, pf)) in fixed.iter().enumerate() {
                raw += 4 * mf * sin15(n as i64 * i * 4 + pf);
                assert!(raw.abs() <= i64::from(i32::MAX), "the firmware's int sum overflows");
            }
            let s = round_fixed(raw, 23);
            (s, s as i8)
        })
        .collect()
}

/// What the fixed point can be off before the final rounding, in table units: per
/// non-zero item, the rounding of mag_fixed (4·½·2¹⁵/2²³), of pha_fixed (4·|mag|·π/4096, as units), of the
/// 2¹⁵ sine (4·|mag_fixed|·½/2²³) and of the 6 written decimals (4·0.5e-6, as units).
fn fixed_point_slack(items: &[(f32, f32); 17]) -> f64 {
    items
        .iter()
        .filter(|&&(m, _)| m != 0.0)
        .map(|&(m, _)| {
            let mu = f64::from(m.abs()) / UNIT; // |mag| in table units
            4.0 * (0.5 / 256.0 + mu * (UNIT / 2.0) + mu * 256.0 * 0.5 / 8_388_608.0 + 0.5e-6 / UNIT)
        })
        .sum()
}

fn profiles() -> Vec<Profile> {
    let mut v: Vec<Profile> = ["patent-motor", "nema17-17hs4401", "nema23-57mm", "nema34-86mm"]
        .iter()
        .map(|n| Profile::preset(n).unwrap())
        .collect();
    v.push(
        Profile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles/patent-motor-identified.toml"))
            .unwrap(),
    );
    v
}

fn export(p: &Profile, current: RunCurrent) -> (prusa::Fitted, String, Correction) {
    let c = Correction::from_profile(p, Some(current.peak_a())).unwrap();
    let f = prusa::fit(&c, prusa::Firmware::V6_3_1).unwrap();
    let g = prusa::gcode::write(&f, 'X', &prusa::gcode::Header { profile: &p.name, current }).unwrap();
    (f, g, c)
}

#[test]
fn exported_gcode_turns_the_current_vector_by_the_intended_angle_at_every_tick() {
    for p in profiles() {
        // The profile's own current, the XL's 650 mA RMS and the Core One's 550 mA RMS: at the
        // printers' currents some motors need more than the table holds, and get `kept` of it.
        let currents = [p.drive.holding_current_a, 0.65 * std::f64::consts::SQRT_2, 0.55 * std::f64::consts::SQRT_2];
        for current in currents.map(|i| RunCurrent::from_peak(i).unwrap()) {
            let (f, g, c) = export(&p, current);
            eprintln!("{} at {current}: kept {:.3}", p.name, f.kept);
            let mut pr = Printer::new();
            pr.feed(&g);
            assert!(pr.errors.is_empty(), "{:?}", pr.errors);
            assert_eq!(pr.enabled, [true, true], "phase stepping back on");
            assert!(pr.written[0].iter().flatten().all(|&w| w), "every item of X written, the zero ones too");
            for d in 0..2 {
                let t = table(&pr.items[0][d]);
                let slack = fixed_point_slack(&pr.items[0][d]);
                assert!(slack < 0.15, "{slack}");
                let mut worst: f64 = 0.0;
                for (i, &(exact, stored)) in t.iter().enumerate() {
                    assert_eq!(exact, i64::from(stored), "{}: tick {i} wraps", p.name);
                    let want = f.kept * c.delta_rad(TAU * i as f64 / 1024.0) / UNIT;
                    worst = worst.max((f64::from(stored) - want).abs());
                }
                // Half a table unit (the firmware's final rounding) plus its fixed point.
                assert!(worst <= 0.5 + slack, "{} at {current}: {worst:.3} units off (slack {slack:.3})", p.name);
            }
        }
    }
}

/// What `M971 X F` and `M971 X B` print (`SERIAL_PRINT(…, 5)`), in an OctoPrint terminal.
fn readback(pr: &Printer, dirs: &[usize]) -> String {
    let mut t = String::from("Send: M971 X F\r\necho:busy: processing\r\n");
    for &d in dirs {
        for (n, &(m, p)) in pr.items[0][d].iter().enumerate() {
            t += &format!("Recv: M971 X {} I{n} M{m:.5} P{p:.5}\r\n", ['F', 'B'][d]);
        }
    }
    t + "Recv: ok\r\n"
}

#[test]
fn import_of_an_m971_read_back_reproduces_the_profiles_harmonics() {
    for p in profiles() {
        let current = RunCurrent::from_rms(0.65).unwrap();
        let (f, g, _) = export(&p, current);
        let mut pr = Printer::new();
        pr.feed(&g);
        for dirs in [&[0usize, 1][..], &[0], &[1]] {
            let (c, kind) = prusa::parse_text(&readback(&pr, dirs), None, "readback").unwrap();
            assert!(kind.contains("axis X"), "{kind}");
            let (q, spread) = prusa::import_profile(&p, &c, current.peak_a()).unwrap();
            assert_eq!(spread, 0.0);
            // The profile's ripple at the run current (its detent, plus the part that grows
            // with the current for a preset with [motor.flux]) times the share kept (1 where
            // the table holds it), within the written (1e-6) and printed (1e-5) decimals, in
            // the scale 4, as torque.
            let tol_a = 4.0 * (0.5e-6 + 0.5e-5) * p.motor.km_nm_per_a * current.peak_a();
            let total = stepdamp_sim::profile::ripple::ripple(&p, current.peak_a(), 0.0).unwrap();
            for h in total.harmonics.iter().filter(|h| h.amplitude_nm > 1e-9) {
                let Some(got) = q.motor.detent.iter().find(|g| g.order == h.order) else {
                    // An order the table's decimals round away.
                    assert!(f.kept * h.amplitude_nm <= tol_a, "{}: order {} {h:?} missing", p.name, h.order);
                    continue;
                };
                let dphi =
                    (got.phase_rad - h.phase_rad + 3.0 * std::f64::consts::PI).rem_euclid(TAU) - std::f64::consts::PI;
                let want = f.kept * h.amplitude_nm;
                assert!((got.amplitude_nm - want).abs() <= tol_a, "{}: order {} {got:?} vs {want}", p.name, h.order);
                assert!(dphi.abs() * want <= tol_a + 1e-5 * want, "{}: order {} phase {dphi}", p.name, h.order);
            }
        }
    }
}

#[test]
fn a_correction_beyond_the_int8_table_is_scaled_never_wrapped_and_predicted_as_scaled() {
    let p = Profile::preset("patent-motor").unwrap();
    let current = RunCurrent::from_peak(0.5).unwrap();
    let (f, g, c) = export(&p, current);
    assert!(f.kept < 0.9 && f.kept > 0.5, "{}", f.kept);
    assert!(g.contains(&format!("; correction kept: {:.1} %", 100.0 * f.kept)), "{g}");
    let mut pr = Printer::new();
    pr.feed(&g);
    let t = table(&pr.items[0][0]);
    let slack = fixed_point_slack(&pr.items[0][0]);
    for (i, &(exact, stored)) in t.iter().enumerate() {
        assert!(exact.abs() <= 127 && exact == i64::from(stored), "tick {i}: {exact} stored as {stored}");
        let want = f.kept * c.delta_rad(TAU * i as f64 / 1024.0) / UNIT;
        assert!((f64::from(stored) - want).abs() <= 0.5 + slack, "tick {i}");
    }
    // The unscaled items (what an exporter without the range check writes) wrap on the chip.
    let mut raw = prusa::Spectrum::default();
    for h in &p.motor.detent {
        raw.mag[usize::from(h.order)] = (h.amplitude_nm / p.motor.km_nm_per_a / 0.5 / 4.0) as f32;
        raw.pha[usize::from(h.order)] = h.phase_rad as f32;
    }
    let wrapped = raw.shifts(prusa::Firmware::V6_3_1);
    let exact = raw.shifts_exact(prusa::Firmware::V6_3_1).unwrap();
    assert!(exact.iter().zip(&wrapped).any(|(e, w)| *e != i64::from(*w)), "the unscaled table would wrap");
    // The prediction replays the scaled table the file makes (read back from the text).
    let (written, _) = prusa::parse_text(&g, None, "g").unwrap();
    assert_eq!(written, f.correction);
    let sim = p.edited("patent-motor at 0.5 A", |d| d.drive.holding_current_a = 0.5).unwrap();
    let wrapped_c = prusa::PrusaCorrection { forward: raw, backward: raw, firmware: prusa::Firmware::V6_3_1 };
    let comps = vec![
        ("scaled".to_string(), predict::config(&sim, Compensation::Table, Some(&written.table())).unwrap()),
        ("wrapped".to_string(), predict::config(&sim, Compensation::Table, Some(&wrapped_c.table())).unwrap()),
    ];
    let pr = predict::predict(&sim, &comps, 1.0).unwrap();
    eprint!("{}{}", pr[0], pr[1]);
    for (s, w) in pr[0].rows.iter().zip(&pr[1].rows) {
        assert!(s.reduction_db() > 0.0, "the scaled table helps at order {}: {s:?}", s.order);
        assert!(s.reduction_db() > w.reduction_db(), "and beats the wrapped one at order {}", s.order);
    }
}
