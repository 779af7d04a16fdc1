//! # stepdamp-export
//!
//! A detent model (a motor profile) written in the correction formats of the drives people
//! already run, read back from them, and replayed in the simulator before anyone flashes it:
//!
//! - [`prusa`]: Prusa-Firmware-Buddy phase stepping: `M970`/`M971` lines for firmware
//!   ≥ 6.3.1 (`M973` for 6.2), the binary correction files, the `M971` read-back and the 6.2
//!   `M972` print; replayed as the firmware's 1024-tick current table.
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

pub use model::{Correction, RunCurrent};

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

/// [`load_table`] of the file at `path`, read whole up to [`prusa::read::MAX_BYTES`]
/// ([`prusa::read::read_capped`]): a longer or endless input is refused within that much.
pub fn load_table_file(
    path: &std::path::Path,
    axis: Option<char>,
) -> Result<(stepdamp_core::CorrectionTable, String), ExportError> {
    let bytes = prusa::read::read_capped(path)?;
    load_table(&bytes, &path.display().to_string(), axis)
}

/// A replay table read from a file, and what it was. A 168-byte Prusa correction file is read
/// in the scale of firmware ≥ 6.3.1 (the releases users run); Prusa text says its own version.
pub fn load_table(
    bytes: &[u8],
    what: &str,
    axis: Option<char>,
) -> Result<(stepdamp_core::CorrectionTable, String), ExportError> {
    let is_prusa_file = bytes.len() == prusa::FILE_BYTES && bytes[..32].iter().all(|&b| b == 0);
    if !is_prusa_file {
        if let Ok(text) = std::str::from_utf8(bytes) {
            if text.contains("driver_MSLUT0") {
                let t = tmc::table(&tmc::parse_klipper(text, what)?);
                return Ok((t, "Klipper Trinamic microstep table".to_string()));
            }
        }
    }
    let (c, kind) = prusa::parse_bytes(bytes, axis, what, prusa::Firmware::V6_3_1).map_err(|e| ExportError::Parse {
        what: what.to_string(),
        reason: format!("not a Klipper block with driver_MSLUT0…, nor Prusa: {e}"),
    })?;
    c.check_replay(what)?;
    Ok((c.table(), kind))
}
