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
    /// Electrical angle `θe` in rad, in `[−π, π]`: the low 32 bits as a signed fraction
    /// of a turn, so `−π` for a half turn; the last 64 units below a half turn round to
    /// `+π` in `f32` (both ends are the same angle). Resolution 2π·2⁻²⁴ ≈ 3.7·10⁻⁷ rad
    /// near ±π, finer towards 0.
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
/// The commanded speed is turned into a fixed integer increment per period once (when it
/// changes), so the angle is an exact integer sum: after `n` periods at constant speed the
/// position is exactly `start + n·increment` (mod 2⁶⁴), however long it runs; no rounding
/// error accumulates in the sum itself.
///
/// What is *not* exact is the speed: it is quantised to whole units per period, i.e. to
/// `2π / (2³²·Nr·Ts)` rad/s, and rounded to the nearest step. So the commanded position
/// moves at a speed within half a quantum of the one requested, and departs from the ideal
/// real-valued `ω·t` linearly, by at most half a unit per period. For `Nr = 50` at 20 kHz:
/// the quantum is 5.85·10⁻⁷ rad/s (mechanical), the error at most 2.93·10⁻⁷ rad/s, i.e.
/// ≤ 1.05 mrad (0.06°) per hour of running relative to the requested real speed, whatever
/// the speed (a relative error below `0.5 / increment`, ≈ 3·10⁻⁷ at 1 rad/s).
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

    /// `start + n·increment` reduced into `i64` with exact 128-bit arithmetic: the position
    /// that `n` periods must reach, computed independently of the accumulator.
    fn expected_position(start: i64, increment: i64, n: u64) -> i64 {
        let exact = i128::from(start) + i128::from(increment) * i128::from(n);
        // Two's-complement reduction mod 2⁶⁴, by arithmetic rather than by a cast.
        let m = exact.rem_euclid(1i128 << 64);
        if m >= 1i128 << 63 { (m - (1i128 << 64)) as i64 } else { m as i64 }
    }

    #[test]
    fn accumulator_is_exact_over_a_billion_steps() {
        // 10^9 periods at 20 kHz is 13.9 hours.
        let ts = 1.0 / 20_000.0;
        let speed = 7.3_f32; // rad/s
        let upr = units_per_rad_s(50, ts);
        let mut acc = MicrostepAccumulator { position: Position(-123_456_789), increment: 0 };
        acc.set_speed(speed, upr);
        // The increment is the requested speed rounded to whole units per period: 7.3 rad/s
        // (7.30000019 as f32) is 7.3·50·2³²/(2π·20000) = 12 475 066.605… units, so 12 475 067.
        assert_eq!(acc.increment, 12_475_067);
        let n: u64 = 1_000_000_000;
        acc.advance_by(n);
        let want = expected_position(-123_456_789, 12_475_067, n);
        assert_eq!(acc.position.0, want);
        // 1.2475067e16 units: the electrical angle is the low 32 bits of that, exactly.
        let turns = (12_475_067i128 * 1_000_000_000 - 123_456_789) as f64 / UNITS_PER_ELECTRICAL_REV;
        let frac = turns - libm::round(turns);
        assert!((f64::from(acc.position.electrical_angle_rad()) - frac * core::f64::consts::TAU).abs() < 1e-6);
        // Against the ideal real-valued motion the error grows linearly, bounded by half a
        // unit per period (the speed quantisation): here 0.39 unit/period, 11.6 mrad after
        // 13.9 h of a 3.65·10⁵ rad move (3·10⁻⁸ relative), and at most 14.6 mrad.
        let ideal_units = f64::from(speed) * upr * n as f64;
        let err_units = (acc.position.0 + 123_456_789) as f64 - ideal_units;
        assert!(err_units.abs() <= 0.5 * n as f64, "err {err_units}");
        let unit_rad = core::f64::consts::TAU / UNITS_PER_ELECTRICAL_REV / 50.0;
        assert!((err_units * unit_rad).abs() < 0.0147, "{} rad", err_units * unit_rad);
        let rel = err_units / ideal_units;
        assert!(rel.abs() <= 0.5 / acc.increment as f64, "{rel}");
    }

    #[test]
    fn speed_quantum_matches_the_documented_figures() {
        // One unit per period at Nr = 50, 20 kHz: 5.85·10⁻⁷ rad/s; half of it per hour:
        // 1.05 mrad.
        let quantum = 1.0 / units_per_rad_s(50, 1.0 / 20_000.0);
        assert!((quantum - 5.85e-7).abs() < 0.01e-7, "{quantum}");
        assert!((0.5 * quantum * 3600.0 - 1.05e-3).abs() < 0.01e-3);
    }

    #[test]
    fn electrical_angle_stays_within_plus_minus_pi() {
        use core::f32::consts::PI;
        assert_eq!(Position(1 << 31).electrical_angle_rad(), -PI);
        // Just below a half turn, f32 rounding reaches +π (the same angle as −π).
        let near = Position((1 << 31) - 1).electrical_angle_rad();
        assert!(near <= PI && near > PI - 1e-6, "{near}");
        for p in [0i64, 1, -1, (1 << 31) - 64, (1 << 31) - 65, i64::MAX, i64::MIN] {
            let th = Position(p).electrical_angle_rad();
            assert!((-PI..=PI).contains(&th), "{p}: {th}");
        }
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
        fn advance_by_is_additive_across_wraps(
            start in any::<i64>(), increment in any::<i64>(), a in any::<u64>(), b in any::<u64>()
        ) {
            let (a, b) = (a >> 1, b >> 1); // so that a + b fits a u64
            let mut split = MicrostepAccumulator { position: Position(start), increment };
            split.advance_by(a);
            split.advance_by(b);
            let mut whole = MicrostepAccumulator { position: Position(start), increment };
            whole.advance_by(a + b);
            prop_assert_eq!(split, whole);
            prop_assert_eq!(whole.position.0, expected_position(start, increment, a + b));
        }

        #[test]
        fn advance_by_matches_exact_arithmetic_for_real_speeds(
            start in any::<i64>(), speed in -600.0f32..600.0, n in 0u64..100_000_000_000
        ) {
            let mut acc = MicrostepAccumulator { position: Position(start), increment: 0 };
            acc.set_speed(speed, units_per_rad_s(50, 5e-5));
            let inc = acc.increment;
            acc.advance_by(n);
            prop_assert_eq!(acc.position.0, expected_position(start, inc, n));
        }

        #[test]
        fn wrapping_diff_inverts_addition(a in any::<i64>(), d in any::<i64>()) {
            let p = Position(a);
            let q = Position(a.wrapping_add(d));
            prop_assert_eq!(q.wrapping_diff(p), d);
        }
    }
}
