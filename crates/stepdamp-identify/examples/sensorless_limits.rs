//! Where the sensorless route stops working: the worst harmonic error over patent-motor and
//! five seeded random motors as one condition at a time departs from the plan's (current
//! noise, untrimmed or wrong R, wrong L, wrong Km, slower runs). Prints a Markdown table
//! (docs/sensorless.md and README quote it):
//!
//! ```text
//! cargo run --release -p stepdamp-identify --example sensorless_limits
//! ```

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::f64::consts::PI;
use stepdamp_identify::fit::wrap_pi;
use stepdamp_identify::plan::run_seed;
use stepdamp_identify::sensorless::flux::FluxOptions;
use stepdamp_identify::sensorless::log::SensorlessLog;
use stepdamp_identify::sensorless::plan::{SensorlessPlanOptions, plan};
use stepdamp_identify::sensorless::{fit_options, identify};
use stepdamp_identify::simulate::simulate_open_loop_run;
use stepdamp_profile::{DetentTerm, Profile};

/// One condition: what the base profile, the noise, the plan and the estimate get.
struct Condition {
    name: &'static str,
    noise_a: f64,
    r: f64,
    l: f64,
    km: f64,
    trim_r: bool,
    resonance_fraction: f64,
}

const PLAN: Condition = Condition {
    name: "the plan (5 mA, R trimmed)",
    noise_a: 0.005,
    r: 1.1,
    l: 1.0,
    km: 1.0,
    trim_r: true,
    resonance_fraction: 0.35,
};

fn motor(seed: u64) -> Profile {
    let p = Profile::preset("patent-motor").unwrap();
    if seed == 0 {
        return p;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(0x1_1a17 + seed);
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
    })
    .unwrap()
}

/// Worst amplitude error (fraction) and phase error (rad) over the harmonics ≥ 5 mN·m.
fn errors(m: &Profile, c: &Condition, seed: u64) -> Result<(f64, f64), String> {
    let base = m
        .edited("datasheet", |d| {
            d.motor.detent.clear();
            d.motor.resistance_ohm *= c.r;
            d.motor.inductance_h *= c.l;
            d.motor.km_nm_per_a *= c.km;
        })
        .map_err(|e| e.to_string())?;
    let o = SensorlessPlanOptions { resonance_fraction: c.resonance_fraction, ..SensorlessPlanOptions::default() };
    let p = plan(&base, &o).map_err(|e| e.to_string())?;
    let logs = p
        .runs
        .iter()
        .enumerate()
        .map(|(i, r)| {
            simulate_open_loop_run(m, &base, r, c.noise_a, run_seed(seed, i as u64))
                .map(|rows| SensorlessLog::from_rows(&rows, &r.name))
                .map_err(|e| e.to_string())
        })
        .collect::<Result<Vec<_>, _>>()?;
    let fo = FluxOptions { min_standstill_s: if c.trim_r { 0.02 } else { f64::INFINITY }, ..FluxOptions::default() };
    let f = identify(&logs, &base, &fit_options(&base, &[1, 2, 4]), &fo).map_err(|e| e.to_string())?;
    let (mut amp, mut phase) = (0.0f64, 0.0f64);
    for h in m.motor.detent.iter().filter(|h| h.amplitude_nm >= 0.005) {
        let g = f.fit.harmonics.iter().find(|g| g.order == h.order).ok_or("order missing")?;
        amp = amp.max((g.amplitude_nm.value / h.amplitude_nm - 1.0).abs());
        phase = phase.max(wrap_pi(g.phase_rad.value - h.phase_rad).abs());
    }
    Ok((amp, phase))
}

fn main() {
    let conditions = [
        PLAN,
        Condition { name: "current noise 20 mA", noise_a: 0.02, ..PLAN },
        Condition { name: "current noise 50 mA", noise_a: 0.05, ..PLAN },
        Condition { name: "current noise 100 mA", noise_a: 0.1, ..PLAN },
        Condition { name: "R not trimmed, base exact", trim_r: false, r: 1.0, ..PLAN },
        Condition { name: "R not trimmed, base +1 %", trim_r: false, r: 1.01, ..PLAN },
        Condition { name: "R not trimmed, base +10 %", trim_r: false, ..PLAN },
        Condition { name: "L +5 %", l: 1.05, ..PLAN },
        Condition { name: "L −10 %", l: 0.9, ..PLAN },
        Condition { name: "L +20 %", l: 1.2, ..PLAN },
        Condition { name: "Km +10 %", km: 1.1, ..PLAN },
        Condition { name: "runs 4× slower (less back-EMF)", resonance_fraction: 0.35 / 4.0, ..PLAN },
        Condition {
            name: "runs 4× slower, R not trimmed, base +1 %",
            resonance_fraction: 0.35 / 4.0,
            trim_r: false,
            r: 1.01,
            ..PLAN
        },
    ];
    let motors: Vec<Profile> = (0..6).map(motor).collect();
    println!("| condition (one at a time; base R +10 % unless said) | worst amplitude error | worst phase error |");
    println!("|---|---:|---:|");
    for c in &conditions {
        let r: Vec<Result<(f64, f64), String>> =
            motors.par_iter().enumerate().map(|(i, m)| errors(m, c, 1 + i as u64)).collect();
        match r.into_iter().collect::<Result<Vec<_>, _>>() {
            Ok(v) => {
                let a = v.iter().map(|x| x.0).fold(0.0, f64::max);
                let p = v.iter().map(|x| x.1).fold(0.0, f64::max);
                println!("| {} | {:.1} % | {:.3} rad |", c.name, 100.0 * a, p);
            }
            Err(e) => println!("| {} | fails: {e} | |", c.name),
        }
    }
    println!(
        "\npatent-motor and 5 random motors (detent 4–30 mN·m, J ×0.5–3); tolerance of docs/sensorless.md: 10 % and 0.1 rad"
    );
}
