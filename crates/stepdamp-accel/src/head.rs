//! The print head in the model: a GT2 pulley on the motor shaft, the belt as a spring with
//! damping, the carriage as a mass, and the rotor held in open loop by the magnetic stiffness
//! (`docs/accelerometer.md#identifying-the-ripple-from-captures`). The one home of the
//! transfer function from a ripple torque to the head's acceleration: the simulated printer
//! (`stepdamp-printer`) runs the same model in the time domain, the identification fits it.
//!
//! **Approximations.** The carriage is coupled **rigidly** to the rotor for the motor's
//! dynamics: its inertia reflected through the pulley, `m·r²`, is added to the rotor's `J`
//! ([`HeadModel::reflected_inertia_kg_m2`]). The head's acceleration is then the rotor's
//! angular acceleration times `r` seen through the belt mode, a second-order low-pass at the
//! belt's natural frequency `ω_b = √(k/m)` with damping ratio `ζ`:
//! `a_head(s) = r·α(s)·ω_b²/(s² + 2ζω_b·s + ω_b²)` ([`belt_transfer`]). The belt's own
//! reaction on the rotor (the two-mass system) is left out; it matters near and above `ω_b`,
//! where the rigid coupling over-states the load the rotor carries.

use crate::complex::Complex;
use std::f64::consts::TAU;

/// The mechanics between the rotor and the accelerometer (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadModel {
    /// Pulley pitch radius (m). Default 5.09 mm: a GT2 (2 mm pitch) 16-tooth pulley,
    /// `16·2 mm/(2π)`, the pulley of Prusa's MK4 and Core One (32 mm of belt per revolution).
    pub pulley_radius_m: f64,
    /// Belt stiffness seen by the carriage (N/m). Default 1.0 MN/m: an **assumption**, chosen
    /// so that the belt mode with the default carriage is at 225 Hz ("a few hundred Hz").
    pub belt_stiffness_n_per_m: f64,
    /// Moving mass of the carriage with the tool head (kg). Default 0.5 kg: an
    /// **assumption** of the order of a Core One / MK4 head (extruder, hotend, fans).
    pub carriage_mass_kg: f64,
    /// Damping ratio of the belt mode (dimensionless, > 0). Default 0.05: an
    /// **assumption** (a lightly damped glass-fibre belt).
    pub belt_damping_ratio: f64,
}

impl Default for HeadModel {
    fn default() -> Self {
        HeadModel {
            pulley_radius_m: 16.0 * 2.0e-3 / TAU,
            belt_stiffness_n_per_m: 1.0e6,
            carriage_mass_kg: 0.5,
            belt_damping_ratio: 0.05,
        }
    }
}

/// A head parameter out of range; one line naming the key, the value and the range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("head.{key} = {value}: must be {allowed}")]
pub struct HeadError {
    /// The parameter.
    pub key: &'static str,
    /// The value as given.
    pub value: f64,
    /// The allowed range.
    pub allowed: &'static str,
}

impl HeadModel {
    /// Checks every parameter: finite and in a physical range (radius 1–50 mm, stiffness
    /// 1 kN/m–1 GN/m, mass 10 g–20 kg, damping ratio in (0, 2]).
    pub fn check(&self) -> Result<(), HeadError> {
        let ranges: [(&'static str, f64, f64, f64, &'static str); 4] = [
            ("pulley_radius_m", self.pulley_radius_m, 1e-3, 0.05, "in 0.001..=0.05 m"),
            ("belt_stiffness_n_per_m", self.belt_stiffness_n_per_m, 1e3, 1e9, "in 1e3..=1e9 N/m"),
            ("carriage_mass_kg", self.carriage_mass_kg, 0.01, 20.0, "in 0.01..=20 kg"),
            ("belt_damping_ratio", self.belt_damping_ratio, f64::MIN_POSITIVE, 2.0, "in (0, 2]"),
        ];
        for (key, value, lo, hi, allowed) in ranges {
            if !(value.is_finite() && (lo..=hi).contains(&value)) {
                return Err(HeadError { key, value, allowed });
            }
        }
        Ok(())
    }

