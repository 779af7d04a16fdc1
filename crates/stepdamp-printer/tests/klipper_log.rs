//! The simulated printer's Klipper motion-analysis log read back by `stepdamp_accel::klipper`:
//! the samples, times and angles it wrote, and the ripple identified from it
//! (`docs/accelerometer.md#klippers-motion-analysis-logs`).

use std::f64::consts::TAU;
use stepdamp_accel::klipper::{Kinematics, KlipperOptions, Log, TrialShift, read_log};
use stepdamp_accel::ripple::{Direction, RippleOptions, identify_ripple};
use stepdamp_accel::{Axis, Complex, Gcode, Reconstruction, TrialSweep};
use stepdamp_export::tmc::{self, ShiftTable, TmcRegisters};
use stepdamp_printer::{KlipperSetup, MotanLog, SimulatedPrinter};
use stepdamp_sim::Profile;

fn real_motor() -> Profile {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles/patent-motor-real.toml");
    Profile::from_file(std::path::Path::new(path)).unwrap()
}

fn read(log: &MotanLog, axis: Axis) -> Log {
    read_log(log.json_gz.as_slice(), "sim.json.gz", &KlipperOptions { axis, accelerometer: None, trial: None }).unwrap()
}

/// `M974 A<a> B<b> R<revs>` as a move shape.
fn sweep(a: f64, b: f64, revs: f64) -> Gcode {
    Gcode::SpeedSweep { axis: Axis::X, start_speed: a, end_speed: b, revs }
}

#[test]
fn a_simulated_klipper_log_reads_back_exactly_the_samples_times_and_angles_it_wrote() {
    let p = SimulatedPrinter::new(real_motor(), 0.9);
    let zero = TrialSweep { harmonic: 4, pha_start: 0.0, pha_end: 0.0, mag_start: 0.0, mag_end: 0.0 };
    let moves = [sweep(2.0, 4.0, 4.0), Gcode::ParamSweep { axis: Axis::X, speed: 3.0, revs: -3.0, trial: zero }];
    for (kinematics, axis) in [(Kinematics::Cartesian, Axis::X), (Kinematics::CoreXy, Axis::Y)] {
        let k = KlipperSetup { kinematics, axis, ..KlipperSetup::default() };
        let log = p.motan_log(&moves, &k).unwrap();
        let r = read(&log, axis);
        let (wx, wy) = kinematics.projection(axis);
        assert_eq!(r.times_s, log.samples.iter().map(|s| s.t_s).collect::<Vec<_>>());
        let want: Vec<f64> = log.samples.iter().map(|s| (wx * s.xyz[0] + wy * s.xyz[1]) * 1e-3).collect();
        assert_eq!(r.accel_m_s2, want);
        assert_eq!((r.steps, r.skipped_records, r.mcu_phase_offset), (log.steps, 0, Some(k.mcu_phase_offset)));
        // Everywhere within a microstep (the rests' sparse steps are smoothed as readlog.py
        // smooths them); inside the stretches the fit uses, the path itself.
        let err = |i: usize| (r.commanded[i].electrical_rad - log.samples[i].planned_rad).abs();
        let worst = (0..r.times_s.len()).map(err).fold(0.0, f64::max);
        assert!(worst < TAU / 64.0, "{worst} rad");
        let segments = r.segments();
        assert_eq!(segments.len(), 2, "one per move");
        let inside = segments.iter().flat_map(|s| s.range.clone()).map(err).fold(0.0, f64::max);
        println!("{kinematics:?} {axis:?}: angle off by {worst:.2e} rad at most, {inside:.2e} in the stretches");
        assert!(inside < 1e-4, "{inside} rad");
    }
}

/// `M973 X F2 R<revs> H4 C<mag> A0` as a move whose trial the driver's table carries.
fn at_2_rev_s(revs: f64, mag: f64) -> Gcode {
    let trial = TrialSweep { harmonic: 4, pha_start: 0.0, pha_end: 0.0, mag_start: mag, mag_end: mag };
    Gcode::ParamSweep { axis: Axis::X, speed: 2.0, revs, trial }
}

/// The Prusa route's recipe (tests/identify_ripple.rs) as two Klipper logs: the sweeps from 2
/// to 4 rev/s and back over 8 revolutions and a steady 2 rev/s per direction by `plain`, then
/// the steady moves again by `trial` with `mag` as `M973`'s trial (0 when `trial`'s driver
/// table carries it), which `shift` tells the reader.
fn recipe(plain: &SimulatedPrinter, trial: &SimulatedPrinter, mag: f64, shift: TrialShift) -> Vec<Log> {
    let k = KlipperSetup::default();
    let plain_moves = [sweep(2.0, 4.0, 8.0), sweep(2.0, 4.0, -8.0), at_2_rev_s(6.0, 0.0), at_2_rev_s(-6.0, 0.0)];
    let trial_moves = [at_2_rev_s(6.0, mag), at_2_rev_s(-6.0, mag)];
    [(plain, &plain_moves[..], None, 1), (trial, &trial_moves[..], Some(shift), 2)]
        .into_iter()
        .map(|(p, moves, trial, seed)| {
            let log = SimulatedPrinter { seed, ..p.clone() }.motan_log(moves, &k).unwrap();
            let o = KlipperOptions { axis: Axis::X, accelerometer: None, trial };
            read_log(log.json_gz.as_slice(), "sim.json.gz", &o).unwrap()
        })
        .collect()
}

