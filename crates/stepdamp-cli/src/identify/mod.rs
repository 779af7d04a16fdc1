//! `stepdamp identify`: detent harmonics and friction from servo-mode run logs
//! (docs/design.md#identification), the experiment plan, simulated runs, refinement, the static route.
//!
//! ```text
//! stepdamp identify --log a.csv --log b.csv --motor base.toml --out identified.toml [--orders 1,2,4] [--report DIR]
//! stepdamp identify plan   --motor FILE [--sensorless] [--format text|json|csv]
//! stepdamp identify run    --motor FILE --out DIR [--refine] [--report] [--sensorless]
//! stepdamp identify static --table curve.csv --motor base.toml --out identified.toml [--sign on-rotor|holding]
//! ```

use crate::Global;
use crate::common::{AtomicFiles, Format, choice_parser, load_motor, print_json, progress, write_atomic};
use anyhow::{Result, anyhow, bail};
use plotters::coord::Shift;
use plotters::prelude::*;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;
use stepdamp_identify::conditions::InertiaMode;
use stepdamp_identify::fit::{Effort, FeedForwardCheck, Fit, FitOptions, FitReport, fit};
use stepdamp_identify::log::{LogOptions, RunLog, read_log};
use stepdamp_identify::model::Model;
use stepdamp_identify::plan::{Plan, PlanOptions, plan, run_plan};
use stepdamp_identify::refine::{RefineOptions, Refinement, RefinementReport, RunReport, refine, series_nm};
use stepdamp_identify::spectrum::order_spectrum;
use stepdamp_identify::static_curve::{StaticReport, TorqueSign, analyse, read_table};
use stepdamp_identify::validation::Validation;
use stepdamp_sim::Profile;

mod fit_cmd;
mod report;
mod run_cmd;
mod sensorless_cmd;

use fit_cmd::*;
use report::*;
use run_cmd::*;
use sensorless_cmd::*;
use stepdamp_identify::plan::PlannedRun;

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
    /// A run log (CSV, docs/files.md). A servo-mode log needs t_s, theta_fb_rad and i_q_a
    /// (or i_a_a and i_b_a). A log without theta_fb_rad takes the sensorless route (said so
    /// in the output; docs/sensorless.md): it needs t_s, theta_cmd_rad, i_a_a, i_b_a,
    /// v_a_v, v_b_v of the runs of `identify plan --sensorless`. Repeat for several runs.
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
    #[arg(long, default_value = "1,2,4", value_parser = parse_orders)]
    orders: Orders,
    /// Directory for the report: effort-ripple spectrum and residual plots (SVG + PNG).
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
    /// The effort signal: measured (i_q_a) or command (iq_cmd_a).
    #[arg(long, default_value = "measured", value_parser = choice_parser(Effort::ALL, Effort::name))]
    effort: Effort,
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
    #[arg(long, default_value = "auto", value_parser = choice_parser(InertiaMode::ALL, InertiaMode::name))]
    inertia: InertiaMode,
    /// text, or json: the fit's report (stepdamp_identify::fit::FitReport) as one line of
    /// JSON on stdout, nothing else (the files are written the same).
    #[arg(long, value_enum, default_value_t)]
    format: Format,
    /// Name of the identified profile (default: base name + "-identified").
    #[arg(long)]
    name: Option<String>,
    /// Take the sensorless route even when the logs have theta_fb_rad (to compare the two
    /// routes on the same runs; the encoder angle is then not read).
    #[arg(long)]
    sensorless: bool,
}

/// `stepdamp identify plan`.
#[derive(clap::Args, Debug)]
struct PlanArgs {
    /// Motor profile (preset or TOML) to plan for.
    #[arg(long, value_name = "PRESET|FILE")]
    motor: String,
    /// Harmonic orders to identify.
    #[arg(long, default_value = "1,2,4", value_parser = parse_orders)]
    orders: Orders,
    /// Electrical periods of steady running per run.
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true)]
    periods: f64,
    /// Plan open-loop runs for the sensorless route (no encoder: the drive's own voltages
    /// and currents), with a standstill that trims R.
    #[arg(long)]
    sensorless: bool,
    /// text; json: the plan (stepdamp_identify::plan::Plan, or
    /// stepdamp_identify::sensorless::plan::SensorlessPlan) as one line of JSON; csv: one
    /// row per run, columns run,speed_rad_s,duration_s,standstill_s,ramp_s.
    #[arg(long, value_enum, default_value_t)]
    format: PlanFormat,
}

