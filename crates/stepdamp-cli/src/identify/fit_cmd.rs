//! `stepdamp identify` itself: the fit of run logs, its table, decisions and validation.

use super::*;

pub(super) fn run_fit_cmd(a: FitArgs, _global: &Global) -> Result<()> {
    let Some(motor) = &a.motor else { bail!("--motor is needed: the base profile (preset or TOML) with Km, Nr, J") };
    let Some(out) = &a.out else { bail!("--out is needed: where to write the identified profile (TOML)") };
    if a.logs.is_empty() {
        bail!("no --log given: pass the servo-mode run logs (CSV), e.g. --log a.csv --log b.csv");
    }
    let base = load_motor(motor)?;
    let orders = a.orders.0.clone();
    if a.sensorless || route_of(&a.logs)? == stepdamp_identify::sensorless::log::LogKind::Sensorless {
        return run_sensorless_fit_cmd(&a, &base, &orders, out);
    }
    if let Some(bw) = a.servo_bandwidth
        && !(bw.is_finite() && bw > 0.0)
    {
        bail!("--servo-bandwidth {bw}: must be a positive number of Hz");
    }
    check_output_dir(out)?;
    // With --format json stdout is the report's JSON alone (one line); the files are written
    // all the same.
    let text = a.format == Format::Text;
    let t0 = Instant::now();
    let logs = read_logs(&a.logs, base.motor.pole_pairs)?;
    let t_read = t0.elapsed().as_secs_f64();
    for l in &logs {
        if text && !l.ignored_columns.is_empty() {
            outln!("note: {}: ignored unknown columns: {}", l.source, l.ignored_columns.join(", "));
        }
    }
    let mut fo = FitOptions::for_profile(&base, &orders);
    fo.effort = a.effort;
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
    let ff = a.ff_on.then(|| FeedForwardCheck::new(&base, &f));
    let validation = print_fit_report(&f, &base.name, ff, a.format)?;
    if text {
        outln!("{} logs, {rows} rows: read in {t_read:.3} s, fitted in {t_fit:.3} s", logs.len());
    }
    if let Some(dir) = &a.report {
        let written = write_report(dir, &f, None, Some(&validation), &profile.name)?;
        for w in written.iter().filter(|_| text) {
            outln!("wrote {}", w.display());
        }
    }
    write_atomic(out, profile.to_toml_string().as_bytes())?;
    if text {
        outln!("wrote {out_s}");
    }
    Ok(())
}

/// Prints the fit's report ([`FitReport`]: the table, the warnings, the decisions — which
/// `J`, and why — and the validation) and returns its validation for the plots.
pub(super) fn print_fit_report(
    f: &Fit,
    base: &str,
    ff: Option<FeedForwardCheck>,
    format: Format,
) -> Result<Validation> {
    let mut report = FitReport::new(base, f.clone());
    if let Some(c) = ff {
        report = report.with_feed_forward(c);
    }
    match format {
        Format::Text => outln!("{report}"),
        Format::Json => print_json(&report)?,
    }
    Ok(report.validation)
}

pub(super) fn check_output_dir(out: &Path) -> Result<()> {
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
