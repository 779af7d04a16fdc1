//! The total ripple torque of a motor at an operating point: the detent, which does not depend
//! on current, plus the ripple of the motor torque, which grows with it
//! (docs/design.md#real-motors-flux-harmonics).
//!
//! The operating point is the current in the rotor's frame, `(i_d, i_q)` at the rotor's own
//! electrical angle `θe`: open loop at the holding current with load angle `δ` is
//! `(I·cos δ, I·sin δ)` (`(I_hold, 0)` unloaded); a servo at `i_d = 0` is `(0, i_q)`. The
//! winding currents are then `i_a = i_d·cos θe − i_q·sin θe`, `i_b = i_d·sin θe + i_q·cos θe`,
//! and the motor torque `τ_m(θe)` of [`crate::flux`] is evaluated over one electrical period
//! and resolved into harmonics by a discrete Fourier transform, exact for the orders present
//! (at most [`crate::flux::MAX_FLUX_ORDER`] + 1 = 16, far below the [`SAMPLES`]/2 it resolves).
//!
//! Every harmonic is given in the detent's sign convention: torque **on the rotor**
//! `−A·sin(k·θe + φ)`, cancelled by supplying `+A·sin(k·θe + φ)`.

use crate::profile::Profile;
use serde::Serialize;
use std::fmt;
use stepdamp_core::limits::Num;

/// Samples of one electrical period in the transform: resolves orders up to 63 without
/// aliasing (the motor-torque ripple has orders up to 16).
pub const SAMPLES: usize = 128;

/// Amplitudes below this (N·m) are reported as 0: the transform's rounding, not ripple.
pub const ROUNDING_NM: f64 = 1e-12;

/// Orders always reported (1–8), more where a part has higher ones.
pub const MIN_REPORTED_ORDERS: u16 = 8;

/// One harmonic of a ripple: torque on the rotor `−amplitude_nm·sin(order·θe + phase_rad)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RippleHarmonic {
    /// Order `k` of the electrical angle.
    pub order: u16,
    /// Amplitude `A ≥ 0` in N·m ([`ROUNDING_NM`] and below are 0).
    pub amplitude_nm: f64,
    /// Phase `φ` in rad, in `(−π, π]` (0 where the amplitude is 0).
    pub phase_rad: f64,
}

/// The ripple of a profile at one operating point ([`ripple`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Ripple {
    /// The profile's name.
    pub motor: String,
    /// `i_d` in A (rotor frame).
    pub i_d_a: f64,
    /// `i_q` in A (rotor frame).
    pub i_q_a: f64,
    /// Mean motor torque over an electrical period in N·m (`Km·i_q` for a pure sine).
    pub mean_torque_nm: f64,
    /// Detent plus motor-torque ripple, orders 1 to at least 8.
    pub harmonics: Vec<RippleHarmonic>,
    /// The part that does not depend on current (the profile's `[[motor.detent]]`).
    pub detent: Vec<RippleHarmonic>,
    /// The part that grows with current (the motor torque's ripple from `[motor.flux]`).
    pub current: Vec<RippleHarmonic>,
}

/// An operating point the drive cannot make.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{option} {value} A: must be in [-{limit}, {limit}] A (drive.current_limit_a of {motor}){extra}",
    value = Num(*.value), limit = Num(*.limit))]
pub struct RippleError {
    /// The option or argument, e.g. `--id`.
    pub option: &'static str,
    /// The value given.
    pub value: f64,
    /// The profile's current limit in A.
    pub limit: f64,
    /// The profile's name.
    pub motor: String,
    /// More about a vector beyond the limit.
    pub extra: String,
}

/// Fourier coefficients `(α, β)` of `α·cos kθ + β·sin kθ`, indexed by `k − 1`.
type Coefficients = Vec<(f64, f64)>;

