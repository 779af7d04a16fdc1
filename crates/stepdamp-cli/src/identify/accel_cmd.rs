//! `stepdamp identify --accel CAPTURE…`: the head and the motor's ripple in N·m from
//! accelerometer captures (docs/accelerometer.md#identifying-the-ripple-from-captures),
//! printed and written as the TOML of docs/files.md#identified-ripple-toml. Translation
//! only: `stepdamp_accel::ripple` reads and fits.

use super::args::check_output_dir;
use super::fit_cmd::FitArgs;
use crate::common::{load_motor, write_atomic};
use anyhow::{Result, anyhow, bail};
use serde::Serialize;
use std::f64::consts::TAU;
use std::io::Read;
use std::path::PathBuf;
use stepdamp_accel::capture::SETTLE_S;
use stepdamp_accel::klipper::segment::MIN_SEGMENT_S;
use stepdamp_accel::klipper::{KlipperOptions, Log, TrialShift};
use stepdamp_accel::ripple::{Interval95, RippleFit, RippleOptions, identify_ripple};
use stepdamp_accel::{Axis, Reconstruction};
use stepdamp_export::escape;
use stepdamp_export::prusa::Firmware;

/// The belt travel per revolution the pulley radius follows from (mm): `--mm-per-rev`'s range,
/// a pitch radius of 1–50 mm.
const MM_PER_REV_RANGE: (f64, f64) = (6.3, 314.0);

/// Runs `stepdamp identify --accel …`.
pub(super) fn run_accel_cmd(a: &FitArgs) -> Result<()> {
    let Some(motor) = &a.motor else { bail!("--motor is needed: the base profile (preset or TOML) with Km, Nr, J") };
    let Some(out) = &a.out else { bail!("--out is needed: where to write the identified ripple (TOML)") };
    if !a.logs.is_empty() {
        bail!("--log and --accel are two routes: give run logs or accelerometer captures, not both");
    }
    if a.report.is_some() || a.ff_on || a.sensorless || a.format != crate::common::Format::Text {
        bail!("--report, --ff-on, --sensorless and --format json go with --log, not --accel");
    }
    let Some(axis_arg) = &a.axis else { bail!("--axis is needed with --accel: X or Y (on CoreXY the A or B motor)") };
    let (axis, letter) = crate::accel::parse_axis(axis_arg)?;
    let run = a.current.run_current()?;
    let (lo, hi) = MM_PER_REV_RANGE;
    if !(a.mm_per_rev.is_finite() && (lo..=hi).contains(&a.mm_per_rev)) {
        bail!("--mm-per-rev {}: must be in {lo}..={hi} mm (a pulley pitch radius of 1-50 mm)", a.mm_per_rev);
    }
    let base = load_motor(motor)?;
    check_output_dir(out)?;
    let m = &base.motor;
    let o = RippleOptions {
        rotor_inertia_kg_m2: m.inertia_kg_m2,
        km_nm_per_a: m.km_nm_per_a,
        viscous_nm_s_per_rad: m.viscous_nm_s_per_rad,
        coulomb_friction_nm: m.coulomb_friction_nm,
        periods_per_block: a.periods_per_block,
        trial_scale: Firmware::V6_3_1.scale(),
        ..RippleOptions::new(u32::from(m.pole_pairs), a.mm_per_rev * 1e-3 / TAU, run.peak_a())
    };
    let r = Reconstruction {
        periods_per_rev: o.periods_per_rev,
        start_angle_rad: 0.0,
        first_sample_s: 0.0,
        mm_per_rev: a.mm_per_rev,
    };
    let fit = if klipper_logs(&a.accel)? {
        let logs = read_klipper_logs(a, axis, o.periods_per_rev)?;
        let segments: Vec<_> = logs.iter().flat_map(Log::segments).collect();
        if segments.is_empty() {
            bail!(
                "no stretch of steady motion in the Klipper logs (at least {MIN_SEGMENT_S} s between ramps, the first and last {SETTLE_S} s cut): move at constant speed or sweep slowly (docs/accelerometer.md#klippers-motion-analysis-logs)"
            );
        }
        let fit = identify_ripple(&segments, &r, &o)?;
        let n = logs.len();
        outln!(
            "{} stretches of {n} Klipper logs of axis {letter} on {} at {run}; belt {} mm/rev",
            segments.len(),
            base.name,
            a.mm_per_rev
        );
        fit
    } else {
        if !a.klipper_trial.is_empty() {
            bail!("--klipper-trial goes with Klipper logs (LOG.json.gz); Prusa captures carry their trial in M973");
        }
        let captures = crate::accel::read_captures(&a.accel, axis)?;
        let fit = identify_ripple(&captures, &r, &o)?;
        outln!("{} captures of axis {letter} on {} at {run}; belt {} mm/rev", captures.len(), base.name, a.mm_per_rev);
        fit
    };
    outln!("{fit}");
    let file = IdentifiedFile::new(&fit, &base.name, letter, run.peak_a());
    let text = format!(
        "# stepdamp identify --accel: the head and the motor's ripple at one run current, per direction\n\
         # (docs/files.md#identified-ripple-toml). Not a motor profile.\n{}",
        toml::to_string(&file)?
    );
    write_atomic(out, text.as_bytes())?;
    outln!("wrote {}", out.display());
    Ok(())
}

