//! The print head in the model: a GT2 pulley on the motor shaft, the belt as a spring with
//! damping, the carriage as a mass (`docs/accelerometer.md#simulated-printer`).
//!
//! **Approximations.** The carriage is coupled **rigidly** to the rotor for the motor's
//! dynamics: its inertia reflected through the pulley, `m·r²`, is added to the rotor's `J`
//! in the motor simulation ([`HeadModel::reflected_inertia_kg_m2`]). The head's acceleration
//! is then the rotor's angular acceleration times `r` seen through the belt mode, a
//! second-order low-pass at the belt's natural frequency `ω_b = √(k/m)` with damping ratio
//! `ζ`: `a_head(s) = r·α(s)·ω_b²/(s² + 2ζω_b·s + ω_b²)` ([`HeadModel::transfer`]). The
//! belt's own reaction on the rotor (the two-mass system) is left out; it matters near and
//! above `ω_b`, where the rigid coupling over-states the load the rotor carries.

use std::f64::consts::TAU;
use stepdamp_accel::Complex;

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
    /// frequency `w` (rad/s, signed: a negative `w` gives the conjugate):
    /// `r·ω_b²/(ω_b² − w² + 2iζω_b·w)`.
    pub fn transfer(&self, w: f64) -> Complex {
        let wb = self.belt_omega_rad_s();
        let den = Complex::new(wb * wb - w * w, 2.0 * self.belt_damping_ratio * wb * w);
        Complex::new(self.pulley_radius_m * wb * wb, 0.0) / den
    }
}

/// The belt mode in the time domain: `y'' + 2ζω_b·y' + ω_b²·y = ω_b²·u` with `u = r·α`
/// held over each step, integrated with one RK4 step per control period. `y` is the head
/// acceleration (m/s²). Held at its mean over the step (centred on the step's middle), the
/// input stands for the continuous one without delay: the output is the head's acceleration
/// at the step's end.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BeltFilter {
    wb: f64,
    zeta: f64,
    r: f64,
    y: f64,
    dy: f64,
}

impl BeltFilter {
    pub(crate) fn new(h: &HeadModel) -> Self {
        BeltFilter { wb: h.belt_omega_rad_s(), zeta: h.belt_damping_ratio, r: h.pulley_radius_m, y: 0.0, dy: 0.0 }
    }

    /// Advances by `dt` (s) with the rotor's mean angular acceleration `alpha` (rad/s²)
    /// over the step; returns the head acceleration (m/s²) at its end.
    pub(crate) fn step(&mut self, alpha: f64, dt: f64) -> f64 {
        let u = self.r * alpha;
        let (wb, z) = (self.wb, self.zeta);
        let f = |y: f64, dy: f64| (dy, wb * wb * (u - y) - 2.0 * z * wb * dy);
        let k1 = f(self.y, self.dy);
        let k2 = f(self.y + 0.5 * dt * k1.0, self.dy + 0.5 * dt * k1.1);
        let k3 = f(self.y + 0.5 * dt * k2.0, self.dy + 0.5 * dt * k2.1);
        let k4 = f(self.y + dt * k3.0, self.dy + dt * k3.1);
        self.y += dt / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
        self.dy += dt / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
        self.y
    }
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
    fn the_belt_filter_follows_the_transfer_function_in_steady_state() {
        let h = HeadModel::default();
        let (dt, w) = (1.0 / 20_000.0, TAU * 400.0);
        let mut f = BeltFilter::new(&h);
        // Drive with sin(w t) held over each step (its mean over the step, dated at its middle).
        let (mut s, mut c) = (0.0, 0.0);
        let n = 20_000;
        for k in 0..n {
            let mid = (k as f64 + 0.5) * dt;
            let y = f.step((w * mid).sin(), dt);
            if k >= n / 2 {
                let end = (k + 1) as f64 * dt;
                s += y * (w * end).sin();
                c += y * (w * end).cos();
            }
        }
        let m = (n / 2) as f64;
        let got = Complex::new(2.0 * s / m, 2.0 * c / m);
        let want = h.transfer(w);
        assert!((got - want).abs() < 0.01 * want.abs(), "{got:?} vs {want:?}");
    }
}