/// Output of `identify plan`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
enum PlanFormat {
    /// For people: the runs with their reasons.
    #[default]
    Text,
    /// One JSON object.
    Json,
    /// One row per run (run,speed_rad_s,duration_s,standstill_s,ramp_s), for a script or
    /// another drive to perform exactly the plan.
    Csv,
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
    #[arg(long, default_value = "1,2,4", value_parser = parse_orders)]
    orders: Orders,
    /// Electrical periods of steady running per run.
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true)]
    periods: f64,
    /// Current-sensor noise, standard deviation in A.
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    current_noise: f64,
    /// Seed of the noise generators.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    seed: u64,
    /// Simulate the sensorless plan (open loop, no encoder; logs with the applied
    /// voltages), identify from it and write DIR/identified.toml with R trimmed.
    #[arg(long)]
    sensorless: bool,
    /// Most refinement iterations.
    #[arg(long, default_value_t = 3, allow_negative_numbers = true)]
    iterations: i64,
    /// text, or json: the run's result (stepdamp_identify::refine::RunReport: the plan, and
    /// with --refine the fit's report and the refinement) as one line of JSON on stdout,
    /// nothing else (the files are written the same).
    #[arg(long, value_enum, default_value_t)]
    format: Format,
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
    #[arg(long, value_parser = choice_parser(TorqueSign::ALL, TorqueSign::name))]
    sign: TorqueSign,
    /// Base motor profile (preset or TOML).
    #[arg(long, value_name = "PRESET|FILE")]
    motor: String,
    /// Where to write the profile with the detent replaced (friction kept).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Harmonic orders to keep.
    #[arg(long, default_value = "1,2,4", value_parser = parse_orders)]
    orders: Orders,
    /// Name of the new profile (default: base name + "-static").
    #[arg(long)]
    name: Option<String>,
    /// text, or json: the analysis (stepdamp_identify::static_curve::StaticReport) as one
    /// line of JSON on stdout, nothing else (the profile is written the same).
    #[arg(long, value_enum, default_value_t)]
    format: Format,
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

/// `--orders`: harmonic orders, distinct, each in 1..=[`stepdamp_core::MAX_HARMONIC_ORDER`]
/// (a typed clap value: clap names the option and the value as written).
#[derive(Clone, Debug, PartialEq)]
struct Orders(Vec<u16>);

/// Parses a comma list of harmonic orders (1..=32, distinct).
fn parse_orders(s: &str) -> Result<Orders, String> {
    let mut out: Vec<u16> = Vec::new();
    for part in s.split(',').map(str::trim) {
        if part.is_empty() {
            return Err("an empty entry; give a comma list such as 1,2,4".into());
        }
        let k: u16 = part.parse().map_err(|_| format!("'{part}' is not a whole number"))?;
        if k == 0 || usize::from(k) > stepdamp_core::MAX_HARMONIC_ORDER {
            return Err(format!("{k}: each order must be in 1..={}", stepdamp_core::MAX_HARMONIC_ORDER));
        }
        if out.contains(&k) {
            return Err(format!("{k} is listed twice"));
        }
        out.push(k);
    }
    Ok(Orders(out))
}

fn plan_options(orders: &[u16], periods: f64) -> Result<PlanOptions> {
    if !(periods.is_finite() && (2.0..=100_000.0).contains(&periods)) {
        bail!("--periods {periods}: must be between 2 and 100000 electrical periods");
    }
    Ok(PlanOptions { orders: orders.to_vec(), electrical_periods: periods, ..PlanOptions::default() })
}

fn run_plan_cmd(a: PlanArgs) -> Result<()> {
    let motor = load_motor(&a.motor)?;
    let orders = a.orders.0.clone();
    if a.sensorless {
        return run_sensorless_plan_cmd(&a, &motor, &orders);
    }
    let p = plan(&motor, &plan_options(&orders, a.periods)?)?;
    print_plan(&p, &p, &p.runs, a.format)
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::fmt::Write as _;

    fn try_args(v: &[&str]) -> Result<IdentifyArgs, clap::Error> {
        use clap::Parser;
        #[derive(Parser)]
        struct W {
            #[command(flatten)]
            a: IdentifyArgs,
        }
        let mut all = vec!["identify"];
        all.extend_from_slice(v);
        W::try_parse_from(all).map(|w| w.a)
    }

    fn args(v: &[&str]) -> IdentifyArgs {
        try_args(v).unwrap()
    }

    const Q: Global = Global { quiet: true };

    #[test]
    fn orders_parse_and_reject_nonsense() {
        assert_eq!(parse_orders("1, 2,4").unwrap(), Orders(vec![1, 2, 4]));
        assert!(parse_orders("0").unwrap_err().to_string().contains("1..=32"));
        assert!(parse_orders("4,4").unwrap_err().to_string().contains("twice"));
        assert!(parse_orders("x").unwrap_err().to_string().contains("'x'"));
        assert!(parse_orders("1,,2").unwrap_err().to_string().contains("empty entry"));
    }

    #[test]
    fn choices_take_the_library_names_and_a_wrong_one_names_the_value_and_the_names_allowed() {
        for &e in Effort::ALL {
            assert_eq!(args(&["--effort", e.name()]).fit.effort, e);
        }
        for &m in InertiaMode::ALL {
            assert_eq!(args(&["--inertia", m.name()]).fit.inertia, m);
        }
        for &s in TorqueSign::ALL {
            let a = args(&["static", "--table", "t.csv", "--sign", s.name(), "--motor", "m", "--out", "o.toml"]);
            assert!(matches!(a.command, Some(IdentifyCommand::Static(StaticArgs { sign, .. })) if sign == s));
        }
        assert_eq!(args(&["--orders", "4,1"]).fit.orders, Orders(vec![4, 1]));
        for (v, want) in [
            (&["--effort", "iq"][..], "[possible values: measured, command]"),
            (&["--inertia", "Auto"], "[possible values: fit, base, auto]"),
            (&["static", "--table", "t", "--sign", "up", "--motor", "m", "--out", "o"], "on-rotor, holding"),
            (&["--orders", "1,x"], "'x' is not a whole number"),
        ] {
            let e = try_args(v).map(|_| ()).unwrap_err().to_string();
            let written = v[v.len() - 1 - usize::from(v[0] == "static") * 4];
            assert!(e.contains(&format!("invalid value '{written}'")) && e.contains(want), "{v:?}: {e}");
        }
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
