//! `stepdamp accel klipper-plan` (docs/accelerometer.md#refining-a-trinamic-table).
//! Translation only: the moves are `stepdamp_accel::klipper::plan`'s.

use super::KinematicsArg;
use anyhow::Result;
use stepdamp_accel::klipper::Kinematics;
use stepdamp_accel::klipper::plan::{KlipperPlanOptions, plan_klipper};
use stepdamp_export::tmc;

/// Arguments of `stepdamp accel klipper-plan`.
#[derive(clap::Args, Debug)]
pub struct KlipperPlanArgs {
    /// Klipper section of the driver: tmc2130, tmc2240 or tmc5160 and stepper_x or stepper_y
    /// (e.g. "tmc5160 stepper_x"): the motor moved.
    #[arg(long)]
    axis: String,
    /// The printer's kinematics.
    #[arg(long, value_enum)]
    kinematics: KinematicsArg,
    /// The stepper's rotation_distance in printer.cfg, mm per motor revolution.
    #[arg(long)]
    rotation_distance: f64,
    /// How far the head may move from where it starts, mm (along X, or X and Y each on CoreXY).
    #[arg(long, default_value_t = 100.0)]
    travel_mm: f64,
    /// The steady speed, motor rev/s.
    #[arg(long, default_value_t = 2.0)]
    speed_rev_s: f64,
    /// The toolhead acceleration for the moves, mm/s².
    #[arg(long, default_value_t = 1000.0)]
    accel_mm_s2: f64,
    /// Steady motion per direction, s.
    #[arg(long, default_value_t = 3.0)]
    steady_s: f64,
}

/// Runs `stepdamp accel klipper-plan`.
pub(super) fn run_klipper_plan(a: KlipperPlanArgs) -> Result<()> {
    let section = tmc::klipper_section(&a.axis)?;
    let axis = super::klipper_motor(&section, &a.axis)?;
    let kinematics = Kinematics::from(a.kinematics);
    let o = KlipperPlanOptions {
        rotation_distance_mm: a.rotation_distance,
        travel_mm: a.travel_mm,
        speed_rev_s: a.speed_rev_s,
        accel_mm_s2: a.accel_mm_s2,
        steady_s: a.steady_s,
        ..KlipperPlanOptions::new(kinematics, axis)
    };
    out!("{}", plan_klipper(&o)?);
    Ok(())
}
