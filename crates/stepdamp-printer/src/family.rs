//! A seeded family of simulated Prusa printers: random real motors, random heads, the
//! accelerometer of [`AccelModel`] and a random run current
//! (`docs/accelerometer.md#a-family-of-simulated-printers`).
//!
//! Every range below is drawn **uniformly** (phases in `[−π, π)`), each from its own source:
//!
//! | what | range | source or assumption |
//! |---|---|---|
//! | motor | `patent-motor` (Km 0.3 N·m/A, Nr 50, R 0.9 Ω, L 2.5 mH) | the project's reference motor |
//! | detent, orders 4, 2, 1 | [`DETENT_AMPLITUDE_NM`] each | the real-motor family (the sensorless acceptance test's ranges) |
//! | flux 3rd harmonic | ratio [`FLUX_THIRD_RATIO`] | measured motors: 0.4–1.5 % (`stepdamp_profile::flux::flux_limits::RATIO`), widened |
//! | flux 5th harmonic | ratio [`FLUX_FIFTH_RATIO`] | measured motors: 0.1–0.6 %, widened |
//! | `phase_b_gain` | [`PHASE_B_GAIN`] | measured motors: phases within ±4 % |
//! | rotor inertia | [`INERTIA_FACTOR`] × patent-motor's 40 g·cm² (20–80 g·cm²) | the real-motor family |
//! | Coulomb friction | [`COULOMB_FRICTION_NM`] | the real-motor family |
//! | pulley | GT2, [`PULLEY_TEETH`] teeth (`r = teeth·2 mm/2π`) | 16: MK4 and Core One (`HeadModel`'s default); 20: the other common size, an **assumption** |
//! | carriage | [`CARRIAGE_MASS_KG`] | an **assumption**: a light head to a heavy gantry |
//! | belt stiffness | [`BELT_STIFFNESS_N_PER_M`] | an **assumption**: with the mass, belt modes of 92–503 Hz |
//! | belt damping ratio | [`BELT_DAMPING_RATIO`] | an **assumption**: a glass- or steel-fibre belt |
//! | run current | [`RUN_CURRENT_A`] A peak (0.42–0.85 A RMS) | an **assumption** around the 0.9 A peak of the end-to-end tests |
//!
//! The accelerometer is [`AccelModel::default`]: the LIS2DH12's 1344 Hz with a seeded rate
//! error of ±0.1 %, 0.3 m/s² RMS of noise, 10-bit counts at ±2 g.
//!
//! **The belt mode is not kept away from the corrected harmonics.** In this model the belt
//! is a linear filter after the rotor (`HeadModel`'s rigid coupling): a harmonic on the
//! belt mode is amplified up to `1/(2ζ)`, the baseline and the residual alike, and the
//! correction (a torque on the rotor) is the same. Nothing in the physics of the model forces
//! a gap, so none is imposed.

use crate::{AccelModel, HeadModel, SimulatedPrinter};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::{PI, TAU};
use stepdamp_sim::Profile;
use stepdamp_sim::profile::{DetentTerm, FluxHarmonic, FluxSection};

/// The detent orders drawn, each with an amplitude in [`DETENT_AMPLITUDE_NM`].
pub const DETENT_ORDERS: [u16; 3] = [4, 2, 1];
/// Detent amplitude of each order (N·m): 4–30 mN·m.
pub const DETENT_AMPLITUDE_NM: (f64, f64) = (0.004, 0.030);
/// The flux linkage's 3rd harmonic, relative to the fundamental: 0–2 %.
pub const FLUX_THIRD_RATIO: (f64, f64) = (0.0, 0.02);
/// The flux linkage's 5th harmonic, relative to the fundamental: 0–1 %.
pub const FLUX_FIFTH_RATIO: (f64, f64) = (0.0, 0.01);
/// `motor.flux.phase_b_gain`: ±5 %.
pub const PHASE_B_GAIN: (f64, f64) = (-0.05, 0.05);
/// The rotor inertia's factor on patent-motor's: ×0.5–2.
pub const INERTIA_FACTOR: (f64, f64) = (0.5, 2.0);
/// Coulomb friction (N·m): 5–20 mN·m.
pub const COULOMB_FRICTION_NM: (f64, f64) = (0.005, 0.020);
/// GT2 pulley teeth, one of these with equal chance.
pub const PULLEY_TEETH: [u32; 2] = [16, 20];
/// Moving mass of the carriage (kg): 0.3–1.5 kg.
pub const CARRIAGE_MASS_KG: (f64, f64) = (0.3, 1.5);
/// Belt stiffness seen by the carriage (N/m): 0.5–3 MN/m.
pub const BELT_STIFFNESS_N_PER_M: (f64, f64) = (0.5e6, 3.0e6);
/// Damping ratio of the belt mode: 0.02–0.1.
pub const BELT_DAMPING_RATIO: (f64, f64) = (0.02, 0.1);
/// Run current (A, peak: the current vector's magnitude): 0.6–1.2 A.
pub const RUN_CURRENT_A: (f64, f64) = (0.6, 1.2);

