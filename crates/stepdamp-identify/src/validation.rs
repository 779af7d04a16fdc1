//! A validation a user can trust: how much of the effort's periodic ripple
//! the identified model explains, per run and overall, and what is left, order by order.
//!
//! The torque the detent model must explain at each used sample is the fit's
//! [`FitSamples::ripple_nm`](crate::fit::FitSamples::ripple_nm) (`Km·i − J·dω/dt` minus
//! friction and the constant); what it leaves is the residual. Both are projected, by least
//! squares over the samples, on `sin, cos(k·θe)` for `k = 1..=`[`Validation::max_order`]
//! (and a constant): the *periodic* part, at every order whether fitted or not. The share
//! explained is `1 − Σ_k R_k² / Σ_k P_k²`, with `P_k`, `R_k` the amplitudes of the ripple
//! and of the residual at order `k` — the share of the ripple's periodic power the model
//! accounts for. Noise and loop jitter that are not periodic in the angle do not count
//! against it. An order not fitted (or fitted wrongly) shows as its residual amplitude.

use crate::fit::Fit;
use serde::Serialize;

/// Residual ripple at one order.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct OrderAmplitude {
    /// Harmonic order `k` of the electrical angle.
    pub order: u16,
    /// Amplitude, N·m.
    pub amplitude_nm: f64,
}

/// The validation of one run, or of all runs together.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunValidation {
    /// The run's source, or `all runs`.
    pub source: String,
    /// Share of the periodic effort ripple the model explains, 0–1.
    pub explained_share: f64,
    /// RMS of the periodic effort ripple (all orders up to the maximum), N·m.
    pub periodic_ripple_rms_nm: f64,
    /// Amplitude of the residual ripple at each order `1..=max_order`, N·m.
    pub unexplained: Vec<OrderAmplitude>,
}

impl RunValidation {
    /// The order with the largest unexplained amplitude.
    pub fn largest_unexplained(&self) -> Option<OrderAmplitude> {
        self.unexplained.iter().copied().max_by(|a, b| a.amplitude_nm.total_cmp(&b.amplitude_nm))
    }
}

/// The validation of a fit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Validation {
    /// Highest order examined.
    pub max_order: u16,
    /// Per run, in the fit's order.
    pub runs: Vec<RunValidation>,
    /// All runs together.
    pub overall: RunValidation,
}

/// Default highest order examined: twice the highest fitted order, at least 8.
pub fn default_max_order(f: &Fit) -> u16 {
    f.harmonics.iter().map(|h| h.order).max().unwrap_or(1).saturating_mul(2).max(8)
}

/// Validates a fit up to order `max_order` (≥ 1).
pub fn validate(f: &Fit, max_order: u16) -> Validation {
    let max_order = max_order.max(1);
    let s = &f.samples;
    let mut runs = Vec::with_capacity(f.runs.len());
    let mut start = 0;
    for r in &f.runs {
        let end = (start + r.samples_used).min(s.theta_e_rad.len());
        runs.push(one(
            &r.source,
            &s.theta_e_rad[start..end],
            &s.ripple_nm[start..end],
            &s.residual_nm[start..end],
            max_order,
        ));
        start = end;
    }
    let overall = one("all runs", &s.theta_e_rad, &s.ripple_nm, &s.residual_nm, max_order);
    Validation { max_order, runs, overall }
}

fn one(source: &str, theta_e: &[f64], ripple: &[f64], residual: &[f64], max_order: u16) -> RunValidation {
    let p = amplitudes(theta_e, ripple, max_order);
    let r = amplitudes(theta_e, residual, max_order);
    let (pp, rr): (f64, f64) = (p.iter().map(|a| a * a).sum(), r.iter().map(|a| a * a).sum());
    RunValidation {
        source: source.to_string(),
        explained_share: if pp > 0.0 { (1.0 - rr / pp).max(0.0) } else { 0.0 },
        periodic_ripple_rms_nm: (0.5 * pp).sqrt(),
        unexplained: r
            .iter()
            .enumerate()
            .map(|(k, &a)| OrderAmplitude { order: k as u16 + 1, amplitude_nm: a })
            .collect(),
    }
}

