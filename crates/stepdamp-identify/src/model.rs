//! The identified model (detent harmonics, `Fs`, `D`, and `J` when identified) and the
//! motor profile made from it.

use crate::fit::Fit;
use stepdamp_profile::{DetentTerm, Profile, ProfileError};

/// What identification produces: the detent series and the friction, in the profile's
/// conventions (torque on the rotor `−Σ A_k sin(k·Nr·θ + φ_k)`, friction
/// `−Fs·sgn(ω) − D·ω`).
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    /// Detent harmonics, in the order they were asked for.
    pub detent: Vec<DetentTerm>,
    /// Coulomb friction `Fs` in N·m (≥ 0).
    pub coulomb_friction_nm: f64,
    /// Viscous friction `D` in N·m·s/rad (≥ 0).
    pub viscous_nm_s_per_rad: f64,
    /// Rotor + load inertia `J` in kg·m² when identified; `None` keeps the base profile's.
    pub inertia_kg_m2: Option<f64>,
    /// Phase resistance `R` in Ω when measured (the sensorless route trims it at
    /// standstill, [`crate::sensorless::flux`]); `None` keeps the base profile's.
    pub resistance_ohm: Option<f64>,
}

impl Model {
    /// The model a fit found, with `J` when the fit identified it ([`Fit::inertia_kg_m2`]).
    /// Negative friction estimates become 0 (friction cannot drive the rotor); the fit warns when that happens ([`crate::fit::Warning::CoulombNotPositive`],
    /// [`crate::fit::Warning::ViscousNegative`]). `D` is the fitted one, or the fallback the fit
    /// held when the logs could not separate it ([`Fit::viscous_used`]).
    pub fn from_fit(f: &Fit) -> Model {
        Model {
            detent: f
                .harmonics
                .iter()
                .map(|h| DetentTerm {
                    order: h.order,
                    amplitude_nm: h.amplitude_nm.value,
                    phase_rad: h.phase_rad.value,
                })
                .collect(),
            coulomb_friction_nm: f.coulomb_friction_nm.value.max(0.0),
            viscous_nm_s_per_rad: f.viscous_used.max(0.0),
            inertia_kg_m2: f.inertia_kg_m2.map(|j| j.value),
            resistance_ohm: None,
        }
    }

    /// The model of a profile (its detent list and friction; `J` left to the profile).
    pub fn of_profile(p: &Profile) -> Model {
        Model {
            detent: p.motor.detent.clone(),
            coulomb_friction_nm: p.motor.coulomb_friction_nm,
            viscous_nm_s_per_rad: p.motor.viscous_nm_s_per_rad,
            inertia_kg_m2: None,
            resistance_ohm: None,
        }
    }

    /// `base` with `motor.detent`, `motor.coulomb_friction_nm`,
    /// `motor.viscous_nm_s_per_rad` and, when identified, `motor.inertia_kg_m2` and
    /// `motor.resistance_ohm` replaced by
    /// this model, validated. Everything else (drive, encoder, servo, Km) is kept. `name` replaces the profile's name when
    /// given.
    pub fn apply_to(&self, base: &Profile, name: Option<&str>, origin: &str) -> Result<Profile, ProfileError> {
        base.edited(origin, |p| {
            p.motor.detent = self.detent.clone();
            p.motor.coulomb_friction_nm = self.coulomb_friction_nm;
            p.motor.viscous_nm_s_per_rad = self.viscous_nm_s_per_rad;
            if let Some(j) = self.inertia_kg_m2 {
                p.motor.inertia_kg_m2 = j;
            }
            if let Some(r) = self.resistance_ohm {
                p.motor.resistance_ohm = r;
            }
            if let Some(n) = name {
                p.name = n.to_string();
            }
        })
    }

