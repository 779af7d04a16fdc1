//! The plausible range of every motor and drive parameter: defined here once and used by
//! the controller's [`crate::Config::new`], the profile reader (`stepdamp-profile`) and the
//! command line.
//!
//! Each range is that of a real hybrid stepper and its drive, widened by a factor of
//! about ten on each side so that no real motor is refused; the `why` of each [`Limit`]
//! says where the numbers come from. A value outside is a typo, a unit mistake (mH for H,
//! degrees for radians) or a number chosen to break the program — `km_nm_per_a = 1e308`
//! would make every derived quantity infinite. Inside the ranges every derived quantity
//! (the natural frequency, the current-loop and servo gains, the resonance speeds) is
//! finite.

use core::fmt;

/// The allowed range of one parameter, by its profile key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limit {
    /// The key as written in a profile, e.g. `"motor.km_nm_per_a"`.
    pub key: &'static str,
    /// Smallest allowed value (allowed itself unless `min_exclusive`).
    pub min: f64,
    /// `min` itself is not allowed (the value must be strictly greater).
    pub min_exclusive: bool,
    /// Largest allowed value (allowed itself).
    pub max: f64,
    /// Unit, as printed after the range (empty for counts).
    pub unit: &'static str,
    /// Where the range comes from.
    pub why: &'static str,
}

impl Limit {
    /// `v` is finite and within the range.
    pub fn contains(&self, v: f64) -> bool {
        v.is_finite() && if self.min_exclusive { v > self.min } else { v >= self.min } && v <= self.max
    }

    /// `v` (an `f32` of the controller) is finite and within the range.
    pub fn contains_f32(&self, v: f32) -> bool {
        self.contains(f64::from(v))
    }
}

/// Prints the range as `[min, max] unit` or `(min, max] unit`.
impl fmt::Display for Limit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let open = if self.min_exclusive { '(' } else { '[' };
        write!(f, "{open}{}, {}]", Num(self.min), Num(self.max))?;
        if !self.unit.is_empty() {
            write!(f, " {}", self.unit)?;
        }
        Ok(())
    }
}

/// A number printed the way people write it, in the shortest form that reads back as the
/// same `f64`: plain from 0.01 to 100000 (`0.3`, `20000`), beyond that the exponent form
/// when it is shorter (`1e308`, `4e-5`, `1e-3`), so that an error quotes the value as
/// written, not `inf` or three hundred zeros.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        short(f, self.0, self.0.abs())
    }
}

/// [`Num`] for an `f32` (a controller parameter): the shortest form that reads back as the
/// same `f32` (`0.3`, not the `0.30000001192092896` of its `f64` widening).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Num32(pub f32);

impl fmt::Display for Num32 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        short(f, self.0, f64::from(self.0.abs()))
    }
}

/// `v` plain or in exponent form, whichever [`Num`] chooses; `abs` is `|v|` as `f64`.
fn short<T: fmt::Display + fmt::LowerExp>(f: &mut fmt::Formatter<'_>, v: T, abs: f64) -> fmt::Result {
    if !abs.is_finite() || abs == 0.0 {
        return write!(f, "{v}");
    }
    // Both forms are the shortest that round-trip; choose by length without allocating.
    let plain = Len::of(format_args!("{v}"));
    let exp = Len::of(format_args!("{v:e}"));
    if !(1e-2..1e5).contains(&abs) && exp < plain { write!(f, "{v:e}") } else { write!(f, "{v}") }
}

/// Counts the bytes a `format_args!` would print.
struct Len(usize);

impl Len {
    fn of(args: fmt::Arguments<'_>) -> usize {
        let mut l = Len(0);
        let _ = fmt::write(&mut l, args);
        l.0
    }
}

impl fmt::Write for Len {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        self.0 += s.len();
        Ok(())
    }
}

const fn closed(key: &'static str, min: f64, max: f64, unit: &'static str, why: &'static str) -> Limit {
    Limit { key, min, min_exclusive: false, max, unit, why }
}

