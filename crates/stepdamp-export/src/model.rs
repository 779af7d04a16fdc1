//! The correction a profile asks for: the compensating q-current harmonics in A.

use crate::ExportError;
use stepdamp_sim::Profile;

/// The compensating current of a profile at a holding current: `i_q(θe) = Σ c_k sin(k θe + φ_k)`
/// with `c_k = A_k/Km` in A (design.md §2–§3), and the holding current `I` it is exported for.
#[derive(Clone, Debug, PartialEq)]
pub struct Correction {
    /// Profile name (for comments in the exported files).
    pub name: String,
    /// `(order k, c_k in A, φ_k in rad)`, as in the profile.
    pub terms: Vec<(u16, f64, f64)>,
    /// Holding (run) current `I` in A the correction is scaled for.
    pub holding_current_a: f64,
    /// Torque constant `Km` in N·m/A.
    pub km_nm_per_a: f64,
}

impl Correction {
    /// From a profile; `current_a` overrides the profile's holding current.
    pub fn from_profile(p: &Profile, current_a: Option<f64>) -> Result<Self, ExportError> {
        let i = current_a.unwrap_or(p.drive.holding_current_a);
        if !(i.is_finite() && i > 0.0) {
            return Err(ExportError::Invalid(format!("--current {i} A: must be finite and > 0")));
        }
        if !(p.motor.km_nm_per_a.is_finite() && p.motor.km_nm_per_a > 0.0) {
            return Err(ExportError::Invalid(format!("motor.km_nm_per_a = {}: must be > 0", p.motor.km_nm_per_a)));
        }
        Ok(Correction {
            name: p.name.clone(),
            terms: p
                .motor
                .detent
                .iter()
                .map(|h| (h.order, h.amplitude_nm / p.motor.km_nm_per_a, h.phase_rad))
                .collect(),
            holding_current_a: i,
            km_nm_per_a: p.motor.km_nm_per_a,
        })
    }

    /// The compensating current at `θe`, A.
    pub fn current_a(&self, theta_e: f64) -> f64 {
        self.terms.iter().map(|&(k, c, ph)| c * (f64::from(k) * theta_e + ph).sin()).sum()
    }

    /// The angle correction `Δ(θe) = i_q(θe)/I` in rad (the rotation of the current vector
    /// at constant magnitude that gives the same q current to first order).
    pub fn delta_rad(&self, theta_e: f64) -> f64 {
        self.current_a(theta_e) / self.holding_current_a
    }
}
