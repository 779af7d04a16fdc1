//! The stress family: identification on logs this repository did not write.
//!
//! Seeded random motors simulated by the independent generator of `independent/` (half
//! with smooth-creep friction, half Stribeck; a drive tuned by its own rule at 40–80 Hz;
//! ±0.5 and ±1 rad/s; 4000-count encoder; current noise), written as CSV run logs, read
//! with [`parse_log`] and fitted from a base profile that carries the true `J` and no detent.
//! Done when every harmonic of 5 mN·m or more is within max(5 %, 0.5 mN·m) in amplitude and
//! 0.05 rad in phase, and `Fs` within 10 %, for every motor.
//!
//! Two sets of seeds, both held to the same tolerances ([`accept`]):
//!
//! * [`TUNING_SEEDS`] (0–49): the motors the thresholds of the fit (among them
//!   `MAX_FRICTION_DEFICIT` of the count-rate rule, docs/identification.md) were tuned on.
//! * [`HELD_OUT_SEEDS`] (1000–1049): a held-out set of the same family. **No threshold was
//!   tuned on these**; they show whether the rules carry over to motors not looked at. Do not
//!   retune on them: a failure here is a finding about the rule, to be fixed on the tuning set
//!   (or on a new held-out set), never by loosening these tolerances. Measured when the set
//!   was added: motor 1026 failed on `Fs`, fixed by a rule about what the fit uses, not by a
//!   threshold (docs/identification.md, *Logs no code of this repository wrote*).

mod independent;

use independent::{Friction, run, stress_motor};
use rayon::prelude::*;
use stepdamp_identify::fit::{FitOptions, fit, wrap_pi};
use stepdamp_identify::log::{LogOptions, RunLog, parse_log};
use stepdamp_identify::validation::{default_max_order, validate};
use stepdamp_profile::Profile;

/// The four runs of each motor: speed (rad/s) and steady duration (s): about 12 electrical
/// periods at 0.5 rad/s, 16 at 1 rad/s.
const RUNS: [(f64, f64); 4] = [(0.5, 3.0), (-0.5, 3.0), (1.0, 2.0), (-1.0, 2.0)];

struct Outcome {
    seed: u64,
    stribeck: bool,
    amplitude_over_tolerance: f64,
    phase_rad: f64,
    coulomb_relative: f64,
    stopped: f64,
    summary: String,
}

fn identify(seed: u64) -> Outcome {
    let (m, d) = stress_motor(seed);
    let mut stopped = 0.0f64;
    let logs: Vec<RunLog> = RUNS
        .iter()
        .enumerate()
        .map(|(i, &(speed, steady))| {
            let (csv, s) = run(&m, &d, speed, steady, 1000 * seed + i as u64);
            stopped = stopped.max(s);
            parse_log(csv.as_bytes(), &format!("motor{seed}-run{i}"), &LogOptions::new(m.nr)).unwrap()
        })
        .collect();
    // What the user has: the preset with the true J, no detent, its own Fs and servo.
    let base = Profile::preset("patent-motor")
        .unwrap()
        .edited("stress base", |d| {
            d.motor.detent.clear();
            d.motor.inertia_kg_m2 = m.j;
        })
        .unwrap();
    let f = fit(&logs, &FitOptions::for_profile(&base, &[1, 2, 4])).unwrap();
    let (mut over, mut phase) = (0.0f64, 0.0f64);
    for &(k, a, p) in m.detent.iter().filter(|t| t.1 >= 0.005) {
        let h = f.harmonics.iter().find(|h| h.order == k).unwrap();
        over = over.max((h.amplitude_nm.value - a).abs() / (0.05 * a).max(0.0005));
        phase = phase.max(wrap_pi(h.phase_rad.value - p).abs());
    }
    let coulomb_relative = (f.coulomb_friction_nm.value / m.fs - 1.0).abs();
    let summary = format!(
        "{}; {}; J fitted {:?} used {:.3} of true; D {:?}; warnings: {}",
        validate(&f, default_max_order(&f)).overall,
        f.decisions.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(" | "),
        f.inertia_kg_m2.map(|j| j.value / m.j),
        f.inertia_used / m.j,
        f.viscous_nm_s_per_rad.map(|v| v.value),
        f.warnings.iter().map(|w| w.to_string()).collect::<Vec<_>>().join(" | ")
    );
    Outcome {
        seed,
        stribeck: matches!(m.friction, Friction::Stribeck { .. }),
        amplitude_over_tolerance: over,
        phase_rad: phase,
        coulomb_relative,
        stopped,
        summary,
    }
}