const fn above(key: &'static str, min: f64, max: f64, unit: &'static str, why: &'static str) -> Limit {
    Limit { key, min, min_exclusive: true, max, unit, why }
}

/// Torque constant `Km`.
pub const KM_NM_PER_A: Limit = closed(
    "motor.km_nm_per_a",
    1e-3,
    50.0,
    "N·m/A",
    "catalogue steppers run from about 0.03 N·m/A (NEMA 8, 20 mN·m at 0.6 A) to about 5 N·m/A \
     (NEMA 42, 30 N·m at 6 A)",
);

/// Rotor teeth `Nr` (electrical turns per mechanical turn).
pub const POLE_PAIRS: Limit = closed(
    "motor.pole_pairs",
    1.0,
    1024.0,
    "",
    "hybrid steppers have 50 (1.8°) or 100 (0.9°) teeth; the controller is tested up to 1024",
);

/// Phase resistance.
pub const RESISTANCE_OHM: Limit = closed(
    "motor.resistance_ohm",
    1e-3,
    1e3,
    "Ω",
    "phase resistances run from about 0.1 Ω (large low-voltage motors) to about 100 Ω (small 24 V motors)",
);

/// Phase inductance.
pub const INDUCTANCE_H: Limit = closed(
    "motor.inductance_h",
    1e-6,
    10.0,
    "H",
    "phase inductances run from about 0.1 mH to about 100 mH; the unit is H, not mH",
);

/// Rotor and load inertia.
pub const INERTIA_KG_M2: Limit = closed(
    "motor.inertia_kg_m2",
    1e-8,
    1.0,
    "kg·m²",
    "a NEMA 8 rotor is about 2e-7 kg·m², a NEMA 42 rotor about 1e-3 kg·m²; the load may add a hundredfold",
);

/// Viscous friction `D`.
pub const VISCOUS_NM_S_PER_RAD: Limit = closed(
    "motor.viscous_nm_s_per_rad",
    0.0,
    10.0,
    "N·m·s/rad",
    "bearing and eddy-current damping is below 0.1 N·m·s/rad even for large motors",
);

/// Coulomb friction `Fs`.
pub const COULOMB_FRICTION_NM: Limit = closed(
    "motor.coulomb_friction_nm",
    0.0,
    100.0,
    "N·m",
    "friction is below the holding torque, which is below 50 N·m for the largest steppers",
);

/// Detent harmonic amplitude `A_k`.
pub const DETENT_AMPLITUDE_NM: Limit = closed(
    "detent.amplitude_nm",
    0.0,
    100.0,
    "N·m",
    "detent torque is a few percent of the holding torque, which is below 50 N·m",
);

/// Detent harmonic phase `φ_k`.
pub const DETENT_PHASE_RAD: Limit = closed(
    "detent.phase_rad",
    -core::f64::consts::TAU,
    core::f64::consts::TAU,
    "rad",
    "a phase is in radians; beyond ±2π it is almost surely in degrees",
);

/// Amplitude of one harmonic of the ripple per ampere of `i_d` or `i_q`
/// ([`crate::ripple::CurrentRipple`]): not a profile key (the profile's `[motor.flux]`
/// gives it), so not in [`ALL`].
pub const CURRENT_RIPPLE_NM_PER_A: Limit = closed(
    "current_ripple.amplitude_nm_per_a",
    0.0,
    100.0,
    "N·m/A",
    "the ripple per ampere is a fraction of the torque constant, which is below 50 N·m/A",
);

/// Phase of one harmonic of the ripple per ampere ([`crate::ripple::CurrentRipple`]): the
/// range of [`DETENT_PHASE_RAD`] under its own key.
pub const CURRENT_RIPPLE_PHASE_RAD: Limit = Limit { key: "current_ripple.phase_rad", ..DETENT_PHASE_RAD };

/// Detent harmonic order `k`.
pub const DETENT_ORDER: Limit = closed(
    "detent.order",
    1.0,
    crate::detent::MAX_HARMONIC_ORDER as f64,
    "",
    "the controller's series holds orders up to MAX_HARMONIC_ORDER; measured detent spectra end near 8",
);

