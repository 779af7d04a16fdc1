//! `stepdamp identify`: detent harmonics and friction from servo-mode run logs
//! (design.md §5), the experiment plan, simulated runs, refinement, the static route.
//!
//! ```text
//! stepdamp identify --log a.csv --log b.csv --motor base.toml --out identified.toml [--orders 1,2,4] [--report DIR]
//! stepdamp identify plan   --motor FILE
//! stepdamp identify run    --motor FILE --out DIR [--refine] [--report]
//! stepdamp identify static --table curve.csv --motor base.toml --out identified.toml [--sign on-rotor|holding]
//! ```

use crate::Global;
use crate::common::{AtomicFiles, load_motor, progress, write_atomic};
use anyhow::{Result, anyhow, bail};
use plotters::coord::Shift;
use plotters::prelude::*;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;
use stepdamp_identify::conditions::InertiaMode;
use stepdamp_identify::fit::{Effort, Fit, FitOptions, fit};
use stepdamp_identify::log::{LogOptions, RunLog, read_log};
use stepdamp_identify::model::Model;
use stepdamp_identify::plan::{Plan, PlanOptions, plan, run_plan};
use stepdamp_identify::refine::{PERIODIC_ORDERS, RefineOptions, Refinement, refine, remaining_ripple_nm, series_nm};
use stepdamp_identify::spectrum::order_spectrum;
use stepdamp_identify::static_curve::{TorqueSign, analyse, read_table};
use stepdamp_identify::validation::{Validation, default_max_order, validate};
use stepdamp_sim::Profile;

/// Arguments of `stepdamp identify`.
#[derive(clap::Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct IdentifyArgs {
    #[command(subcommand)]
    command: Option<IdentifyCommand>,
    #[command(flatten)]
    fit: FitArgs,
}

/// `stepdamp identify <subcommand>`.
#[derive(clap::Subcommand, Debug)]
enum IdentifyCommand {
    /// Print the runs to record for identification, with the reason for each.
    Plan(PlanArgs),
    /// Simulate the plan's runs and write their logs (optionally identify and refine).
    Run(RunArgs),
    /// Harmonics from a static torque-versus-angle table (CSV theta_rad, torque_nm) by FFT.
    Static(StaticArgs),
}

/// Identification from logs (the default action).
#[derive(clap::Args, Debug)]
struct FitArgs {
    /// A servo-mode run log (CSV, design.md §6). Needs t_s, theta_fb_rad and i_q_a (or
    /// i_a_a and i_b_a); repeat for several runs (two speeds, both directions).
    #[arg(long = "log", value_name = "CSV")]
    logs: Vec<PathBuf>,
    /// Base motor profile (preset or TOML): Km, Nr, encoder and servo settings are taken
    /// from it; its detent list, friction and J are replaced by what is identified (J is
    /// fitted; a warning says when it differs from the base's by more than 20 %).
    #[arg(long, value_name = "PRESET|FILE")]
    motor: Option<String>,
    /// Where to write the identified profile (TOML).
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Harmonic orders to identify (comma list).
    #[arg(long, default_value = "1,2,4")]
    orders: String,
    /// Directory for the report: effort-ripple spectrum and residual plots (SVG + PNG).
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
    /// The effort signal: measured (i_q_a) or command (iq_cmd_a).
    #[arg(long, default_value = "measured")]
    effort: String,
    /// The logs were recorded with the --motor profile's detent and Fs fed forward: print
    /// the remaining ripple (the patent's refinement criterion). J is then held at the
    /// --motor profile's (fitted otherwise).
    #[arg(long)]
    ff_on: bool,
    /// Servo position-loop bandwidth of the logged runs in Hz (default: the profile's
    /// [servo] bandwidth_hz); only used for warnings.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    servo_bandwidth: Option<f64>,
    /// How J is obtained: fit (always fitted), base (the --motor profile's) or auto
    /// (fitted when the logs separate it — two speeds in both directions — and its 95 %
    /// interval is narrow, else the base profile's). The decision is printed.
    #[arg(long, default_value = "auto", value_parser = inertia_parser())]
    inertia: InertiaMode,
    /// Name of the identified profile (default: base name + "-identified").
    #[arg(long)]
    name: Option<String>,
}

/// `stepdamp identify plan`.
#[derive(clap::Args, Debug)]
struct PlanArgs {
    /// Motor profile (preset or TOML) to plan for.
    #[arg(long, value_name = "PRESET|FILE")]
    motor: String,
    /// Harmonic orders to identify.
    #[arg(long, default_value = "1,2,4")]
    orders: String,
    /// Electrical periods of steady running per run.
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true)]
    periods: f64,
}

/// `stepdamp identify run`.
#[derive(clap::Args, Debug)]
struct RunArgs {
    /// Motor profile (preset or TOML) to simulate.
    #[arg(long, value_name = "PRESET|FILE")]
    motor: String,
    /// Output directory for the logs (one CSV per run), plan.txt, base.toml (the profile the
    /// runs were recorded with, [servo] included: pass it to `identify --motor`) and, with
    /// --refine, identified.toml and refine-summary.csv.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Also identify from the logs, refine with the feed-forward on (patent criterion) and
    /// write DIR/identified.toml.
    #[arg(long)]
    refine: bool,
    /// With --refine: write the report plots into DIR.
    #[arg(long)]
    report: bool,
    /// Harmonic orders to identify.
    #[arg(long, default_value = "1,2,4")]
    orders: String,
    /// Electrical periods of steady running per run.
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true)]
    periods: f64,
    /// Current-sensor noise, standard deviation in A.
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    current_noise: f64,
    /// Seed of the noise generators.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    seed: u64,
    /// Most refinement iterations.
    #[arg(long, default_value_t = 3, allow_negative_numbers = true)]
    iterations: i64,
}