/// Whether the inputs are Klipper motion-analysis logs (a gzip header, `1f 8b`) rather than
/// Prusa captures (text); refuses a mix. A file that cannot be opened counts as a capture,
/// whose reader names it.
fn klipper_logs(paths: &[PathBuf]) -> Result<bool> {
    let gzip = |p: &PathBuf| {
        let mut magic = [0u8; 2];
        std::fs::File::open(p).and_then(|mut f| f.read_exact(&mut magic)).is_ok() && magic == [0x1f, 0x8b]
    };
    let kinds: Vec<bool> = paths.iter().map(gzip).collect();
    if kinds.iter().any(|&k| k) && !kinds.iter().all(|&k| k) {
        bail!("--accel: Klipper logs (gzip) and Prusa captures (text) mixed: give one kind");
    }
    Ok(kinds.first().copied().unwrap_or(false))
}

/// Every `--accel` Klipper log with its `--klipper-trial`, checked against the profile's
/// electrical periods per revolution.
fn read_klipper_logs(a: &FitArgs, axis: Axis, periods_per_rev: u32) -> Result<Vec<Log>> {
    let mut trials: Vec<(PathBuf, TrialShift)> = Vec::new();
    for t in &a.klipper_trial {
        let form = || format!("--klipper-trial {}: expected LOG=H,U,PHI (H 1..=16, U and PHI in rad)", escape::line(t));
        let (log, v) = t.rsplit_once('=').ok_or_else(|| anyhow!(form()))?;
        let f: Vec<&str> = v.split(',').map(str::trim).collect();
        let [h, u, phi] = f[..] else { bail!(form()) };
        let (Ok(harmonic), Ok(amplitude_rad), Ok(phase_rad)) = (h.parse(), u.parse(), phi.parse()) else {
            bail!(form())
        };
        let log = PathBuf::from(log);
        if !a.accel.contains(&log) {
            bail!(
                "--klipper-trial {}: {} is not one of the --accel logs",
                escape::line(t),
                escape::line(&log.display().to_string())
            );
        }
        trials.push((log, TrialShift { harmonic, amplitude_rad, phase_rad }));
    }
    let mut logs = Vec::new();
    for path in &a.accel {
        let trial = trials.iter().find(|(p, _)| p == path).map(|x| x.1);
        let log = stepdamp_accel::klipper::read_file(path, &KlipperOptions { axis, accelerometer: None, trial })?;
        if log.periods_per_rev() != periods_per_rev {
            bail!(
                "{}: full_steps_per_rotation {} is {} electrical periods per revolution, the profile's pole pairs {periods_per_rev}: a wrong --motor or --axis",
                log.source,
                log.full_steps_per_rotation,
                log.periods_per_rev()
            );
        }
        logs.push(log);
    }
    Ok(logs)
}

