//! `stepdamp accel klipper-trial` (docs/accelerometer.md#a-trial-table-for-klipper).
//! Translation only: the table and its block are `stepdamp_export::tmc`'s.

use crate::common::write_atomic;
use anyhow::Result;
use std::path::PathBuf;
use stepdamp_export::escape;
use stepdamp_export::tmc::{ShiftTable, trial_block};

/// Arguments of `stepdamp accel klipper-trial`.
#[derive(clap::Args, Debug)]
pub struct KlipperTrialArgs {
    /// Klipper section of the driver: tmc2130, tmc2240 or tmc5160 and the stepper
    /// (e.g. "tmc5160 stepper_x"; the other drivers have no wave table).
    #[arg(long)]
    axis: String,
    /// The trial's order H: 4, 8, 12 or 16 (what a Trinamic table can turn).
    #[arg(long, default_value_t = 4)]
    harmonic: u16,
    /// The trial's shift U, rad: the table turns the current vector by U·sin(H·θe).
    /// Negative for phase π. Order 4 holds up to about 0.18 rad, 8 0.04, 12 and 16 0.02.
    #[arg(long, default_value_t = 0.12, allow_negative_numbers = true)]
    shift_rad: f64,
    /// Where to write the Klipper block.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `stepdamp accel klipper-trial`.
pub(super) fn run_klipper_trial(a: KlipperTrialArgs) -> Result<()> {
    let t = ShiftTable::trial(a.harmonic, a.shift_rad)?;
    let block = trial_block(&t, &a.axis)?;
    write_atomic(&a.out, block.as_bytes())?;
    outln!(
        "wrote {}: the driver's table turns the current vector by {:.4}·sin({}·θe) rad (other orders within {:.4} rad)",
        escape::line(&a.out.display().to_string()),
        t.achieved_rad,
        t.harmonic,
        t.stray_rad
    );
    outln!(
        "[include] it after the driver's section, FIRMWARE_RESTART, record the trial log, then pass --klipper-trial TRIAL_LOG={}",
        t.klipper_trial_arg()
    );
    Ok(())
}
