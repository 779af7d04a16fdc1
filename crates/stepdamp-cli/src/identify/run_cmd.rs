//! `stepdamp identify run`: simulate the plan's runs and write their logs; with `--refine`
//! identify, refine and summarise; with `--sensorless` the sensorless plan, identified.

use super::args::{Orders, default_name, parse_orders, plan_options};
use super::plan_cmd::sensorless_options;
use super::report::write_report;
use crate::Global;
use crate::common::{Format, load_motor, print_json, progress, write_atomic};
use anyhow::{Result, anyhow, bail};
use std::path::PathBuf;
use std::time::Instant;
use stepdamp_identify::from_logs::{IdentifyOptions, IdentifyReport, LogSource, Route, RouteReport, identify};
use stepdamp_identify::model::Model;
use stepdamp_identify::plan::{Plan, PlanOptions, plan, run_plan};
use stepdamp_identify::refine::{RefineOptions, RefinementReport, RunReport, refine};
use stepdamp_identify::sensorless::plan::{SensorlessPlan, plan as sensorless_plan};
use stepdamp_identify::sensorless::report::SensorlessReport;
use stepdamp_identify::simulate::run_sensorless_plan;
use stepdamp_sim::Profile;

/// `stepdamp identify run`.
#[derive(clap::Args, Debug)]
pub(super) struct RunArgs {
    /// Motor profile (preset or TOML) to simulate.
    #[arg(long, value_name = "PRESET|FILE")]
    pub(super) motor: String,
    /// Output directory for the logs (one CSV per run), plan.txt, base.toml (the profile the
    /// runs were recorded with, [servo] included: pass it to `identify --motor`) and, with
    /// --refine, identified.toml and refine-summary.csv.
    #[arg(long, value_name = "DIR")]
    pub(super) out: PathBuf,
    /// Also identify from the logs, refine with the feed-forward on (patent criterion) and
    /// write DIR/identified.toml.
    #[arg(long)]
    pub(super) refine: bool,
    /// With --refine: write the report plots into DIR.
    #[arg(long)]
    pub(super) report: bool,
    /// Harmonic orders to identify.
    #[arg(long, default_value = "1,2,4", value_parser = parse_orders)]
    pub(super) orders: Orders,
    /// Electrical periods of steady running per run.
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true)]
    pub(super) periods: f64,
    /// Current-sensor noise, standard deviation in A.
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    pub(super) current_noise: f64,
    /// Seed of the noise generators.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub(super) seed: u64,
    /// Simulate the sensorless plan (open loop, no encoder; logs with the applied
    /// voltages), identify from it and write DIR/identified.toml with R trimmed.
    #[arg(long)]
    pub(super) sensorless: bool,
    /// Most refinement iterations.
    #[arg(long, default_value_t = 3, allow_negative_numbers = true)]
    pub(super) iterations: i64,
    /// text, or json: the run's result (stepdamp_identify::refine::RunReport: the plan, and
    /// with --refine the fit's report and the refinement) as one line of JSON on stdout,
    /// nothing else (the files are written the same).
    #[arg(long, value_enum, default_value_t)]
    pub(super) format: Format,
}

/// `outln!` when `$text` (text output), nothing with `--format json`.
macro_rules! say {
    ($text:expr, $($arg:tt)*) => {
        if $text {
            outln!($($arg)*);
        }
    };
}

/// Most control periods `identify run` simulates over all runs (200 s at 20 kHz, a few
/// hundred MB of logs).
const MAX_SIMULATED_ROWS: f64 = 4e6;

pub(super) fn run_run_cmd(a: RunArgs, global: &Global) -> Result<()> {
    let motor = load_motor(&a.motor)?;
    let orders = a.orders.0.clone();
    if !(a.current_noise.is_finite() && a.current_noise >= 0.0) {
        bail!("--current-noise {}: must be a finite number ≥ 0 A", a.current_noise);
    }
    if a.sensorless {
        return run_sensorless(&a, global, &motor, &orders);
    }
    if a.report && !a.refine {
        bail!("--report needs --refine (it plots the identification)");
    }
    if !(1..=20).contains(&a.iterations) {
        bail!("--iterations {}: must be in 1..=20", a.iterations);
    }
    let po = PlanOptions { current_noise_a: a.current_noise, seed: a.seed, ..plan_options(&orders, a.periods)? };
    let p = plan(&motor, &po)?;
    in_run_dir(&a, p.total_s(), p.profile.drive.pwm_hz, || simulate_and_identify(&a, global, &motor, &orders, &po, &p))
}