/// `stepdamp identify static`.
#[derive(clap::Args, Debug)]
struct StaticArgs {
    /// Torque-versus-angle table: CSV with columns theta_rad (mechanical) and torque_nm,
    /// over a whole number of electrical periods.
    #[arg(long, value_name = "CSV")]
    table: PathBuf,
    /// What the table holds: on-rotor (the detent torque on the rotor, −Σ A sin) or holding
    /// (the torque applied to hold the rotor, +Σ A sin).
    #[arg(long)]
    sign: String,
    /// Base motor profile (preset or TOML).
    #[arg(long, value_name = "PRESET|FILE")]
    motor: String,
    /// Where to write the profile with the detent replaced (friction kept).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Harmonic orders to keep.
    #[arg(long, default_value = "1,2,4")]
    orders: String,
    /// Name of the new profile (default: base name + "-static").
    #[arg(long)]
    name: Option<String>,
}

/// Runs `stepdamp identify`.
pub fn run(args: IdentifyArgs, global: &Global) -> Result<()> {
    match args.command {
        Some(IdentifyCommand::Plan(a)) => run_plan_cmd(a),
        Some(IdentifyCommand::Run(a)) => run_run_cmd(a, global),
        Some(IdentifyCommand::Static(a)) => run_static_cmd(a),
        None => run_fit_cmd(args.fit, global),
    }
}

/// Parses a comma list of harmonic orders (1..=32, distinct).
/// `--inertia`: the names of [`InertiaMode`], parsed by its `FromStr` (one home for them).
fn inertia_parser() -> impl clap::builder::TypedValueParser<Value = InertiaMode> {
    use clap::builder::TypedValueParser as _;
    clap::builder::PossibleValuesParser::new(InertiaMode::ALL.map(InertiaMode::name))
        .try_map(|s| s.parse::<InertiaMode>())
}

fn parse_orders(s: &str) -> Result<Vec<u16>> {
    let mut out: Vec<u16> = Vec::new();
    for part in s.split(',').map(str::trim) {
        if part.is_empty() {
            bail!("--orders '{s}': an empty entry; give a comma list such as 1,2,4");
        }
        let k: u16 = part.parse().map_err(|_| anyhow!("--orders '{part}': not a whole number"))?;
        if k == 0 || usize::from(k) > stepdamp_core::MAX_HARMONIC_ORDER {
            bail!("--orders {k}: each order must be in 1..={}", stepdamp_core::MAX_HARMONIC_ORDER);
        }
        if out.contains(&k) {
            bail!("--orders {k}: listed twice");
        }
        out.push(k);
    }
    if out.is_empty() {
        bail!("--orders '{s}': give at least one order, e.g. 1,2,4");
    }
    Ok(out)
}

fn plan_options(orders: &[u16], periods: f64) -> Result<PlanOptions> {
    if !(periods.is_finite() && (2.0..=100_000.0).contains(&periods)) {
        bail!("--periods {periods}: must be between 2 and 100000 electrical periods");
    }
    Ok(PlanOptions { orders: orders.to_vec(), electrical_periods: periods, ..PlanOptions::default() })
}

fn run_plan_cmd(a: PlanArgs) -> Result<()> {
    let motor = load_motor(&a.motor)?;
    let orders = parse_orders(&a.orders)?;
    let p = plan(&motor, &plan_options(&orders, a.periods)?)?;
    out!("{}", p.describe());
    outln!(
        "total {:.1} s of logging; record t_s, theta_fb_rad, i_q_a (or i_a_a, i_b_a) every control period",
        p.total_s()
    );
    Ok(())
}

/// Reads the logs in parallel; the first error (in argument order) wins.
fn read_logs(paths: &[PathBuf], pole_pairs: u16) -> Result<Vec<RunLog>> {
    let opts = LogOptions::new(pole_pairs);
    let logs: Vec<Result<RunLog, _>> = paths.par_iter().map(|p| read_log(p, &opts)).collect();
    logs.into_iter().map(|r| r.map_err(|e| anyhow!("{e}"))).collect()
}

fn default_name(base: &Profile, suffix: &str) -> String {
    format!("{}-{suffix}", base.name)
}

fn run_fit_cmd(a: FitArgs, _global: &Global) -> Result<()> {
    let Some(motor) = &a.motor else { bail!("--motor is needed: the base profile (preset or TOML) with Km, Nr, J") };
    let Some(out) = &a.out else { bail!("--out is needed: where to write the identified profile (TOML)") };
    if a.logs.is_empty() {
        bail!("no --log given: pass the servo-mode run logs (CSV), e.g. --log a.csv --log b.csv");
    }
    let base = load_motor(motor)?;
    let orders = parse_orders(&a.orders)?;
    let effort = match a.effort.as_str() {
        "measured" => Effort::MeasuredIq,
        "command" => Effort::CommandIq,
        e => bail!("--effort '{e}': expected measured or command"),
    };
    if let Some(bw) = a.servo_bandwidth
        && !(bw.is_finite() && bw > 0.0)
    {
        bail!("--servo-bandwidth {bw}: must be a positive number of Hz");
    }
    check_output_dir(out)?;
    let t0 = Instant::now();
    let logs = read_logs(&a.logs, base.motor.pole_pairs)?;
    let t_read = t0.elapsed().as_secs_f64();
    for l in &logs {
        if !l.ignored_columns.is_empty() {
            outln!("note: {}: ignored unknown columns: {}", l.source, l.ignored_columns.join(", "));
        }
    }
    let mut fo = FitOptions::for_profile(&base, &orders);
    fo.effort = effort;
    fo.inertia = a.inertia;
    if let Some(bw) = a.servo_bandwidth {
        fo.servo_bandwidth_hz = Some(bw);
    }
    if a.ff_on {
        // Feed-forward-on logs: raw effort, J held at the base profile's (the one whose
        // feed-forward ran, normally identified from feed-forward-off logs).
        fo.correct_quantisation = false;
        fo.smooth_effort = false;
        fo.fit_inertia = false;
    }
    let f = fit(&logs, &fo)?;
    let t_fit = t0.elapsed().as_secs_f64() - t_read;
    let model = Model::from_fit(&f);
    let name = a.name.clone().unwrap_or_else(|| default_name(&base, "identified"));
    let out_s = out.display().to_string();
    let profile = model.apply_to(&base, Some(&name), &out_s).map_err(|e| anyhow!("{e}"))?;
    let rows: usize = logs.iter().map(RunLog::len).sum();
    out!("{}", fit_table(&f, &base.name));
    let validation = decisions_and_validation(&f)?;
    if a.ff_on {
        let before = Model::of_profile(&base);
        outln!(
            "feed-forward on: remaining ripple {:.3} mN·m RMS (the feed-forward of {} carried {:.3} mN·m RMS)",
            1e3 * remaining_ripple_nm(&before, &f),
            base.name,
            1e3 * before.ripple_rms_nm()
        );
    }
    outln!("{} logs, {rows} rows: read in {t_read:.3} s, fitted in {t_fit:.3} s", logs.len());
    if let Some(dir) = &a.report {
        let written = write_report(dir, &f, None, Some(&validation), &profile.name)?;
        for w in written {
            outln!("wrote {}", w.display());
        }
    }
    write_atomic(out, profile.to_toml_string().as_bytes())?;
    outln!("wrote {out_s}");
    Ok(())
}

