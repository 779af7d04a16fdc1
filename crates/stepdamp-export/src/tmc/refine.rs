//! The Trinamic table step from Klipper logs, as `stepdamp accel klipper-refine` and the
//! Python binding run it (`docs/accelerometer.md#refining-a-trinamic-table`): the shift of the
//! table in use, the step (`stepdamp_accel::klipper::table_step`), the new table and its block.

use super::{ShiftTable, TmcRegisters, check_order, order_parts, shift_block};
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