/// The file `identify --accel` writes (docs/files.md#identified-ripple-toml).
#[derive(Serialize)]
struct IdentifiedFile {
    motor: String,
    axis: String,
    current_peak_a: f64,
    captures: usize,
    blocks: usize,
    explained_share: f64,
    head: HeadSection,
    ripple: Vec<RippleRow>,
    not_identified: Vec<MissingRow>,
}

#[derive(Serialize)]
struct HeadSection {
    pulley_radius_m: f64,
    total_inertia_kg_m2: f64,
    total_inertia_95_kg_m2: [f64; 2],
    carriage_mass_kg: f64,
    carriage_mass_95_kg: [f64; 2],
    belt_hz: f64,
    belt_95_hz: [f64; 2],
    belt_damping_ratio: f64,
    belt_damping_ratio_95: [f64; 2],
    belt_stiffness_n_per_m: f64,
    rotor_damping_nm_s_per_rad: f64,
    rotor_damping_95_nm_s_per_rad: [f64; 2],
    shift_delay_s: f64,
    shift_delay_95_s: [f64; 2],
}

#[derive(Serialize)]
struct RippleRow {
    direction: &'static str,
    order: u32,
    amplitude_nm: f64,
    amplitude_95_nm: [f64; 2],
    phase_rad: f64,
    phase_95_rad: [f64; 2],
    radius95_nm: f64,
    blocks: usize,
    speeds_rev_s: [f64; 2],
    explained_share: f64,
}

#[derive(Serialize)]
struct MissingRow {
    direction: &'static str,
    order: u32,
    reason: String,
}

fn pair(i: Interval95) -> [f64; 2] {
    [i.low, i.high]
}