/// Largest sum of the detent amplitudes `Σ A_k`, as a fraction of the open loop's holding
/// torque `Km·I_hold`: 1 (see [`detent_within_holding_torque`]).
///
/// Why: open loop holds the rotor by the magnet torque of the holding current alone, which
/// is at most `Km·I_hold` (`τ = −Km·I_hold·sin(Nr·δ)`, largest at a load angle `δ` of a
/// quarter electrical turn; docs/design.md#the-plant). The detent torque
/// `Σ A_k·sin(k·Nr·θ + φ_k)` reaches `Σ A_k` at some rotor angle for some phases. Where it
/// exceeds the holding torque no load angle balances it: the rotor is pulled to a detent
/// position and the open loop skips, whatever the compensation. So a profile beyond it
/// describes a motor that cannot run in open loop at that current (a unit mistake, or the
/// detent identified with a wrong sign or gain). It is a necessary condition only: real
/// motors have detent torques of a few percent of the holding torque (the presets 4–9 %).
pub const DETENT_PER_HOLDING_TORQUE: f64 = 1.0;

/// Whether detent amplitudes summing to `sum_amplitude_nm` (N·m) stay below the holding
/// torque `km_nm_per_a · holding_current_a` ([`DETENT_PER_HOLDING_TORQUE`] of it). The
/// controller, the profile reader and the C library judge with this one function.
pub fn detent_within_holding_torque(sum_amplitude_nm: f64, km_nm_per_a: f64, holding_current_a: f64) -> bool {
    sum_amplitude_nm < DETENT_PER_HOLDING_TORQUE * km_nm_per_a * holding_current_a
}

/// DC bus voltage.
pub const BUS_VOLTAGE_V: Limit =
    closed("drive.bus_voltage_v", 1.0, 1000.0, "V", "stepper drives run from 5 V to about 300 V (mains-rectified)");

/// PWM and control frequency.
pub const PWM_HZ: Limit = closed(
    "drive.pwm_hz",
    1_000.0,
    200_000.0,
    "Hz",
    "drives switch at 10–100 kHz; below 1 kHz the winding current ripples, above 200 kHz no MCU computes the step",
);

/// Open-loop holding current `I_hold`.
pub const HOLDING_CURRENT_A: Limit = above(
    "drive.holding_current_a",
    0.0,
    100.0,
    "A",
    "open loop holds the rotor with it (zero holds nothing: no stiffness, no resonance); rated currents are below 10 A",
);

/// Limit of the current vector.
pub const CURRENT_LIMIT_A: Limit =
    above("drive.current_limit_a", 0.0, 100.0, "A", "stepper drives deliver up to about 10 A per phase");

/// Closed current-loop bandwidth (also at most [`CURRENT_LOOP_BANDWIDTH_PER_PWM`] of the PWM
/// frequency).
pub const CURRENT_LOOP_BANDWIDTH_HZ: Limit = closed(
    "drive.current_loop_bandwidth_hz",
    1.0,
    50_000.0,
    "Hz",
    "current loops close at 0.5–5 kHz; above a quarter of the PWM frequency the sampled loop is unstable",
);

/// Largest current-loop bandwidth as a fraction of the PWM frequency: a quarter. A
/// sampled PI loop with a period of computation delay loses its phase margin beyond it.
pub const CURRENT_LOOP_BANDWIDTH_PER_PWM: f64 = 0.25;

/// Periods of computation delay.
pub const COMPUTATION_DELAY_PERIODS: Limit = closed(
    "drive.computation_delay_periods",
    0.0,
    1.0,
    "",
    "a drive applies its duties within the period (0) or loads them for the next (1)",
);

/// Encoder counts per mechanical revolution.
pub const COUNTS_PER_REV: Limit =
    closed("encoder.counts_per_rev", 1.0, 1_048_576.0, "", "quadrature encoders give 400 to 2²⁰ counts per turn");

