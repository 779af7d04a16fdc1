//! Rotor positions in exact fixed point, and the wrapping microstep accumulator.
//!
//! A [`Position`] counts 2⁻³² of an *electrical* revolution in an `i64`. The low 32 bits
//! are the electrical angle (so `θe` never loses precision however long the motor runs),
//! the high 32 bits count electrical revolutions (±2³¹ of them: for `Nr = 50`, ±43 million
//! mechanical revolutions). Differences of positions are exact; positions wrap instead of
//! overflowing.

use core::f32::consts::TAU;

/// Units of [`Position`] in one electrical revolution.
pub const UNITS_PER_ELECTRICAL_REV: f64 = 4_294_967_296.0;

/// A rotor position in units of 2⁻³² electrical revolution (wrapping `i64`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Position(pub i64);

impl Position {
    /// Electrical angle `θe` in rad, in `[−π, π)`. Resolution 2π·2⁻²⁴ ≈ 3.7·10⁻⁷ rad.
    #[inline]
    pub fn electrical_angle_rad(self) -> f32 {
        // The low 32 bits as a signed fraction of a turn keeps |θe| ≤ π, where sinf is
        // most accurate.
        (self.0 as i32) as f32 * (TAU / UNITS_PER_ELECTRICAL_REV as f32)
    }

    /// Signed difference `self − other` in position units (exact, wrapping).
    #[inline]
    pub fn wrapping_diff(self, other: Position) -> i64 {
        self.0.wrapping_sub(other.0)
    }

    /// Mechanical angle in rad as `f64` (for logs on a host; exact to 2⁻³² electrical rev
    /// until `f64`'s 53-bit mantissa is exceeded, i.e. for |θ| < 2²¹ electrical revs).
    pub fn mechanical_rad_f64(self, pole_pairs: u16) -> f64 {
        self.0 as f64 * (core::f64::consts::TAU / UNITS_PER_ELECTRICAL_REV) / f64::from(pole_pairs)
    }

    /// The position of a mechanical angle in rad (rounded to the nearest unit, saturating).
    pub fn from_mechanical_rad_f64(theta_rad: f64, pole_pairs: u16) -> Position {
        let units = theta_rad * f64::from(pole_pairs) * UNITS_PER_ELECTRICAL_REV / core::f64::consts::TAU;
        Position(libm::round(units) as i64)
    }
}

/// Wrapping microstep / phase accumulator: `θ_cmd` advanced once per control period.
///
/// The commanded speed is turned into a fixed increment per period once (when it changes),
/// so the angle is an exact integer sum: after `n` periods at constant speed the position
/// is exactly `n·increment` (mod 2⁶⁴). The only error is the rounding of the speed to the
/// increment, at most ½ unit per period: a relative speed error below `0.5 / increment`
/// (≈ 3·10⁻⁷ at 1 rad/s for `Nr = 50` and 20 kHz), which never grows into a drift.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MicrostepAccumulator {
    /// The commanded position `θ_cmd`.
    pub position: Position,
    /// Position units added each control period.
    pub increment: i64,
}

impl MicrostepAccumulator {
    /// Sets the increment for a speed in rad/s (mechanical), given
    /// `units_per_rad_s = Nr·2³²·Ts / 2π` (see [`units_per_rad_s`]). Non-finite speeds keep
    /// the previous increment; values beyond `i64` saturate.
    #[inline]
    pub fn set_speed(&mut self, speed_rad_s: f32, units_per_rad_s: f64) {
        if speed_rad_s.is_finite() {
            self.increment = libm::round(f64::from(speed_rad_s) * units_per_rad_s) as i64;
        }
    }

    /// Advances by one control period.
    #[inline]
    pub fn advance(&mut self) {
        self.position.0 = self.position.0.wrapping_add(self.increment);
    }