impl IdentifiedFile {
    fn new(f: &RippleFit, motor: &str, axis: char, current_peak_a: f64) -> Self {
        let h = &f.head;
        IdentifiedFile {
            motor: motor.into(),
            axis: axis.to_string(),
            current_peak_a,
            captures: f.captures,
            blocks: f.blocks,
            explained_share: f.explained_share,
            head: HeadSection {
                pulley_radius_m: f.axis.pulley_radius_m,
                total_inertia_kg_m2: h.total_inertia_kg_m2.value,
                total_inertia_95_kg_m2: pair(h.total_inertia_kg_m2),
                carriage_mass_kg: h.carriage_mass_kg.value,
                carriage_mass_95_kg: pair(h.carriage_mass_kg),
                belt_hz: h.belt_hz.value,
                belt_95_hz: pair(h.belt_hz),
                belt_damping_ratio: h.belt_damping_ratio.value,
                belt_damping_ratio_95: pair(h.belt_damping_ratio),
                belt_stiffness_n_per_m: h.belt_stiffness_n_per_m,
                rotor_damping_nm_s_per_rad: h.rotor_damping_nm_s_per_rad.value,
                rotor_damping_95_nm_s_per_rad: pair(h.rotor_damping_nm_s_per_rad),
                shift_delay_s: h.shift_delay_s.value,
                shift_delay_95_s: pair(h.shift_delay_s),
            },
            ripple: f
                .harmonics
                .iter()
                .map(|x| RippleRow {
                    direction: x.direction.name(),
                    order: x.order,
                    amplitude_nm: x.amplitude_nm.value,
                    amplitude_95_nm: pair(x.amplitude_nm),
                    phase_rad: x.phase_rad.value,
                    phase_95_rad: pair(x.phase_rad),
                    radius95_nm: x.radius95_nm,
                    blocks: x.blocks,
                    speeds_rev_s: [x.speeds_rev_s.0, x.speeds_rev_s.1],
                    explained_share: x.explained_share,
                })
                .collect(),
            not_identified: f
                .not_identified
                .iter()
                .map(|x| MissingRow { direction: x.direction.name(), order: x.order, reason: x.reason.clone() })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{IdentifyArgs, run};
    use crate::Global;
    use stepdamp_accel::{Axis, Gcode, TrialSweep};
    use stepdamp_printer::SimulatedPrinter;

    const Q: Global = Global { quiet: true };
    const MOTOR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles/patent-motor-real.toml");

    fn args(v: &[&str]) -> IdentifyArgs {
        use clap::Parser;
        #[derive(Parser)]
        struct W {
            #[command(flatten)]
            a: IdentifyArgs,
        }
        W::try_parse_from(std::iter::once("identify").chain(v.iter().copied())).unwrap().a
    }

    /// The plan's captures on the simulated printer at 0.9 A: an M973 H4 pair (C0, C0.03) at 2 rev/s per
    /// direction and, with `sweeps`, an M974 A2 B4 R±8 per direction, in one session log.
    fn session(dir: &std::path::Path, sweeps: bool) -> String {
        let p = SimulatedPrinter::new(stepdamp_sim::Profile::from_file(std::path::Path::new(MOTOR)).unwrap(), 0.9);
        let mut g: Vec<Gcode> = Vec::new();
        for revs in [-6.0, 6.0] {
            for mag in [0.0, 0.03] {
                let trial = TrialSweep { harmonic: 4, pha_start: 0.0, pha_end: 0.0, mag_start: mag, mag_end: mag };
                g.push(Gcode::ParamSweep { axis: Axis::X, speed: 2.0, revs, trial });
            }
            if sweeps {
                g.push(Gcode::SpeedSweep { axis: Axis::X, start_speed: 2.0, end_speed: 4.0, revs: 8.0 * revs / 6.0 });
            }
        }
        let mut text = String::new();
        for (seed, g) in g.iter().enumerate() {
            let p = SimulatedPrinter { seed: seed as u64, ..p.clone() };
            text += &format!("Send: {g}\n{}", p.capture(g).unwrap());
        }
        let path = dir.join("session.log");
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_string()
    }

    #[test]
    fn identify_accel_writes_the_head_and_the_ripple_per_direction() {
        let dir = tempfile::tempdir().unwrap();
        let log = session(dir.path(), true);
        let out = dir.path().join("ripple.toml");
        let o = out.to_str().unwrap();
        run(args(&["--accel", &log, "--motor", MOTOR, "--axis", "X", "--current", "0.9", "--out", o]), &Q).unwrap();
        let v: toml::Table = toml::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        let belt = v["head"]["belt_hz"].as_float().unwrap();
        assert!((belt / stepdamp_printer::HeadModel::default().belt_hz() - 1.0).abs() < 0.1, "{belt}");
        let rows = v["ripple"].as_array().unwrap();
        for dir in ["forward", "backward"] {
            let row = rows.iter().find(|r| r["direction"].as_str() == Some(dir) && r["order"].as_integer() == Some(4));
            let a = row.unwrap()["amplitude_nm"].as_float().unwrap();
            // motor ripple --motor patent-motor-real --id 0.9 --iq 0: order 4 is 32.9 mN·m.
            assert!((a / 0.0329 - 1.0).abs() < 0.1, "{dir}: {a}");
        }
        assert!(v["explained_share"].as_float().unwrap() > 0.9);
        assert!(v["not_identified"].as_array().unwrap().iter().any(|r| r["order"].as_integer() == Some(16)));
    }

    #[test]
    fn identify_accel_reads_klipper_logs_and_their_trial() {
        use stepdamp_printer::KlipperSetup;
        let dir = tempfile::tempdir().unwrap();
        let p = SimulatedPrinter::new(stepdamp_sim::Profile::from_file(std::path::Path::new(MOTOR)).unwrap(), 0.9);
        let at_2 = |revs: f64, mag: f64| {
            let trial = TrialSweep { harmonic: 4, pha_start: 0.0, pha_end: 0.0, mag_start: mag, mag_end: mag };
            Gcode::ParamSweep { axis: Axis::X, speed: 2.0, revs, trial }
        };
        let sweep = |revs| Gcode::SpeedSweep { axis: Axis::X, start_speed: 2.0, end_speed: 4.0, revs };
        // The table carries 0.12·sin(4·θe) (Prusa's H4 C0.03) in the second log only.
        let logs = [
            ("plain.json.gz", vec![sweep(8.0), sweep(-8.0), at_2(6.0, 0.0), at_2(-6.0, 0.0)], 1),
            ("trial.json.gz", vec![at_2(6.0, 0.03), at_2(-6.0, 0.03)], 2),
        ];
        let mut paths = Vec::new();
        for (name, moves, seed) in logs {
            let log = SimulatedPrinter { seed, ..p.clone() }.motan_log(&moves, &KlipperSetup::default()).unwrap();
            let path = dir.path().join(name);
            std::fs::write(&path, log.json_gz).unwrap();
            paths.push(path.to_str().unwrap().to_string());
        }
        let out = dir.path().join("ripple.toml");
        let trial = format!("{}=4,0.12,0", paths[1]);
        let a = ["--accel", &paths[0], &paths[1], "--klipper-trial", &trial, "--motor", MOTOR, "--axis", "X"];
        run(args(&[&a[..], &["--current", "0.9", "--out", out.to_str().unwrap()]].concat()), &Q).unwrap();
        let v: toml::Table = toml::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        let rows = v["ripple"].as_array().unwrap();
        for dir in ["forward", "backward"] {
            let row = rows.iter().find(|r| r["direction"].as_str() == Some(dir) && r["order"].as_integer() == Some(4));
            let a = row.unwrap()["amplitude_nm"].as_float().unwrap();
            // motor ripple --motor patent-motor-real --id 0.9 --iq 0: order 4 is 32.9 mN·m.
            assert!((a / 0.0329 - 1.0).abs() < 0.1, "{dir}: {a}");
        }
        assert_eq!(v["captures"].as_integer(), Some(6), "one stretch per move");
        let mixed = ["--accel", &paths[0], "x.log", "--motor", MOTOR, "--axis", "X", "--current", "0.9", "--out"];
        let e = run(args(&[&mixed[..], &[out.to_str().unwrap()]].concat()), &Q).unwrap_err().to_string();
        assert!(e.contains("Klipper logs (gzip) and Prusa captures (text) mixed") && !e.contains('\n'), "{e}");
    }

    #[test]
    fn without_a_sweep_the_head_is_ill_determined_and_nothing_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let log = session(dir.path(), false);
        let out = dir.path().join("ripple.toml");
        let o = out.to_str().unwrap();
        let e = run(args(&["--accel", &log, "--motor", MOTOR, "--axis", "X", "--current", "0.9", "--out", o]), &Q)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("ill-determined: ") && !e.contains('\n'), "{e}");
        assert!(!out.exists());
    }

