//! The magnet flux linkage of a real hybrid stepper: odd harmonics and unequal phases
//! (docs/design.md#real-motors-flux-harmonics).
//!
//! ```text
//! ψ_a(θe) = (Km/Nr)·Σ_n h_n·cos(n·θe + a_n)                 (h_1 = 1, a_1 = 0)
//! ψ_b(θe) = (1 + g)·(Km/Nr)·Σ_n h_n·cos(n·θe + a_n − n·π/2)  (ψ_a a quarter period later)
//! ```
//!
//! Back-EMF and torque come from the same `ψ`: `e_x = Nr·ω·dψ_x/dθe` and
//! `τ_m = Nr·(i_a·dψ_a/dθe + i_b·dψ_b/dθe)`. Written with the *shape sums*
//!
//! ```text
//! S_a(θe) = Σ_n n·h_n·sin(n·θe + a_n)          S_b(θe) = Σ_n n·h_n·sin(n·θe + a_n − n·π/2)
//! ```
//!
//! this is `e_a = −Km·ω·S_a`, `e_b = −(1 + g)·Km·ω·S_b`,
//! `τ_m = −Km·(i_a·S_a + (1 + g)·i_b·S_b)`. Without harmonics and with `g = 0`,
//! `S_a = sin θe`, `S_b = −cos θe`: the plant of docs/design.md#the-plant, `τ_m = Km·i_q`.
//!
//! A profile without `[motor.flux]` has the pure sine; the simulator then runs today's plant
//! bit for bit. The controller is given the ripple it makes, per ampere of `i_d` and `i_q`
//! ([`crate::ripple::ripple_parts`], [`crate::Profile::controller_harmonics`]).

use serde::{Deserialize, Serialize};
use stepdamp_core::limits::Limit;

/// Highest flux harmonic order a profile may give: a 15th harmonic makes a 14th/16th-order
/// torque ripple, beyond what any drive's correction table resolves well.
pub const MAX_FLUX_ORDER: u16 = 15;

/// `[motor.flux]` (optional): the magnet flux linkage's shape (module doc).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FluxSection {
    /// `g`: phase b's flux amplitude is `(1 + g)` times phase a's (a gain imbalance of the
    /// phases; unequal windings or magnet paths). Default 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub phase_b_gain: f64,
    /// Odd harmonics of each phase's flux linkage, relative to the fundamental.
    #[serde(default, rename = "harmonic", skip_serializing_if = "Vec::is_empty")]
    pub harmonics: Vec<FluxHarmonic>,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// One `[[motor.flux.harmonic]]`: `h_n·cos(n·θe + a_n)` in phase a's flux per unit of the
/// fundamental `Km/Nr`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FluxHarmonic {
    /// The order `n` of the electrical angle: odd, 3 to [`MAX_FLUX_ORDER`].
    pub order: u16,
    /// `h_n`, the amplitude relative to the fundamental (0.01 is 1 %).
    pub ratio: f64,
    /// `a_n` in rad.
    pub phase_rad: f64,
}

impl FluxSection {
    /// A pure sine and equal phases (the section is then not written out).
    pub fn is_default(&self) -> bool {
        self.phase_b_gain == 0.0 && self.harmonics.is_empty()
    }
}

/// Ranges of the `[motor.flux]` keys.
pub mod flux_limits {
    use super::Limit;

    /// `motor.flux.harmonic[i].ratio`. Measured hybrid steppers show thirds of 0.4–1.5 % and
    /// fifths of 0.1–0.6 % of the fundamental (±3–5 % step-angle error under microstepping);
    /// 20 % is a broken magnetic circuit, not a motor to correct.
    pub const RATIO: Limit = Limit {
        key: "motor.flux.harmonic.ratio",
        min: 0.0,
        min_exclusive: false,
        max: 0.2,
        unit: "× the fundamental",
        why: "real motors show a few percent at most",
    };
    /// `motor.flux.harmonic[i].phase_rad`.
    pub const PHASE_RAD: Limit = Limit {
        key: "motor.flux.harmonic.phase_rad",
        min: -core::f64::consts::TAU,
        min_exclusive: false,
        max: core::f64::consts::TAU,
        unit: "rad",
        why: "a phase is in radians; beyond ±2π it is almost surely in degrees",
    };
    /// `motor.flux.phase_b_gain`: phases within ±20 % of each other (measured motors: ±4 %).
    pub const PHASE_B_GAIN: Limit = Limit {
        key: "motor.flux.phase_b_gain",
        min: -0.2,
        min_exclusive: false,
        max: 0.2,
        unit: "",
        why: "phases more than 20 % apart are a wiring fault, not a motor to correct",
    };
}