/// Prints the fit's decisions (which `J`, and why) and then its validation (per run, then
/// the verdict), and returns the validation for the report.
fn decisions_and_validation(f: &Fit) -> Result<Validation> {
    for d in &f.decisions {
        outln!("{d}");
    }
    let validation = validate(f, default_max_order(f));
    outln!("validation (orders 1–{}):\n{validation}", validation.max_order);
    Ok(validation)
}

fn check_output_dir(out: &Path) -> Result<()> {
    let dir = out.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        bail!("--out {}: directory {} does not exist", out.display(), dir.display());
    }
    if out.is_dir() {
        bail!(
            "--out {}: is a directory; give the profile's file name, e.g. {}",
            out.display(),
            out.join("identified.toml").display()
        );
    }
    // Fail now, before any work or any report file, if the profile could not be written.
    let probe = dir.join(format!(".stepdamp-write-test-{}", std::process::id()));
    std::fs::write(&probe, b"")
        .map_err(|e| anyhow!("--out {}: directory {} is not writable: {e}", out.display(), dir.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// The printed table of a fit.
fn fit_table(f: &Fit, base: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "identified from {} samples (base {base}); 95 % intervals", f.samples_used);
    let _ = writeln!(s, "  order   amplitude mN·m       phase rad");
    for h in &f.harmonics {
        let _ = writeln!(
            s,
            "  {:>5}   {:8.3} ± {:<7.3}   {:+8.4} ± {:.4}",
            h.order,
            1e3 * h.amplitude_nm.value,
            1e3 * h.amplitude_nm.ci95,
            h.phase_rad.value,
            h.phase_rad.ci95
        );
    }
    let fs = f.coulomb_friction_nm;
    let _ = writeln!(s, "  Fs   {:8.3} ± {:.3} mN·m", 1e3 * fs.value, 1e3 * fs.ci95);
    match f.viscous_nm_s_per_rad {
        Some(d) => {
            let _ = writeln!(s, "  D    {:.4e} ± {:.1e} N·m·s/rad", d.value, d.ci95);
        }
        None => {
            let _ = writeln!(s, "  D    {:.4e} N·m·s/rad (not separable: kept)", f.viscous_used);
        }
    }
    match f.inertia_kg_m2 {
        Some(j) => {
            let _ =
                writeln!(s, "  J    {:.4e} ± {:.1e} kg·m² (written to the profile's inertia_kg_m2)", j.value, j.ci95);
        }
        None => {
            let _ = writeln!(s, "  J    {:.4e} kg·m² (held: the base profile's)", f.inertia_used);
        }
    }
    if let Some(c) = f.offset_nm {
        let _ = writeln!(
            s,
            "  constant torque {:.3} ± {:.3} mN·m (load or current offset; not in the profile)",
            1e3 * c.value,
            1e3 * c.ci95
        );
    }
    let _ = writeln!(
        s,
        "  residual {:.3} mN·m RMS (fitted detent ripple {:.3} mN·m RMS)",
        1e3 * f.residual_rms_nm,
        1e3 * f.ripple_rms_nm
    );
    for r in &f.runs {
        let _ = writeln!(
            s,
            "  run {}: {:+.4} rad/s, {:.1} electrical periods, {}/{} samples, J·dω/dt share {:.2}",
            r.source, r.mean_speed_rad_s, r.electrical_periods, r.samples_used, r.samples, r.inertial_share
        );
    }
    for w in &f.warnings {
        let _ = writeln!(s, "warning: {w}");
    }
    s
}

/// Most control periods `identify run` simulates over all runs (200 s at 20 kHz, a few
/// hundred MB of logs).
const MAX_SIMULATED_ROWS: f64 = 4e6;

fn run_run_cmd(a: RunArgs, global: &Global) -> Result<()> {
    let motor = load_motor(&a.motor)?;
    let orders = parse_orders(&a.orders)?;
    if !(a.current_noise.is_finite() && a.current_noise >= 0.0) {
        bail!("--current-noise {}: must be a finite number ≥ 0 A", a.current_noise);
    }
    if a.report && !a.refine {
        bail!("--report needs --refine (it plots the identification)");
    }
    if !(1..=20).contains(&a.iterations) {
        bail!("--iterations {}: must be in 1..=20", a.iterations);
    }
    let po = PlanOptions { current_noise_a: a.current_noise, seed: a.seed, ..plan_options(&orders, a.periods)? };
    let p = plan(&motor, &po)?;
    // The logs are held in memory (and written as CSV): bound their size.
    let rows = p.total_s() * p.profile.drive.pwm_hz;
    if rows > MAX_SIMULATED_ROWS {
        bail!(
            "--periods {}: the plan would log {:.0} s = {:.2e} rows at {} Hz; at most {MAX_SIMULATED_ROWS:.0e} rows are simulated (use fewer periods)",
            a.periods,
            p.total_s(),
            rows,
            p.profile.drive.pwm_hz
        );
    }
    if a.out.exists() && !a.out.is_dir() {
        bail!("--out {}: exists and is not a directory", a.out.display());
    }
    // Everything is checked: create the directory now. If the run fails or is interrupted,
    // a directory it created is removed, and from an existing one what it added.
    let out_dir = stepdamp_out::OutputDir::prepare(&a.out)?;
    let result = simulate_and_identify(&a, global, &motor, &orders, &po, &p);
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
    out!("{}", p.describe());
    let pb = progress(p.runs.len() as u64, global.quiet, "simulating");
    let t0 = Instant::now();
    let done = run_plan(motor, motor, &a.out, po, &|| pb.inc(1))?;
    pb.finish_and_clear();
    outln!("simulated {:.1} s of runs in {:.2} s", p.total_s(), t0.elapsed().as_secs_f64());
    write_atomic(&a.out.join("plan.txt"), p.describe().as_bytes())?;
    // The profile the runs were recorded with (its [servo] section is the plan's): the
    // base profile for `identify`, so the fit knows the servo bandwidth of the logs.
    let base_toml = a.out.join("base.toml");
    write_atomic(&base_toml, p.profile.to_toml_string().as_bytes())?;
    for f in &done.files {
        outln!("wrote {}", f.display());
    }
    outln!("wrote {} (the planned profile: {}'s, with the [servo] settings of the runs)", base_toml.display(), a.motor);
    if !a.refine {
        let logs: Vec<String> = done.files.iter().map(|f| format!("--log {}", f.display())).collect();
        outln!(
            "identify with: stepdamp identify {} --motor {} --out {}",
            logs.join(" "),
            base_toml.display(),
            a.out.join("identified.toml").display()
        );
        return Ok(());
    }
    let logs = read_logs(&done.files, motor.motor.pole_pairs)?;
    let fo = FitOptions::for_profile(&p.profile, orders);
    let f0 = fit(&logs, &fo)?;
    out!("{}", fit_table(&f0, &motor.name));
    let validation = decisions_and_validation(&f0)?;
    let start = Model::from_fit(&f0);
    let ro = RefineOptions {
        max_iterations: a.iterations as usize,
        current_noise_a: a.current_noise,
        seed: a.seed,
        ..RefineOptions::default()
    };
    let pb = progress((p.runs.len() * (a.iterations as usize + 1)) as u64, global.quiet, "refining");
    let r = refine(motor, p, &start, Some(&f0), &fo, &ro, &|| pb.inc(1))?;
    pb.finish_and_clear();
    out!("{}", refine_table(&r));
    let out = a.out.join("identified.toml");
    let profile = r
        .model
        .apply_to(motor, Some(&default_name(motor, "identified")), &out.display().to_string())
        .map_err(|e| anyhow!("{e}"))?;
    if a.report {
        for w in write_report(&a.out, &f0, Some((&r, p)), Some(&validation), &profile.name)? {
            outln!("wrote {}", w.display());
        }
    }
    let summary = a.out.join(SUMMARY_FILE);
    write_atomic(&summary, refine_summary_csv(motor, &f0, &r)?.as_bytes())?;
    outln!(
        "wrote {} (simulated motor, feed-forward-off fit and refined values; ripple before/after)",
        summary.display()
    );
    write_atomic(&out, profile.to_toml_string().as_bytes())?;
    outln!("wrote {}", out.display());
    Ok(())
}

/// File `identify run --refine` writes its summary to, in the output directory.
const SUMMARY_FILE: &str = "refine-summary.csv";

/// The summary of `identify run --refine` as CSV, for scripts: one row per quantity with
/// the simulated motor's value (the truth), the feed-forward-off fit's and the refined one.
/// Columns `quantity,order,unit,motor,identified,refined`; quantities `amplitude` and
/// `phase` (one row per order), `coulomb_friction`, `viscous_friction`, `inertia`, and
/// `periodic_ripple_rms` (the loop effort's ripple over orders 1–16: `identified` = before,
/// feed-forward off; `refined` = after, the refined estimate fed forward) and
/// `ripple_reduction` (before / after, in `refined`). Empty cells: not applicable.
fn refine_summary_csv(motor: &Profile, f0: &Fit, r: &Refinement) -> Result<String> {
    let e6 = |v: f64| format!("{v:.6e}");
    let cell = |v: Option<f64>, f: &dyn Fn(f64) -> String| v.map_or(String::new(), f);
    let mut rows: Vec<[String; 6]> = Vec::new();
    let mut row = |q: &str, order: Option<u16>, unit: &str, m: String, i: String, r: String| {
        rows.push([q.to_string(), order.map_or(String::new(), |k| k.to_string()), unit.to_string(), m, i, r]);
    };
    let start = Model::from_fit(f0);
    let find = |m: &Model, k: u16| m.detent.iter().find(|h| h.order == k).copied();
    let truth = Model::of_profile(motor);
    for h in &r.model.detent {
        let (t, i) = (find(&truth, h.order), find(&start, h.order));
        let amp = |h: Option<stepdamp_profile::DetentTerm>| h.map(|h| h.amplitude_nm);
        let phase = |v: f64| format!("{v:.6}");
        row("amplitude", Some(h.order), "N·m", cell(amp(t).or(Some(0.0)), &e6), cell(amp(i), &e6), e6(h.amplitude_nm));
        row(
            "phase",
            Some(h.order),
            "rad",
            cell(t.map(|t| t.phase_rad), &phase),
            cell(i.map(|i| i.phase_rad), &phase),
            phase(h.phase_rad),
        );
    }
    let m = &motor.motor;
    let refined_j = r.model.inertia_kg_m2.unwrap_or(f0.inertia_used);
    row(
        "coulomb_friction",
        None,
        "N·m",
        e6(m.coulomb_friction_nm),
        e6(start.coulomb_friction_nm),
        e6(r.model.coulomb_friction_nm),
    );
    row(
        "viscous_friction",
        None,
        "N·m·s/rad",
        e6(m.viscous_nm_s_per_rad),
        e6(start.viscous_nm_s_per_rad),
        e6(r.model.viscous_nm_s_per_rad),
    );
    row("inertia", None, "kg·m²", e6(m.inertia_kg_m2), e6(f0.inertia_used), e6(refined_j));
    let (before, after) = r.ripple_before_after_nm();
    row("periodic_ripple_rms", None, "N·m", String::new(), e6(before), e6(after));
    row("ripple_reduction", None, "ratio", String::new(), String::new(), format!("{:.1}", before / after.max(1e-15)));
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(["quantity", "order", "unit", "motor", "identified", "refined"])?;
    for r in &rows {
        w.write_record(r)?;
    }
    Ok(String::from_utf8(w.into_inner().map_err(|e| anyhow!("{e}"))?)?)
}

fn refine_table(r: &Refinement) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "refinement with the feed-forward on (servo mode):");
    for st in &r.steps {
        let terms: Vec<String> = st
            .model
            .detent
            .iter()
            .map(|h| format!("k{} {:.3} mN·m {:+.4} rad", h.order, 1e3 * h.amplitude_nm, h.phase_rad))
            .collect();
        let _ = writeln!(
            s,
            "  step {}: ripple {:8.4} mN·m RMS on the fitted orders, {:8.4} on orders 1–{PERIODIC_ORDERS} ({}); {}; Fs {:.3} mN·m",
            st.iteration,
            1e3 * st.ripple_rms_nm,
            1e3 * st.periodic_rms_nm,
            if st.iteration == 0 {
                "feed-forward off".to_string()
            } else {
                format!("step {}'s estimate on", st.iteration - 1)
            },
            terms.join(", "),
            1e3 * st.model.coulomb_friction_nm
        );
    }
    let _ = writeln!(
        s,
        "  check, the refined estimate on: ripple {:8.4} mN·m RMS on the fitted orders, {:8.4} on orders 1–{PERIODIC_ORDERS}",
        1e3 * r.check.ripple_rms_nm,
        1e3 * r.check.periodic_rms_nm
    );
    let (b, a) = r.ripple_before_after_nm();
    let _ = writeln!(
        s,
        "  periodic ripple of the loop effort (orders 1–{PERIODIC_ORDERS}): {:.4} → {:.4} mN·m RMS ({:.0}× less)",
        1e3 * b,
        1e3 * a,
        b / a.max(1e-15)
    );
    for w in &r.check.fit.warnings {
        let _ = writeln!(s, "  warning (feed-forward-on fit): {w}");
    }
    s
}

