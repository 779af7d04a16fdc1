//! `stepdamp accel klipper-refine` (docs/accelerometer.md#refining-a-trinamic-table).
//! Translation only: the logs are read by `stepdamp_accel::sources`, the step is
//! `stepdamp_accel::klipper::table_step`, the table and its block `stepdamp_export::tmc`'s.

use crate::common::{load_motor, write_atomic};
use anyhow::{Result, anyhow, bail};
use std::path::PathBuf;
use stepdamp_accel::sources::{Sources, read};
use stepdamp_export::escape;
use stepdamp_export::tmc;

/// Arguments of `stepdamp accel klipper-refine`.
#[derive(clap::Args, Debug)]
pub struct KlipperRefineArgs {
    /// Klipper motion-analysis logs (data_logger.py's LOG.json.gz): those recorded with the
    /// table in use, and those recorded with the trial table (named by --klipper-trial), with
    /// steady moves of the same speeds in each direction.
    #[arg(long = "log", required = true, value_name = "FILE")]
    logs: Vec<PathBuf>,
    /// LOG=H,U,PHI: the log recorded with the trial table, and its shift as
    /// `accel klipper-trial` printed it (e.g. "trial.json.gz=4,0.1201,0").
    #[arg(long = "klipper-trial", required = true, value_name = "LOG=H,U,PHI")]
    klipper_trial: Vec<String>,
    /// Motor profile (preset or TOML): its pole pairs are checked against the logs.
    #[arg(long, value_name = "PRESET|FILE")]
    motor: String,
    /// Klipper section of the driver: tmc2130, tmc2240 or tmc5160 and stepper_x or stepper_y
    /// (e.g. "tmc5160 stepper_x"): the logs' motor, and the section written.
    #[arg(long)]
    axis: String,
    /// The table in use while the baseline logs were recorded: `none` (Klipper's default
    /// table) or a file with its driver_MSLUT… lines (what this command wrote before).
    #[arg(long, value_name = "FILE|none")]
    in_use: String,
    /// Whole electrical periods per lock-in block.
    #[arg(long, default_value_t = 20)]
    periods_per_block: u32,
    /// Where to write the new table's Klipper block.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `stepdamp accel klipper-refine`.
pub(super) fn run_klipper_refine(a: KlipperRefineArgs) -> Result<()> {
    let section = tmc::klipper_section(&a.axis)?;
    let axis = super::klipper_motor(&section, &a.axis)?;
    let motor = load_motor(&a.motor)?;
    let trials = super::parse_klipper_trials(&a.klipper_trial)?;
    let Some(&(_, first)) = trials.first() else { bail!("--klipper-trial: at least one trial log") };
    // Refuse an order no table turns before reading the logs.
    tmc::check_order(first.harmonic).map_err(|e| anyhow!("--klipper-trial: {e}"))?;
    let names = super::LOG_NAMES;
    let Sources::Klipper(logs) = read(&a.logs, axis, &trials, u32::from(motor.motor.pole_pairs), &names)? else {
        bail!("--log: Prusa captures; accel refine takes those (this command reads Klipper's logs)")
    };
    let used = super::klipper_table_in_use(&a.in_use)?;
    let r = tmc::klipper_refine(&logs, &used, &a.axis, a.periods_per_block)?;
    out!("{}", r.step);
    let (table, block) = (r.table, r.block);
    write_atomic(&a.out, block.as_bytes())?;
    outln!(
        "wrote {}: the table turns the current vector by {:+.4}·sin({}·θe) rad; record again with it (--in-use {}) to check",
        escape::line(&a.out.display().to_string()),
        table.achieved_rad,
        table.harmonic,
        escape::line(&a.out.display().to_string())
    );
    Ok(())
}