/// The flux shape ready to evaluate: for each order `n` (1 first) the coefficients of
/// `n·h_n·sin(n·θe + a_n)` and `n·h_n·sin(n·θe + a_n − n·π/2)` on `(sin nθe, cos nθe)`,
/// and `1 + g`.
#[derive(Clone, Debug, PartialEq)]
pub struct FluxShape {
    /// `(order, [ca, sa], [cb, sb])`: `S_a += ca·sin nθe + sa·cos nθe`, likewise `S_b`.
    terms: Vec<(u16, [f64; 2], [f64; 2])>,
    /// `1 + g`.
    b_gain: f64,
}

impl FluxShape {
    /// The shape of a section (unchecked data never panics: a harmonic of order 0 or 1 is
    /// ignored, an even one is evaluated as written).
    pub fn new(f: &FluxSection) -> Self {
        let mut terms = vec![(1, [1.0, 0.0], [0.0, -1.0])];
        for h in f.harmonics.iter().filter(|h| h.order > 1) {
            let n = f64::from(h.order);
            let amp = n * h.ratio;
            let b_phase = h.phase_rad - n * core::f64::consts::FRAC_PI_2;
            let (sa, ca) = h.phase_rad.sin_cos();
            let (sb, cb) = b_phase.sin_cos();
            terms.push((h.order, [amp * ca, amp * sa], [amp * cb, amp * sb]));
        }
        FluxShape { terms, b_gain: 1.0 + f.phase_b_gain }
    }

    /// `1 + g`: phase b's flux gain against phase a's.
    pub fn b_gain(&self) -> f64 {
        self.b_gain
    }

    /// The terms `(order, [ca, sa], [cb, sb])`, the fundamental first (for integrators that
    /// evaluate `sin nθe`, `cos nθe` their own way; [`Self::shape_sums`] is the reference).
    pub fn terms(&self) -> &[(u16, [f64; 2], [f64; 2])] {
        &self.terms
    }

    /// `(S_a, S_b)` at `θe` (module doc).
    pub fn shape_sums(&self, theta_e: f64) -> (f64, f64) {
        self.terms.iter().fold((0.0, 0.0), |(a, b), &(n, [ca, sa], [cb, sb])| {
            let (s, c) = (f64::from(n) * theta_e).sin_cos();
            (a + ca * s + sa * c, b + cb * s + sb * c)
        })
    }

    /// The flux linkage per unit of the fundamental `Km/Nr`, `(ψ_a, ψ_b)·Nr/Km` at `θe`:
    /// `Σ h_n·cos(n·θe + a_n)` and `(1 + g)·Σ h_n·cos(n·θe + a_n − n·π/2)` (module doc); the
    /// pure sine gives `(cos θe, sin θe)`.
    pub fn linkage(&self, theta_e: f64) -> (f64, f64) {
        // S's term `ca·sin nθ + sa·cos nθ = n·h·sin(nθ + a)`, so ψ's `h·cos(nθ + a)` is
        // `(ca·cos nθ − sa·sin nθ)/n`.
        let (a, b) = self.terms.iter().fold((0.0, 0.0), |(a, b), &(n, [ca, sa], [cb, sb])| {
            let k = f64::from(n);
            let (s, c) = (k * theta_e).sin_cos();
            (a + (ca * c - sa * s) / k, b + (cb * c - sb * s) / k)
        });
        (a, self.b_gain * b)
    }

    /// Motor torque `τ_m = −Km·(i_a·S_a + (1 + g)·i_b·S_b)` in N·m at `θe`.
    pub fn torque_nm(&self, km: f64, theta_e: f64, i_a: f64, i_b: f64) -> f64 {
        let (sa, sb) = self.shape_sums(theta_e);
        -km * (i_a * sa + self.b_gain * i_b * sb)
    }

