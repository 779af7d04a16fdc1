//! `stepdamp accel simulate-klipper`: the simulated printer as a Klipper printer with a
//! Trinamic driver, its moves recorded as data_logger.py records them
//! (docs/accelerometer.md#the-simulated-klipper-printer). Translation only.

use crate::common::{load_motor, write_atomic};
use crate::export::CurrentArgs;
use anyhow::{Result, anyhow, bail};
use std::path::PathBuf;
use stepdamp_accel::prusa::parse_gcode;
use stepdamp_export::{escape, tmc};
use stepdamp_printer::{KlipperSetup, SimulatedPrinter};

/// Arguments of `stepdamp accel simulate-klipper`.
#[derive(clap::Args, Debug)]
pub struct SimulateKlipperArgs {
    /// Motor: a preset name or a profile TOML file.
    #[arg(long)]
    motor: String,
    /// The printer's run current.
    #[command(flatten)]
    current: CurrentArgs,
    /// A move, written as the Prusa G-code of its shape: "M973 X F2 R6 H4 A0 B0 C0 D0" is
    /// 6 revolutions at a steady 2 rev/s (R < 0 the other way; C and D must be 0: the
    /// trial is the driver's table), "M974 X A2 B4 R8" a sweep; repeat for several moves,
    /// recorded one after the other in one log.
    #[arg(long = "move", required = true, value_name = "GCODE")]
    moves: Vec<String>,
    /// Klipper section of the driver: tmc2130, tmc2240 or tmc5160 and stepper_x or
    /// stepper_y (cartesian kinematics).
    #[arg(long)]
    axis: String,
    /// The driver's wave table: `none` (Klipper's default) or a file with its driver_MSLUT…
    /// lines (what `accel klipper-trial` or `accel klipper-refine` wrote).
    #[arg(long, value_name = "FILE|none")]
    table: String,
    /// Seed of the sensor's rate error and noise (another seed, another log's noise).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The log to write (data_logger.py's NAME.json.gz; its index is not written).
    #[arg(long)]
    out: PathBuf,
}

/// Runs `stepdamp accel simulate-klipper`.
pub(super) fn run_simulate_klipper(a: SimulateKlipperArgs) -> Result<()> {
    let section = tmc::klipper_section(&a.axis)?;
    let axis = super::klipper_motor(&section, &a.axis)?;
    let mut moves = Vec::new();
    for m in &a.moves {
        let g = parse_gcode(m).ok_or_else(|| {
            anyhow!("--move `{}`: expected M973 X|Y F<rev/s> R<revs> H<1..16> A0 B0 C0 D0 or M974 X|Y A<rev/s> B<rev/s> R<revs>", escape::line(m))
        })?;
        if g.axis() != axis {
            bail!("--move `{}`: moves the other motor than {}", escape::line(m), escape::line(&section));
        }
        moves.push(g);
    }
    let registers = super::klipper_table_in_use(&a.table)?;
    let current = a.current.run_current()?.peak_a();
    let p = SimulatedPrinter {
        driver_table: Some(tmc::table(&registers)),
        seed: a.seed,
        ..SimulatedPrinter::new(load_motor(&a.motor)?, current)
    };
    let log = p.motan_log(&moves, &KlipperSetup { axis, ..KlipperSetup::default() }).map_err(|e| anyhow!("{e}"))?;
    write_atomic(&a.out, &log.json_gz)?;
    outln!(
        "wrote {}: {} moves of {} at {current} A peak, {} accelerometer samples, {} steps",
        escape::line(&a.out.display().to_string()),
        moves.len(),
        escape::line(&p.profile.name),
        log.samples.len(),
        log.steps
    );
    Ok(())
}