/// The part of `identify run` both routes share: bound the logs a plan of `total_s` seconds
/// at `pwm_hz` would hold in memory, check `--out`, then run `work` in the prepared output
/// directory. If `work` fails or is interrupted, a directory it created is removed, and from
/// an existing one what it added.
fn in_run_dir(a: &RunArgs, total_s: f64, pwm_hz: f64, work: impl FnOnce() -> Result<()>) -> Result<()> {
    let rows = total_s * pwm_hz;
    if rows > MAX_SIMULATED_ROWS {
        bail!(
            "--periods {}: the plan would log {total_s:.0} s = {rows:.2e} rows at {pwm_hz} Hz; at most {MAX_SIMULATED_ROWS:.0e} rows are simulated (use fewer periods)",
            a.periods
        );
    }
    if a.out.exists() && !a.out.is_dir() {
        bail!("--out {}: exists and is not a directory", a.out.display());
    }
    let out_dir = stepdamp_out::OutputDir::prepare(&a.out)?;
    let result = work();
    // A reader that closed standard output (`| head`) is not a failure of the run: keep
    // what was written.
    if result.as_ref().is_ok() || result.as_ref().is_err_and(crate::common::is_stdout_closed) {
        out_dir.finish();
    }
    result
}

/// The part of `identify run` after the checks: simulate, write the logs, the plan and the
/// planned profile, and with `--refine` identify, refine and summarise.
fn simulate_and_identify(
    a: &RunArgs,
    global: &Global,
    motor: &Profile,
    orders: &[u16],
    po: &PlanOptions,
    p: &Plan,
) -> Result<()> {
    let text = a.format == Format::Text;
    say!(text, "{p}");
    let pb = progress(p.runs.len() as u64, global.quiet, "simulating");
    let t0 = Instant::now();
    let done = run_plan(motor, motor, &a.out, po, &|| pb.inc(1))?;
    pb.finish_and_clear();
    say!(text, "simulated {:.1} s of runs in {:.2} s", p.total_s(), t0.elapsed().as_secs_f64());
    write_atomic(&a.out.join("plan.txt"), format!("{p}\n").as_bytes())?;
    // The profile the runs were recorded with (its [servo] section is the plan's): the
    // base profile for `identify`, so the fit knows the servo bandwidth of the logs.
    let base_toml = a.out.join("base.toml");
    write_atomic(&base_toml, p.profile.to_toml_string().as_bytes())?;
    for f in &done.files {
        say!(text, "wrote {}", f.display());
    }
    say!(
        text,
        "wrote {} (the planned profile: {}'s, with the [servo] settings of the runs)",
        base_toml.display(),
        a.motor
    );
    if !a.refine {
        let logs: Vec<String> = done.files.iter().map(|f| format!("--log {}", f.display())).collect();
        say!(
            text,
            "identify with: stepdamp identify {} --motor {} --out {}",
            logs.join(" "),
            base_toml.display(),
            a.out.join("identified.toml").display()
        );
        if !text {
            print_json(&RunReport { plan: p.clone(), fit: None, refinement: None })?;
        }
        return Ok(());
    }
    let id = identify_simulated(&done.files, &p.profile, orders, Route::Encoder, None, &a.out)?;
    let fit_report = id.fit_report().clone();
    say!(text, "{id}");
    let validation = fit_report.validation.clone();
    let f0 = &fit_report.fit;
    let fo = IdentifyOptions::new(orders).encoder_fit_options(&p.profile);
    let start = Model::from_fit(f0);
    let ro = RefineOptions {
        max_iterations: a.iterations as usize,
        current_noise_a: a.current_noise,
        seed: a.seed,
        ..RefineOptions::default()
    };
    let pb = progress((p.runs.len() * (a.iterations as usize + 1)) as u64, global.quiet, "refining");
    let r = refine(motor, p, &start, Some(f0), &fo, &ro, &|| pb.inc(1))?;
    pb.finish_and_clear();
    let refinement = RefinementReport::new(motor, f0, &r);
    say!(text, "{refinement}");
    let out = a.out.join("identified.toml");
    let profile = r
        .model
        .apply_to(motor, Some(&default_name(motor, "identified")), &out.display().to_string())
        .map_err(|e| anyhow!("{e}"))?;
    if a.report {
        for w in write_report(&a.out, f0, Some((&r, p)), Some(&validation), &profile.name)? {
            say!(text, "wrote {}", w.display());
        }
    }
    let summary = a.out.join(SUMMARY_FILE);
    write_atomic(&summary, refine_summary_csv(&refinement)?.as_bytes())?;
    say!(
        text,
        "wrote {} (simulated motor, feed-forward-off fit and refined values; ripple before/after)",
        summary.display()
    );
    write_atomic(&out, profile.to_toml_string().as_bytes())?;
    say!(text, "wrote {}", out.display());
    if !text {
        print_json(&RunReport { plan: p.clone(), fit: Some(fit_report), refinement: Some(refinement) })?;
    }
    Ok(())
}

