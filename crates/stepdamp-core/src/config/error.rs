//! Why the controller's parameters were rejected ([`crate::Config::new`]).

use crate::limits::{Limit, Num32};

/// Why parameters were rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConfigError {
    /// A value is out of its range.
    Invalid {
        /// The parameter, e.g. `"motor.km_nm_per_a"`.
        field: &'static str,
        /// The value given.
        value: f32,
        /// What it must be.
        reason: Reason,
    },
    /// A harmonic order outside `1..=MAX_HARMONIC_ORDER`.
    HarmonicOrder {
        /// The order given.
        order: u16,
    },
    /// The same harmonic order given twice.
    DuplicateHarmonic {
        /// The order given twice.
        order: u16,
    },
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ConfigError::Invalid { field, value, reason } => write!(f, "{field} = {}: {reason}", Num32(*value)),
            ConfigError::HarmonicOrder { order } => {
                write!(f, "detent harmonic order {order}: must be in 1..={}", crate::detent::MAX_HARMONIC_ORDER)
            }
            ConfigError::DuplicateHarmonic { order } => {
                write!(f, "detent harmonic order {order} is given more than once")
            }
        }
    }
}

impl core::error::Error for ConfigError {}

/// What a rejected value must be.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reason {
    /// Within the plausible range of the parameter ([`crate::limits`]).
    OutOfRange(&'static Limit),
    /// A relation to another parameter, or a derived value that overflowed.
    Other(&'static str),
    /// The detent amplitudes sum to the holding torque `Km·I_hold` (N·m) or more
    /// ([`crate::limits::detent_within_holding_torque`]).
    DetentAboveHoldingTorque {
        /// `Km·I_hold` in N·m.
        holding_torque_nm: f32,
    },
}

impl core::fmt::Display for Reason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Reason::OutOfRange(l) => write!(f, "must be in {l}"),
            Reason::Other(s) => f.write_str(s),
            Reason::DetentAboveHoldingTorque { holding_torque_nm } => write!(
                f,
                "the detent amplitudes must sum to less than motor.km_nm_per_a × drive.holding_current_a = {} N·m: \
                 open loop cannot hold the rotor against a larger detent",
                Num32(*holding_torque_nm)
            ),
        }
    }
}
