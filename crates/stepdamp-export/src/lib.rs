//! # stepdamp-export
//!
//! A detent model (a motor profile) written in the correction formats of the drives people
//! already run, read back from them, and replayed in the simulator before anyone flashes it:
//!
//! - [`prusa`]: Prusa-Firmware-Buddy phase stepping: `M973` lines, the binary correction
//!   files, the `M972` printout; replayed as the firmware's 1024-tick current table.
//! - [`tmc`]: the Trinamic microstep table (`MSLUT0..7`, `MSLUTSEL`, `MSLUTSTART`) as a
//!   Klipper `[tmc5160 …]` block (sections `tmc2130`, `tmc2240`, `tmc5160` only), with a coverage report (a mirrored quarter wave can carry
//!   only the sine part of orders 4, 8, …).
//! - [`simplefoc`]: a C++ header for `HybridStepperMotor::feed_forward_current.q`.
//! - [`escape`]: the one escaping module every writer uses for profile text (names in
//!   comments, C identifiers, SVG, CSV, the terminal).
//! - [`predict`]: the peak-to-peak velocity error at each resonance with and without a
//!   correction, from short simulator runs of the `table` (or any) compensation.
//!
//! **Angle convention** (pinned by tests in each module): stepdamp's electrical angle is
//! `θe = 2π·p/1024` where `p` is the driver's microstep phase (Prusa's motor phase, the
//! Trinamic `MSCNT`), counting up in the driver's positive direction, with stepdamp's
//! winding **a** on the driver's coil **B** (the cosine coil: `CUR_B`, Prusa's `b`) and
//! winding **b** on coil **A** (the sine coil). See `docs/exporters.md`.

pub mod c_header;
pub mod escape;
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

/// A replay table read from a file, and what it was.
pub fn load_table(
    bytes: &[u8],
    what: &str,
    axis: Option<char>,
) -> Result<(stepdamp_core::CorrectionTable, &'static str), ExportError> {
    if bytes.len() == prusa::FILE_BYTES && bytes[..32].iter().all(|&b| b == 0) {
        let s = prusa::decode_file(bytes, what)?;
        return Ok((
            prusa::PrusaCorrection { forward: s, backward: s }.table(),
            "Prusa correction file (both directions)",
        ));
    }
    let text = std::str::from_utf8(bytes).map_err(|_| ExportError::Parse {
        what: what.to_string(),
        reason: format!("neither a {}-byte Prusa correction file nor text", prusa::FILE_BYTES),
    })?;
    if text.contains("driver_MSLUT0") {
        return Ok((tmc::table(&tmc::parse_klipper(text, what)?), "Klipper Trinamic microstep table"));
    }
    if text.lines().any(|l| l.trim().starts_with("M973 ")) {
        return Ok((prusa::parse_m973(text, axis, what)?.table(), "Prusa M973 lines"));
    }
    if text.lines().any(|l| l.split(',').count() == 5) {
        return Ok((prusa::parse_m972(text, axis, what)?.table(), "Prusa M972 output"));
    }
    Err(ExportError::Parse {
        what: what.to_string(),
        reason: "not a Prusa correction file, M973/M972 text or a Klipper block with driver_MSLUT0…".into(),
    })
}
