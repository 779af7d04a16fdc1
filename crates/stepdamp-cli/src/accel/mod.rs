//! `stepdamp accel`: the accelerometer route on a printer (docs/accelerometer.md): simulate a
//! Prusa printer's capture, refine its table from recorded ones, write a Klipper trial table.

mod klipper_plan;
mod klipper_refine;
mod klipper_trial;
mod refine;
mod simulate;
mod simulate_klipper;

use crate::Global;
use anyhow::{Result, anyhow, bail};
use std::path::PathBuf;
use stepdamp_accel::klipper::TrialShift;
use stepdamp_accel::{AccelCapture, Axis};
use stepdamp_export::escape;
use stepdamp_export::prusa::{self, PrusaCorrection};
use stepdamp_export::tmc::TmcRegisters;

/// `stepdamp accel …`.
#[derive(clap::Subcommand, Debug)]
pub enum AccelCommand {
    /// Simulate a printer axis answering M973/M974 and write its accelerometer capture as
    /// Prusa's firmware (>= 6.3.1) prints it.
    Simulate(simulate::SimulateArgs),
    /// One influence step from recorded M973 captures (`identify plan --accel` lists them):
    /// the Prusa table (M971 lines, firmware >= 6.3.1) that cancels what they measured.
    Refine(refine::RefineArgs),
    /// The Klipper G-code of the moves to log for `klipper-refine` (one motor, back and
    /// forth at a steady speed), with the steps around it.
    KlipperPlan(klipper_plan::KlipperPlanArgs),
    /// A Klipper block with a Trinamic trial wave table (tmc2130/2240/5160): the current
    /// vector turned by a known U·sin(H·θe), for the trial log of `identify --accel`.
    KlipperTrial(klipper_trial::KlipperTrialArgs),
    /// One influence step on a Trinamic wave table from Klipper logs recorded with the table
    /// in use and with the trial table: the table that leaves the least of the harmonic.
    KlipperRefine(klipper_refine::KlipperRefineArgs),
    /// Simulate a Klipper printer axis with a Trinamic driver and write its motion-analysis
    /// log (data_logger.py's .json.gz) of the moves given.
    SimulateKlipper(simulate_klipper::SimulateKlipperArgs),
}

/// Runs `stepdamp accel`.
pub fn run(c: AccelCommand, _g: &Global) -> Result<()> {
    match c {
        AccelCommand::Simulate(a) => simulate::run_simulate(a),
        AccelCommand::Refine(a) => refine::run_refine(a),
        AccelCommand::KlipperPlan(a) => klipper_plan::run_klipper_plan(a),
        AccelCommand::KlipperTrial(a) => klipper_trial::run_klipper_trial(a),
        AccelCommand::KlipperRefine(a) => klipper_refine::run_klipper_refine(a),
        AccelCommand::SimulateKlipper(a) => simulate_klipper::run_simulate_klipper(a),
    }
}

/// The table in use on a printer axis: `none` (all items 0), or the M971 lines of a file for
/// `axis` (what `export prusa` or `accel refine` wrote, or the printer's M972 read-back),
/// read bounded.
fn table_in_use(arg: &str, axis: char) -> Result<PrusaCorrection> {
    let path = (arg != "none").then(|| std::path::Path::new(arg));
    Ok(prusa::refine::table_in_use(path, axis)?)
}

/// The printer's kinematics (Klipper's `printer.kinematics`; a Prusa MK4 is cartesian, the
/// XL, iX and Core One CoreXY).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum KinematicsArg {
    /// One motor per axis.
    Cartesian,
    /// Two belts; one motor alone moves the head diagonally.
    Corexy,
}

impl From<KinematicsArg> for stepdamp_accel::klipper::Kinematics {
    fn from(k: KinematicsArg) -> Self {
        match k {
            KinematicsArg::Cartesian => Self::Cartesian,
            KinematicsArg::Corexy => Self::CoreXy,
        }
    }
}

/// The names of the `accel` commands' inputs, in the library's messages.
pub(crate) const LOG_NAMES: stepdamp_accel::sources::Names = stepdamp_accel::sources::Names {
    paths: "--log",
    axis: "--axis",
    motor: "--motor",
    trial: "--klipper-trial",
    kinematics: "--kinematics",
};

/// Every capture of every log, refusing one of another axis.
pub(crate) fn read_captures(logs: &[PathBuf], axis: Axis) -> Result<Vec<AccelCapture>> {
    Ok(stepdamp_accel::sources::read_prusa(logs, axis, &LOG_NAMES)?)
}

/// `--axis`: `X` or `Y` (either case), with its letter for the M971 lines.
pub(crate) fn parse_axis(arg: &str) -> Result<(Axis, char)> {
    match arg {
        "X" | "x" => Ok((Axis::X, 'X')),
        "Y" | "y" => Ok((Axis::Y, 'Y')),
        o => bail!("--axis {}: Prusa phase stepping has axes X and Y", escape::line(o)),
    }
}

/// Every `--klipper-trial LOG=H,U,PHI` as given, parsed (one line naming the argument and
/// the form when one is not); the library checks that each `LOG` is one of the logs given.
pub(crate) fn parse_klipper_trials(args: &[String]) -> Result<Vec<(PathBuf, TrialShift)>> {
    let mut trials = Vec::new();
    for t in args {
        let form = || format!("--klipper-trial {}: expected LOG=H,U,PHI (H 1..=16, U and PHI in rad)", escape::line(t));
        let (log, v) = t.rsplit_once('=').ok_or_else(|| anyhow!(form()))?;
        let f: Vec<&str> = v.split(',').map(str::trim).collect();
        let [h, u, phi] = f[..] else { bail!(form()) };
        let (Ok(harmonic), Ok(amplitude_rad), Ok(phase_rad)) = (h.parse(), u.parse(), phi.parse()) else {
            bail!(form())
        };
        trials.push((PathBuf::from(log), TrialShift { harmonic, amplitude_rad, phase_rad }));
    }
    Ok(trials)
}

/// The motor of a Klipper driver section checked by `tmc::klipper_section` (`section`, as
/// `arg` gave it): `stepper_x` is X, `stepper_y` Y (on CoreXY the A and B motors).
pub(crate) fn klipper_motor(section: &str, arg: &str) -> Result<Axis> {
    match section.split_once(' ').map(|x| x.1) {
        Some("stepper_x") => Ok(Axis::X),
        Some("stepper_y") => Ok(Axis::Y),
        _ => bail!(
            "--axis \"{}\": the logs are read for stepper_x or stepper_y (on CoreXY the A and B motors)",
            escape::line(arg)
        ),
    }
}

/// A Trinamic wave table given as `none` (Klipper's default table) or a file with its
/// `driver_MSLUT…` lines.
pub(crate) fn klipper_table_in_use(arg: &str) -> Result<TmcRegisters> {
    let path = (arg != "none").then(|| std::path::Path::new(arg));
    Ok(stepdamp_export::tmc::table_in_use(path)?)
}
