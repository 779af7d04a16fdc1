//! `stepdamp accel simulate`: a simulated Prusa printer axis answers `M973`/`M974` with an
//! accelerometer capture, printed as the firmware prints it
//! (docs/accelerometer.md#simulated-printer).

use crate::common::{load_motor, write_atomic};
use crate::export::CurrentArgs;
use anyhow::{Result, anyhow};
use std::path::PathBuf;
use stepdamp_accel::prusa::parse_gcode;
use stepdamp_printer::{AccelModel, SimulatedPrinter};

/// The accelerometer of `stepdamp accel simulate`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Sensor {
    /// LIS2DH12 as the firmware runs it: 1344 Hz with a seeded rate error (±0.1 %), 0.3 m/s²
    /// RMS noise, 10-bit counts at ±2 g.
    #[default]
    Lis2dh12,
    /// Exactly 1344 Hz, no noise, no quantisation.
    Ideal,
}

/// Arguments of `stepdamp accel simulate`.
#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Motor: a preset name or a profile TOML file.
    #[arg(long)]
    pub motor: String,
    /// The printer's run current.
    #[command(flatten)]
    pub current: CurrentArgs,
    /// The calibration G-code, e.g. "M973 X F2 R10 H4 A0 B0 C0 D0" (a constant trial:
    /// A = B, C = D) or "M974 X A1 B3 R8".
    #[arg(long)]
    pub gcode: String,
    /// The table in use on the axis: a file with its M971 lines (what `export prusa` or
    /// `accel refine` wrote) or `none`.
    #[arg(long, value_name = "FILE|none")]
    pub in_use: String,
    /// The accelerometer.
    #[arg(long, value_enum, default_value_t)]
    pub sensor: Sensor,
    /// The printer's kinematics: the firmware prints the belt's acceleration on a cartesian
    /// axis (MK4), ±1/√2 of it on CoreXY (XL, iX, Core One).
    #[arg(long, value_enum, default_value_t = super::KinematicsArg::Cartesian)]
    pub kinematics: super::KinematicsArg,
    /// Seed of the sensor's rate error and noise (another seed, another capture's noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Start the file with the command as a host echoes it (`Send: M973 …`), so that a
    /// reader knows the capture's G-code.
    #[arg(long)]
    pub echo: bool,
    /// The capture file to write.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs `stepdamp accel simulate`.
pub(super) fn run_simulate(a: SimulateArgs) -> Result<()> {
    let g = parse_gcode(&a.gcode).ok_or_else(|| {
        anyhow!(
            "--gcode `{}`: not a calibration G-code the firmware runs (M973 X|Y F<rev/s> R<revs> H<1..16> A<pha> \
             B<pha> C<mag> D<mag> with C, D in -1..1, or M974 X|Y A<rev/s> B<rev/s> R<revs>)",
            stepdamp_export::escape::line(&a.gcode)
        )
    })?;
    let current = a.current.run_current()?.peak_a();
    let mut p = SimulatedPrinter::new(load_motor(&a.motor)?, current);
    p.seed = a.seed;
    p.kinematics = a.kinematics.into();
    let axis = if g.axis() == stepdamp_accel::Axis::X { 'X' } else { 'Y' };
    p.correction = super::table_in_use(&a.in_use, axis)?;
    if a.sensor == Sensor::Ideal {
        p.accel = AccelModel::ideal();
    }
    let trace = p.simulate(&g).map_err(|e| anyhow!("{}: {e}", a.motor))?;
    let mut text = if a.echo { format!("Send: {g}\n") } else { String::new() };
    text.push_str(&p.print(&trace));
    write_atomic(&a.out, text.as_bytes())?;
    outln!(
        "wrote {}: {g} on {} at {current:.3} A peak, {} samples at {:.2} Hz",
        stepdamp_export::escape::line(&a.out.display().to_string()),
        stepdamp_export::escape::line(&p.profile.name),
        trace.samples_m_s2.len(),
        trace.rate_hz
    );
    Ok(())
}
