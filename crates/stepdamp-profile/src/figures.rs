//! The figures derived from a profile that `stepdamp motor show` and `stepdamp resonance`
//! print: `Display` is that text, `Serialize` the same numbers for scripts.

use crate::profile::Profile;
use serde::Serialize;
use std::f64::consts::{SQRT_2, TAU};
use std::fmt;

/// Derived figures of a motor.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MotorFigures {
    /// The profile's name.
    pub name: String,
    /// Two-phase holding torque `√2·Km·I_hold`, N·m.
    pub holding_torque_nm: f64,
    /// Holding stiffness `Nr·Km·I_hold`, N·m/rad.
    pub holding_stiffness_nm_per_rad: f64,
    /// Natural frequency `ω_n`, rad/s.
    pub natural_frequency_rad_s: f64,
    /// Damping ratio `D/(2Jω_n)`.
    pub damping_ratio: f64,
    /// Electrical time constant `L/R`, s.
    pub electrical_time_constant_s: f64,
    /// Full step `90°/Nr`, degrees.
    pub full_step_deg: f64,
    /// Resonance speeds `ω_n/(k·Nr)`, highest order first ([`Profile::resonance_orders`]).
    pub resonances: Vec<ResonanceSpeed>,
}

/// The resonance speed of one harmonic order.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ResonanceSpeed {
    /// Harmonic order `k`.
    pub order: u16,
    /// Speed in rad/s.
    pub speed_rad_s: f64,
}

impl MotorFigures {
    /// The figures of `p`.
    pub fn of(p: &Profile) -> MotorFigures {
        let (m, d) = (&p.motor, &p.drive);
        MotorFigures {
            name: p.name.clone(),
            holding_torque_nm: SQRT_2 * m.km_nm_per_a * d.holding_current_a,
            holding_stiffness_nm_per_rad: p.holding_stiffness_nm_per_rad(),
            natural_frequency_rad_s: p.natural_frequency_rad_s(),
            damping_ratio: p.damping_ratio(),
            electrical_time_constant_s: m.inductance_h / m.resistance_ohm,
            full_step_deg: 90.0 / f64::from(m.pole_pairs),
            resonances: p
                .resonance_orders()
                .into_iter()
                .map(|order| ResonanceSpeed { order, speed_rad_s: p.resonance_speed_rad_s(order) })
                .collect(),
        }
    }
}

/// One figure per line (without the name).
impl fmt::Display for MotorFigures {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let wn = self.natural_frequency_rad_s;
        writeln!(f, "holding torque √2·Km·I      {:.4} N·m", self.holding_torque_nm)?;
        writeln!(f, "holding stiffness Nr·Km·I   {:.3} N·m/rad", self.holding_stiffness_nm_per_rad)?;
        writeln!(f, "natural frequency ω_n       {wn:.1} rad/s ({:.1} Hz)", wn / TAU)?;
        writeln!(f, "damping ratio D/(2Jω_n)     {:.4}", self.damping_ratio)?;
        writeln!(f, "electrical time constant    {:.2} ms", 1e3 * self.electrical_time_constant_s)?;
        writeln!(f, "full step                   {:.3}°", self.full_step_deg)?;
        for r in &self.resonances {
            let label = format!("k={}", r.order);
            writeln!(
                f,
                "resonance {label:<5}             {:.3} rad/s ({:.2} rev/s)",
                r.speed_rad_s,
                r.speed_rad_s / TAU
            )?;
        }
        Ok(())
    }
}

/// What `stepdamp motor show --format json` prints: the profile and its figures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MotorShow {
    /// The profile.
    pub profile: Profile,
    /// Its derived figures.
    pub figures: MotorFigures,
}