    /// Advances by `n` control periods at once (same result as `n` calls of [`advance`]).
    ///
    /// [`advance`]: MicrostepAccumulator::advance
    pub fn advance_by(&mut self, n: u64) {
        self.position.0 = self.position.0.wrapping_add(self.increment.wrapping_mul(n as i64));
    }
}

/// Position units per period per rad/s of mechanical speed: `Nr·2³²·Ts / 2π`.
pub fn units_per_rad_s(pole_pairs: u16, period_s: f64) -> f64 {
    f64::from(pole_pairs) * UNITS_PER_ELECTRICAL_REV * period_s / core::f64::consts::TAU
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn electrical_angle_wraps_into_minus_pi_to_pi() {
        let quarter = Position(1 << 30);
        assert!((quarter.electrical_angle_rad() - TAU / 4.0).abs() < 1e-6);
        let minus_quarter = Position((3 << 30) + (5 << 32));
        assert!((minus_quarter.electrical_angle_rad() + TAU / 4.0).abs() < 1e-6);
        assert!((Position(1 << 31).electrical_angle_rad() + core::f32::consts::PI).abs() < 1e-6);
    }

    #[test]
    fn mechanical_round_trip_is_exact_to_one_unit() {
        for theta in [0.0, 1.0e-3, -2.5, 1234.5678, -98765.4321] {
            let p = Position::from_mechanical_rad_f64(theta, 50);
            let back = p.mechanical_rad_f64(50);
            let unit = core::f64::consts::TAU / UNITS_PER_ELECTRICAL_REV / 50.0;
            assert!((back - theta).abs() <= unit, "{theta} -> {back}");
        }
    }

    #[test]
    fn accumulator_has_no_drift_over_a_billion_steps() {
        // 10^9 periods at 20 kHz is 13.9 hours. Stepping one at a time would give the same
        // integer as advance_by (integer addition is associative); check the arithmetic
        // against the exact commanded angle.
        let ts = 1.0 / 20_000.0;
        let speed = 7.3_f32; // rad/s
        let upr = units_per_rad_s(50, ts);
        let mut acc = MicrostepAccumulator::default();
        acc.set_speed(speed, upr);
        let n: u64 = 1_000_000_000;
        acc.advance_by(n);
        assert_eq!(acc.position.0, acc.increment * n as i64);
        // The only error is the rounding of the speed to one increment: ≤ ½ unit/period.
        let exact_units = f64::from(speed) * upr * n as f64;
        let err_units = (acc.position.0 as f64 - exact_units).abs();
        assert!(err_units <= 0.5 * n as f64, "err {err_units}");
        // That rounding is a fixed speed error, 4·10⁻⁸ relative here, not a growing drift:
        // 12 mrad of a 5.3·10⁵ rad move over 13.9 h.
        let err_rad = acc.position.mechanical_rad_f64(50) - f64::from(speed) * ts * n as f64;
        let rel = err_rad / (f64::from(speed) * ts * n as f64);
        assert!(rel.abs() <= 0.5 / acc.increment as f64, "{rel}");
    }

    #[test]
    fn advance_by_matches_repeated_advance() {
        let mut a = MicrostepAccumulator { position: Position(-17), increment: 1_234_567_891 };
        let mut b = a;
        for _ in 0..10_000 {
            a.advance();
        }
        b.advance_by(10_000);
        assert_eq!(a, b);
    }

    #[test]
    fn non_finite_speed_keeps_the_previous_increment() {
        let mut acc = MicrostepAccumulator::default();
        acc.set_speed(3.0, 1e6);
        let inc = acc.increment;
        acc.set_speed(f32::NAN, 1e6);
        acc.set_speed(f32::INFINITY, 1e6);
        assert_eq!(acc.increment, inc);
    }

    proptest! {
        #[test]
        fn wrapping_diff_inverts_addition(a in any::<i64>(), d in any::<i64>()) {
            let p = Position(a);
            let q = Position(a.wrapping_add(d));
            prop_assert_eq!(q.wrapping_diff(p), d);
        }
    }
}
