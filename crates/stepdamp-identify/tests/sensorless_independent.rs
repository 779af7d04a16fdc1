//! Logs written by another simulator: the sensorless route on open-loop logs
//! written by the independent generator of `independent/open_loop.rs` (its own PWM bridge,
//! PI current loop with a computation delay, RK4 plant, Karnopp and smooth friction; no code
//! of `stepdamp-sim` or `stepdamp-core`), performing exactly the plan CSV that
//! `identify plan --sensorless --format csv` prints.
//!
//! Each motor: patent-motor's winding and drive (`Km` 0.3 N·m/A, `Nr` 50, `R` 0.9 Ω, `L`
//! 2.5 mH, `I_hold` 1.9 A, 48 V, 20 kHz), detent amplitudes 4–30 mN·m for orders 1, 2, 4
//! with random phases, `J` ×0.5–3 of 4e-5 kg·m², `Fs` 5–20 mN·m, `D` 1 mN·m·s/rad; Karnopp
//! friction for even seeds, smooth (creep 0.01–0.05 rad/s) for odd ones; motor 0 has
//! patent-motor's own detent and friction. The base profile is the datasheet: patent-motor
//! without detent, `R` off by ±10 %, `J` 4e-5. The logs (5 mA current-sensor noise) are
//! written as CSV text, read with `parse_sensorless_log` and identified; every harmonic of
//! 5 mN·m or more must come out within max(10 %, 1 mN·m) and 0.1 rad.

mod independent;

use independent::flux::FluxShape;
use independent::open_loop::{Friction, Motor, PLAN_HEADER, parse_plan, patent_drive, run};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::f64::consts::PI;
use stepdamp_identify::fit::wrap_pi;
use stepdamp_identify::plan::RUNS_CSV_HEADER as PLAN_CSV_HEADER;
use stepdamp_identify::sensorless::flux::FluxOptions;
use stepdamp_identify::sensorless::log::parse_sensorless_log;
use stepdamp_identify::sensorless::plan::{SensorlessPlanOptions, plan};
use stepdamp_identify::sensorless::{fit_options, identify};
use stepdamp_profile::Profile;

/// Motors checked (motor 0 and `MOTORS − 1` random ones).
const MOTORS: u64 = 16;

/// The true motor of `seed` and the base profile its identification starts from.
fn motor(seed: u64) -> (Motor, Profile) {
    let mut rng = ChaCha8Rng::seed_from_u64(0x0de1_6000 + seed);
    let r_error = if rng.random_bool(0.5) { 1.1 } else { 0.9 };
    let mut m = Motor {
        nr: 50,
        km: 0.3,
        r: 0.9,
        l: 2.5e-3,
        j: 4.0e-5,
        d: 1.0e-3,
        fs: 0.01,
        friction: Friction::Karnopp,
        detent: vec![(4, 0.02, 0.0), (2, 0.012, 0.7), (1, 0.008, -1.1)],
        flux: FluxShape::sine(),
    };
    if seed > 0 {
        m.detent =
            [1u16, 2, 4].iter().map(|&k| (k, rng.random_range(0.004..0.030), rng.random_range(-PI..PI))).collect();
        m.j *= rng.random_range(0.5..3.0);
        m.fs = rng.random_range(0.005..0.020);
        if seed % 2 == 1 {
            m.friction = Friction::Smooth { creep_rad_s: rng.random_range(0.01..0.05) };
        }
    }
    let base = Profile::preset("patent-motor")
        .unwrap()
        .edited("datasheet", |d| {
            d.motor.detent.clear();
            d.motor.resistance_ohm *= r_error;
        })
        .unwrap();
    (m, base)
}

struct Outcome {
    seed: u64,
    amplitude_over_tolerance: f64,
    phase_rad: f64,
    line: String,
}

