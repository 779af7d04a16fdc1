//! One pass of the fit: the solve ([`crate::lsq`]) of the design ([`super::design`]) and the
//! result made from it.

use super::design::{self, Built};
use super::prepare::Prepared;
use super::thresholds::Z_95;
use super::{Effort, Estimate, Fit, FitError, FitOptions, FitSamples, HarmonicEstimate, Warning, polar_with_ci};
use crate::lsq::{self, LsqError};

/// Fits the prepared logs once; `d_ripple` is the `D` of the viscous torque of the speed
/// ripple subtracted from the data.
pub(super) fn fit_prepared(prepared: &[&Prepared], o: &FitOptions, d_ripple: f64) -> Result<Fit, FitError> {
    let Built { design, cols, theta_e: theta_e_used, alpha: alpha_used, mut runs, mut warnings, one_direction, fit_d } =
        design::build(prepared, o, d_ripple)?;
    let non_finite = |what: String| non_finite(prepared, o, what);
    let (nh, p) = (o.orders.len(), cols.p);
    let sol = match lsq::solve(&design) {
        Ok(sol) => sol,
        Err(LsqError::NonFinite(what)) => return Err(non_finite(what.to_string())),
        Err(e) => return Err(e.into()),
    };
    if let Some(what) = non_finite_in(&sol) {
        return Err(non_finite(what.to_string()));
    }

    let mut harmonics = Vec::with_capacity(nh);
    for (j, &k) in o.orders.iter().enumerate() {
        let (a, b) = (sol.beta[2 * j], sol.beta[2 * j + 1]);
        let (vaa, vab, vbb) = (sol.cov[(2 * j, 2 * j)], sol.cov[(2 * j, 2 * j + 1)], sol.cov[(2 * j + 1, 2 * j + 1)]);
        let (amplitude, phase) = polar_with_ci(a, b, vaa, vab, vbb);
        if amplitude.value < amplitude.ci95 {
            warnings.push(Warning::NotSignificant { order: k });
        }
        harmonics.push(HarmonicEstimate { order: k, amplitude_nm: amplitude, phase_rad: phase, a_nm: a, b_nm: b });
    }
    let est = |c: usize| Estimate { value: sol.beta[c], ci95: Z_95 * sol.cov[(c, c)].max(0.0).sqrt() };
    let coulomb = est(cols.fs);
    let viscous = cols.d.map(est);
    let offset = cols.c.map(est);
    let inertia = cols.j.map(est);
    let inertia_used = inertia.map_or(o.inertia_kg_m2, |j| j.value);
    let finite = |e: &Estimate| e.value.is_finite() && e.ci95.is_finite();
    if !harmonics.iter().all(|h| finite(&h.amplitude_nm) && finite(&h.phase_rad)) {
        return Err(non_finite("a harmonic amplitude or its interval".into()));
    }
    if !(finite(&coulomb) && viscous.iter().chain(&offset).all(finite)) {
        return Err(non_finite("a friction term or its interval".into()));
    }
    if !inertia.iter().all(finite) {
        return Err(non_finite("the inertia or its interval".into()));
    }
    warnings.extend(super::warnings::of_estimates(o, &cols, &sol, coulomb, viscous, inertia, one_direction, fit_d));

    // Periodic part and per-log inertial share.
    let mut ripple = Vec::with_capacity(sol.residual.len());
    let mut fitted_ss = 0.0;
    let mut start = 0;
    for run in runs.iter_mut() {
        let (mut s_inertial, mut s_fit) = (0.0, 0.0);
        #[allow(clippy::needless_range_loop)] // three parallel arrays are read at i
        for i in start..start + run.samples_used {
            let xrow = &design.x[i * p..(i + 1) * p];
            let fitted: f64 = (0..2 * nh).map(|c| xrow[c] * sol.beta[c]).sum();
            ripple.push(fitted + sol.residual[i]);
            let j_alpha = inertia_used * alpha_used[i];
            s_inertial += j_alpha * j_alpha;
            s_fit += fitted * fitted;
        }
        fitted_ss += s_fit;
        run.inertial_share = if s_fit > 0.0 { (s_inertial / s_fit).sqrt() } else { 0.0 };
        if run.inertial_share > o.max_inertial_share {
            warnings.push(Warning::InertialShare { source: run.source.clone(), share: run.inertial_share });
        }
        start += run.samples_used;
    }
    let ripple_rms_nm = (fitted_ss / ripple.len().max(1) as f64).sqrt();
    if !ripple_rms_nm.is_finite() {
        return Err(non_finite("the fitted detent ripple".into()));
    }
    Ok(Fit {
        harmonics,
        coulomb_friction_nm: coulomb,
        viscous_used: viscous.map_or(o.viscous_fallback_nm_s_per_rad, |v| v.value),
        viscous_nm_s_per_rad: viscous,
        offset_nm: offset,
        inertia_kg_m2: inertia,
        inertia_used,
        residual_rms_nm: sol.residual_rms,
        ripple_rms_nm,
        samples_used: sol.residual.len(),
        condition: sol.condition,
        runs,
        warnings,
        decisions: Vec::new(),
        samples: FitSamples { theta_e_rad: theta_e_used, ripple_nm: ripple, residual_nm: sol.residual },
    })
}