/// Natural frequency of the servo position loop.
pub const SERVO_BANDWIDTH_HZ: Limit = closed(
    "servo.bandwidth_hz",
    0.1,
    1_000.0,
    "Hz",
    "stepper position loops close at 10–200 Hz; the current loop must be about ten times faster",
);

/// Corner of the encoder velocity filter.
pub const VELOCITY_FILTER_HZ: Limit = closed(
    "servo.velocity_filter_hz",
    1.0,
    100_000.0,
    "Hz",
    "the filter corner sits between the servo bandwidth and the PWM frequency",
);

/// Every limit, in profile order.
pub const ALL: [&Limit; 19] = [
    &KM_NM_PER_A,
    &POLE_PAIRS,
    &RESISTANCE_OHM,
    &INDUCTANCE_H,
    &INERTIA_KG_M2,
    &VISCOUS_NM_S_PER_RAD,
    &COULOMB_FRICTION_NM,
    &DETENT_ORDER,
    &DETENT_AMPLITUDE_NM,
    &DETENT_PHASE_RAD,
    &BUS_VOLTAGE_V,
    &PWM_HZ,
    &HOLDING_CURRENT_A,
    &CURRENT_LIMIT_A,
    &CURRENT_LOOP_BANDWIDTH_HZ,
    &COMPUTATION_DELAY_PERIODS,
    &COUNTS_PER_REV,
    &SERVO_BANDWIDTH_HZ,
    &VELOCITY_FILTER_HZ,
];

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::ToString;

    #[test]
    fn numbers_print_as_people_write_them() {
        for (v, s) in [
            (1e308, "1e308"),
            (4e-5, "4e-5"),
            (0.3, "0.3"),
            (20_000.0, "20000"),
            (1e5, "1e5"),
            (1_048_576.0, "1048576"),
            (-1.1, "-1.1"),
            (0.0, "0"),
        ] {
            assert_eq!(Num(v).to_string(), s);
        }
        assert_eq!(Num(f64::INFINITY).to_string(), "inf");
        assert_eq!(Num(1e-300).to_string(), "1e-300");
        for (v, s) in [(0.3f32, "0.3"), (f32::MAX, "3.4028235e38"), (1e-30, "1e-30"), (20_000.0, "20000")] {
            assert_eq!(Num32(v).to_string(), s);
        }
    }

    #[test]
    fn ranges_print_open_and_closed_ends_with_the_unit() {
        assert_eq!(KM_NM_PER_A.to_string(), "[1e-3, 50] N·m/A");
        assert_eq!(HOLDING_CURRENT_A.to_string(), "(0, 100] A");
        assert_eq!(POLE_PAIRS.to_string(), "[1, 1024]");
    }

    #[test]
    fn ends_nan_and_infinity_are_judged_right() {
        assert!(KM_NM_PER_A.contains(1e-3) && KM_NM_PER_A.contains(50.0));
        assert!(!KM_NM_PER_A.contains(50.000_001) && !KM_NM_PER_A.contains(f64::NAN));
        assert!(!HOLDING_CURRENT_A.contains(0.0) && HOLDING_CURRENT_A.contains(1e-9));
        assert!(!INERTIA_KG_M2.contains(f64::INFINITY) && !INERTIA_KG_M2.contains(1e-308));
    }

    #[test]
    fn a_detent_at_or_above_the_holding_torque_is_refused() {
        // Km·I_hold = 0.3 × 1.9 = 0.57 N·m.
        assert!(detent_within_holding_torque(0.04, 0.3, 1.9));
        assert!(detent_within_holding_torque(0.56, 0.3, 1.9));
        assert!(!detent_within_holding_torque(0.57, 0.3, 1.9));
        assert!(!detent_within_holding_torque(5.0, 0.3, 1.9));
        assert!(!detent_within_holding_torque(f64::NAN, 0.3, 1.9));
    }

    #[test]
    fn every_limit_is_a_nonempty_range_with_a_reason() {
        for l in ALL {
            assert!(l.min < l.max && !l.why.is_empty() && l.key.contains('.'), "{l:?}");
        }
    }
}