    /// Back-EMF `(e_a, e_b) = (−Km·ω·S_a, −(1 + g)·Km·ω·S_b)` in V at `θe` and rotor speed
    /// `ω` (rad/s, mechanical).
    pub fn back_emf_v(&self, km: f64, theta_e: f64, omega: f64) -> (f64, f64) {
        let (sa, sb) = self.shape_sums(theta_e);
        (-km * omega * sa, -self.b_gain * km * omega * sb)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_linkage_is_the_integral_of_the_shape_sums() {
        // S = −dψ/dθe (per unit Km/Nr): compare with a central difference.
        let f = FluxSection {
            phase_b_gain: 0.04,
            harmonics: vec![
                FluxHarmonic { order: 3, ratio: 0.015, phase_rad: 0.4 },
                FluxHarmonic { order: 5, ratio: 0.006, phase_rad: -0.8 },
            ],
        };
        let shape = FluxShape::new(&f);
        assert_eq!(FluxShape::new(&FluxSection::default()).linkage(0.3), (0.3f64.cos(), 0.3f64.sin()));
        for i in 0..50 {
            let (te, h) = (-3.0 + 0.13 * f64::from(i), 1e-5);
            let (p, m) = (shape.linkage(te + h), shape.linkage(te - h));
            let (sa, sb) = shape.shape_sums(te);
            assert!(((p.0 - m.0) / (2.0 * h) + sa).abs() < 1e-8, "a at {te}");
            assert!(((p.1 - m.1) / (2.0 * h) + shape.b_gain() * sb).abs() < 1e-8, "b at {te}");
        }
    }

    #[test]
    fn a_pure_sine_is_the_patent_plant() {
        let f = FluxShape::new(&FluxSection::default());
        for i in 0..100 {
            let te = -7.0 + 0.37 * f64::from(i);
            let (s, c) = te.sin_cos();
            let (i_a, i_b) = (0.3 - 0.01 * f64::from(i), 1.1);
            let want = 0.3 * (-i_a * s + i_b * c);
            assert!((f.torque_nm(0.3, te, i_a, i_b) - want).abs() < 1e-15);
            let (ea, eb) = f.back_emf_v(0.3, te, 2.0);
            assert!((ea + 0.3 * 2.0 * s).abs() < 1e-15 && (eb - 0.3 * 2.0 * c).abs() < 1e-15);
        }
    }

    #[test]
    fn phase_b_is_phase_a_a_quarter_period_later() {
        // ψ_b(θe) = (1+g)·ψ_a(θe − π/2), so dψ_b/dθe(θe) = (1+g)·dψ_a/dθe(θe − π/2):
        // S_b(θe) = S_a(θe − π/2).
        let sec = FluxSection {
            phase_b_gain: 0.0,
            harmonics: vec![
                FluxHarmonic { order: 3, ratio: 0.012, phase_rad: 0.7 },
                FluxHarmonic { order: 5, ratio: 0.004, phase_rad: -2.1 },
                FluxHarmonic { order: 7, ratio: 0.002, phase_rad: 1.3 },
            ],
        };
        let f = FluxShape::new(&sec);
        for i in 0..50 {
            let te = 0.13 * f64::from(i);
            let (_, sb) = f.shape_sums(te);
            let (sa_q, _) = f.shape_sums(te - core::f64::consts::FRAC_PI_2);
            assert!((sb - sa_q).abs() < 1e-14, "θe {te}: {sb} vs {sa_q}");
        }
    }

    #[test]
    fn back_emf_power_equals_torque_times_speed() {
        let sec = FluxSection {
            phase_b_gain: 0.037,
            harmonics: vec![FluxHarmonic { order: 3, ratio: 0.015, phase_rad: 0.4 }],
        };
        let f = FluxShape::new(&sec);
        for i in 0..40 {
            let te = 0.31 * f64::from(i);
            let (i_a, i_b, w) = (1.2 - 0.05 * f64::from(i), 0.4, 3.0);
            let (ea, eb) = f.back_emf_v(0.3, te, w);
            let p_mech = f.torque_nm(0.3, te, i_a, i_b) * w;
            assert!((ea * i_a + eb * i_b - p_mech).abs() < 1e-13);
        }
    }
}
