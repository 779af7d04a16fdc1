//! `stepdamp identify plan`: the runs to record (servo or sensorless), printed as text, JSON
//! or CSV.

use super::args::{Orders, parse_orders, plan_options};
use crate::common::{load_motor, print_json};
use crate::export::CurrentArgs;
use anyhow::{Result, bail};
use stepdamp_accel::capture::MAX_HARMONIC;
use stepdamp_accel::plan::{CapturePlanOptions, plan_captures};
use stepdamp_export::{Correction, prusa};
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
    /// Plan accelerometer captures on a Prusa printer (firmware >= 6.3.1) instead: per order
    /// and direction an M973 without and one with a known trial correction (the model's at
    /// the run current), printed as G-code with the reasons (docs/accelerometer.md#planning-captures).
    #[arg(long, conflicts_with = "sensorless")]
    pub(super) accel: bool,
    /// With --accel: the motor, X or Y (on CoreXY the A or B motor).
    #[arg(long, value_name = "X|Y")]
    pub(super) axis: Option<String>,
    /// With --accel: the run current the trials are sized for.
    #[command(flatten)]
    pub(super) current: CurrentArgs,
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
    if a.accel {
        return run_accel_plan(&a, &motor);
    }
    if a.axis.is_some() || a.current.given() {
        bail!(
            "--axis and --current/--current-rms do nothing without --accel (the drive runs use the profile's current)"
        );
    }
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

/// `identify plan --accel`: the M973 captures of an influence step, trials from the model.
fn run_accel_plan(a: &PlanArgs, motor: &stepdamp_sim::Profile) -> Result<()> {
    if a.format != PlanFormat::Text {
        bail!("--format {:?} does nothing with --accel: the plan is G-code (text)", a.format);
    }
    let (axis, _) = crate::accel::parse_axis(a.axis.as_deref().unwrap_or("X"))?;
    let run = a.current.run_current()?;
    // The model's correction at the run current, in the firmware's table form (one home:
    // the exporter's fit), is each order's trial.
    let c = Correction::from_profile(motor, Some(run.peak_a()))?;
    let fitted = prusa::fit(&c, prusa::Firmware::V6_3_1)?;
    let mut harmonics = Vec::new();
    for &k in &a.orders.0 {
        let n = u32::from(k);
        if n > MAX_HARMONIC {
            bail!("--orders {k}: M973 takes harmonics 1..={MAX_HARMONIC}");
        }
        let (mag, pha) = (fitted.correction.backward.mag[k as usize], fitted.correction.backward.pha[k as usize]);
        harmonics.push((n, (mag > 0.0).then_some((f64::from(mag), f64::from(pha)))));
    }
    let o = CapturePlanOptions { harmonics, ..CapturePlanOptions::new(axis, motor.motor.pole_pairs) };
    out!("{}", plan_captures(&o)?);
    Ok(())
}