    /// The carriage's inertia reflected to the rotor, `m·r²` (kg·m²), which the rigid-coupling
    /// approximation adds to the rotor's `J`.
    pub fn reflected_inertia_kg_m2(&self) -> f64 {
        self.carriage_mass_kg * self.pulley_radius_m * self.pulley_radius_m
    }

    /// The belt mode's natural angular frequency `ω_b = √(k/m)` (rad/s).
    pub fn belt_omega_rad_s(&self) -> f64 {
        (self.belt_stiffness_n_per_m / self.carriage_mass_kg).sqrt()
    }

    /// The belt mode's natural frequency (Hz).
    pub fn belt_hz(&self) -> f64 {
        self.belt_omega_rad_s() / TAU
    }

    /// Head acceleration (m/s²) per rotor angular acceleration (rad/s²) at the angular
    /// frequency `w` (rad/s, signed: a negative `w` gives the conjugate): [`belt_transfer`].
    pub fn transfer(&self, w: f64) -> Complex {
        belt_transfer(self.pulley_radius_m, self.belt_omega_rad_s(), self.belt_damping_ratio, w)
    }
}

/// Head acceleration (m/s²) per rotor angular acceleration (rad/s²) at the angular frequency
/// `w` (rad/s, signed) through a pulley of radius `r` (m) and the belt mode at `wb` (rad/s)
/// with damping ratio `zeta`: `r·ω_b²/(ω_b² − w² + 2iζω_b·w)`.
pub fn belt_transfer(r: f64, wb: f64, zeta: f64, w: f64) -> Complex {
    let den = Complex::new(wb * wb - w * w, 2.0 * zeta * wb * w);
    Complex::new(r * wb * wb, 0.0) / den
}

/// The axis in open loop: the rotor held by the magnetic stiffness at the run current,
/// loaded by the carriage (rigid coupling), seen through the belt. SI units; the angles of
/// the stiffness and viscous terms are **mechanical** radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisModel {
    /// Pulley pitch radius `r` (m).
    pub pulley_radius_m: f64,
    /// Total inertia on the rotor `J_t = J_rotor + m·r²` (kg·m²).
    pub total_inertia_kg_m2: f64,
    /// The belt mode's natural angular frequency `ω_b` (rad/s).
    pub belt_omega_rad_s: f64,
    /// The belt mode's damping ratio `ζ`.
    pub belt_damping_ratio: f64,
    /// The magnetic stiffness `K = Km·I·Nr` (N·m per mechanical rad) at the peak run
    /// current `I` (`docs/design.md#the-plant`), times `cos δ` at a load angle `δ`.
    pub stiffness_nm_per_rad: f64,
    /// The rotor's viscous damping `c` (N·m·s/rad).
    pub viscous_nm_s_per_rad: f64,
}

impl AxisModel {
    /// The axis of `head` on a rotor of inertia `rotor_inertia` (kg·m²), stiffness `k`
    /// (N·m/rad) and viscous damping `c` (N·m·s/rad).
    pub fn new(head: &HeadModel, rotor_inertia: f64, k: f64, c: f64) -> Self {
        AxisModel {
            pulley_radius_m: head.pulley_radius_m,
            total_inertia_kg_m2: rotor_inertia + head.reflected_inertia_kg_m2(),
            belt_omega_rad_s: head.belt_omega_rad_s(),
            belt_damping_ratio: head.belt_damping_ratio,
            stiffness_nm_per_rad: k,
            viscous_nm_s_per_rad: c,
        }
    }

    /// The head's acceleration (m/s²) per ripple torque (N·m) on the rotor at the angular
    /// frequency `w` (rad/s, signed; the harmonic `k` at `v` rev/s is `w = k·Nr·2π·v`), both
    /// as phasors of the same angle: the rotor's deviation `x = T/(K − J_t·w² + i·c·w)`, its
    /// acceleration `−w²·x`, through the belt ([`belt_transfer`]).
    pub fn acceleration_per_torque(&self, w: f64) -> Complex {
        let rotor = Complex::new(-w * w, 0.0)
            / Complex::new(self.stiffness_nm_per_rad - self.total_inertia_kg_m2 * w * w, self.viscous_nm_s_per_rad * w);
        belt_transfer(self.pulley_radius_m, self.belt_omega_rad_s, self.belt_damping_ratio, w) * rotor
    }

