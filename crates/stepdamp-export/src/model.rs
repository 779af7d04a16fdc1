//! The correction a profile asks for: the compensating q-current harmonics in A.

use crate::ExportError;
use stepdamp_sim::Profile;

/// The compensating current of a profile at a holding current: `i_q(θe) = Σ c_k sin(k θe + φ_k)`
/// with `c_k = A_k/Km` in A (`docs/design.md#the-drive-and-its-control-laws`), and the holding
/// current `I` (peak, see [`RunCurrent`]) it is exported for.
#[derive(Clone, Debug, PartialEq)]
pub struct Correction {
    /// Profile name (for comments in the exported files).
    pub name: String,
    /// `(order k, c_k in A, φ_k in rad)`, as in the profile.
    pub terms: Vec<(u16, f64, f64)>,
    /// Holding (run) current `I` in A the correction is scaled for: the peak, i.e. the current
    /// vector's magnitude ([`RunCurrent::peak_a`]).
    pub holding_current_a: f64,
    /// Torque constant `Km` in N·m/A.
    pub km_nm_per_a: f64,
}

impl Correction {
    /// From a profile; `current_a` overrides the profile's holding current. The terms are the
    /// detent's, except for a profile with a `[motor.flux]` section exported at a run current
    /// (`current_a` given: an open-loop drive holding that current): then they are the total
    /// ripple at that current and no load, detent plus the part that grows with the current
    /// (`stepdamp_profile::ripple`, docs/design.md#real-motors-flux-harmonics). Without a run
    /// current (SimpleFOC's servo at `i_d = 0`) the current part is not carried.
    pub fn from_profile(p: &Profile, current_a: Option<f64>) -> Result<Self, ExportError> {
        let i = current_a.unwrap_or(p.drive.holding_current_a);
        if !(i.is_finite() && i > 0.0) {
            return Err(ExportError::Invalid(format!("--current {i} A: must be finite and > 0")));
        }
        if !(p.motor.km_nm_per_a.is_finite() && p.motor.km_nm_per_a > 0.0) {
            return Err(ExportError::Invalid(format!("motor.km_nm_per_a = {}: must be > 0", p.motor.km_nm_per_a)));
        }
        let km = p.motor.km_nm_per_a;
        let terms = match current_a {
            Some(i) if !p.motor.flux.is_default() => stepdamp_sim::profile::ripple(p, i, 0.0)
                .map_err(|e| ExportError::Invalid(e.to_string()))?
                .harmonics
                .iter()
                .filter(|h| h.amplitude_nm > 0.0)
                .map(|h| (h.order, h.amplitude_nm / km, h.phase_rad))
                .collect(),
            _ => p.motor.detent.iter().map(|h| (h.order, h.amplitude_nm / km, h.phase_rad)).collect(),
        };
        Ok(Correction { name: p.name.clone(), terms, holding_current_a: i, km_nm_per_a: p.motor.km_nm_per_a })
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

/// A drive's run current, stated once and read both ways. stepdamp's holding current (the
/// profile's `drive.holding_current_a`, the `I` of [`Correction`]) is the **peak**: the
/// magnitude of the current vector, which is the amplitude of each phase's sine wave. Drive
/// settings such as Klipper's `run_current` and Prusa's motor current are **RMS** per phase:
/// `peak = √2 · RMS` for sinusoidal phase currents.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunCurrent {
    peak_a: f64,
}

impl RunCurrent {
    /// From the peak (current-vector magnitude), A; finite and > 0.
    pub fn from_peak(peak_a: f64) -> Result<Self, ExportError> {
        if peak_a.is_finite() && peak_a > 0.0 {
            Ok(RunCurrent { peak_a })
        } else {
            Err(ExportError::Invalid(format!("--current {peak_a:e} A (peak): must be finite and > 0")))
        }
    }

    /// From the RMS of each phase's current, A; finite and > 0. `peak = √2 · rms`.
    pub fn from_rms(rms_a: f64) -> Result<Self, ExportError> {
        if rms_a.is_finite() && rms_a > 0.0 {
            Ok(RunCurrent { peak_a: rms_a * std::f64::consts::SQRT_2 })
        } else {
            Err(ExportError::Invalid(format!("--current-rms {rms_a:e} A: must be finite and > 0")))
        }
    }

    /// Peak (current-vector magnitude), A.
    pub fn peak_a(&self) -> f64 {
        self.peak_a
    }

    /// RMS per phase, A (`peak/√2`).
    pub fn rms_a(&self) -> f64 {
        self.peak_a / std::f64::consts::SQRT_2
    }
}

impl std::fmt::Display for RunCurrent {
    /// `1.900 A peak (current vector) = 1.344 A RMS per phase`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:.3} A peak (current vector) = {:.3} A RMS per phase", self.peak_a, self.rms_a())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rms_and_peak_differ_by_root_two() {
        let a = RunCurrent::from_rms(1.0).unwrap();
        assert!((a.peak_a() - std::f64::consts::SQRT_2).abs() < 1e-15);
        let b = RunCurrent::from_peak(a.peak_a()).unwrap();
        assert!((b.rms_a() - 1.0).abs() < 1e-15);
        assert_eq!(a.to_string(), "1.414 A peak (current vector) = 1.000 A RMS per phase");
        assert!(RunCurrent::from_rms(0.0).unwrap_err().to_string().contains("--current-rms 0e0 A"));
        assert!(RunCurrent::from_peak(f64::NAN).is_err());
    }
}
