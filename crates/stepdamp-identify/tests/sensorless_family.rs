//! Acceptance of the sensorless route (docs/sensorless.md): the sensorless route on patent-motor and 50 seeded random motors.
//!
//! Each motor: patent-motor's winding and drive, detent amplitudes 4–30 mN·m for orders 1,
//! 2 and 4 with random phases, `J` ×0.5–3 (the base keeps patent-motor's), `Fs` 5–20 mN·m,
//! Karnopp friction for even seeds and smooth Coulomb (`tanh`, creep 0.01–0.05 rad/s) for
//! odd ones. The base profile is what a datasheet gives: no detent, `R` off by ±10 %,
//! patent-motor's `J`. The plan of `identify plan --sensorless` is simulated with 5 mA of
//! current-sensor noise, the logs go through the sensorless route, and:
//!
//! * every harmonic of 5 mN·m or more is within max(10 %, 1 mN·m) and 0.1 rad;
//! * the open-loop sweep compensated with the identified profile reaches at least 70 % of
//!   the true profile's reduction in dB at every resonance (the largest peak-to-peak
//!   velocity error over 0.92–1.08 × the resonance speed, compensation off against on).

#![cfg(feature = "simulate")]

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::f64::consts::PI;
use stepdamp_core::Mode;
use stepdamp_identify::fit::wrap_pi;
use stepdamp_identify::plan::run_seed;
use stepdamp_identify::sensorless::flux::FluxOptions;
use stepdamp_identify::sensorless::log::SensorlessLog;
use stepdamp_identify::sensorless::plan::{SensorlessPlanOptions, plan};
use stepdamp_identify::sensorless::{fit_options, identify as identify_sensorless};
use stepdamp_identify::simulate::simulate_open_loop_run;
use stepdamp_profile::data::FrictionLawName;
use stepdamp_profile::{DetentTerm, Profile};
use stepdamp_sim::{ClosedLoop, Compensation, RunSpec, SimOptions, run};

const NOISE_A: f64 = 0.005;

/// The true motor and the base profile of seed `seed` (seed 0: patent-motor itself).
fn motor(seed: u64) -> (Profile, Profile) {
    let p = Profile::preset("patent-motor").unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(0x5e45_0000 + seed);
    let r_error = if rng.random_bool(0.5) { 1.1 } else { 0.9 };
    let m = if seed == 0 {
        p.clone()
    } else {
        p.edited(&format!("random-{seed}"), |d| {
            d.motor.detent = [4u16, 2, 1]
                .iter()
                .map(|&order| DetentTerm {
                    order,
                    amplitude_nm: rng.random_range(0.004..0.030),
                    phase_rad: rng.random_range(-PI..PI),
                })
                .collect();
            d.motor.inertia_kg_m2 *= rng.random_range(0.5..3.0);
            d.motor.coulomb_friction_nm = rng.random_range(0.005..0.020);
            if seed % 2 == 1 {
                d.motor.friction.law = FrictionLawName::Smooth;
                d.motor.friction.creep_speed_rad_s = Some(rng.random_range(0.01..0.05));
            }
        })
        .unwrap()
    };
    let base = p
        .edited("datasheet", |d| {
            d.motor.detent.clear();
            d.motor.resistance_ohm *= r_error;
        })
        .unwrap();
    (m, base)
}

/// Sensorless identification of `m` from `base`.
fn identify(m: &Profile, base: &Profile, seed: u64) -> Profile {
    let p = plan(base, &SensorlessPlanOptions::default()).unwrap();
    let logs: Vec<_> = p
        .runs
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let rows = simulate_open_loop_run(m, base, r, NOISE_A, run_seed(seed, i as u64)).unwrap();
            SensorlessLog::from_rows(&rows, &r.name)
        })
        .collect();
    let f = identify_sensorless(&logs, base, &fit_options(base, &[1, 2, 4]), &FluxOptions::default()).unwrap();
    f.model().apply_to(base, Some("sensorless"), "sensorless.toml").unwrap()
}