fn run_static_cmd(a: StaticArgs) -> Result<()> {
    let base = load_motor(&a.motor)?;
    let orders = parse_orders(&a.orders)?;
    let sign = match a.sign.as_str() {
        "on-rotor" => TorqueSign::OnRotor,
        "holding" => TorqueSign::Holding,
        s => bail!(
            "--sign '{s}': expected on-rotor (the detent torque on the rotor) or holding (the torque that holds it)"
        ),
    };
    check_output_dir(&a.out)?;
    let pts = read_table(&a.table).map_err(|e| anyhow!("{e}"))?;
    let kmax = *orders.iter().max().expect("parse_orders returns at least one");
    let src = a.table.display().to_string();
    let c = analyse(&pts, base.motor.pole_pairs, sign, kmax, &src).map_err(|e| anyhow!("{e}"))?;
    let picked = c.select(&orders);
    if picked.len() < orders.len() {
        let missing: Vec<String> =
            orders.iter().filter(|&&k| picked.iter().all(|h| h.order != k)).map(u16::to_string).collect();
        bail!(
            "{src}: {} points over {} electrical periods cannot resolve order {} (order k needs more than 2·k points \
             per electrical period)",
            pts.len(),
            c.electrical_periods,
            missing.join(", ")
        );
    }
    outln!("{src}: {} points, {} electrical periods", pts.len(), c.electrical_periods);
    outln!("  order   amplitude mN·m   phase rad");
    for h in &picked {
        outln!("  {:>5}   {:10.4}       {:+8.4}", h.order, 1e3 * h.amplitude_nm, h.phase_rad);
    }
    outln!("  mean torque {:.4} mN·m, rest (other orders) {:.4} mN·m RMS", 1e3 * c.mean_nm, 1e3 * c.rest_rms_nm);
    let mut model = Model::of_profile(&base);
    model.detent = picked
        .iter()
        .map(|h| stepdamp_sim::profile::DetentTerm {
            order: h.order,
            amplitude_nm: h.amplitude_nm,
            phase_rad: h.phase_rad,
        })
        .collect();
    let name = a.name.clone().unwrap_or_else(|| default_name(&base, "static"));
    let out_s = a.out.display().to_string();
    let profile = model.apply_to(&base, Some(&name), &out_s).map_err(|e| anyhow!("{e}"))?;
    write_atomic(&a.out, profile.to_toml_string().as_bytes())?;
    outln!("wrote {out_s} (friction kept from the base profile: a static table does not measure it)");
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Report plots.

const MAX_PLOT_ORDER: usize = 16;

/// Writes `spectrum.{svg,png}` and `residual.{svg,png}` into `dir` (atomically) and
/// returns the paths. With a refinement, "after" is the feed-forward-on effort beyond the
/// feed-forward; otherwise the fit's residual.
fn write_report(
    dir: &Path,
    f: &Fit,
    refined: Option<(&Refinement, &Plan)>,
    validation: Option<&Validation>,
    title: &str,
) -> Result<Vec<PathBuf>> {
    let mut files = AtomicFiles::in_dir(dir)?;
    let s = &f.samples;
    let before = order_spectrum(&s.theta_e_rad, &s.ripple_nm, MAX_PLOT_ORDER, 256);
    let (after, after_label) = match refined {
        Some((r, _)) => {
            let lf = &r.check.fit;
            // Effort beyond the refined feed-forward (the check run).
            let ff = &r.model;
            let beyond: Vec<f64> = lf
                .samples
                .theta_e_rad
                .iter()
                .zip(&lf.samples.ripple_nm)
                .map(|(&th, &y)| y - series_nm(ff, th))
                .collect();
            (order_spectrum(&lf.samples.theta_e_rad, &beyond, MAX_PLOT_ORDER, 256), "feed-forward on: effort beyond it")
        }
        None => (order_spectrum(&s.theta_e_rad, &s.residual_nm, MAX_PLOT_ORDER, 256), "residual of the fit"),
    };
    let spec_svg = dir.join("spectrum.svg");
    let spec_png = dir.join("spectrum.png");
    let (t1, t2) = (files.stage(&spec_svg)?, files.stage(&spec_png)?);
    let stitle = format!("{title}: effort ripple by harmonic order");
    let spectrum = Spectrum { before: &before, after: &after, after_label, title: &stitle };
    crate::plot::render(&spectrum, (1000, 600), &t1, &t2)?;
    let res_svg = dir.join("residual.svg");
    let res_png = dir.join("residual.png");
    let (t3, t4) = (files.stage(&res_svg)?, files.stage(&res_png)?);
    let model = Model::from_fit(f);
    let rtitle = format!("{title}: needed torque and residual against electrical angle");
    crate::plot::render(&Residual { fit: f, model: &model, title: &rtitle }, (1000, 700), &t3, &t4)?;
    if let Some(validation) = validation {
        let (svg, png) = (dir.join("validation.svg"), dir.join("validation.png"));
        let (t5, t6) = (files.stage(&svg)?, files.stage(&png)?);
        let vtitle = format!("{title}: effort ripple the model leaves unexplained, per run");
        crate::plot::render(&crate::plot::ValidationFigure { validation, title: &vtitle }, (1000, 600), &t5, &t6)?;
    }
    files.commit()
}

struct Spectrum<'a> {
    before: &'a [f64],
    after: &'a [f64],
    after_label: &'a str,
    title: &'a str,
}

