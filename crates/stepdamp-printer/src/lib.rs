//! # stepdamp-printer
//!
//! A simulated Prusa printer axis that answers the phase-stepping calibration G-codes
//! `M973` and `M974` with an accelerometer capture printed exactly as the firmware
//! (≥ 6.3.1) prints it, so that the accelerometer route of [`stepdamp_accel`] can be tried
//! end to end without a printer: capture, response per harmonic, influence coefficient,
//! the cancelling correction in the table, capture again.
//!
//! - [`head`]: the pulley, belt and carriage ([`HeadModel`]) between the rotor and the
//!   accelerometer.
//! - [`printer`]: the axis ([`SimulatedPrinter`]): the motor simulator in open loop
//!   replaying the Prusa table, the move as the firmware plans it, the accelerometer
//!   ([`AccelModel`]) and the printed capture.
//! - [`motan`]: the same axis as a Klipper printer, its moves recorded as Klipper's
//!   motion-analysis logger writes them ([`SimulatedPrinter::motan_log`]).
//! - [`score`]: an absolute vibration score of a capture ([`VibrationScore`]).
//! - [`family`]: a seeded family of random printers ([`family_printer`]): real motors,
//!   heads, run currents.
//!
//! Models and approximations: `docs/accelerometer.md#simulated-printer`.

pub mod family;
mod format;
pub mod head;
pub mod motan;
pub mod printer;
pub mod score;

pub use family::family_printer;
pub use head::{HeadError, HeadModel};
pub use motan::{KlipperSetup, MotanLog};
pub use printer::{AccelModel, PrinterError, SimulatedPrinter, Trace};
pub use score::VibrationScore;

#[cfg(test)]
mod end_to_end;
#[cfg(test)]
mod tests;
