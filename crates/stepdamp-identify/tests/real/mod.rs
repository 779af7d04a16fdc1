//! The real-motor family shared by the route tests (docs/identification.md#the-real-motor-family):
//! the motors, the user's base, the ripple comparison and the compensation check.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;
use stepdamp_profile::flux::{FluxHarmonic, FluxSection};
use stepdamp_profile::ripple::{RippleHarmonic, ripple};
use stepdamp_profile::{DetentTerm, Profile};
use stepdamp_sim::sweep::{SweepSpec, sweep};
use stepdamp_sim::{Compensation, Mode, RunSpec, SimOptions};

/// An operating point of the comparison: its name, `i_d` per unit of the holding current,
/// `i_q` in A.
pub type OperatingPoint = (&'static str, f64, f64);

/// Open loop at the holding current.
pub const OPEN_LOOP_HOLD: OperatingPoint = ("open loop I_hold", 1.0, 0.0);
/// Open loop at half the holding current.
pub const OPEN_LOOP_HALF: OperatingPoint = ("open loop I_hold/2", 0.5, 0.0);
/// Servo, `i_q = 0.5 A`.
pub const SERVO_HALF_AMP: OperatingPoint = ("servo iq 0.5 A", 0.0, 0.5);

/// Random real motor `seed` (module documentation).
pub fn real_motor(seed: u64) -> Profile {
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
pub fn user_base() -> Profile {
    Profile::preset("patent-motor").unwrap().edited("patent-motor", |d| d.motor.detent.clear()).unwrap()
}

/// The worst harmonic error of `id` against `truth` over the three operating points, as a
/// fraction of the tolerance max(10 %, 1 mN·m), with where it is.
pub fn worst_ripple_error(truth: &Profile, id: &Profile, points: &[OperatingPoint]) -> (f64, String) {
    let hold = truth.drive.holding_current_a;
    let mut worst = (0.0, String::new());
    for &(what, i_d_per_hold, i_q) in points {
        let i_d = i_d_per_hold * hold;
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

/// The peak-to-peak velocity error near the resonance of order `k` (largest over five speeds
/// ±10 %) of `motor` in open loop with `controller`, for each compensation of `comps`.
pub fn peaks(motor: &Profile, controller: &Profile, k: u16, comps: &[Compensation]) -> Vec<f64> {
    let w = motor.resonance_speed_rad_s(k);
    let spec = SweepSpec {
        speeds_rad_s: [0.9, 0.95, 1.0, 1.05, 1.1].iter().map(|f| f * w).collect(),
        modes: vec![Mode::OpenLoop],
        compensations: comps.to_vec(),
        run: RunSpec::at(w),
        options: SimOptions::default(),
        table: None,
    };
    let rows = sweep(motor, controller, &spec, &|| {}).unwrap();
    comps
        .iter()
        .map(|c| rows.iter().filter(|r| r.compensation == *c).map(|r| r.vel_err_pp_rad_s).fold(0.0, f64::max))
        .collect()
}

/// The compensation acceptance's bound on the patent's law: at least this share of the true
/// profile's dB reduction at orders 4 and 1 (docs/identification.md#the-real-motor-family).
pub const MIN_DB_SHARE: f64 = 0.8;
/// The compensation acceptance's bound on the estimated mode: at least this reduction (×) of
/// the peak-to-peak velocity error at orders 4, 2 and 1.
pub const MIN_ESTIMATED: f64 = 10.0;

/// The compensation check of the module documentation: the identified profile's share of the
/// true profile's dB reduction at orders 4 and 1 (patent's law), and the estimated mode's
/// worst reduction (×, orders 4, 2, 1) with the identified profile. Returns
/// `(worst share, worst estimated ×, a line)`; the line gives the true profile's reduction
/// beside each.
pub fn compensation(truth: &Profile, id: &Profile) -> (f64, f64, String) {
    use Compensation::{Estimated, Off, Patent};
    let (mut share, mut est, mut line) = (f64::INFINITY, f64::INFINITY, String::new());
    for k in [4u16, 2, 1] {
        let with_id = peaks(truth, id, k, &[Off, Patent, Estimated]);
        let with_truth = peaks(truth, truth, k, &[Off, Patent, Estimated]);
        let (x_est, x_est_true) = (with_id[0] / with_id[2], with_truth[0] / with_truth[2]);
        est = est.min(x_est);
        line += &format!(" k{k}: estimated {x_est:.1}x (true profile {x_est_true:.1}x)");
        if k != 2 {
            let (db_id, db_true) =
                (20.0 * (with_id[0] / with_id[1]).log10(), 20.0 * (with_truth[0] / with_truth[1]).log10());
            share = share.min(db_id / db_true);
            line += &format!(", patent {db_id:.1} dB of the truth's {db_true:.1} dB");
        }
    }
    (share, est, line)
}

/// Asserts the compensation acceptance ([`MIN_DB_SHARE`], [`MIN_ESTIMATED`]) on motor `seed`'s
/// [`compensation`] result: `share`, `estimated` (×) and its `line`.
pub fn assert_compensation(seed: u64, share: f64, estimated: f64, line: &str) {
    assert!(share >= MIN_DB_SHARE, "motor {seed}: {:.0} % of the true profile's dB reduction:{line}", 100.0 * share);
    assert!(estimated >= MIN_ESTIMATED, "motor {seed}: the estimated mode only {estimated:.1}x:{line}");
}

/// The median of `v` (the upper one of an even count).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The family's summary of [`compensation`] results `(share, estimated ×)`: the worst and the
/// median of each.
pub fn compensation_summary(results: &[(f64, f64)]) -> String {
    let (share, est): (Vec<f64>, Vec<f64>) = results.iter().copied().unzip();
    let least = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    format!(
        "patent's law: worst {:.0} % (median {:.0} %) of the true profile's dB at orders 4 and 1; estimated mode: worst {:.1}x (median {:.1}x)",
        100.0 * least(&share),
        100.0 * median(share.clone()),
        least(&est),
        median(est.clone())
    )
}