/// The seed of [`family_printer`]`(seed)`'s draws: distinct from other families' seeds.
const SEED_BASE: u64 = 0x7072_7573_6100_0000;

/// Printer `seed` of the family (module doc): its motor is named `family-<seed>`, its
/// correction is empty (firmware ≥ 6.3.1), its noise seed is `seed` (set
/// [`SimulatedPrinter::seed`] for each capture that should have its own noise). The same
/// seed gives the same printer on every platform (ChaCha8).
pub fn family_printer(seed: u64) -> SimulatedPrinter {
    let mut rng = ChaCha8Rng::seed_from_u64(SEED_BASE ^ seed);
    let mut draw = |(lo, hi): (f64, f64)| if lo < hi { rng.random_range(lo..hi) } else { lo };
    let detent: Vec<DetentTerm> = DETENT_ORDERS
        .iter()
        .map(|&order| DetentTerm { order, amplitude_nm: draw(DETENT_AMPLITUDE_NM), phase_rad: draw((-PI, PI)) })
        .collect();
    let flux = FluxSection {
        phase_b_gain: draw(PHASE_B_GAIN),
        harmonics: vec![
            FluxHarmonic { order: 3, ratio: draw(FLUX_THIRD_RATIO), phase_rad: draw((-PI, PI)) },
            FluxHarmonic { order: 5, ratio: draw(FLUX_FIFTH_RATIO), phase_rad: draw((-PI, PI)) },
        ],
    };
    let inertia = draw(INERTIA_FACTOR);
    let friction = draw(COULOMB_FRICTION_NM);
    let teeth = PULLEY_TEETH[usize::from(draw((0.0, 1.0)) >= 0.5)];
    let head = HeadModel {
        pulley_radius_m: f64::from(teeth) * 2.0e-3 / TAU,
        carriage_mass_kg: draw(CARRIAGE_MASS_KG),
        belt_stiffness_n_per_m: draw(BELT_STIFFNESS_N_PER_M),
        belt_damping_ratio: draw(BELT_DAMPING_RATIO),
    };
    let current = draw(RUN_CURRENT_A);
    let name = format!("family-{seed}");
    let base = Profile::preset("patent-motor").expect("a built-in preset");
    let profile = base
        .edited(&name, |d| {
            d.name = name.clone();
            d.motor.detent = detent;
            d.motor.flux = flux;
            d.motor.inertia_kg_m2 *= inertia;
            d.motor.coulomb_friction_nm = friction;
        })
        .expect("every range is within the profile's limits (tested)");
    SimulatedPrinter { head, accel: AccelModel::default(), seed, ..SimulatedPrinter::new(profile, current) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn family_printers_are_repeatable_distinct_and_within_their_ranges() {
        let within = |v: f64, (lo, hi): (f64, f64)| v >= lo && v <= hi;
        for seed in 0..200 {
            let p = family_printer(seed);
            assert_eq!(format!("{p:?}"), format!("{:?}", family_printer(seed)));
            let m = &p.profile.motor;
            assert_eq!(m.detent.iter().map(|d| d.order).collect::<Vec<_>>(), DETENT_ORDERS);
            assert!(m.detent.iter().all(|d| within(d.amplitude_nm, DETENT_AMPLITUDE_NM)));
            assert!(within(m.flux.harmonics[0].ratio, FLUX_THIRD_RATIO));
            assert!(within(m.flux.harmonics[1].ratio, FLUX_FIFTH_RATIO));
            assert!(within(m.flux.phase_b_gain, PHASE_B_GAIN));
            assert!(within(m.inertia_kg_m2 / 4.0e-5, INERTIA_FACTOR));
            assert!(within(m.coulomb_friction_nm, COULOMB_FRICTION_NM));
            let teeth = (p.head.pulley_radius_m * TAU / 2.0e-3).round() as u32;
            assert!(PULLEY_TEETH.contains(&teeth));
            assert!(within(p.head.carriage_mass_kg, CARRIAGE_MASS_KG));
            assert!(within(p.head.belt_stiffness_n_per_m, BELT_STIFFNESS_N_PER_M));
            assert!(within(p.head.belt_damping_ratio, BELT_DAMPING_RATIO));
            assert!(within(p.run_current_a, RUN_CURRENT_A));
            p.head.check().unwrap();
        }
        assert_ne!(format!("{:?}", family_printer(1)), format!("{:?}", family_printer(2)));
    }
}