/// File `identify run --refine` writes its summary to, in the output directory.
pub(super) const SUMMARY_FILE: &str = "refine-summary.csv";

/// The summary of `identify run --refine` as CSV, for scripts: the rows of
/// [`RefinementReport::summary`] (columns `quantity,order,unit,motor,identified,refined`;
/// empty cells: not applicable), written by the csv crate.
pub(super) fn refine_summary_csv(report: &RefinementReport) -> Result<String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    for row in &report.summary {
        w.serialize(row)?;
    }
    Ok(String::from_utf8(w.into_inner().map_err(|e| anyhow!("{e}"))?)?)
}

/// Identifies the logs `identify run` wrote (`files`) from `base` by the library's entry,
/// on `route`, the profile named `name` (default: `<base>-identified`).
fn identify_simulated(
    files: &[PathBuf],
    base: &Profile,
    orders: &[u16],
    route: Route,
    name: Option<String>,
    out: &std::path::Path,
) -> Result<IdentifyReport> {
    let sources: Vec<LogSource> = files.iter().cloned().map(LogSource::Path).collect();
    let o = IdentifyOptions {
        route: Some(route),
        name,
        destination: out.join("identified.toml").display().to_string(),
        ..IdentifyOptions::new(orders)
    };
    Ok(identify(&sources, base, &o)?)
}

/// What `identify run --sensorless` prints with `--format json`.
#[derive(serde::Serialize)]
struct SensorlessRun<'a> {
    plan: &'a SensorlessPlan,
    identification: &'a SensorlessReport,
}

/// `identify run --sensorless`: simulate the sensorless plan on `--motor` (its
/// [motor] with the base's datasheet values), write the logs, plan.txt, plan.csv and
/// base.toml, identify and write identified.toml.
fn run_sensorless(a: &RunArgs, global: &Global, motor: &Profile, orders: &[u16]) -> Result<()> {
    if a.refine {
        bail!(
            "--refine: refinement runs the feed-forward in servo mode on an encoder; the sensorless route identifies without one (drop --refine)"
        );
    }
    let p = sensorless_plan(motor, &sensorless_options(orders, a.periods)?)?;
    in_run_dir(a, p.total_s(), motor.drive.pwm_hz, || simulate_and_identify_sensorless(a, global, motor, orders, &p))
}

fn simulate_and_identify_sensorless(
    a: &RunArgs,
    global: &Global,
    motor: &Profile,
    orders: &[u16],
    p: &SensorlessPlan,
) -> Result<()> {
    let text = a.format == Format::Text;
    say!(text, "{p}");
    let pb = progress(p.runs.len() as u64, global.quiet, "simulating");
    let t0 = Instant::now();
    let files = run_sensorless_plan(motor, motor, &a.out, p, a.current_noise, a.seed, &|| pb.inc(1))?;
    pb.finish_and_clear();
    say!(text, "simulated {:.1} s of open-loop runs in {:.2} s", p.total_s(), t0.elapsed().as_secs_f64());
    write_atomic(&a.out.join("plan.txt"), format!("{p}\n").as_bytes())?;
    write_atomic(&a.out.join("plan.csv"), p.to_csv()?.as_bytes())?;
    write_atomic(&a.out.join("base.toml"), motor.to_toml_string().as_bytes())?;
    let name = default_name(motor, "sensorless");
    let id = identify_simulated(&files, motor, orders, Route::Sensorless, Some(name), &a.out)?;
    say!(text, "{id}");
    if a.report {
        let fit = id.fit_report();
        for w in write_report(&a.out, &fit.fit, None, Some(&fit.validation), &id.profile.name)? {
            say!(text, "wrote {}", w.display());
        }
    }
    let out = a.out.join("identified.toml");
    write_atomic(&out, id.profile.to_toml_string().as_bytes())?;
    if text {
        for f in &files {
            outln!("wrote {}", f.display());
        }
        outln!("wrote {} and plan.txt, plan.csv, base.toml", out.display());
    } else if let RouteReport::Sensorless(report) = &id.result {
        print_json(&SensorlessRun { plan: p, identification: report })?;
    }
    Ok(())
}