fn to_harmonics(c: &[(f64, f64)]) -> Vec<RippleHarmonic> {
    c.iter()
        .enumerate()
        .map(|(i, &(alpha, beta))| {
            // α cos kθ + β sin kθ = −A sin(kθ + φ) ⇔ β = −A cos φ, α = −A sin φ.
            let a = alpha.hypot(beta);
            // Below a pN·m it is the transform's rounding (1e-17 N·m on a pure sine): 0.
            // `+ 0.0` turns a phase of −0 into 0.
            let (a, phase) = if a < ROUNDING_NM { (0.0, 0.0) } else { (a, (-alpha).atan2(-beta) + 0.0) };
            RippleHarmonic { order: i as u16 + 1, amplitude_nm: a, phase_rad: phase }
        })
        .collect()
}

/// The profile's detent as coefficients up to `orders`.
fn detent_coefficients(p: &Profile, orders: usize) -> Coefficients {
    let mut c = vec![(0.0, 0.0); orders];
    for h in p.motor.detent.iter().filter(|h| (1..=orders).contains(&usize::from(h.order))) {
        let (s, co) = h.phase_rad.sin_cos();
        let e = &mut c[usize::from(h.order) - 1];
        e.0 -= h.amplitude_nm * s;
        e.1 -= h.amplitude_nm * co;
    }
    c
}

/// The motor torque over one electrical period at `(i_d, i_q)`: its mean and coefficients.
fn current_coefficients(p: &Profile, i_d: f64, i_q: f64, orders: usize) -> (f64, Coefficients) {
    let shape = crate::flux::FluxShape::new(&p.motor.flux);
    let km = p.motor.km_nm_per_a;
    let mut mean = 0.0;
    let mut c = vec![(0.0, 0.0); orders];
    for j in 0..SAMPLES {
        let te = core::f64::consts::TAU * j as f64 / SAMPLES as f64;
        let (s, co) = te.sin_cos();
        let tau = shape.torque_nm(km, te, i_d * co - i_q * s, i_d * s + i_q * co);
        mean += tau;
        for (k, e) in c.iter_mut().enumerate() {
            let (sk, ck) = (((k + 1) as f64) * te).sin_cos();
            e.0 += tau * ck;
            e.1 += tau * sk;
        }
    }
    let n = SAMPLES as f64;
    let clean = |(a, b): (f64, f64)| {
        let (a, b) = (2.0 * a / n, 2.0 * b / n);
        if a.hypot(b) < ROUNDING_NM { (0.0, 0.0) } else { (a, b) }
    };
    // `+ 0.0`: a mean of −0 prints as 0.
    (mean / n + 0.0, c.into_iter().map(clean).collect())
}

/// The total ripple of `p` at rotor-frame currents `i_d`, `i_q` (A), with its detent and
/// current parts (module doc). The current vector must be within the drive's current limit.
pub fn ripple(p: &Profile, i_d: f64, i_q: f64) -> Result<Ripple, RippleError> {
    let limit = p.drive.current_limit_a;
    let err = |option, value, extra: String| RippleError { option, value, limit, motor: p.name.clone(), extra };
    for (option, v) in [("--id", i_d), ("--iq", i_q)] {
        if !(v.is_finite() && v.abs() <= limit) {
            return Err(err(option, v, String::new()));
        }
    }
    if i_d.hypot(i_q) > limit {
        let extra = format!("; the vector's magnitude is {} A", Num(i_d.hypot(i_q)));
        return Err(err("--iq", i_q, extra));
    }
    let orders = reported_orders(p);
    let detent = detent_coefficients(p, orders);
    let (mean, current) = current_coefficients(p, i_d, i_q, orders);
    let total: Coefficients = detent.iter().zip(&current).map(|(d, c)| (d.0 + c.0, d.1 + c.1)).collect();
    Ok(Ripple {
        motor: p.name.clone(),
        i_d_a: i_d,
        i_q_a: i_q,
        mean_torque_nm: mean,
        harmonics: to_harmonics(&total),
        detent: to_harmonics(&detent),
        current: to_harmonics(&current),
    })
}

