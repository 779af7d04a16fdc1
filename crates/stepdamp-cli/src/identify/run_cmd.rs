//! `stepdamp identify run` (simulated runs, refinement and its summary) and `identify static`.

use super::*;

/// Most control periods `identify run` simulates over all runs (200 s at 20 kHz, a few
/// hundred MB of logs).
pub(super) const MAX_SIMULATED_ROWS: f64 = 4e6;

pub(super) fn run_run_cmd(a: RunArgs, global: &Global) -> Result<()> {
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
pub(super) fn simulate_and_identify(
    a: &RunArgs,
    global: &Global,
    motor: &Profile,
    orders: &[u16],
    po: &PlanOptions,
    p: &Plan,
) -> Result<()> {
    outln!("{p}");
    let pb = progress(p.runs.len() as u64, global.quiet, "simulating");
    let t0 = Instant::now();
    let done = run_plan(motor, motor, &a.out, po, &|| pb.inc(1))?;
    pb.finish_and_clear();
    outln!("simulated {:.1} s of runs in {:.2} s", p.total_s(), t0.elapsed().as_secs_f64());
    write_atomic(&a.out.join("plan.txt"), format!("{p}\n").as_bytes())?;
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
    let validation = print_fit_report(&f0, &motor.name, Format::Text)?;
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
pub(super) const SUMMARY_FILE: &str = "refine-summary.csv";

/// The summary of `identify run --refine` as CSV, for scripts: one row per quantity with
/// the simulated motor's value (the truth), the feed-forward-off fit's and the refined one.
/// Columns `quantity,order,unit,motor,identified,refined`; quantities `amplitude` and
/// `phase` (one row per order), `coulomb_friction`, `viscous_friction`, `inertia`, and
/// `periodic_ripple_rms` (the loop effort's ripple over orders 1–16: `identified` = before,
/// feed-forward off; `refined` = after, the refined estimate fed forward) and
/// `ripple_reduction` (before / after, in `refined`). Empty cells: not applicable.
pub(super) fn refine_summary_csv(motor: &Profile, f0: &Fit, r: &Refinement) -> Result<String> {
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

pub(super) fn refine_table(r: &Refinement) -> String {
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

pub(super) fn run_static_cmd(a: StaticArgs) -> Result<()> {
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
