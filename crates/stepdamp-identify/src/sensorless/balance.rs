//! The phase currents' balance: in open loop the drive commands both phases with the same
//! amplitude (`i_a = I·cos θe_cmd`, `i_b = I·sin θe_cmd`), so logged amplitudes that differ
//! mean a current sensor's (or the logger's) gain is off. A gain error `ε` in one phase
//! puts an electrical second harmonic of about `ε/2` of the current into the Park `i_q`
//! the fit reads, and the fit reports it as detent order 2: phase A ×1.1 on `patent-motor`
//! gave order 2 at 106 mN·m for a true 12. Nothing in the torque balance can tell it from
//! detent, so the route refuses such logs, naming the ratio to correct the column by
//! (docs/sensorless.md#current-balance).

use super::log::SensorlessLog;
use nalgebra::{Matrix3, Vector3};

/// The largest relative difference of the phase-current amplitudes accepted, `|A_a/A_b − 1|`.
/// A 1 % gain error moves order 2 of `patent-motor` by about a tenth of the 106 mN·m of a
/// 10 % one, i.e. by most of its true 12 mN·m: more would not be an identification. The
/// simulator's logs (5 mA noise) differ by less than 0.1 %.
pub const MAX_CURRENT_IMBALANCE: f64 = 0.01;

/// The amplitudes of `i_a` and `i_b` at the commanded electrical angle, A: each phase's
/// least-squares fit `c₀ + c₁·cos θe_cmd + c₂·sin θe_cmd` over the samples after the
/// command starts moving (unbiased whatever fraction of a period the log ends on; the
/// constant takes a sensor offset). `None` when the command does not move or the fit is
/// singular.
pub fn phase_amplitudes(log: &SensorlessLog, pole_pairs: u16) -> Option<(f64, f64)> {
    let nr = f64::from(pole_pairs);
    let start = log.theta_cmd_rad.iter().position(|&c| c != log.theta_cmd_rad[0])?;
    let (mut m, mut ya, mut yb) = (Matrix3::<f64>::zeros(), Vector3::<f64>::zeros(), Vector3::<f64>::zeros());
    for k in start..log.theta_cmd_rad.len() {
        let (s, c) = (nr * log.theta_cmd_rad[k]).sin_cos();
        let row = Vector3::new(1.0, c, s);
        m += row * row.transpose();
        ya += row * log.i_a_a[k];
        yb += row * log.i_b_a[k];
    }
    let lu = m.lu();
    let (a, b) = (lu.solve(&ya)?, lu.solve(&yb)?);
    let (amp_a, amp_b) = (a[1].hypot(a[2]), b[1].hypot(b[2]));
    (amp_a.is_finite() && amp_b.is_finite() && amp_b > 0.0).then_some((amp_a, amp_b))
}

/// Phase currents of unequal amplitude in an open-loop log ([`MAX_CURRENT_IMBALANCE`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "{log}: the phase currents' amplitudes differ: i_a_a {amp_a:.4} A, i_b_a {amp_b:.4} A (ratio {ratio:.4}, more than ±{limit_pct} %), while open loop commands both alike: a current sensor's or the logger's gain is off, and its error would come out as detent order 2 (about ε/2 of the current as torque ripple); check the gains (hold a standstill current in phase A, then in B, against a meter), correct the column (i_b_a × {ratio:.4}, or i_a_a ÷ {ratio:.4}, whichever sensor is wrong) and identify again (docs/sensorless.md#current-balance)"
)]
pub struct Imbalance {
    /// The log.
    pub log: String,
    /// Amplitude of `i_a`, A.
    pub amp_a: f64,
    /// Amplitude of `i_b`, A.
    pub amp_b: f64,
    /// `amp_a / amp_b`.
    pub ratio: f64,
    /// [`MAX_CURRENT_IMBALANCE`] in percent.
    pub limit_pct: f64,
}

/// Refuses the first log whose phase-current amplitudes differ by more than
/// [`MAX_CURRENT_IMBALANCE`].
pub fn check(logs: &[SensorlessLog], pole_pairs: u16) -> Result<(), Imbalance> {
    for l in logs {
        if let Some((amp_a, amp_b)) = phase_amplitudes(l, pole_pairs) {
            let ratio = amp_a / amp_b;
            if (ratio - 1.0).abs() > MAX_CURRENT_IMBALANCE {
                let limit_pct = 100.0 * MAX_CURRENT_IMBALANCE;
                return Err(Imbalance { log: l.source.clone(), amp_a, amp_b, ratio, limit_pct });
            }
        }
    }
    Ok(())
}
