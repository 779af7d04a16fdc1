//! An absolute vibration score from one capture's harmonic responses
//! (`docs/accelerometer.md#repeatability-and-the-vibration-score`).
//!
//! A harmonic's response `Y` (m/s²) stands for the component `|Y|·sin(nθ + arg Y)` of the
//! head's acceleration, whose RMS is `|Y|/√2`. The score of a set of harmonics is the RMS of
//! their sum (the components are orthogonal over whole periods):
//!
//! ```text
//! S = √(½·Σ|Y_n|²)        (m/s² RMS)
//! δ = √(½·Σ r_n²)         (r_n: each response's 95 % radius)
//! ```
//!
//! If every `Y_n` is within its radius of the truth, the true score is within `[S − δ, S + δ]`
//! (the triangle inequality in `ℂⁿ`); each disc holds with 95 %, so the interval holds with at
//! least that per harmonic, not jointly. Its lower end is kept at 0 or above.

use stepdamp_accel::Response;

/// The score `S` and its interval (module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VibrationScore {
    /// `S`: the RMS of the head's acceleration at the harmonics (m/s²).
    pub rms_m_s2: f64,
    /// `δ`: the half-width of its interval from the responses' 95 % radii (m/s²).
    pub half_width_m_s2: f64,
}

impl VibrationScore {
    /// The score of `responses` (any harmonics of one capture; none gives 0 ± 0).
    pub fn of(responses: &[Response]) -> Self {
        let half = |f: &dyn Fn(&Response) -> f64| (0.5 * responses.iter().map(f).sum::<f64>()).sqrt();
        VibrationScore { rms_m_s2: half(&|y| y.value.norm_sqr()), half_width_m_s2: half(&|y| y.radius95 * y.radius95) }
    }

    /// The interval `[max(0, S − δ), S + δ]` (m/s²).
    pub fn interval(&self) -> (f64, f64) {
        ((self.rms_m_s2 - self.half_width_m_s2).max(0.0), self.rms_m_s2 + self.half_width_m_s2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use stepdamp_accel::Complex;

    fn response(harmonic: u32, value: Complex, radius95: f64) -> Response {
        Response { harmonic, value, radius95, blocks: 10, periods_per_block: 20, speed_rev_s: 2.0 }
    }

    #[test]
    fn the_score_is_the_rms_of_the_harmonic_components() {
        // 3 and 4 m/s² amplitudes: 5 m/s² combined amplitude, 5/√2 RMS.
        let s = VibrationScore::of(&[
            response(4, Complex::new(3.0, 0.0), 0.03),
            response(2, Complex::new(0.0, -4.0), 0.04),
        ]);
        assert!((s.rms_m_s2 - 5.0 / 2f64.sqrt()).abs() < 1e-12, "{s:?}");
        assert!((s.half_width_m_s2 - 0.05 / 2f64.sqrt()).abs() < 1e-12, "{s:?}");
        let z = VibrationScore::of(&[response(1, Complex::new(0.001, 0.0), 0.01)]);
        assert_eq!(z.interval().0, 0.0);
        assert_eq!(VibrationScore::of(&[]).rms_m_s2, 0.0);
    }
}