/// Least-squares amplitudes of `y` on `sin, cos(k·θe)`, `k = 1..=max_order`, and a constant;
/// zeros when the system cannot be solved (too few samples or angles).
fn amplitudes(theta_e: &[f64], y: &[f64], max_order: u16) -> Vec<f64> {
    let m = 2 * usize::from(max_order) + 1;
    let mut design = crate::lsq::Design::new(m);
    let mut row = vec![0.0; m];
    for (&te, &v) in theta_e.iter().zip(y) {
        let (s1, c1) = te.sin_cos();
        let (mut s, mut c) = (s1, c1);
        for k in 0..usize::from(max_order) {
            row[2 * k] = s;
            row[2 * k + 1] = c;
            // Angle addition: sin, cos of (k+2)·θe from (k+1)·θe.
            (s, c) = (s * c1 + c * s1, c * c1 - s * s1);
        }
        row[m - 1] = 1.0;
        // One block: only the coefficients are used, not their covariance.
        design.push(&row, v, 0);
    }
    match crate::lsq::solve(&design) {
        Ok(sol) => (0..usize::from(max_order)).map(|k| sol.beta[2 * k].hypot(sol.beta[2 * k + 1])).collect(),
        Err(_) => vec![0.0; usize::from(max_order)],
    }
}

impl std::fmt::Display for RunValidation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: explains {:.1} % of the effort ripple", self.source, 100.0 * self.explained_share)?;
        if let Some(w) = self.largest_unexplained() {
            write!(f, "; largest unexplained order {}: {:.2} mN·m", w.order, 1e3 * w.amplitude_nm)?;
        }
        Ok(())
    }
}

impl std::fmt::Display for Validation {
    /// One line per run, then the verdict line (without the source name).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for r in &self.runs {
            writeln!(f, "  {r}")?;
        }
        write!(f, "explains {:.1} % of the effort ripple", 100.0 * self.overall.explained_share)?;
        if let Some(w) = self.overall.largest_unexplained() {
            write!(f, "; largest unexplained order {}: {:.2} mN·m", w.order, 1e3 * w.amplitude_nm)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    #[test]
    fn an_order_left_out_of_the_model_is_the_largest_unexplained_with_its_amplitude() {
        // Ripple: orders 4 (20 mN·m) and 3 (0.4 mN·m); the model explains order 4 only.
        let n = 20_000;
        let te: Vec<f64> = (0..n).map(|i| (f64::from(i) * 0.0123) % TAU).collect();
        let ripple: Vec<f64> = te.iter().map(|&x| 0.02 * (4.0 * x + 0.3).sin() + 0.0004 * (3.0 * x).cos()).collect();
        let residual: Vec<f64> = te.iter().map(|&x| 0.0004 * (3.0 * x).cos()).collect();
        let v = one("r", &te, &ripple, &residual, 8);
        let w = v.largest_unexplained().unwrap();
        assert_eq!(w.order, 3);
        assert!((w.amplitude_nm - 0.0004).abs() < 1e-9, "{w:?}");
        let want = 1.0 - (0.0004f64 / 0.02).powi(2) / (1.0 + (0.0004f64 / 0.02).powi(2));
        assert!((v.explained_share - want).abs() < 1e-9, "{}", v.explained_share);
        let line = v.to_string();
        assert!(line.contains("explains 100.0 %") && line.contains("order 3: 0.40 mN·m"), "{line}");
    }

    #[test]
    fn noise_that_is_not_periodic_in_the_angle_does_not_count_against_the_model() {
        let n = 50_000u32;
        let te: Vec<f64> = (0..n).map(|i| (f64::from(i) * 0.01) % TAU).collect();
        // A pseudo-random residual (a fixed sequence, not periodic in θe).
        let noise: Vec<f64> = (0..n).map(|i| 1e-3 * ((f64::from(i) * 12.9898).sin() * 43758.5453).fract()).collect();
        let ripple: Vec<f64> = te.iter().zip(&noise).map(|(&x, e)| 0.01 * (2.0 * x).sin() + e).collect();
        let v = one("r", &te, &ripple, &noise, 8);
        assert!(v.explained_share > 0.99, "{}", v.explained_share);
    }
}
