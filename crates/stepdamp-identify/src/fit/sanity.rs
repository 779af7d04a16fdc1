//! Physics sanity of a finished fit: Coulomb friction `Fs`, viscous damping `D` and inertia
//! `J` cannot be negative. One of them significantly negative (below zero by more than its
//! 95 % half-width, so not a noisy zero) means the logs' current and angle disagree in sign,
//! and every other number of the fit is then wrong too (the harmonics come out with the
//! wrong phase and a misleading amplitude, the fit still "explains" the data). So the fit is
//! refused here, before anything clamps (`Fs`, `D` to 0 in the profile) or holds (`J` at the
//! base's) the term and hides the cause (docs/identification.md#signs).
//!
//! `Fs` counts only when the constant torque `c` was fitted beside it (both directions
//! logged): with one direction `Fs` absorbs `c`, and a load that pushes the rotor along
//! makes it negative honestly (warned about and clamped: [`super::Warning::CoulombNotPositive`]).

use super::{Estimate, Fit, FitError};

/// Refuses a fit in which `Fs` (when `c` is fitted), `D` (when fitted) or `J` (when
/// fitted) lies below zero by
/// more than its 95 % half-width, naming the terms and the likely cause
/// ([`FitError::Unphysical`]). A value below zero within its interval is left to the
/// warnings (too little data).
pub(super) fn refuse_unphysical(f: &Fit) -> Result<(), FitError> {
    let terms: Vec<String> = [
        ("Fs", f.offset_nm.map(|_| f.coulomb_friction_nm), 1e3, "mN·m"),
        ("D", f.viscous_nm_s_per_rad, 1.0, "N·m·s/rad"),
        ("J", f.inertia_kg_m2, 1.0, "kg·m²"),
    ]
    .into_iter()
    .filter_map(|(name, e, scale, unit)| {
        let e: Estimate = e?;
        (e.value + e.ci95 < 0.0).then(|| format!("{name} = {:.4e} ± {:.1e} {unit}", scale * e.value, scale * e.ci95))
    })
    .collect();
    if terms.is_empty() {
        return Ok(());
    }
    let logs = f.runs.iter().map(|r| r.source.as_str()).collect::<Vec<_>>().join(", ");
    Err(FitError::Unphysical { terms: terms.join(", "), logs })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::FitSamples;

    fn fit_with(fs: Estimate, d: Option<Estimate>, j: Option<Estimate>) -> Fit {
        Fit {
            harmonics: Vec::new(),
            coulomb_friction_nm: fs,
            viscous_nm_s_per_rad: d,
            viscous_used: d.map_or(0.0, |d| d.value),
            offset_nm: Some(est(0.0, 1e-4)),
            inertia_kg_m2: j,
            inertia_used: j.map_or(1e-5, |j| j.value),
            residual_rms_nm: 0.0,
            ripple_rms_nm: 0.0,
            samples_used: 0,
            condition: 1.0,
            runs: Vec::new(),
            warnings: Vec::new(),
            decisions: Vec::new(),
            samples: FitSamples::default(),
        }
    }

    const fn est(value: f64, ci95: f64) -> Estimate {
        Estimate { value, ci95 }
    }

    #[test]
    fn significantly_negative_friction_damping_or_inertia_is_refused_naming_the_signs() {
        let bad = [
            fit_with(est(-0.008, 0.0001), None, None),
            fit_with(est(0.008, 0.0001), Some(est(-1e-4, 1e-6)), None),
            fit_with(est(0.008, 0.0001), None, Some(est(-1e-5, 1e-7))),
        ];
        for (f, term) in bad.iter().zip(["Fs = ", "D = ", "J = "]) {
            let e = refuse_unphysical(f).unwrap_err().to_string();
            assert!(e.contains(term) && e.contains("reversed") && e.contains("positive i_q"), "{e}");
            assert_eq!(e.lines().count(), 1, "{e}");
        }
    }

    #[test]
    fn a_noisy_zero_or_a_positive_term_passes() {
        assert!(
            refuse_unphysical(&fit_with(est(-0.001, 0.002), Some(est(-1e-6, 2e-6)), Some(est(1e-5, 1e-6)))).is_ok()
        );
        assert!(refuse_unphysical(&fit_with(est(0.008, 0.0001), Some(est(1e-4, 1e-6)), None)).is_ok());
    }

    #[test]
    fn a_negative_fs_that_absorbs_a_constant_torque_passes() {
        // One direction logged: `c` not fitted, a load pushing the rotor along makes Fs < 0.
        let f = Fit { offset_nm: None, ..fit_with(est(-0.02, 0.0005), None, None) };
        assert!(refuse_unphysical(&f).is_ok());
    }

    /// `patent-motor`'s planned runs (in memory), planned from the preset without its detent.
    #[cfg(feature = "simulate")]
    fn planned_logs() -> (Vec<crate::log::RunLog>, crate::fit::FitOptions) {
        use crate::plan::{PlanOptions, plan};
        let truth = stepdamp_sim::Profile::preset("patent-motor").unwrap();
        let base = truth.edited("user base", |b| b.motor.detent.clear()).unwrap();
        let o = PlanOptions { electrical_periods: 15.0, ..PlanOptions::default() };
        let p = plan(&base, &o).unwrap();
        let comp = stepdamp_sim::Compensation::Off;
        let logs =
            crate::simulate::simulate_plan(&truth, &p.profile, comp, &p, o.current_noise_a, o.seed, &|| {}).unwrap();
        (logs, crate::fit::FitOptions::for_profile(&p.profile, &[1, 2, 4]))
    }

    #[cfg(feature = "simulate")]
    #[test]
    fn a_reversed_current_or_angle_sign_is_refused_not_fitted() {
        let (logs, o) = planned_logs();
        assert!(crate::fit::fit(&logs, &o).is_ok());
        let negated = |f: fn(&mut crate::log::RunLog)| {
            let mut l = logs.clone();
            l.iter_mut().for_each(f);
            crate::fit::fit(&l, &o)
        };
        let current = negated(|l| l.i_q_a.iter_mut().for_each(|i| *i = -*i)).unwrap_err();
        let angle = negated(|l| l.theta_fb_rad.iter_mut().for_each(|t| *t = -*t)).unwrap_err();
        for e in [current, angle] {
            let text = e.to_string();
            eprintln!("{text}");
            assert!(matches!(e, FitError::Unphysical { .. }), "{e:?}");
            assert!(text.contains("Fs = -") && text.contains("positive i_q must turn the rotor"), "{text}");
        }
    }
}
