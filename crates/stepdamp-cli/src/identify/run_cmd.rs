//! `stepdamp identify run` (simulated runs, refinement and its summary) and `identify static`.

use super::*;

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
pub(super) const MAX_SIMULATED_ROWS: f64 = 4e6;

pub(super) fn run_run_cmd(a: RunArgs, global: &Global) -> Result<()> {
    let motor = load_motor(&a.motor)?;
    let orders = a.orders.0.clone();
    if !(a.current_noise.is_finite() && a.current_noise >= 0.0) {
        bail!("--current-noise {}: must be a finite number ≥ 0 A", a.current_noise);
    }
    if a.sensorless {
        return run_sensorless_run_cmd(&a, global, &motor, &orders);
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
pub(super) fn in_run_dir(a: &RunArgs, total_s: f64, pwm_hz: f64, work: impl FnOnce() -> Result<()>) -> Result<()> {
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
pub(super) fn simulate_and_identify(
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
    let logs = read_logs(&done.files, motor.motor.pole_pairs)?;
    let fo = FitOptions::for_profile(&p.profile, orders);
    let f0 = fit(&logs, &fo)?;
    let fit_report = FitReport::new(&motor.name, f0.clone());
    say!(text, "{fit_report}");
    let validation = fit_report.validation.clone();
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
    let refinement = RefinementReport::new(motor, &f0, &r);
    say!(text, "{refinement}");
    let out = a.out.join("identified.toml");
    let profile = r
        .model
        .apply_to(motor, Some(&default_name(motor, "identified")), &out.display().to_string())
        .map_err(|e| anyhow!("{e}"))?;
    if a.report {
        for w in write_report(&a.out, &f0, Some((&r, p)), Some(&validation), &profile.name)? {
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

pub(super) fn run_static_cmd(a: StaticArgs) -> Result<()> {
    let base = load_motor(&a.motor)?;
    let orders = a.orders.0.clone();
    let sign = a.sign;
    check_output_dir(&a.out)?;
    let pts = read_table(&a.table).map_err(|e| anyhow!("{e}"))?;
    let kmax = *orders.iter().max().expect("parse_orders gives at least one order");
    let src = a.table.display().to_string();
    let c = analyse(&pts, base.motor.pole_pairs, sign, kmax, &src).map_err(|e| anyhow!("{e}"))?;
    let report = StaticReport::new(&src, pts.len(), &c, &orders);
    let picked = &report.harmonics;
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
    let json = a.format == Format::Json;
    if !json {
        outln!("{report}");
    }
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
    if json {
        print_json(&report)?;
    } else {
        outln!("wrote {out_s} (friction kept from the base profile: a static table does not measure it)");
    }
    Ok(())
}
