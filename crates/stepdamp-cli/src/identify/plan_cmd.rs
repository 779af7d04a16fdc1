//! `stepdamp identify plan`: the runs to record (servo or sensorless), printed as text, JSON
//! or CSV.

use super::args::{Orders, parse_orders, plan_options};
use crate::common::{load_motor, print_json};
use anyhow::Result;
use stepdamp_identify::plan::{PlannedRun, plan, runs_csv};
use stepdamp_identify::sensorless::plan::{SensorlessPlanOptions, plan as sensorless_plan};

/// `stepdamp identify plan`.
#[derive(clap::Args, Debug)]
pub(super) struct PlanArgs {
    /// Motor profile (preset or TOML) to plan for.
    #[arg(long, value_name = "PRESET|FILE")]
    pub(super) motor: String,
    /// Harmonic orders to identify.
    #[arg(long, default_value = "1,2,4", value_parser = parse_orders)]
    pub(super) orders: Orders,
    /// Electrical periods of steady running per run.
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true)]
    pub(super) periods: f64,
    /// Plan open-loop runs for the sensorless route (no encoder: the drive's own voltages
    /// and currents), with a standstill that trims R.
    #[arg(long)]
    pub(super) sensorless: bool,
    /// text; json: the plan (stepdamp_identify::plan::Plan, or
    /// stepdamp_identify::sensorless::plan::SensorlessPlan) as one line of JSON; csv: one
    /// row per run, the columns of docs/files.md#plan-csv (run, mode, speed profile and the
    /// drive's settings).
    #[arg(long, value_enum, default_value_t)]
    pub(super) format: PlanFormat,
}

/// Output of `identify plan`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) enum PlanFormat {
    /// For people: the runs with their reasons.
    #[default]
    Text,
    /// One JSON object.
    Json,
    /// One row per run (docs/files.md#plan-csv: run, mode, speed profile and the drive's
    /// settings), for a script or another drive to perform exactly the plan.
    Csv,
}

/// Runs `stepdamp identify plan`.
pub(super) fn run_plan_cmd(a: PlanArgs) -> Result<()> {
    let motor = load_motor(&a.motor)?;
    if a.sensorless {
        let p = sensorless_plan(&motor, &sensorless_options(&a.orders.0, a.periods)?)?;
        return print_plan(&p, &p, &p.runs, a.format);
    }
    let p = plan(&motor, &plan_options(&a.orders.0, a.periods)?)?;
    print_plan(&p, &p, &p.runs, a.format)
}

/// The sensorless plan's options from the command line.
pub(super) fn sensorless_options(orders: &[u16], periods: f64) -> Result<SensorlessPlanOptions> {
    // The same bounds as the servo plan's (one home: plan_options).
    let po = plan_options(orders, periods)?;
    Ok(SensorlessPlanOptions {
        orders: po.orders,
        electrical_periods: po.electrical_periods,
        ..SensorlessPlanOptions::default()
    })
}

/// Prints a plan in `format`.
fn print_plan(
    text: &dyn std::fmt::Display,
    json: &impl serde::Serialize,
    runs: &[PlannedRun],
    format: PlanFormat,
) -> Result<()> {
    match format {
        PlanFormat::Text => outln!("{text}"),
        PlanFormat::Json => print_json(json)?,
        PlanFormat::Csv => out!("{}", runs_csv(runs)?),
    }
    Ok(())
}