impl crate::plot::Figure for Spectrum<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        draw_spectrum(root, self.before, self.after, self.after_label, self.title)
    }
}

struct Residual<'a> {
    fit: &'a Fit,
    model: &'a Model,
    title: &'a str,
}

impl crate::plot::Figure for Residual<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        draw_residual(root, self.fit, self.model, self.title)
    }
}

fn draw_spectrum<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    before: &[f64],
    after: &[f64],
    after_label: &str,
    title: &str,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {e}");
    root.fill(&WHITE).map_err(err)?;
    let to_mnm = |v: &[f64]| v.iter().skip(1).map(|x| 1e3 * x).collect::<Vec<f64>>();
    let (b, a) = (to_mnm(before), to_mnm(after));
    let finite = || b.iter().chain(&a).copied().filter(|v| v.is_finite() && *v > 0.0);
    let top = finite().fold(1e-6, f64::max) * 2.0;
    // Log scale: the ripple left after refinement is orders of magnitude below the detent.
    let floor = finite().fold(top, f64::min).max(top * 1e-5) / 2.0;
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 20))
        .margin(14)
        .x_label_area_size(40)
        .y_label_area_size(80)
        .build_cartesian_2d(0.5f64..(MAX_PLOT_ORDER as f64 + 0.5), (floor..top).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("harmonic order k of the electrical angle")
        .y_desc("amplitude (mN·m)")
        .x_labels(MAX_PLOT_ORDER)
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_label_formatter(&|y| format!("{y:.1e}"))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    let red = RGBColor(200, 40, 40);
    let blue = RGBColor(30, 90, 200);
    let bar = |k: f64, v: f64, left: bool| {
        let (x0, x1) = if left { (k - 0.38, k - 0.02) } else { (k + 0.02, k + 0.38) };
        (x0, x1, v.max(floor))
    };
    chart
        .draw_series(b.iter().enumerate().map(|(i, &v)| {
            let (x0, x1, y) = bar((i + 1) as f64, v, true);
            Rectangle::new([(x0, floor), (x1, y)], red.filled())
        }))
        .map_err(err)?
        .label("feed-forward off: needed torque minus friction")
        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], red.filled()));
    chart
        .draw_series(a.iter().enumerate().map(|(i, &v)| {
            let (x0, x1, y) = bar((i + 1) as f64, v, false);
            Rectangle::new([(x0, floor), (x1, y)], blue.filled())
        }))
        .map_err(err)?
        .label(after_label.to_string())
        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], blue.filled()));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    Ok(())
}

