//! The sensorless route of `stepdamp identify` (docs/sensorless.md): the plan of open-loop
//! runs, the fit of logs without `theta_fb_rad`, and `identify run --sensorless`.

use super::*;
use stepdamp_identify::plan::runs_csv;
use stepdamp_identify::sensorless::flux::FluxOptions;
use stepdamp_identify::sensorless::log::{LogKind, SensorlessLog, log_kind, read_sensorless_log};
use stepdamp_identify::sensorless::plan::{SensorlessPlan, SensorlessPlanOptions, plan as sensorless_plan};
use stepdamp_identify::sensorless::report::SensorlessReport;
use stepdamp_identify::sensorless::{SensorlessFit, fit_options, identify as identify_sensorless};
use stepdamp_identify::simulate::run_sensorless_plan;

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
pub(super) fn print_plan(
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

/// `identify plan --sensorless`.
pub(super) fn run_sensorless_plan_cmd(a: &PlanArgs, motor: &Profile, orders: &[u16]) -> Result<()> {
    let p = sensorless_plan(motor, &sensorless_options(orders, a.periods)?)?;
    print_plan(&p, &p, &p.runs, a.format)
}

/// The route the logs call for: all of one kind, else an error naming the odd one.
pub(super) fn route_of(paths: &[PathBuf]) -> Result<LogKind> {
    let kinds = paths.iter().map(|p| log_kind(p).map_err(|e| anyhow!("{e}"))).collect::<Result<Vec<_>>>()?;
    let first = kinds[0];
    if let Some(i) = kinds.iter().position(|&k| k != first) {
        let name = |k: LogKind| match k {
            LogKind::Encoder => "has theta_fb_rad (an encoder log)",
            LogKind::Sensorless => "has no theta_fb_rad (a sensorless log)",
        };
        bail!(
            "--log {} {}, but --log {} {}: give logs of one route",
            paths[i].display(),
            name(kinds[i]),
            paths[0].display(),
            name(first)
        );
    }
    Ok(first)
}

/// Reads sensorless logs in parallel; the first error (in argument order) wins.
fn read_sensorless_logs(paths: &[PathBuf]) -> Result<Vec<SensorlessLog>> {
    let logs: Vec<Result<SensorlessLog, _>> = paths.par_iter().map(|p| read_sensorless_log(p)).collect();
    logs.into_iter().map(|r| r.map_err(|e| anyhow!("{e}"))).collect()
}

/// The fit's options for sensorless logs, with the command line's choices.
fn options(base: &Profile, orders: &[u16], inertia: InertiaMode) -> FitOptions {
    FitOptions { inertia, ..fit_options(base, orders) }
}

/// `identify --log …` on sensorless logs: the same outputs as the servo route, and `R`
/// trimmed into the profile.
pub(super) fn run_sensorless_fit_cmd(a: &FitArgs, base: &Profile, orders: &[u16], out: &Path) -> Result<()> {
    for (given, flag) in [
        (a.ff_on, "--ff-on"),
        (a.servo_bandwidth.is_some(), "--servo-bandwidth"),
        (a.effort != Effort::MeasuredIq, "--effort"),
    ] {
        if given {
            bail!("{flag}: the logs are sensorless (no theta_fb_rad), and {flag} applies to servo logs only");
        }
    }
    check_output_dir(out)?;
    let text = a.format == Format::Text;
    let t0 = Instant::now();
    let logs = read_sensorless_logs(&a.logs)?;
    for l in logs.iter().filter(|l| text && !l.ignored_columns.is_empty()) {
        outln!("note: {}: ignored unknown columns: {}", l.source, l.ignored_columns.join(", "));
    }
    let f = identify_sensorless(&logs, base, &options(base, orders, a.inertia), &FluxOptions::default())?;
    let name = a.name.clone().unwrap_or_else(|| default_name(base, "identified"));
    let out_s = out.display().to_string();
    let profile = f.model().apply_to(base, Some(&name), &out_s).map_err(|e| anyhow!("{e}"))?;
    let report = print_report(base, &f, a.format)?;
    if text {
        let rows: usize = logs.iter().map(SensorlessLog::len).sum();
        outln!("{} logs, {rows} rows: read and identified in {:.3} s", logs.len(), t0.elapsed().as_secs_f64());
    }
    if let Some(dir) = &a.report {
        for w in write_report(dir, &f.fit, None, Some(&report.fit.validation), &profile.name)? {
            if text {
                outln!("wrote {}", w.display());
            }
        }
    }
    write_atomic(out, profile.to_toml_string().as_bytes())?;
    if text {
        outln!("wrote {out_s}");
    }
    Ok(())
}

fn print_report(base: &Profile, f: &SensorlessFit, format: Format) -> Result<SensorlessReport> {
    let report = SensorlessReport::new(&base.name, base.motor.resistance_ohm, base.motor.km_nm_per_a, f);
    match format {
        Format::Text => outln!("{report}"),
        Format::Json => print_json(&report)?,
    }
    Ok(report)
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
pub(super) fn run_sensorless_run_cmd(a: &RunArgs, global: &Global, motor: &Profile, orders: &[u16]) -> Result<()> {
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
    if text {
        outln!("{p}");
    }
    let pb = progress(p.runs.len() as u64, global.quiet, "simulating");
    let t0 = Instant::now();
    let files = run_sensorless_plan(motor, motor, &a.out, p, a.current_noise, a.seed, &|| pb.inc(1))?;
    pb.finish_and_clear();
    if text {
        outln!("simulated {:.1} s of open-loop runs in {:.2} s", p.total_s(), t0.elapsed().as_secs_f64());
    }
    write_atomic(&a.out.join("plan.txt"), format!("{p}\n").as_bytes())?;
    write_atomic(&a.out.join("plan.csv"), p.to_csv()?.as_bytes())?;
    let base_toml = a.out.join("base.toml");
    write_atomic(&base_toml, motor.to_toml_string().as_bytes())?;
    let logs = read_sensorless_logs(&files)?;
    let f = identify_sensorless(&logs, motor, &options(motor, orders, InertiaMode::Auto), &FluxOptions::default())?;
    let report = print_report(motor, &f, a.format)?;
    let out = a.out.join("identified.toml");
    let profile = f
        .model()
        .apply_to(motor, Some(&default_name(motor, "sensorless")), &out.display().to_string())
        .map_err(|e| anyhow!("{e}"))?;
    if a.report {
        for w in write_report(&a.out, &f.fit, None, Some(&report.fit.validation), &profile.name)? {
            if text {
                outln!("wrote {}", w.display());
            }
        }
    }
    write_atomic(&out, profile.to_toml_string().as_bytes())?;
    if text {
        for f in &files {
            outln!("wrote {}", f.display());
        }
        outln!("wrote {} and plan.txt, plan.csv, base.toml", out.display());
    } else {
        print_json(&SensorlessRun { plan: p, identification: &report })?;
    }
    Ok(())
}
