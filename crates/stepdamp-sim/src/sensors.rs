//! Sensor imperfections of a real drive, as pure functions: per-phase
//! current-sensor offset and gain mismatch, and encoder eccentricity.
//!
//! * **Current sensors**: the drive reads `i_meas = g·i + o` per phase, with gain `g = 1 + ε`
//!   (`ε` the gain mismatch, dimensionless) and offset `o` (A). In the rotor's frame an
//!   offset is a current vector fixed in the stator: a ripple at the electrical frequency
//!   (order 1) of amplitude `|o|` in `i_q`; a gain mismatch `ε_a ≠ ε_b` a ripple at twice it
//!   (order 2) of amplitude `|ε_a − ε_b|·|i|/2` — so both show up as detent-like orders 1
//!   and 2 in an identification ([`CurrentSensors::q_error_a`] gives the exact error).
//! * **Encoder eccentricity**: a code disc mounted off-centre reads
//!   `θ_read = θ + e·sin(θ + φ_e)` — a once-per-revolution angle error of amplitude `e` (rad),
//!   before quantisation.
//!
//! Profile keys (defaults = today's ideal sensors; ranges checked by the profile crate,
//! `stepdamp_profile::data::sim_limits`):
//!
//! | key | unit | range | default |
//! |---|---|---|---|
//! | `drive.current_offset_a = [o_a, o_b]` | A | each `|o| ≤` 10 % of `current_limit_a` | `[0, 0]` |
//! | `drive.current_gain_error = [ε_a, ε_b]` | 1 | each in `[−0.2, 0.2]` | `[0, 0]` |
//! | `encoder.eccentricity_rad` | rad | `[0, 0.01]` (≈ 6 counts of 4000) | `0` |
//! | `encoder.eccentricity_phase_rad` | rad | `[−π, π]` | `0` |

/// Per-phase current-sensor errors.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CurrentSensors {
    /// Offsets of phases A and B, A.
    pub offset_a: [f64; 2],
    /// Gain errors `ε` of phases A and B (the gain is `1 + ε`).
    pub gain_error: [f64; 2],
}

impl CurrentSensors {
    /// The profile's `drive.current_offset_a` and `drive.current_gain_error`; `None` for
    /// ideal sensors (the loop then reads the currents untouched, bit for bit).
    pub fn from_profile(p: &crate::profile::ProfileData) -> Option<Self> {
        let s = CurrentSensors { offset_a: p.drive.current_offset_a, gain_error: p.drive.current_gain_error };
        (s != CurrentSensors::default()).then_some(s)
    }

    /// What the drive reads for true phase currents `(i_a, i_b)`, A.
    pub fn read(&self, i_a: f64, i_b: f64) -> (f64, f64) {
        ((1.0 + self.gain_error[0]) * i_a + self.offset_a[0], (1.0 + self.gain_error[1]) * i_b + self.offset_a[1])
    }

    /// Error of the measured `i_q` (read minus true) at electrical angle `theta_e` for true
    /// phase currents `(i_a, i_b)`, with the Park convention of the log format
    /// `i_q = −i_a sin θe + i_b cos θe`, A.
    pub fn q_error_a(&self, i_a: f64, i_b: f64, theta_e: f64) -> f64 {
        let (ra, rb) = self.read(i_a, i_b);
        let (s, c) = theta_e.sin_cos();
        (-(ra - i_a)) * s + (rb - i_b) * c
    }
}

/// A once-per-revolution encoder angle error.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Eccentricity {
    /// Amplitude `e`, rad (mechanical).
    pub amplitude_rad: f64,
    /// Phase `φ_e`, rad.
    pub phase_rad: f64,
}

impl Eccentricity {
    /// The profile's `encoder.eccentricity_rad` and `encoder.eccentricity_phase_rad`;
    /// `None` for a centred disc.
    pub fn from_profile(p: &crate::profile::ProfileData) -> Option<Self> {
        let e = &p.encoder;
        (e.eccentricity_rad != 0.0)
            .then_some(Eccentricity { amplitude_rad: e.eccentricity_rad, phase_rad: e.eccentricity_phase_rad })
    }

    /// The angle the encoder reads (before quantisation) at mechanical angle `theta`, rad.
    pub fn read(&self, theta: f64) -> f64 {
        theta + self.amplitude_rad * (theta + self.phase_rad).sin()
    }
}

/// `x.floor() as i64` without the library call `floor` is on baseline x86-64 (no SSE4.1
/// `roundsd`): truncate, then step down when that rounded up. Same result for every `f64`,
/// including NaN (0) and out-of-range values (saturated).
/// (The encoder's count of the simulated angle.)
#[inline]
pub(crate) fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x { t.saturating_sub(1) } else { t }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn floor_i64_is_floor(x in proptest::num::f64::ANY) {
            prop_assert_eq!(floor_i64(x), x.floor() as i64);
        }
    }

    #[test]
    fn floor_i64_is_floor_at_the_edges() {
        for x in [0.0, -0.0, -0.5, 0.5, -1.0, 1e300, -1e300, f64::NAN, f64::INFINITY, -f64::INFINITY, 9.2e18, -9.3e18] {
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        }
    }

    use std::f64::consts::{PI, TAU};

    /// Amplitude of the component of `f(θe)` at `order`, by a 720-point Fourier sum.
    fn harmonic(f: impl Fn(f64) -> f64, order: f64) -> f64 {
        let n = 720;
        let (mut s, mut c) = (0.0, 0.0);
        for i in 0..n {
            let x = TAU * f64::from(i) / f64::from(n);
            s += f(x) * (order * x).sin();
            c += f(x) * (order * x).cos();
        }
        2.0 * s.hypot(c) / f64::from(n)
    }

    #[test]
    fn ideal_sensors_read_the_truth() {
        assert_eq!(CurrentSensors::default().read(1.2, -0.7), (1.2, -0.7));
        assert_eq!(Eccentricity::default().read(0.3), 0.3);
    }

    #[test]
    fn a_current_offset_is_a_first_order_ripple_of_its_size_in_iq() {
        let s = CurrentSensors { offset_a: [0.02, 0.0], gain_error: [0.0; 2] };
        // Currents in the q axis of the true angle: i_a = −I sin θe, i_b = I cos θe.
        let iq = 1.5;
        let err = |te: f64| s.q_error_a(-iq * te.sin(), iq * te.cos(), te);
        assert!((harmonic(err, 1.0) - 0.02).abs() < 1e-9);
        assert!(harmonic(err, 2.0) < 1e-9);
    }

    #[test]
    fn a_gain_mismatch_is_a_second_order_ripple_of_half_the_mismatch_in_iq() {
        let s = CurrentSensors { offset_a: [0.0; 2], gain_error: [0.03, -0.01] };
        let iq = 2.0;
        let err = |te: f64| s.q_error_a(-iq * te.sin(), iq * te.cos(), te);
        assert!((harmonic(err, 2.0) - 0.5 * 0.04 * iq).abs() < 1e-9, "{}", harmonic(err, 2.0));
        assert!(harmonic(err, 1.0) < 1e-9);
    }

    #[test]
    fn eccentricity_is_a_once_per_revolution_error_of_its_amplitude() {
        let e = Eccentricity { amplitude_rad: 1e-3, phase_rad: PI / 3.0 };
        let err = |th: f64| e.read(th) - th;
        assert!((harmonic(err, 1.0) - 1e-3).abs() < 1e-12);
        assert!(harmonic(err, 2.0) < 1e-12);
    }
}