/// The ripple of `p` split by what it is proportional to (the ripple is exactly linear in
/// the rotor-frame currents at each angle): `T(θe) = detent(θe) + i_d·D(θe) + i_q·Q(θe)`,
/// the parts the controller feeds forward at its operating point
/// (`stepdamp_core::ripple`, docs/design.md#real-motors-flux-harmonics).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RippleParts {
    /// The part that does not depend on current, N·m (orders 1 to at least 8).
    pub detent: Vec<RippleHarmonic>,
    /// `D`: the motor torque's ripple per ampere of `i_d`, N·m/A (its mean is 0).
    pub per_amp_d: Vec<RippleHarmonic>,
    /// `Q̃`: the motor torque's ripple per ampere of `i_q` without its mean, N·m/A.
    pub per_amp_q: Vec<RippleHarmonic>,
    /// The mean of `Q`, the torque constant of the whole motor, N·m/A: `Km·(1 + g/2)`
    /// with a phase imbalance `g`, `Km` for equal phases.
    pub mean_per_amp_q_nm_per_a: f64,
}

/// The orders a transform of `p` reports: 1 to at least [`MIN_REPORTED_ORDERS`], and every
/// detent order and flux-made order (`n + 1` for flux harmonic `n`).
fn reported_orders(p: &Profile) -> usize {
    let highest_detent = p.motor.detent.iter().map(|h| h.order).max().unwrap_or(0);
    let highest_flux = p.motor.flux.harmonics.iter().map(|h| h.order + 1).max().unwrap_or(0);
    usize::from(MIN_REPORTED_ORDERS.max(highest_detent).max(highest_flux).max(2))
}

/// The parts of [`RippleParts`]: the motor torque at `(1, 0)` and `(0, 1)` A, the same
/// transform as [`ripple`] (no current limit applies: these are per ampere).
pub fn ripple_parts(p: &Profile) -> RippleParts {
    let orders = reported_orders(p);
    let (_, d) = current_coefficients(p, 1.0, 0.0, orders);
    let (mean_q, q) = current_coefficients(p, 0.0, 1.0, orders);
    RippleParts {
        detent: to_harmonics(&detent_coefficients(p, orders)),
        per_amp_d: to_harmonics(&d),
        per_amp_q: to_harmonics(&q),
        mean_per_amp_q_nm_per_a: mean_q,
    }
}

/// The text `stepdamp motor ripple` prints: one row per order, amplitudes in mN·m.
impl fmt::Display for Ripple {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}: ripple torque on the rotor −A·sin(k·θe + φ) at i_d = {} A, i_q = {} A (mean motor torque {:.4} N·m)",
            self.motor,
            Num(self.i_d_a),
            Num(self.i_q_a),
            self.mean_torque_nm
        )?;
        writeln!(f, "order   total mN·m  phase rad   detent mN·m  phase rad   current mN·m  phase rad")?;
        for ((t, d), c) in self.harmonics.iter().zip(&self.detent).zip(&self.current) {
            writeln!(
                f,
                "{:>5}  {:>11.4}  {:>9.4}  {:>12.4}  {:>9.4}  {:>13.4}  {:>9.4}",
                t.order,
                t.amplitude_nm * 1e3,
                t.phase_rad,
                d.amplitude_nm * 1e3,
                d.phase_rad,
                c.amplitude_nm * 1e3,
                c.phase_rad
            )?;
        }
        Ok(())
    }
}

/// Column names of the CSV form, one row per order (amplitudes in N·m, phases in rad).
pub const RIPPLE_CSV_COLUMNS: [&str; 7] = [
    "order",
    "total_amplitude_nm",
    "total_phase_rad",
    "detent_amplitude_nm",
    "detent_phase_rad",
    "current_amplitude_nm",
    "current_phase_rad",
];