/// The seeds the thresholds were tuned on.
const TUNING_SEEDS: std::ops::Range<u64> = 0..50;

/// Held-out seeds: no threshold was tuned on these. Disjoint from [`TUNING_SEEDS`], and so are
/// their run seeds (`1000·seed + run`).
const HELD_OUT_SEEDS: std::ops::Range<u64> = 1000..1050;

/// Acceptance, the same for every set: amplitude within max(5 %, 0.5 mN·m) (1 = the
/// tolerance), phase within 0.05 rad, `Fs` within 10 %.
const MAX_AMPLITUDE_OVER_TOLERANCE: f64 = 1.0;
const MAX_PHASE_RAD: f64 = 0.05;
const MAX_COULOMB_RELATIVE: f64 = 0.10;

/// Identifies the motors of `seeds`, prints each and the worst of each measure under the name
/// `set`, and asserts the acceptance tolerances on every motor (listing every failure).
fn accept(set: &str, seeds: std::ops::Range<u64>) {
    let n = seeds.end - seeds.start;
    let out: Vec<Outcome> = seeds.into_par_iter().map(identify).collect();
    for o in &out {
        eprintln!(
            "{set} motor {:2} ({}): amplitude {:.2} of tolerance, phase {:.4} rad, Fs {:.1} %, stopped ≤ {:.0} % — {}",
            o.seed,
            if o.stribeck { "Stribeck" } else { "creep" },
            o.amplitude_over_tolerance,
            o.phase_rad,
            100.0 * o.coulomb_relative,
            100.0 * o.stopped,
            o.summary
        );
    }
    let worst = |g: fn(&Outcome) -> f64| {
        out.iter().map(|o| (g(o), o.seed)).fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a })
    };
    let (a, sa) = worst(|o| o.amplitude_over_tolerance);
    let (p, sp) = worst(|o| o.phase_rad);
    let (c, sc) = worst(|o| o.coulomb_relative);
    eprintln!(
        "stress family, {set} ({n} motors): worst amplitude {a:.2} of tolerance (motor {sa}), phase {p:.4} rad (motor {sp}), Fs {:.1} % (motor {sc})",
        100.0 * c
    );
    let failures: Vec<String> = out
        .iter()
        .filter(|o| {
            o.amplitude_over_tolerance > MAX_AMPLITUDE_OVER_TOLERANCE
                || o.phase_rad > MAX_PHASE_RAD
                || o.coulomb_relative > MAX_COULOMB_RELATIVE
        })
        .map(|o| {
            format!(
                "motor {}: amplitude {:.2} of tolerance, phase {:.4} rad, Fs {:.1} %",
                o.seed,
                o.amplitude_over_tolerance,
                o.phase_rad,
                100.0 * o.coulomb_relative
            )
        })
        .collect();
    assert!(
        failures.is_empty(),
        "{set}: {} of {n} motors outside the tolerances (amplitude ≤ {MAX_AMPLITUDE_OVER_TOLERANCE}, phase ≤ {MAX_PHASE_RAD} rad, Fs ≤ {} %):\n{}",
        failures.len(),
        100.0 * MAX_COULOMB_RELATIVE,
        failures.join("\n")
    );
}

#[test]
fn fifty_independent_stick_slip_motors_are_identified_within_tolerance() {
    accept("tuning set", TUNING_SEEDS);
}

#[test]
fn held_out_stress_motors_meet_the_same_tolerances() {
    accept("held-out set", HELD_OUT_SEEDS);
}
