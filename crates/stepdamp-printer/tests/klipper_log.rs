//! The simulated printer's Klipper motion-analysis log read back by `stepdamp_accel::klipper`:
//! the samples, times and angles it wrote, and the ripple identified from it
//! (`docs/accelerometer.md#klippers-motion-analysis-logs`).

use std::f64::consts::TAU;
use stepdamp_accel::klipper::{Kinematics, KlipperOptions, Log, TrialShift, read_log};
use stepdamp_accel::ripple::{Direction, RippleOptions, identify_ripple};
use stepdamp_accel::{Axis, Complex, Gcode, Reconstruction, TrialSweep};
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
/// to 4 rev/s and back over 8 revolutions and a steady 2 rev/s per direction with the
/// driver's own table, then the steady moves again with the table carrying the trial
/// `0.12·sin(4·θe)` (Prusa's `H4 C0.03`), which [`TrialShift`] tells the reader.
fn recipe(p: &SimulatedPrinter) -> Vec<Log> {
    let k = KlipperSetup::default();
    let plain = [sweep(2.0, 4.0, 8.0), sweep(2.0, 4.0, -8.0), at_2_rev_s(6.0, 0.0), at_2_rev_s(-6.0, 0.0)];
    let trial = [at_2_rev_s(6.0, 0.03), at_2_rev_s(-6.0, 0.03)];
    let shift = TrialShift { harmonic: 4, amplitude_rad: 4.0 * 0.03, phase_rad: 0.0 };
    [(&plain[..], None, 1), (&trial[..], Some(shift), 2)]
        .into_iter()
        .map(|(moves, trial, seed)| {
            let log = SimulatedPrinter { seed, ..p.clone() }.motan_log(moves, &k).unwrap();
            let o = KlipperOptions { axis: Axis::X, accelerometer: None, trial };
            read_log(log.json_gz.as_slice(), "sim.json.gz", &o).unwrap()
        })
        .collect()
}

#[test]
fn the_order_4_ripple_identified_from_simulated_klipper_logs_is_the_motors() {
    let p = SimulatedPrinter::new(real_motor(), 0.9);
    let logs = recipe(&p);
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
        // The Prusa route's tolerance for order 4 (tests/identify_ripple.rs): max(10 %, 1 mN·m).
        assert!(err <= (0.1 * t.amplitude_nm).max(1e-3), "{}: {err}", dir.name());
    }
}