fn draw_residual<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, f: &Fit, model: &Model, title: &str) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {e}");
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 20)).map_err(err)?;
    let panels = root.split_evenly((2, 1));
    let s = &f.samples;
    let n = s.theta_e_rad.len();
    let step = (n / 4000).max(1);
    let idx: Vec<usize> = (0..n).step_by(step).collect();
    let tau = std::f64::consts::TAU;
    for (pi, panel) in panels.iter().enumerate() {
        let (vals, caption): (Vec<(f64, f64)>, &str) = if pi == 0 {
            (
                idx.iter().map(|&i| (s.theta_e_rad[i], 1e3 * s.ripple_nm[i])).collect(),
                "needed torque minus friction (points) and the identified detent series (line)",
            )
        } else {
            (idx.iter().map(|&i| (s.theta_e_rad[i], 1e3 * s.residual_nm[i])).collect(), "residual of the fit")
        };
        let lim = vals.iter().map(|p| p.1.abs()).filter(|v| v.is_finite()).fold(1e-6, f64::max) * 1.05;
        let mut chart = ChartBuilder::on(panel)
            .caption(caption, ("sans-serif", 15))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..tau, -lim..lim)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("electrical angle Nr·θ_fb (rad)")
            .y_desc("mN·m")
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(err)?;
        let c = if pi == 0 { RGBColor(200, 40, 40) } else { RGBColor(30, 90, 200) };
        chart.draw_series(vals.iter().map(|&p| Circle::new(p, 1, c.mix(0.35).filled()))).map_err(err)?;
        if pi == 0 {
            let line: Vec<(f64, f64)> =
                (0..=400).map(|i| tau * i as f64 / 400.0).map(|t| (t, 1e3 * series_nm(model, t))).collect();
            chart.draw_series(LineSeries::new(line, BLACK.stroke_width(2))).map_err(err)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(v: &[&str]) -> IdentifyArgs {
        use clap::Parser;
        #[derive(Parser)]
        struct W {
            #[command(flatten)]
            a: IdentifyArgs,
        }
        let mut all = vec!["identify"];
        all.extend_from_slice(v);
        W::try_parse_from(all).unwrap().a
    }

    const Q: Global = Global { quiet: true };

    #[test]
    fn orders_parse_and_reject_nonsense() {
        assert_eq!(parse_orders("1, 2,4").unwrap(), vec![1, 2, 4]);
        assert!(parse_orders("0").unwrap_err().to_string().contains("1..=32"));
        assert!(parse_orders("4,4").unwrap_err().to_string().contains("twice"));
        assert!(parse_orders("x").unwrap_err().to_string().contains("'x'"));
        assert!(parse_orders("1,,2").unwrap_err().to_string().contains("empty entry"));
    }

    #[test]
    fn run_then_identify_writes_a_valid_profile_and_report() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().to_str().unwrap();
        run(args(&["run", "--motor", "patent-motor", "--out", d, "--periods", "6"]), &Q).unwrap();
        let mut logs: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().path().display().to_string())
            .filter(|p| p.ends_with(".csv"))
            .collect();
        logs.sort();
        assert_eq!(logs.len(), 4);
        // The planned profile, with the servo settings the runs were recorded with.
        let base = dir.path().join("base.toml");
        let planned = Profile::from_file(&base).unwrap();
        let want = plan(&Profile::preset("patent-motor").unwrap(), &plan_options(&[1, 2, 4], 6.0).unwrap()).unwrap();
        assert_eq!(planned.servo, want.profile.servo);
        assert!(planned.servo.bandwidth_hz > 60.0, "{:?}", planned.servo);
        // Identified with it (no --servo-bandwidth): the fit knows the logs' servo, so no
        // "too fast for the servo" warning.
        let fo = FitOptions::for_profile(&planned, &[1, 2, 4]);
        let parsed = read_logs(&logs.iter().map(PathBuf::from).collect::<Vec<_>>(), 50).unwrap();
        let f = fit(&parsed, &fo).unwrap();
        assert!(
            !f.warnings.iter().any(|w| matches!(w, stepdamp_identify::fit::Warning::TooFast { .. })),
            "{:?}",
            f.warnings
        );
        let out = dir.path().join("id.toml");
        let rep = dir.path().join("report");
        let b = base.to_str().unwrap();
        let mut v = vec!["--motor", b, "--out", out.to_str().unwrap(), "--report", rep.to_str().unwrap()];
        for l in &logs {
            v.push("--log");
            v.push(l);
        }
        run(args(&v), &Q).unwrap();
        let p = Profile::from_file(&out).unwrap();
        assert_eq!(p.motor.detent.len(), 3);
        let a4 = p.motor.detent.iter().find(|h| h.order == 4).unwrap().amplitude_nm;
        assert!((a4 - 0.02).abs() < 0.001, "{a4}");
        // J identified and written (the preset's is 4e-5).
        assert!((p.motor.inertia_kg_m2 / 4e-5 - 1.0).abs() < 0.1, "{}", p.motor.inertia_kg_m2);
        for f in ["spectrum.svg", "spectrum.png", "residual.svg", "residual.png"] {
            assert!(std::fs::metadata(rep.join(f)).unwrap().len() > 1000, "{f}");
        }
    }

    #[test]
    fn identify_run_refused_by_its_checks_creates_no_directory() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("new").join("runs");
        let o = out.to_str().unwrap();
        // Too many rows for the row limit.
        let e = run(args(&["run", "--motor", "patent-motor", "--out", o, "--periods", "90000"]), &Q)
            .unwrap_err()
            .to_string();
        assert!(e.contains("rows"), "{e}");
        // A plan the planner refuses (a stiffness margin is fine; zero noise is fine; bad
        // periods are caught by the option check, a bad motor by the loader).
        let e =
            run(args(&["run", "--motor", "patent-motor", "--out", o, "--periods", "1"]), &Q).unwrap_err().to_string();
        assert!(e.contains("--periods"), "{e}");
        let e = run(args(&["run", "--motor", "no-such-motor", "--out", o]), &Q).unwrap_err().to_string();
        assert!(e.contains("no-such-motor"), "{e}");
        assert!(!dir.path().join("new").exists(), "nothing is created on an error");
        // A file in the way.
        let file = dir.path().join("file");
        std::fs::write(&file, b"x").unwrap();
        let e = run(args(&["run", "--motor", "patent-motor", "--out", file.to_str().unwrap()]), &Q)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a directory"), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn identify_run_with_refine_writes_a_summary_a_script_can_read() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().to_str().unwrap();
        let a = ["run", "--motor", "patent-motor", "--out", d, "--periods", "6", "--refine", "--iterations", "1"];
        run(args(&a), &Q).unwrap();
        let text = std::fs::read_to_string(dir.path().join(SUMMARY_FILE)).unwrap();
        let rows: Vec<Vec<&str>> = text.lines().map(|l| l.split(',').collect()).collect();
        assert_eq!(rows[0], ["quantity", "order", "unit", "motor", "identified", "refined"]);
        assert!(rows.iter().all(|r| r.len() == 6), "{text}");
        let get = |q: &str, k: &str| rows.iter().find(|r| r[0] == q && r[1] == k).unwrap_or_else(|| panic!("{q} {k}"));
        let a4 = get("amplitude", "4");
        assert_eq!(a4[3].parse::<f64>().unwrap(), 0.02);
        assert!((a4[5].parse::<f64>().unwrap() - 0.02).abs() < 0.001, "{text}");
        for q in ["phase", "amplitude"] {
            for k in ["1", "2"] {
                get(q, k);
            }
        }
        let fs: f64 = get("coulomb_friction", "")[5].parse().unwrap();
        assert!((fs / 0.01 - 1.0).abs() < 0.1, "{text}");
        let ripple = get("periodic_ripple_rms", "");
        let (before, after): (f64, f64) = (ripple[4].parse().unwrap(), ripple[5].parse().unwrap());
        assert!(before > 10.0 * after, "{text}");
        let ratio: f64 = get("ripple_reduction", "")[5].parse().unwrap();
        assert!((ratio - before / after).abs() < 0.1 * ratio, "{text}");
        assert!(dir.path().join("identified.toml").exists());
    }

    #[test]
    fn a_bad_log_fails_with_file_and_line_and_writes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("bad.csv");
        std::fs::write(&log, "t_s,theta_fb_rad,i_q_a\n0.0,0.0,0.1\n0.00005,nan,0.1\n").unwrap();
        let out = dir.path().join("id.toml");
        let e =
            run(args(&["--log", log.to_str().unwrap(), "--motor", "patent-motor", "--out", out.to_str().unwrap()]), &Q)
                .unwrap_err()
                .to_string();
        assert!(e.contains("bad.csv") && e.contains("line 3") && e.contains("theta_fb_rad"), "{e}");
        assert!(!out.exists());
    }

    #[test]
    fn a_directory_given_as_out_is_refused_before_any_report_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("any.csv");
        std::fs::write(&log, "t_s,theta_fb_rad,i_q_a\n0.0,0.0,0.1\n").unwrap();
        let report = dir.path().join("rep");
        let (l, o, r) = (log.to_str().unwrap(), dir.path().to_str().unwrap(), report.to_str().unwrap());
        let e =
            run(args(&["--log", l, "--motor", "patent-motor", "--out", o, "--report", r]), &Q).unwrap_err().to_string();
        assert!(e.contains("is a directory") && e.contains("identified.toml"), "{e}");
        assert!(!report.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "only the log is there");
    }

    #[test]
    fn missing_arguments_are_one_line_errors() {
        let e = run(args(&["--motor", "patent-motor", "--out", "x.toml"]), &Q).unwrap_err().to_string();
        assert!(e.contains("--log") && !e.contains('\n'), "{e}");
        let e = run(args(&["--log", "a.csv", "--out", "x.toml"]), &Q).unwrap_err().to_string();
        assert!(e.contains("--motor"), "{e}");
    }

    #[test]
    fn static_table_becomes_a_profile() {
        let dir = tempfile::tempdir().unwrap();
        let table = dir.path().join("curve.csv");
        let mut s = String::from("theta_rad,torque_nm\n");
        for i in 0..400 {
            let th = i as f64 / 400.0 * 2.0 * std::f64::consts::TAU / 50.0;
            // Torque on the rotor: −A sin(4·50·θ + 0.2).
            let _ = writeln!(s, "{th},{}", -0.02 * (200.0 * th + 0.2).sin());
        }
        std::fs::write(&table, s).unwrap();
        let out = dir.path().join("s.toml");
        let t = table.to_str().unwrap();
        let o = out.to_str().unwrap();
        run(
            args(&[
                "static",
                "--table",
                t,
                "--sign",
                "on-rotor",
                "--motor",
                "patent-motor",
                "--out",
                o,
                "--orders",
                "4",
            ]),
            &Q,
        )
        .unwrap();
        let p = Profile::from_file(&out).unwrap();
        assert_eq!(p.motor.detent.len(), 1);
        assert!(
            (p.motor.detent[0].amplitude_nm - 0.02).abs() < 1e-9 && (p.motor.detent[0].phase_rad - 0.2).abs() < 1e-9
        );
    }

    #[test]
    fn a_static_table_too_sparse_for_an_order_names_it_and_writes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let table = dir.path().join("sparse.csv");
        // 4 points per electrical period over 2 periods: order 1 resolves, 2 and 4 do not.
        let mut s = String::from("theta_rad,torque_nm\n");
        for i in 0..8 {
            let th = i as f64 / 8.0 * 2.0 * std::f64::consts::TAU / 50.0;
            let _ = writeln!(s, "{th},{}", 0.02 * (200.0 * th).sin());
        }
        std::fs::write(&table, s).unwrap();
        let out = dir.path().join("s.toml");
        let (t, o) = (table.to_str().unwrap(), out.to_str().unwrap());
        let a = ["static", "--table", t, "--sign", "holding", "--motor", "patent-motor", "--out", o];
        let e = run(args(&a), &Q).unwrap_err().to_string();
        assert!(e.contains("sparse.csv") && e.contains("cannot resolve order 2, 4"), "{e}");
        assert!(!out.exists());
    }
}