/// Largest p-p velocity error of `m` driven open loop by `ctl` with `comp` over 0.92–1.08 ×
/// the order-`k` resonance speed.
fn peak_pp(m: &Profile, ctl: &Profile, comp: Compensation, k: u16) -> f64 {
    let nr = f64::from(m.motor.pole_pairs);
    let wn = (m.motor.km_nm_per_a * m.drive.holding_current_a * nr / m.motor.inertia_kg_m2).sqrt();
    let w0 = wn / (f64::from(k) * nr);
    [0.92, 0.96, 1.0, 1.04, 1.08]
        .iter()
        .map(|f| {
            let mut lp = ClosedLoop::new(m, ctl, Mode::OpenLoop, comp, &SimOptions::default()).unwrap();
            let spec = RunSpec { duration_s: 1.0, window_s: 0.4, ..RunSpec::at(f * w0) };
            run(&mut lp, &spec, m.drive.pwm_hz, |_, _| {}).unwrap().vel_err_pp_rad_s
        })
        .fold(0.0, f64::max)
}

struct Outcome {
    seed: u64,
    amplitude_over_tolerance: f64,
    phase_rad: f64,
    db_ratio: f64,
    line: String,
}

fn check(seed: u64) -> Outcome {
    let (m, base) = motor(seed);
    let id = identify(&m, &base, seed);
    let (mut over, mut phase) = (0.0f64, 0.0f64);
    let mut line = format!("motor {seed:2} (J ×{:.2}): ", m.motor.inertia_kg_m2 / 4e-5);
    for h in m.motor.detent.iter().filter(|h| h.amplitude_nm >= 0.005) {
        let g = id.motor.detent.iter().find(|g| g.order == h.order).unwrap();
        over = over.max((g.amplitude_nm - h.amplitude_nm).abs() / (0.1 * h.amplitude_nm).max(0.001));
        phase = phase.max(wrap_pi(g.phase_rad - h.phase_rad).abs());
        line += &format!(
            "k{} {:+.1} % {:+.3} rad; ",
            h.order,
            100.0 * (g.amplitude_nm / h.amplitude_nm - 1.0),
            wrap_pi(g.phase_rad - h.phase_rad)
        );
    }
    let mut db_ratio = f64::INFINITY;
    for k in [4u16, 2, 1] {
        let off = peak_pp(&m, &m, Compensation::Off, k);
        let db_true = 20.0 * (off / peak_pp(&m, &m, Compensation::Patent, k)).log10();
        let db_id = 20.0 * (off / peak_pp(&m, &id, Compensation::Patent, k)).log10();
        db_ratio = db_ratio.min(db_id / db_true);
        line += &format!("k{k} {db_id:.1}/{db_true:.1} dB; ");
    }
    Outcome { seed, amplitude_over_tolerance: over, phase_rad: phase, db_ratio, line }
}

#[test]
fn sensorless_identification_holds_on_patent_motor_and_50_random_motors() {
    let outcomes: Vec<Outcome> = (0..=50u64).into_par_iter().map(check).collect();
    for o in &outcomes {
        eprintln!("{}", o.line);
    }
    let worst = |f: fn(&Outcome) -> f64| {
        outcomes.iter().map(|o| (f(o), o.seed)).fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a })
    };
    let (a, sa) = worst(|o| o.amplitude_over_tolerance);
    let (p, sp) = worst(|o| o.phase_rad);
    let (r, sr) =
        outcomes.iter().map(|o| (o.db_ratio, o.seed)).fold((f64::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a });
    eprintln!(
        "worst: amplitude {a:.2} × tolerance (motor {sa}), phase {p:.4} rad (motor {sp}), dB ratio {r:.3} (motor {sr})"
    );
    assert!(a <= 1.0, "an amplitude is {a:.2} × its tolerance (motor {sa})");
    assert!(p <= 0.1, "a phase is {p:.4} rad off (motor {sp})");
    assert!(
        r >= 0.7,
        "the identified profile reaches only {:.0} % of the true profile's dB reduction (motor {sr})",
        100.0 * r
    );
}