fn check(seed: u64) -> Outcome {
    let (m, base) = motor(seed);
    let csv = plan(&base, &SensorlessPlanOptions::default()).unwrap().to_csv().unwrap();
    let rows = parse_plan(&csv).unwrap();
    let mut line = format!(
        "motor {seed:2} ({}, J ×{:.2}, Fs {:.1} mN·m, base R ×{:.1}): ",
        if m.friction == Friction::Karnopp { "Karnopp" } else { "smooth " },
        m.j / 4e-5,
        1e3 * m.fs,
        base.motor.resistance_ohm / m.r
    );
    let mut max_delta = 0.0f64;
    let logs: Vec<_> = rows
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let (text, stats) = run(&m, &patent_drive(), r, 1000 * seed + i as u64);
            max_delta = max_delta.max(stats.max_load_angle_rad);
            parse_sensorless_log(text.as_bytes(), &r.run).unwrap()
        })
        .collect();
    let f = identify(&logs, &base, &fit_options(&base, &[1, 2, 4]), &FluxOptions::default()).unwrap();
    let id = f.model().apply_to(&base, Some("sensorless"), "sensorless.toml").unwrap();
    line += &format!("R {:+.2} %, |δ| ≤ {max_delta:.2} rad; ", 100.0 * (f.estimated.resistance_ohm / m.r - 1.0));
    let (mut over, mut phase) = (0.0f64, 0.0f64);
    for &(k, a, p) in m.detent.iter().filter(|h| h.1 >= 0.005) {
        let g = id.motor.detent.iter().find(|g| g.order == k).unwrap();
        over = over.max((g.amplitude_nm - a).abs() / (0.1 * a).max(0.001));
        phase = phase.max(wrap_pi(g.phase_rad - p).abs());
        line += &format!("k{k} {:+.1} % {:+.3} rad; ", 100.0 * (g.amplitude_nm / a - 1.0), wrap_pi(g.phase_rad - p));
    }
    line += &format!(
        "Fs {:+.0} %, D {:.2} mN·m·s/rad",
        100.0 * (id.motor.coulomb_friction_nm / m.fs - 1.0),
        1e3 * id.motor.viscous_nm_s_per_rad
    );
    Outcome { seed, amplitude_over_tolerance: over, phase_rad: phase, line }
}

#[test]
fn sensorless_route_identifies_motors_from_an_independent_open_loop_drive_following_the_plan_csv() {
    let outcomes: Vec<Outcome> = (0..MOTORS).into_par_iter().map(check).collect();
    for o in &outcomes {
        eprintln!("{}", o.line);
    }
    let worst = |f: fn(&Outcome) -> f64| {
        outcomes.iter().map(|o| (f(o), o.seed)).fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a })
    };
    let (a, sa) = worst(|o| o.amplitude_over_tolerance);
    let (p, sp) = worst(|o| o.phase_rad);
    eprintln!("worst: amplitude {a:.2} × tolerance (motor {sa}), phase {p:.4} rad (motor {sp})");
    assert!(a <= 1.0, "an amplitude is {a:.2} × its tolerance (motor {sa})");
    assert!(p <= 0.1, "a phase is {p:.4} rad off (motor {sp})");
}

#[test]
fn the_plan_csv_has_the_documented_header_and_every_row_parses() {
    let base = Profile::preset("patent-motor").unwrap();
    let p = plan(&base, &SensorlessPlanOptions::default()).unwrap();
    let csv = p.to_csv().unwrap();
    assert_eq!(
        csv.lines().next(),
        Some(
            "run,mode,speed_rad_s,duration_s,standstill_s,ramp_s,holding_current_a,d_current_a,servo_bandwidth_hz,velocity_filter_hz"
        )
    );
    assert_eq!(PLAN_CSV_HEADER, PLAN_HEADER);
    let rows = parse_plan(&csv).unwrap();
    assert_eq!(rows.len(), p.runs.len());
    for (row, r) in rows.iter().zip(&p.runs) {
        assert_eq!(
            (row.run.as_str(), row.speed_rad_s, row.duration_s, row.standstill_s, row.ramp_s),
            (r.name.as_str(), r.speed_rad_s, r.duration_s, r.dwell_s, r.ramp_s)
        );
        assert_eq!((row.mode.as_str(), row.holding_current_a), ("open-loop", base.drive.holding_current_a));
    }
}