impl Ripple {
    /// The rows of the CSV form, in the order of [`RIPPLE_CSV_COLUMNS`].
    pub fn csv_rows(&self) -> Vec<[f64; 7]> {
        self.harmonics
            .iter()
            .zip(&self.detent)
            .zip(&self.current)
            .map(|((t, d), c)| {
                [
                    f64::from(t.order),
                    t.amplitude_nm,
                    t.phase_rad,
                    d.amplitude_nm,
                    d.phase_rad,
                    c.amplitude_nm,
                    c.phase_rad,
                ]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flux::{FluxHarmonic, FluxSection};

    fn motor(flux: FluxSection) -> Profile {
        Profile::preset("patent-motor").unwrap().edited("test", |d| d.motor.flux = flux).unwrap()
    }

    /// `−Σ A·sin(kθe + φ)` of a list of harmonics at `θe`.
    fn eval(h: &[RippleHarmonic], te: f64) -> f64 {
        h.iter().map(|h| -h.amplitude_nm * (f64::from(h.order) * te + h.phase_rad).sin()).sum()
    }

    #[test]
    fn open_loop_ripple_of_third_and_fifth_harmonics_is_the_closed_form() {
        // docs/design.md#real-motors-flux-harmonics: at current I and load angle δ
        // (i_d = I cos δ, i_q = I sin δ), with g = 0 the motor torque is exactly
        // Km·I·sin δ − 3h3·Km·I·sin(4θe + a3 + δ) − 5h5·Km·I·sin(4θe + a5 − δ).
        let (h3, a3, h5, a5) = (0.012, 0.4, 0.005, -1.1);
        let p = motor(FluxSection {
            phase_b_gain: 0.0,
            harmonics: vec![
                FluxHarmonic { order: 3, ratio: h3, phase_rad: a3 },
                FluxHarmonic { order: 5, ratio: h5, phase_rad: a5 },
            ],
        });
        let km = p.motor.km_nm_per_a;
        for (i, delta) in [(1.9, 0.0), (1.9, 0.35), (0.95, -0.6)] {
            let r = ripple(&p, i * f64::cos(delta), i * f64::sin(delta)).unwrap();
            assert!((r.mean_torque_nm - km * i * delta.sin()).abs() < 1e-12);
            for j in 0..60 {
                let te = 0.21 * f64::from(j);
                let want = -3.0 * h3 * km * i * (4.0 * te + a3 + delta).sin()
                    - 5.0 * h5 * km * i * (4.0 * te + a5 - delta).sin();
                assert!((eval(&r.current, te) - want).abs() < 1e-12, "I {i} δ {delta} θe {te}");
            }
            // Only order 4 in the current part.
            let big: Vec<u16> = r.current.iter().filter(|h| h.amplitude_nm > 1e-12).map(|h| h.order).collect();
            assert_eq!(big, vec![4]);
        }
    }

    #[test]
    fn phase_imbalance_gives_a_second_order_ripple_proportional_to_current() {
        // (g·Km·I/2)·[sin(2θe + δ) + sin δ], exactly when there are no harmonics.
        let g = 0.04;
        let p = motor(FluxSection { phase_b_gain: g, harmonics: vec![] });
        let km = p.motor.km_nm_per_a;
        for (i, delta) in [(1.9, 0.0), (1.0, 0.5)] {
            let r = ripple(&p, i * f64::cos(delta), i * f64::sin(delta)).unwrap();
            let mean = km * i * delta.sin() + g * km * i / 2.0 * delta.sin();
            assert!((r.mean_torque_nm - mean).abs() < 1e-12);
            let h2 = r.current[1];
            assert!((h2.amplitude_nm - g * km * i / 2.0).abs() < 1e-12, "{h2:?}");
            for j in 0..40 {
                let te = 0.3 * f64::from(j);
                let want = g * km * i / 2.0 * (2.0 * te + delta).sin();
                assert!((eval(&r.current, te) - want).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn the_total_is_detent_plus_current_part_and_the_detent_does_not_grow_with_current() {
        let p = motor(FluxSection {
            phase_b_gain: -0.03,
            harmonics: vec![FluxHarmonic { order: 3, ratio: 0.01, phase_rad: 2.0 }],
        });
        let half = ripple(&p, 0.95, 0.0).unwrap();
        let full = ripple(&p, 1.9, 0.0).unwrap();
        assert_eq!(half.detent, full.detent);
        for te in [0.0, 0.7, 2.9, 5.5] {
            let sum = eval(&full.detent, te) + eval(&full.current, te);
            assert!((eval(&full.harmonics, te) - sum).abs() < 1e-12);
            // Linear in the current: twice the current, twice the current part.
            assert!((eval(&full.current, te) - 2.0 * eval(&half.current, te)).abs() < 1e-12);
        }
        // The preset's detent: orders 4, 2, 1 at 20, 12, 8 mN·m.
        assert!((full.detent[3].amplitude_nm - 0.020).abs() < 1e-15);
        assert!(full.harmonics.len() >= usize::from(MIN_REPORTED_ORDERS));
    }

    #[test]
    fn the_ripple_at_any_current_is_the_detent_plus_the_parts_per_ampere() {
        let p = motor(FluxSection {
            phase_b_gain: 0.03,
            harmonics: vec![
                FluxHarmonic { order: 3, ratio: 0.012, phase_rad: 0.4 },
                FluxHarmonic { order: 5, ratio: 0.004, phase_rad: -0.8 },
            ],
        });
        let parts = ripple_parts(&p);
        let km = p.motor.km_nm_per_a;
        assert!((parts.mean_per_amp_q_nm_per_a - km * (1.0 + 0.03 / 2.0)).abs() < 1e-12);
        for (i_d, i_q) in [(1.9, 0.0), (0.0, 0.5), (1.2, -0.9), (-0.3, 2.1)] {
            let r = ripple(&p, i_d, i_q).unwrap();
            assert!((r.mean_torque_nm - parts.mean_per_amp_q_nm_per_a * i_q).abs() < 1e-12);
            for j in 0..50 {
                let te = 0.13 * f64::from(j);
                let sum = eval(&parts.detent, te) + i_d * eval(&parts.per_amp_d, te) + i_q * eval(&parts.per_amp_q, te);
                assert!((eval(&r.harmonics, te) - sum).abs() < 1e-12, "({i_d}, {i_q}) θe {te}");
            }
        }
    }

    #[test]
    fn the_controller_is_given_the_detent_and_the_ripple_per_ampere() {
        let plain = Profile::preset("patent-motor").unwrap();
        let m = plain.controller_harmonics();
        assert_eq!((m.detent, m.per_amp_d.len(), m.per_amp_q.len()), (plain.harmonics(), 0, 0));
        let p = motor(FluxSection {
            phase_b_gain: 0.03,
            harmonics: vec![FluxHarmonic { order: 3, ratio: 0.012, phase_rad: 0.4 }],
        });
        let m = p.controller_harmonics();
        assert_eq!(m.detent, p.harmonics());
        let parts = ripple_parts(&p);
        let nonzero = |h: &[RippleHarmonic]| -> Vec<(u16, f32)> {
            h.iter().filter(|h| h.amplitude_nm > 0.0).map(|h| (h.order, h.amplitude_nm as f32)).collect()
        };
        let given = |h: &[stepdamp_core::Harmonic]| -> Vec<(u16, f32)> {
            h.iter().map(|h| (h.order, h.amplitude_nm)).collect()
        };
        assert_eq!(given(&m.per_amp_d), nonzero(&parts.per_amp_d));
        assert_eq!(given(&m.per_amp_q), nonzero(&parts.per_amp_q));
        // Per ampere of i_d at a_3 = 0.4: order 4 carries 3·h3·Km, order 2 the imbalance g·Km/2.
        let d4 = m.per_amp_d.iter().find(|h| h.order == 4).unwrap().amplitude_nm;
        assert!((f64::from(d4) - 3.0 * 0.012 * 0.3).abs() < 1e-3 * 0.3, "{d4}");
    }

    #[test]
    fn a_pure_sine_motor_has_no_current_ripple() {
        let p = Profile::preset("patent-motor").unwrap();
        let r = ripple(&p, 0.0, 1.0).unwrap();
        assert!(r.current.iter().all(|h| h.amplitude_nm < 1e-12));
        assert!((r.mean_torque_nm - p.motor.km_nm_per_a).abs() < 1e-12);
    }

    #[test]
    fn currents_beyond_the_limit_are_refused_with_the_value_and_range() {
        let p = Profile::preset("patent-motor").unwrap();
        let e = ripple(&p, 1e9, 0.0).unwrap_err().to_string();
        assert!(e.starts_with("--id 1e9 A: must be in [-"), "{e}");
        assert!(ripple(&p, f64::NAN, 0.0).is_err());
        let lim = p.drive.current_limit_a;
        let e = ripple(&p, lim * 0.8, lim * 0.8).unwrap_err().to_string();
        assert!(e.contains("the vector's magnitude"), "{e}");
    }
}