    /// The rotor's deviation (mechanical rad) per ripple torque (N·m) at `w` (rad/s):
    /// `1/(K − J_t·w² + i·c·w)`.
    pub fn deviation_per_torque(&self, w: f64) -> Complex {
        Complex::new(1.0, 0.0)
            / Complex::new(self.stiffness_nm_per_rad - self.total_inertia_kg_m2 * w * w, self.viscous_nm_s_per_rad * w)
    }
}

/// The rotor's steady electrical angle against the command (rad, signed like the speed's
/// opposite: the rotor lags) in open loop at `speed_rev_s` (signed, motor rev/s), from the
/// load `Fc + c·|ω|` (N·m: Coulomb friction `coulomb_nm`, viscous `viscous`) on the holding
/// torque `Km·I` (`holding_nm`): `−sgn(v)·asin(load/(Km·I))`. `None` when the load exceeds
/// the holding torque (the motor stalls).
pub fn load_angle_rad(speed_rev_s: f64, coulomb_nm: f64, viscous: f64, holding_nm: f64) -> Option<f64> {
    if speed_rev_s == 0.0 {
        return Some(0.0);
    }
    let load = coulomb_nm + viscous * TAU * speed_rev_s.abs();
    let s = load / holding_nm;
    (s.is_finite() && s.abs() < 1.0).then(|| -speed_rev_s.signum() * s.asin())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_head_is_a_gt2_16_tooth_pulley_with_a_belt_mode_of_a_few_hundred_hz() {
        let h = HeadModel::default();
        h.check().unwrap();
        assert!((h.pulley_radius_m - 5.093e-3).abs() < 1e-6, "{}", h.pulley_radius_m);
        assert!((150.0..=400.0).contains(&h.belt_hz()), "{}", h.belt_hz());
    }

    #[test]
    fn a_bad_head_parameter_is_one_line_naming_the_key() {
        let h = HeadModel { carriage_mass_kg: -1.0, ..HeadModel::default() };
        let e = h.check().unwrap_err().to_string();
        assert_eq!(e, "head.carriage_mass_kg = -1: must be in 0.01..=20 kg");
        let h = HeadModel { belt_damping_ratio: f64::NAN, ..HeadModel::default() };
        assert!(h.check().unwrap_err().to_string().contains("belt_damping_ratio = NaN"));
    }

    #[test]
    fn far_below_the_resonances_the_head_follows_the_spring_and_far_above_the_inertia() {
        let a = AxisModel::new(&HeadModel::default(), 4e-5, 13.5, 0.0);
        let r = a.pulley_radius_m;
        // w → 0: α = −w²·T/K, the head r·α.
        let w = 1.0;
        let g = a.acceleration_per_torque(w);
        let want = Complex::new(-r * w * w / 13.5, 0.0);
        assert!((g - want).abs() < 1e-4 * want.abs(), "{g:?}");
        // Between the rotor's and the belt's resonances: α ≈ T/J_t.
        let w = TAU * 5000.0;
        let g = a.acceleration_per_torque(w) / a.head_only(w);
        assert!((g.re - r / a.total_inertia_kg_m2).abs() < 0.01 * r / a.total_inertia_kg_m2, "{g:?}");
        // The negative frequency is the conjugate.
        let (p, n) = (a.acceleration_per_torque(900.0), a.acceleration_per_torque(-900.0));
        assert!((p - n.conj()).abs() < 1e-12 * p.abs());
    }

    impl AxisModel {
        fn head_only(&self, w: f64) -> Complex {
            belt_transfer(1.0, self.belt_omega_rad_s, self.belt_damping_ratio, w)
        }
    }

    #[test]
    fn the_rotor_lags_by_the_load_on_the_holding_torque_and_stalls_beyond_it() {
        let lag = load_angle_rad(2.0, 0.01, 0.001, 0.27).unwrap();
        let want = -((0.01 + 0.001 * TAU * 2.0) / 0.27_f64).asin();
        assert!((lag - want).abs() < 1e-15 && lag < 0.0);
        assert_eq!(load_angle_rad(-2.0, 0.01, 0.001, 0.27), Some(-lag));
        assert_eq!(load_angle_rad(2.0, 0.3, 0.0, 0.27), None);
    }
}
