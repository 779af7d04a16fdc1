//! # stepdamp-export
//!
//! A detent model (a motor profile) written in the correction formats of the drives people
//! already run, read back from them, and replayed in the simulator before anyone flashes it:
//!
//! - [`prusa`]: Prusa-Firmware-Buddy phase stepping: `M973` lines, the binary correction
//!   files, the `M972` printout; replayed as the firmware's 1024-tick current table.
//! - [`tmc`]: the Trinamic microstep table (`MSLUT0..7`, `MSLUTSEL`, `MSLUTSTART`) as a
//!   Klipper `[tmc5160 …]` block, with a coverage report (a mirrored quarter wave can carry
//!   only the sine part of orders 4, 8, …).
//! - [`simplefoc`]: a C++ header for `HybridStepperMotor::feed_forward_current.q`.
//! - [`predict`]: the peak-to-peak velocity error at each resonance with and without a
//!   correction, from short simulator runs of the `table` (or any) compensation.
//!
//! **Angle convention** (pinned by tests in each module): stepdamp's electrical angle is
//! `θe = 2π·p/1024` where `p` is the driver's microstep phase (Prusa's motor phase, the
//! Trinamic `MSCNT`), counting up in the driver's positive direction, with stepdamp's
//! winding **a** on the driver's coil **B** (the cosine coil: `CUR_B`, Prusa's `b`) and
//! winding **b** on coil **A** (the sine coil). See `docs/exporters.md`.

pub mod c_header;
pub mod model;
pub mod predict;
pub mod prusa;
pub mod simplefoc;
pub mod tmc;

pub use model::Correction;

/// Why an export or import failed.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The profile or an option cannot be exported.
    #[error("{0}")]
    Invalid(String),
    /// A file in another project's format could not be read.
    #[error("{what}: {reason}")]
    Parse {
        /// The file or line.
        what: String,
        /// What is wrong.
        reason: String,
    },
    /// The format cannot carry anything of this model.
    #[error("nothing fits: {0}")]
    NothingFits(String),
    /// The simulator refused a prediction run.
    #[error("prediction: {0}")]
    Sim(String),
}
