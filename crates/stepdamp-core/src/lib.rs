//! # stepdamp-core
//!
//! The real-time controller of model-based active damping for hybrid stepper motors
//! (US 7,733,051, figs. 2–3): `no_std`, no allocation, no panics, `f32`, one call per
//! PWM period. The simulator in `stepdamp-sim` runs exactly this code.
//!
//! Per period ([`step`]): sample the phase currents (and the encoder in servo mode);
//! Park them at the controller's angle (`Nr·θ_cmd` in open loop, `Nr·θ_fb` in servo);
//! the outer law gives `i_d`, `i_q` commands (open loop: `I_hold` and the detent
//! compensation `(1/Km) Σ A_k sin(k θe + φ_k)`; servo: patent eq. 15; a motor whose ripple
//! grows with the current has it cancelled at the law's operating point, [`ripple`]); PI current loops
//! with anti-windup give `v_d`, `v_q`; inverse Park; the modulator limits the voltage vector
//! to the bus and returns leg duties in `[0, 1]`.
//!
//! Configuration ([`Config`], validated and precomputed once from [`Params`]) is kept
//! apart from state ([`State`], mutated every period).
//!
//! Sign conventions (docs/design.md#the-plant): `θe = Nr·θ`; `i_d = i_a cos θe + i_b sin θe`,
//! `i_q = −i_a sin θe + i_b cos θe`; motor torque `Km(−i_a sin θe + i_b cos θe)`, i.e.
//! `Km·i_q` when the frame is the rotor's; detent torque on the rotor
//! `−Σ A_k sin(k θe + φ_k)`.
//!
//! ```
//! use stepdamp_core::*;
//!
//! let detent = [
//!     Harmonic { order: 4, amplitude_nm: 0.02, phase_rad: 0.0 },
//!     Harmonic { order: 2, amplitude_nm: 0.012, phase_rad: 0.7 },
//!     Harmonic { order: 1, amplitude_nm: 0.008, phase_rad: -1.1 },
//! ];
//! let params = Params {
//!     motor: MotorModel {
//!         km_nm_per_a: 0.3, pole_pairs: 50, resistance_ohm: 0.9, inductance_h: 2.5e-3,
//!         coulomb_friction_nm: 0.01, detent: &detent, current_ripple: CurrentRipple::NONE,
//!     },
//!     drive: DriveSettings {
//!         bus_voltage_v: 48.0, pwm_hz: 20_000.0, holding_current_a: 1.9,
//!         current_limit_a: 3.0, current_loop_bandwidth_hz: 1500.0,
//!         topology: Topology::ThreeLeg, computation_delay_periods: 1,
//!     },
//!     encoder_counts_per_rev: 4000,
//!     servo: ServoGains::for_bandwidth(4.0e-5, 50.0, 300.0),
//!     mode: Mode::OpenLoop,
//!     compensation: Compensation::Patent,
//! };
//! let cfg = Config::new(&params)?;
//! let mut st = State::default();
//! st.command_speed(&cfg, 8.4); // rad/s
//! let out = step(&cfg, &mut st, &Measurement { i_a_a: 0.0, i_b_a: 0.0, encoder_count: 0 });
//! assert!(out.duties.0.iter().all(|d| (0.0..=1.0).contains(d)));
//! assert_eq!(out.signals.i_dq_cmd.d, 1.9);
//! # Ok::<(), ConfigError>(())
//! ```
#![no_std]

pub mod angle;
pub mod choice;
pub mod config;
pub mod correction;
pub mod detent;
pub mod drive;
pub mod encoder;
pub mod limits;
pub mod lowpass;
pub mod modulator;
pub mod observer;
pub mod park;
pub mod pi;
pub mod ripple;
pub mod trig;

pub use angle::{MicrostepAccumulator, Position};
pub use choice::UnknownName;
pub use config::{
    Compensation, Config, ConfigError, DriveSettings, MAX_ELECTRICAL_TURN_PER_PERIOD, Mode, MotorModel,
    PATENT_MOTOR_DETENT, Params, Reason, ServoGains, max_speed_rad_s,
};
pub use correction::{CorrectionTable, TABLE_TICKS};
pub use detent::{Harmonic, HarmonicSeries, MAX_HARMONIC_ORDER};
pub use drive::{CURRENT_SENSOR_FAULT_PERIODS, Measurement, Output, Signals, State, step};
pub use modulator::{LegDuties, Topology};
pub use park::{Ab, Dq};
pub use ripple::{CurrentRipple, RippleModel, TotalRipple, total_ripple};

/// `x` limited to `[lo, hi]` (`lo ≤ hi`), with NaN mapped to `lo` (`f32::clamp` would
/// return NaN, and the controller must never output or store NaN).
///
/// Built from [`at_least`] and [`at_most`], compare-and-select, because on the Cortex-M4F
/// (no `vmaxnm`) `f32::max`/`f32::min` are calls to `fmaxf`/`fminf`.
#[inline]
pub(crate) fn bound(x: f32, lo: f32, hi: f32) -> f32 {
    at_most(at_least(x, lo), hi)
}

/// `max(x, lo)` by compare-and-select: `lo` when `x` is NaN (as `f32::max` for a non-NaN
/// `lo`), `x` when `lo` is NaN.
#[inline]
pub(crate) fn at_least(x: f32, lo: f32) -> f32 {
    if x > lo { x } else { lo }
}

/// `min(x, hi)` by compare-and-select: `hi` when `x` is NaN (as `f32::min` for a non-NaN
/// `hi`), `x` when `hi` is NaN.
#[inline]
pub(crate) fn at_most(x: f32, hi: f32) -> f32 {
    if x < hi { x } else { hi }
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod bound_tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn nan_is_bounded_to_the_lower_end() {
        assert_eq!(bound(f32::NAN, -2.0, 3.0), -2.0);
        assert_eq!(bound(f32::NAN, 0.0, 1.0), 0.0);
        assert_eq!(at_least(f32::NAN, 0.5), 0.5);
        assert_eq!(at_most(f32::NAN, 0.5), 0.5);
    }

    #[test]
    fn infinities_are_bounded_to_their_end() {
        assert_eq!(bound(f32::INFINITY, -2.0, 3.0), 3.0);
        assert_eq!(bound(f32::NEG_INFINITY, -2.0, 3.0), -2.0);
    }

    proptest! {
        #[test]
        fn bound_agrees_with_clamp_for_numbers(x in any::<f32>(), a in -1e6f32..1e6, b in -1e6f32..1e6) {
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            if x.is_nan() {
                prop_assert_eq!(bound(x, lo, hi), lo);
            } else {
                prop_assert_eq!(bound(x, lo, hi), x.clamp(lo, hi));
                prop_assert_eq!(at_least(x, lo), x.max(lo));
                prop_assert_eq!(at_most(x, hi), x.min(hi));
            }
        }
    }
}
