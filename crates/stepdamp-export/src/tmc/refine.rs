//! The Trinamic table step from Klipper logs, as `stepdamp accel klipper-refine` and the
//! Python binding run it (`docs/accelerometer.md#refining-a-trinamic-table`): the shift of the
//! table in use, the step (`stepdamp_accel::klipper::table_step`), the new table and its block.

use super::{ShiftTable, TmcRegisters, check_order, order_parts, parse_klipper, shift_block};
use crate::ExportError;
use stepdamp_accel::klipper::Log;
use stepdamp_accel::klipper::table_step::{TableStep, table_step_of_logs};

/// The step and the table it asks for.
#[derive(Debug, Clone, PartialEq)]
pub struct KlipperRefined {
    /// The influence step.
    pub step: TableStep,
    /// The new table (its achieved shift is what it does).
    pub table: ShiftTable,
    /// The Klipper block to write: the step as comments, then the table.
    pub block: String,
}

/// The step from `logs` (those with a trial are the trial logs, the others were recorded with
/// `in_use`), for the order of their trial, and the block of the new table for the section
/// `axis`. Refuses: no trial log, an order a table cannot turn, and what the step refuses.
pub fn klipper_refine(
    logs: &[Log],
    in_use: &TmcRegisters,
    axis: &str,
    periods_per_block: u32,
) -> Result<KlipperRefined, ExportError> {
    let Some(trial) = logs.iter().find_map(|l| l.trial) else {
        return Err(ExportError::Invalid("no log has a trial: name the trial log and its shift".into()));
    };
    let order = check_order(trial.harmonic)?;
    let in_use_rad = order_parts(&in_use.decode(), order).0;
    let step = table_step_of_logs(logs, trial.harmonic, in_use_rad, periods_per_block)
        .map_err(|e| ExportError::Invalid(e.to_string()))?;
    let table = ShiftTable::new(order, step.new_rad)?;
    let block = shift_block(&table, axis, &step.to_string())?;
    Ok(KlipperRefined { step, table, block })
}

/// The table in use: Klipper's default (`None`), or the `driver_MSLUT…` lines of the file at
/// `path` (what `accel klipper-refine` wrote), read bounded (`prusa::read::read_capped`).
pub fn table_in_use(path: Option<&std::path::Path>) -> Result<TmcRegisters, ExportError> {
    let Some(path) = path else { return Ok(TmcRegisters::KLIPPER_DEFAULT) };
    let name = crate::escape::line(&path.display().to_string());
    let bytes = crate::prusa::read::read_capped(path)?;
    let text = String::from_utf8(bytes).map_err(|_| ExportError::Invalid(format!("{name}: not UTF-8 text")))?;
    parse_klipper(&text, &name)
}
