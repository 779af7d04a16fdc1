//! `stepdamp identify --accel CAPTURE…`: the head and the motor's ripple in N·m from
//! accelerometer captures (docs/accelerometer.md#identifying-the-ripple-from-captures),
//! printed and written as the TOML of docs/files.md#identified-ripple-toml. Translation
//! only: `stepdamp_accel::sources` reads and fits, `stepdamp_accel::ripple::file` writes.

use super::args::check_output_dir;
use super::fit_cmd::FitArgs;
use crate::common::{load_motor, write_atomic};
use anyhow::{Result, bail};
use std::f64::consts::TAU;
use std::path::PathBuf;
use stepdamp_accel::Reconstruction;
use stepdamp_accel::klipper::{Kinematics, TrialShift};
use stepdamp_accel::ripple::file::RippleFile;
use stepdamp_accel::ripple::{MM_PER_REV_RANGE, RippleOptions};
use stepdamp_accel::sources::{self, Names, Sources};
use stepdamp_export::prusa::Firmware;

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
    let mut o = RippleOptions {
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
    let trials = klipper_trials(a)?;
    let sources = sources::read(&a.accel, axis, &trials, o.periods_per_rev, &NAMES)?;
    o.sensor_gain = sources.sensor_gain(a.kinematics.map(Kinematics::from), axis, &NAMES)?;
    let fit = sources.fit(&r, &o)?;
    match &sources {
        Sources::Klipper(logs) => outln!(
            "{} stretches of {} Klipper logs of axis {letter} on {} at {run}; belt {} mm/rev",
            sources.stretches(),
            logs.len(),
            base.name,
            a.mm_per_rev
        ),
        Sources::Prusa(c) => {
            let k = Kinematics::from(a.kinematics.unwrap_or(crate::accel::KinematicsArg::Cartesian));
            outln!(
                "{} captures of axis {letter} on {} at {run}; belt {} mm/rev; {} kinematics (--kinematics), the firmware \
                 prints {:.3} of the belt's acceleration",
                c.len(),
                base.name,
                a.mm_per_rev,
                k.name(),
                o.sensor_gain
            )
        }
    }
    outln!("{fit}");
    let text = RippleFile::new(&fit, &base.name, letter, run.peak_a()).to_toml_string()?;
    write_atomic(out, text.as_bytes())?;
    outln!("wrote {}", out.display());
    Ok(())
}

/// The CLI's names of the inputs, in the library's messages.
const NAMES: Names =
    Names { paths: "--accel", axis: "--axis", motor: "--motor", trial: "--klipper-trial", kinematics: "--kinematics" };

/// Every `--klipper-trial LOG=H,U,PHI`, parsed; the library checks that each `LOG` is one of
/// the `--accel` logs.
fn klipper_trials(a: &FitArgs) -> Result<Vec<(PathBuf, TrialShift)>> {
    crate::accel::parse_klipper_trials(&a.klipper_trial)
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