/// Identifies the ripple from `logs` of `p`'s motor; order 4's worst error over both
/// directions against the truth, in units of the Prusa route's tolerance
/// (tests/identify_ripple.rs): max(10 %, 1 mN·m).
fn order_4_error(p: &SimulatedPrinter, logs: &[Log]) -> f64 {
    let segments: Vec<_> = logs.iter().flat_map(Log::segments).collect();
    assert_eq!(segments.len(), 6, "one stretch per move");
    let m = &p.profile.motor;
    assert_eq!(logs[0].periods_per_rev(), u32::from(m.pole_pairs));
    let o = RippleOptions {
        rotor_inertia_kg_m2: m.inertia_kg_m2,
        km_nm_per_a: m.km_nm_per_a,
        viscous_nm_s_per_rad: m.viscous_nm_s_per_rad,
        coulomb_friction_nm: m.coulomb_friction_nm,
        ..RippleOptions::new(u32::from(m.pole_pairs), p.head.pulley_radius_m, p.run_current_a)
    };
    // Not used: the logs date and angle their samples.
    let unused = Reconstruction { periods_per_rev: 50, start_angle_rad: 0.0, first_sample_s: 0.0, mm_per_rev: 40.0 };
    let fit = identify_ripple(&segments, &unused, &o).unwrap();
    println!("{fit}");
    let truth = stepdamp_sim::profile::ripple(&p.profile, p.run_current_a, 0.0).unwrap();
    let t = truth.harmonics.iter().find(|x| x.order == 4).unwrap();
    let belt = p.head.belt_hz();
    assert!((fit.head.belt_hz.value / belt - 1.0).abs() < 0.1, "{} vs {belt}", fit.head.belt_hz.value);
    let mut worst: f64 = 0.0;
    for dir in [Direction::Forward, Direction::Backward] {
        let x = fit.harmonics.iter().find(|x| x.order == 4 && x.direction == dir).unwrap();
        let err = (Complex::from_polar(-x.amplitude_nm.value, x.phase_rad.value)
            - Complex::from_polar(-t.amplitude_nm, t.phase_rad))
        .abs();
        println!(
            "{} k=4: true {:.2} mN·m at {:+.3}, identified {:.2} at {:+.3}: off by {:.2} mN·m",
            dir.name(),
            1e3 * t.amplitude_nm,
            t.phase_rad,
            1e3 * x.amplitude_nm.value,
            x.phase_rad.value,
            1e3 * err
        );
        worst = worst.max(err / (0.1 * t.amplitude_nm).max(1e-3));
    }
    worst
}

#[test]
fn the_order_4_ripple_identified_from_simulated_klipper_logs_is_the_motors() {
    // The trial `0.12·sin(4·θe)` as Prusa's `H4 C0.03` turns the current.
    let p = SimulatedPrinter::new(real_motor(), 0.9);
    let shift = TrialShift { harmonic: 4, amplitude_rad: 4.0 * 0.03, phase_rad: 0.0 };
    let e = order_4_error(&p, &recipe(&p, &p, 0.03, shift));
    assert!(e <= 1.0, "{e} of the tolerance");
}

#[test]
fn a_trial_wave_table_from_stepdamp_gives_the_motors_order_4_ripple() {
    // A Trinamic driver: Klipper's default table, then the trial table `ShiftTable` writes,
    // told to the reader as its block says (`klipper_trial_arg`).
    let t = ShiftTable::trial(4, 0.12).unwrap();
    let arg = t.klipper_trial_arg();
    let u: f64 = arg.split(',').nth(1).unwrap().parse().unwrap();
    assert_eq!(arg, format!("4,{u:.4},0"));
    let with = |r: &TmcRegisters| SimulatedPrinter {
        driver_table: Some(tmc::table(r)),
        ..SimulatedPrinter::new(real_motor(), 0.9)
    };
    let (plain, trial) = (with(&TmcRegisters::KLIPPER_DEFAULT), with(&t.registers));
    let shift = TrialShift { harmonic: 4, amplitude_rad: u, phase_rad: 0.0 };
    let e = order_4_error(&plain, &recipe(&plain, &trial, 0.0, shift));
    assert!(e <= 1.0, "{e} of the tolerance");
    // The same logs told the opposite sign read as a sensor turned the other way (the fit
    // takes the sensor's sign, not the trial's, as unknown): the ripple comes out flipped,
    // half a turn off, which the check tells.
    let wrong = TrialShift { phase_rad: std::f64::consts::PI, ..shift };
    let e = order_4_error(&plain, &recipe(&plain, &trial, 0.0, wrong));
    assert!(e > 10.0, "a trial of the wrong sign is only {e} of the tolerance off");
}

#[test]
fn a_driver_table_refuses_an_m973_trial() {
    let p = SimulatedPrinter {
        driver_table: Some(tmc::table(&TmcRegisters::KLIPPER_DEFAULT)),
        ..SimulatedPrinter::new(real_motor(), 0.9)
    };
    let e = p.simulate(&at_2_rev_s(6.0, 0.03)).unwrap_err().to_string();
    assert!(e.contains("C0 D0: the trial is the driver's table"), "{e}");
}