    #[test]
    fn bad_arguments_are_one_line_errors_naming_the_option() {
        let o = "/nonexistent-dir/x.toml";
        let cases: [(&[&str], &str); 4] = [
            (&["--accel", "a.log", "--motor", MOTOR, "--current", "0.9", "--out", o], "--axis is needed"),
            (&["--accel", "a.log", "--motor", MOTOR, "--axis", "Z", "--current", "0.9", "--out", o], "--axis Z"),
            (&["--accel", "a.log", "--motor", MOTOR, "--axis", "X", "--out", o], "the run current is needed"),
            (
                &[
                    "--accel",
                    "a.log",
                    "--motor",
                    MOTOR,
                    "--axis",
                    "X",
                    "--current",
                    "0.9",
                    "--mm-per-rev",
                    "2",
                    "--out",
                    o,
                ],
                "--mm-per-rev 2: must be in 6.3..=314 mm",
            ),
        ];
        for (a, want) in cases {
            let e = run(args(a), &Q).unwrap_err().to_string();
            assert!(e.contains(want) && !e.contains('\n'), "{e}");
        }
        let dir = tempfile::tempdir().unwrap();
        let o = dir.path().join("x.toml");
        let a = [
            "--accel",
            "missing.log",
            "--motor",
            MOTOR,
            "--axis",
            "X",
            "--current",
            "0.9",
            "--out",
            o.to_str().unwrap(),
        ];
        let e = run(args(&a), &Q).unwrap_err().to_string();
        assert!(e.contains("missing.log"), "{e}");
    }
}
