//! # stepdamp-accel
//!
//! The accelerometer route to a Prusa printer's torque ripple: instead of Prusa's black-box
//! search, read what the firmware's calibration G-codes print and identify the response of
//! each harmonic of the motor's electrical angle, model-based. This crate is its first layer:
//!
//! - [`klipper`]: a bounded, streaming reader of Klipper's motion-analysis logs
//!   (`data_logger.py`): samples dated, projected on the motor's belt and angled from the
//!   stepper's queue, cut into the stretches the ripple fit takes.
//! - [`prusa`]: a bounded, streaming reader of `M973`/`M974` output as a host logged it
//!   (OctoPrint, Pronterface, plain serial), every capture of a session in order.
//! - [`capture`]: one capture ([`AccelCapture`]) and the commanded motor angle, electrical
//!   angle and speed at each sample, rebuilt from the move the firmware plans, with what the
//!   output does not say as explicit parameters ([`Reconstruction`]).
//! - [`influence`]: the complex response of one harmonic in the constant-speed window with a
//!   95 % interval, the influence coefficient of a known trial correction, the correction that
//!   cancels the response, and the next step of an iteration.
//! - [`head`]: the pulley, belt and carriage ([`HeadModel`]) and the rotor held in open loop
//!   ([`AxisModel`]): the head's acceleration per ripple torque.
//! - [`lockin`]: the same lock-in on short blocks along a speed sweep, each at its speed.
//! - [`plan`]: the captures to record for an influence step, as G-code with the reasons.
//! - [`refine`]: one influence step from a session's captures, per harmonic and direction,
//!   added to the table in use.
//! - [`ripple`]: the head and the motor's ripple in N·m from a speed sweep, with intervals
//!   and a validation, and the TOML file of it ([`ripple::file`]).
//! - [`sources`]: the fit's inputs as paths (Klipper logs or Prusa captures), read, checked
//!   and fitted: what the CLI and the Python binding share.
//! - [`timing`]: an estimate of when the first sample was taken, from the two marker moves.
//!
//! Formats, equations and sign conventions: `docs/accelerometer.md#accelerometer-captures`.

pub mod capture;
mod complex;
pub mod head;
pub mod influence;
pub mod klipper;
pub mod lockin;
pub mod plan;
pub mod prusa;
pub mod refine;
pub mod ripple;
pub mod sources;
mod timeline;
pub mod timing;

pub use capture::{AccelCapture, Annotations, Axis, CaptureError, Commanded, Gcode, Reconstruction, TrialSweep};
pub use head::{AxisModel, HeadError, HeadModel};
pub use influence::{Complex, Influence, InfluenceError, Next, Response, Step, StopReason};
pub use prusa::{ReadError, read_captures};
