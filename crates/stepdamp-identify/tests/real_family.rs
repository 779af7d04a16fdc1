//! The real-motor family: ripple that grows with the current, identified on the encoder
//! route with the plan's runs (docs/identification.md#the-real-motor-family).
//!
//! Seeded random real motors of our simulator (the ranges): detent orders 4, 2, 1 of
//! 4–30 mN·m at random phases, a third flux harmonic of 0–2 % and a fifth of 0–1 % at random
//! phases, phase b's flux ±5 % off phase a's, `J` ×0.5–2 of the base's (unknown to it),
//! `Fs` 5–20 mN·m. The user's base is `patent-motor` without detent or flux. The plan is
//! made from it, run on the motor (current noise 0.01 A), and the logs identified by
//! [`encoder_route`]. Done when `motor ripple` of the identified profile matches the
//! motor's within max(10 %, 1 mN·m) per harmonic (orders 1–8, as a complex difference) at
//! open loop `I_hold` (`--id I_hold --iq 0`), open loop `I_hold/2`, and servo `i_q = 0.5 A`.
//!
//! CI runs [`CI_MOTORS`] motors; all 50: `cargo test --release -p stepdamp-identify --test
//! real_family -- --ignored --nocapture`.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::f64::consts::PI;
use stepdamp_identify::from_logs::{IdentifyOptions, encoder_route};
use stepdamp_identify::plan::{PlanOptions, plan, simulate_plan};
use stepdamp_profile::flux::{FluxHarmonic, FluxSection};
use stepdamp_profile::ripple::{RippleHarmonic, ripple};
use stepdamp_profile::{DetentTerm, Profile};
use stepdamp_sim::Compensation;

/// Motors CI runs (seeds 0..CI_MOTORS).
const CI_MOTORS: u64 = 6;

/// Random real motor `seed` (module documentation).
fn real_motor(seed: u64) -> Profile {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut phase = || rng.random_range(-PI..PI);
    let (p4, p2, p1, a3, a5) = (phase(), phase(), phase(), phase(), phase());
    Profile::preset("patent-motor")
        .unwrap()
        .edited(&format!("real-{seed}"), |d| {
            d.motor.inertia_kg_m2 *= rng.random_range(0.5..2.0);
            d.motor.coulomb_friction_nm = rng.random_range(0.005..0.020);
            d.motor.detent = [(4u16, p4), (2, p2), (1, p1)]
                .iter()
                .map(|&(order, phase_rad)| DetentTerm {
                    order,
                    amplitude_nm: rng.random_range(0.004..0.030),
                    phase_rad,
                })
                .collect();
            d.motor.flux = FluxSection {
                phase_b_gain: rng.random_range(-0.05..0.05),
                harmonics: vec![
                    FluxHarmonic { order: 3, ratio: rng.random_range(0.0..0.02), phase_rad: a3 },
                    FluxHarmonic { order: 5, ratio: rng.random_range(0.0..0.01), phase_rad: a5 },
                ],
            };
        })
        .unwrap()
}

/// The user's base: the preset without detent or flux (its `J` and `Fs`).
fn user_base() -> Profile {
    Profile::preset("patent-motor").unwrap().edited("patent-motor", |d| d.motor.detent.clear()).unwrap()
}

/// The worst harmonic error of `id` against `truth` over the three operating points, as a
/// fraction of the tolerance max(10 %, 1 mN·m), with where it is.
fn worst_ripple_error(truth: &Profile, id: &Profile) -> (f64, String) {
    let hold = truth.drive.holding_current_a;
    let mut worst = (0.0, String::new());
    for (what, i_d, i_q) in
        [("open loop I_hold", hold, 0.0), ("open loop I_hold/2", hold / 2.0, 0.0), ("servo iq 0.5 A", 0.0, 0.5)]
    {
        let (t, i) = (ripple(truth, i_d, i_q).unwrap(), ripple(id, i_d, i_q).unwrap());
        for h in t.harmonics.iter().filter(|h| h.order <= 8) {
            let other = i.harmonics.iter().find(|x| x.order == h.order).copied();
            let z = |r: &RippleHarmonic| (r.amplitude_nm * r.phase_rad.cos(), r.amplitude_nm * r.phase_rad.sin());
            let (a, b) = (z(h), other.as_ref().map_or((0.0, 0.0), z));
            let err = (a.0 - b.0).hypot(a.1 - b.1) / (0.1 * h.amplitude_nm).max(1e-3);
            if err > worst.0 {
                worst = (
                    err,
                    format!(
                        "{what}, order {}: {:.2} mN·m, identified {:.2}",
                        h.order,
                        1e3 * h.amplitude_nm,
                        1e3 * other.map_or(0.0, |o| o.amplitude_nm)
                    ),
                );
            }
        }
    }
    worst
}

/// Identifies motors `seeds` and asserts the tolerance on each; prints each motor.
fn family(seeds: std::ops::Range<u64>) {
    let base = user_base();
    let o = PlanOptions { electrical_periods: 15.0, min_steady_s: 1.0, ..PlanOptions::default() };
    let p = plan(&base, &o).unwrap();
    let results: Vec<(u64, f64, String)> = seeds
        .into_par_iter()
        .map(|seed| {
            let m = real_motor(seed);
            let logs =
                simulate_plan(&m, &p.profile, Compensation::Off, &p, o.current_noise_a, 100 + seed, &|| {}).unwrap();
            let io = IdentifyOptions::new(&[1, 2, 4]);
            let (report, model, with_flux) = encoder_route(&logs, &p.profile, &io).unwrap();
            let id = model.apply_to(with_flux.as_ref().unwrap(), Some("identified"), "identified").unwrap();
            assert!(report.flux.is_some());
            let (err, at) = worst_ripple_error(&m, &id);
            (seed, err, at)
        })
        .collect();
    for (seed, err, at) in &results {
        println!("motor {seed}: worst {err:.2} of the tolerance ({at})");
    }
    let worst = results.iter().map(|r| r.1).fold(0.0, f64::max);
    println!("{} motors: worst {worst:.2} of the tolerance max(10 %, 1 mN·m)", results.len());
    for (seed, err, at) in &results {
        assert!(*err <= 1.0, "motor {seed}: {err:.2} of the tolerance at {at}");
    }
}

#[test]
fn real_motors_ripple_is_identified_at_every_operating_point_on_the_encoder_route() {
    family(0..CI_MOTORS);
}

#[test]
#[ignore = "50 motors: run with --release --ignored (module documentation)"]
fn fifty_real_motors_ripple_is_identified_at_every_operating_point_on_the_encoder_route() {
    family(0..50);
}
