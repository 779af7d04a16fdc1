//! The Klipper + Trinamic side of the accelerometer route on simulated printers: the moves
//! `plan_klipper` prints, logged with Klipper's default table and with a trial table, one
//! influence step
//! (`stepdamp_accel::klipper::table_step`), the new table written by the exporter, and order 4
//! measured again on fresh logs (`docs/accelerometer.md#refining-a-trinamic-table`).
//!
//! A Trinamic table turns the current only in sine phase, so what it can remove of order 4 is
//! bounded by the part of the response along the trial's influence: the rest (the step's
//! **floor**) stays. The tests compare the measured reduction with that bound, per direction.

use stepdamp_accel::Axis;
use stepdamp_accel::Gcode;
use stepdamp_accel::TrialSweep;
use stepdamp_accel::klipper::plan::{KlipperPlanOptions, plan_klipper};
use stepdamp_accel::klipper::table_step::{TableStep, steady_responses, table_step};
use stepdamp_accel::klipper::{Kinematics, KlipperOptions, Log, TrialShift, read_log};
use stepdamp_accel::ripple::Direction;
use stepdamp_export::tmc::{self, ShiftTable, TmcRegisters, order_parts};
use stepdamp_printer::{KlipperSetup, SimulatedPrinter, family_printer};
use stepdamp_sim::Profile;

/// Whole electrical periods per lock-in block.
const PER_BLOCK: u32 = 20;

fn real_motor() -> Profile {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles/patent-motor-real.toml");
    Profile::from_file(std::path::Path::new(path)).unwrap()
}

/// The moves `plan_klipper` prints for `p`'s X motor (cartesian, its belt's mm per
/// revolution, 100 mm of travel), each as a move shape: a steady `M973` at the plan's speed
/// over the move's motor revolutions (`R < 0` forward), no `M973` trial.
fn planned_moves(p: &SimulatedPrinter) -> Vec<Gcode> {
    let o = KlipperPlanOptions {
        rotation_distance_mm: p.reconstruction().mm_per_rev,
        ..KlipperPlanOptions::new(Kinematics::Cartesian, Axis::X)
    };
    let plan = plan_klipper(&o).unwrap();
    let trial = TrialSweep { harmonic: 4, pha_start: 0.0, pha_end: 0.0, mag_start: 0.0, mag_end: 0.0 };
    plan.moves
        .iter()
        .map(|m| Gcode::ParamSweep { axis: Axis::X, speed: o.speed_rev_s, revs: -m.motor_revs, trial })
        .collect()
}

/// `p` with `registers` in its driver, recording the planned moves with noise seed `seed`,
/// read back with `trial` told.
fn log(p: &SimulatedPrinter, registers: &TmcRegisters, seed: u64, trial: Option<TrialShift>) -> Log {
    let with = SimulatedPrinter { driver_table: Some(tmc::table(registers)), seed, ..p.clone() };
    let m = with.motan_log(&planned_moves(p), &KlipperSetup::default()).unwrap();
    let o = KlipperOptions { axis: Axis::X, accelerometer: None, trial };
    read_log(m.json_gz.as_slice(), "sim.json.gz", &o).unwrap()
}

/// One printer's route: the step, then per direction (forward, backward) the order-4
/// response before and after (m/s²) measured on fresh logs, the after's 95 % radius, and the
/// floor.
struct Outcome {
    step: TableStep,
    before: [f64; 2],
    after: [f64; 2],
    after_radius95: [f64; 2],
    floor: [f64; 2],
    /// The step's baseline radius per direction (the floor's noise).
    step_radius95: [f64; 2],
}