/// The error for a value that is not finite, naming the logs and where their effort is largest.
pub(super) fn non_finite(prepared: &[&Prepared], o: &FitOptions, what: String) -> FitError {
    let logs = prepared.iter().map(|p| p.log.source.as_str()).collect::<Vec<_>>().join(", ");
    FitError::NonFinite { what, logs, detail: largest_effort(prepared, o) }
}

/// The first part of a least-squares solution that is not finite: a coefficient, the
/// covariance (it gives every interval) or the residual.
fn non_finite_in(sol: &lsq::Solution) -> Option<&'static str> {
    if sol.beta.iter().any(|b| !b.is_finite()) {
        Some("a coefficient")
    } else if sol.cov.iter().any(|c| !c.is_finite()) {
        Some("the covariance")
    } else if !sol.residual_rms.is_finite() || sol.residual.iter().any(|e| !e.is_finite()) {
        Some("the residual")
    } else {
        None
    }
}

/// Where the effort of the logs is largest in magnitude (or not a number), for errors.
fn largest_effort(prepared: &[&Prepared], o: &FitOptions) -> String {
    let mut largest: Option<(f64, &str)> = None;
    for p in prepared {
        let effort = match o.effort {
            Effort::MeasuredIq => Some(&p.log.i_q_a),
            Effort::CommandIq => p.log.iq_cmd_a.as_ref(),
        };
        for &v in effort.into_iter().flatten() {
            if v.is_nan() {
                return format!("a current that is not a number in {}", p.log.source);
            }
            if largest.is_none_or(|(m, _)| v.abs() > m) {
                largest = Some((v.abs(), &p.log.source));
            }
        }
    }
    match largest {
        Some((m, src)) => format!("largest |current| {m:.3e} A, in {src}"),
        None => "no current samples".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::wrap_pi;
    use std::f64::consts::PI;

    #[test]
    fn wrap_pi_maps_into_the_half_open_interval() {
        assert_eq!(wrap_pi(PI), PI);
        assert_eq!(wrap_pi(-PI), PI);
        assert!((wrap_pi(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
        assert!((wrap_pi(0.3) - 0.3).abs() < 1e-15);
    }

    #[test]
    fn a_non_finite_coefficient_covariance_or_residual_is_caught_after_the_solve() {
        let ok = lsq::Solution {
            beta: vec![1.0, 2.0],
            cov: nalgebra::DMatrix::identity(2, 2),
            residual: vec![0.1, -0.1, 0.0],
            residual_rms: 0.08,
            condition: 1.0,
            inflation: vec![1.0, 1.0],
        };
        assert_eq!(non_finite_in(&ok), None);
        let mut s = ok.clone();
        s.cov[(1, 0)] = f64::NAN;
        assert_eq!(non_finite_in(&s), Some("the covariance"));
        let mut s = ok.clone();
        s.beta[0] = f64::INFINITY;
        assert_eq!(non_finite_in(&s), Some("a coefficient"));
        let mut s = ok;
        s.residual_rms = f64::INFINITY;
        assert_eq!(non_finite_in(&s), Some("the residual"));
    }
}
