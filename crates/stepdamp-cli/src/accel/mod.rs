//! `stepdamp accel`: the accelerometer route on a printer (docs/accelerometer.md): simulate a
//! Prusa printer's capture, refine its table from recorded ones, write a Klipper trial table.

mod klipper_trial;
mod refine;
mod simulate;

use crate::Global;
use anyhow::{Context, Result, bail};
use std::path::PathBuf;
use stepdamp_accel::{AccelCapture, Axis};
use stepdamp_export::escape;
use stepdamp_export::prusa::{self, Firmware, PrusaCorrection, Spectrum};

/// `stepdamp accel …`.
#[derive(clap::Subcommand, Debug)]
pub enum AccelCommand {
    /// Simulate a printer axis answering M973/M974 and write its accelerometer capture as
    /// Prusa's firmware (>= 6.3.1) prints it.
    Simulate(simulate::SimulateArgs),
    /// One influence step from recorded M973 captures (`identify plan --accel` lists them):
    /// the Prusa table (M971 lines, firmware >= 6.3.1) that cancels what they measured.
    Refine(refine::RefineArgs),
    /// A Klipper block with a Trinamic trial wave table (tmc2130/2240/5160): the current
    /// vector turned by a known U·sin(H·θe), for the trial log of `identify --accel`.
    KlipperTrial(klipper_trial::KlipperTrialArgs),
}

/// Runs `stepdamp accel`.
pub fn run(c: AccelCommand, _g: &Global) -> Result<()> {
    match c {
        AccelCommand::Simulate(a) => simulate::run_simulate(a),
        AccelCommand::Refine(a) => refine::run_refine(a),
        AccelCommand::KlipperTrial(a) => klipper_trial::run_klipper_trial(a),
    }
}

/// The table in use on a printer axis: `none` (all items 0), or the M971 lines of a file for
/// `axis` (what `export prusa` or `accel refine` wrote, or the printer's M972 read-back),
/// read bounded.
fn table_in_use(arg: &str, axis: char) -> Result<PrusaCorrection> {
    if arg == "none" {
        let zero = Spectrum::default();
        return Ok(PrusaCorrection { forward: zero, backward: zero, firmware: Firmware::V6_3_1 });
    }
    let path = PathBuf::from(arg);
    let bytes = prusa::read::read_capped(&path)?;
    let text = String::from_utf8(bytes).with_context(|| format!("{}: not UTF-8 text", escape::line(arg)))?;
    let (c, _) = prusa::parse_text(&text, Some(axis), arg)?;
    if c.firmware != Firmware::V6_3_1 {
        bail!(
            "{}: an M973 (6.2) table; the captures need firmware >= 6.3.1, whose table is M971 lines",
            escape::line(arg)
        );
    }
    Ok(c)
}

/// Every capture of every log, refusing one of another axis.
pub(crate) fn read_captures(logs: &[PathBuf], axis: Axis) -> Result<Vec<AccelCapture>> {
    const NAMES: stepdamp_accel::sources::Names =
        stepdamp_accel::sources::Names { paths: "--log", axis: "--axis", motor: "--motor", trial: "--klipper-trial" };
    Ok(stepdamp_accel::sources::read_prusa(logs, axis, &NAMES)?)
}

/// `--axis`: `X` or `Y` (either case), with its letter for the M971 lines.
pub(crate) fn parse_axis(arg: &str) -> Result<(Axis, char)> {
    match arg {
        "X" | "x" => Ok((Axis::X, 'X')),
        "Y" | "y" => Ok((Axis::Y, 'Y')),
        o => bail!("--axis {}: Prusa phase stepping has axes X and Y", escape::line(o)),
    }
}