    /// The torque the detent needs from the motor at electrical angle `theta_e`:
    /// `Σ A_k sin(k θe + φ_k)`, N·m (the feed-forward of servo mode). Identification's only
    /// evaluation of the series (the controller's, in `f32`, is `stepdamp_core::HarmonicSeries`).
    pub fn series_nm(&self, theta_e: f64) -> f64 {
        self.detent.iter().map(|h| h.amplitude_nm * (f64::from(h.order) * theta_e + h.phase_rad).sin()).sum()
    }

    /// RMS over an electrical period of `Σ A_k sin(kθe + φ_k)`: `√(Σ A_k²/2)`, N·m.
    pub fn ripple_rms_nm(&self) -> f64 {
        (self.detent.iter().map(|h| h.amplitude_nm * h.amplitude_nm).sum::<f64>() / 2.0).sqrt()
    }

    /// RMS over an electrical period of the difference of two detent series (orders missing
    /// in one count as zero there), N·m.
    pub fn ripple_difference_rms_nm(&self, other: &Model) -> f64 {
        let mut orders: Vec<u16> = self.detent.iter().chain(&other.detent).map(|h| h.order).collect();
        orders.sort_unstable();
        orders.dedup();
        let ab = |m: &Model, k: u16| {
            m.detent
                .iter()
                .find(|h| h.order == k)
                .map_or((0.0, 0.0), |h| (h.amplitude_nm * h.phase_rad.cos(), h.amplitude_nm * h.phase_rad.sin()))
        };
        let ss: f64 = orders
            .iter()
            .map(|&k| {
                let ((a1, b1), (a2, b2)) = (ab(self, k), ab(other, k));
                (a1 - a2).powi(2) + (b1 - b2).powi(2)
            })
            .sum();
        (ss / 2.0).sqrt()
    }
}

/// [`Model::series_nm`] as a function.
pub fn series_nm(m: &Model, theta_e: f64) -> f64 {
    m.series_nm(theta_e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn applying_a_model_replaces_only_detent_and_friction_and_validates() {
        let base = Profile::preset("nema23-57mm").unwrap();
        let m = Model {
            detent: vec![DetentTerm { order: 4, amplitude_nm: 0.03, phase_rad: 0.1 }],
            coulomb_friction_nm: 0.02,
            viscous_nm_s_per_rad: 0.002,
            inertia_kg_m2: None,
            resistance_ohm: None,
        };
        let p = m.apply_to(&base, Some("x"), "out.toml").unwrap();
        assert_eq!(p.motor.detent, m.detent);
        assert_eq!((p.motor.coulomb_friction_nm, p.motor.viscous_nm_s_per_rad), (0.02, 0.002));
        assert_eq!((p.name.as_str(), &p.drive, p.motor.inertia_kg_m2), ("x", &base.drive, base.motor.inertia_kg_m2));
        let with_j = Model { inertia_kg_m2: Some(3e-5), ..m.clone() };
        assert_eq!(with_j.apply_to(&base, None, "out.toml").unwrap().motor.inertia_kg_m2, 3e-5);
        let bad = Model { coulomb_friction_nm: f64::NAN, ..m };
        let e = bad.apply_to(&base, None, "out.toml").unwrap_err().to_string();
        assert!(e.contains("out.toml") && e.contains("coulomb_friction_nm"), "{e}");
        let bad = Model { inertia_kg_m2: Some(-1.0), ..with_j };
        let e = bad.apply_to(&base, None, "out.toml").unwrap_err().to_string();
        assert!(e.contains("inertia_kg_m2"), "{e}");
    }

    #[test]
    fn ripple_difference_counts_missing_orders_as_zero() {
        let a = Model {
            detent: vec![DetentTerm { order: 4, amplitude_nm: 0.02, phase_rad: 0.0 }],
            coulomb_friction_nm: 0.0,
            viscous_nm_s_per_rad: 0.0,
            inertia_kg_m2: None,
            resistance_ohm: None,
        };
        let b = Model { detent: vec![], ..a.clone() };
        assert!((a.ripple_difference_rms_nm(&b) - a.ripple_rms_nm()).abs() < 1e-15);
        assert!(a.ripple_difference_rms_nm(&a) < 1e-15);
    }
}