fn route(p: &SimulatedPrinter, seed: u64) -> Outcome {
    let default = TmcRegisters::KLIPPER_DEFAULT;
    let in_use = order_parts(&default.decode(), 4).0;
    let trial = ShiftTable::trial(4, 0.12).unwrap();
    let shift = TrialShift { harmonic: 4, amplitude_rad: trial.achieved_rad, phase_rad: 0.0 };
    let base = log(p, &default, 3 * seed, None);
    let with_trial = log(p, &trial.registers, 3 * seed + 1, Some(shift));
    let step = table_step(&[base], &[with_trial], 4, in_use, PER_BLOCK).unwrap();
    let new = ShiftTable::new(4, step.new_rad).unwrap();
    // Fresh noise for the score: neither log was used by the step.
    const WAYS: [Direction; 2] = [Direction::Forward, Direction::Backward];
    let measure = |r: &TmcRegisters, s: u64| {
        let l = log(p, r, s, None);
        let v = steady_responses(std::slice::from_ref(&l), 4, PER_BLOCK);
        assert_eq!(v.len(), 2, "one response per direction, its stretches pooled");
        WAYS.map(|d| v.iter().find(|x| x.0 == d).map(|x| (x.1.value.abs(), x.1.radius95)).expect("both ways"))
    };
    let (before, after) = (measure(&default, 3 * seed + 2), measure(&new.registers, 3 * seed + 2));
    let pair = |d: Direction| *step.pairs.iter().find(|x| x.direction == d).expect("both ways");
    Outcome {
        before: before.map(|x| x.0),
        after: after.map(|x| x.0),
        after_radius95: after.map(|x| x.1),
        floor: WAYS.map(|d| pair(d).floor_m_s2),
        step_radius95: WAYS.map(|d| pair(d).baseline.radius95),
        step,
    }
}

fn db(a: f64, b: f64) -> f64 {
    20.0 * (a / b).log10()
}

#[test]
fn one_table_step_from_klipper_logs_takes_order_4_down_to_what_a_sine_table_can() {
    let p = SimulatedPrinter::new(real_motor(), 0.9);
    let o = route(&p, 1);
    println!("new shift {:.4} ± {:.4} rad", o.step.new_rad, o.step.new_radius95_rad);
    for d in 0..2 {
        println!(
            "{}: order 4 {:.3} -> {:.3} m/s² ({:.1} dB), floor {:.3}",
            ["forward", "backward"][d],
            o.before[d],
            o.after[d],
            db(o.before[d], o.after[d]),
            o.floor[d]
        );
        // patent-motor-real's order 4 is in sine phase (−0.003 rad): the table can take it
        // all, and one step gets 20 dB in both directions.
        assert!(db(o.before[d], o.after[d]) >= 20.0, "{d}: {:?} -> {:?}", o.before, o.after);
    }
}

/// The family of random real motors and heads: the measured residual is the floor the
/// sine-only table leaves, within 5 % of the baseline plus the noise of both (the floor's from
/// the step's baseline, twice the 95 % radii). Printed: the reduction and the best a Trinamic
/// table can do. `cargo test --release -p stepdamp-printer --test klipper_table -- --ignored --nocapture`.
#[test]
#[ignore = "30 printers, about a minute in release"]
fn on_thirty_random_printers_one_step_reaches_the_sine_table_floor() {
    let mut at_20 = 0;
    let mut worst_over_floor: f64 = 0.0;
    for seed in 1..=30 {
        let p = family_printer(seed);
        let o = route(&p, seed);
        for d in 0..2 {
            let (got, best) = (db(o.before[d], o.after[d]), db(o.before[d], o.floor[d].max(1e-12)));
            at_20 += usize::from(got >= 20.0);
            // How far above the floor the residual is, less the noise, in units of the baseline.
            let noise = 2.0 * (o.after_radius95[d] + o.step_radius95[d]);
            worst_over_floor = worst_over_floor.max((o.after[d] - o.floor[d] - noise) / o.before[d]);
            println!(
                "printer {seed:2} {}: {:.2} -> {:.3} m/s², {got:5.1} dB (a sine table's best {best:5.1} dB), shift {:+.4} rad",
                ["F", "B"][d],
                o.before[d],
                o.after[d],
                o.step.new_rad
            );
        }
    }
    println!(
        "{at_20} of 60 directions at >= 20 dB; residual above the floor and the noise at most {worst_over_floor:.3} of the baseline"
    );
    assert!(worst_over_floor < 0.05, "{worst_over_floor}");
}
