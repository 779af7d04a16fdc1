//! `stepdamp sweep`: velocity error against speed, with and without compensation.

use crate::Global;
use crate::common::{AtomicFiles, load_motor, parse_compensations, parse_modes, progress};
use crate::plot::{Marker, sweep_plot};
use anyhow::{Context, Result, anyhow, bail};
use std::path::PathBuf;
use std::time::Instant;
use stepdamp_core::Mode;
use stepdamp_sim::{
    Compensation, ESTIMATED_IS_OPEN_LOOP_ONLY, MAX_SPEED_RAD_S, Profile, RunSpec, SimError, SimOptions, SweepRow,
    SweepSpec, linear_grid, sweep,
};

/// Arguments of `stepdamp sweep`.
#[derive(clap::Args, Debug)]
pub struct SweepArgs {
    /// Motor: a preset name (patent-motor, nema17-17hs4401, nema23-57mm, nema34-86mm) or a
    /// profile TOML file.
    #[arg(long, default_value = "patent-motor")]
    pub motor: String,
    /// The motor the controller believes in (default: the simulated one). Models a
    /// mis-identified motor.
    #[arg(long, value_name = "PRESET|FILE")]
    pub controller_motor: Option<String>,
    /// open-loop, servo or both.
    #[arg(long, default_value = "both")]
    pub mode: String,
    /// Comma list of off, patent (alias on), estimated (open loop only); both = off,patent.
    #[arg(long, default_value = "both")]
    pub compensation: String,
    /// Lowest speed in rad/s.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub from: f64,
    /// Highest speed in rad/s (at most 10000).
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true)]
    pub to: f64,
    /// Number of speeds.
    #[arg(long, default_value_t = 60)]
    pub points: usize,
    /// Simulated time per run in s (50 ms standstill, 0.1 s ramp, error measured over the
    /// last ≤ 0.5 s in whole electrical periods, at least 50 ms after the ramp).
    #[arg(long, default_value_t = 1.5, allow_negative_numbers = true)]
    pub duration: f64,
    /// Constant load torque in N·m opposing the direction of travel.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub load_torque: f64,
    /// Current-sensor noise, standard deviation in A.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub current_noise: f64,
    /// RK4 steps per PWM period.
    #[arg(long, default_value_t = 2)]
    pub substeps: u32,
    /// Seed of the noise generators.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory: sweep.csv, sweep.svg, sweep.png.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
}

/// Builds the sweep specification after checking every argument.
pub fn spec_of(a: &SweepArgs) -> Result<SweepSpec> {
    if !(a.from.is_finite() && a.to.is_finite()) {
        bail!("--from {} / --to {}: must be finite numbers", a.from, a.to);
    }
    if a.from >= a.to {
        bail!("--from {} must be below --to {}", a.from, a.to);
    }
    if a.from <= 0.0 {
        bail!("--from {}: speeds must be > 0 rad/s (a sweep runs in one direction)", a.from);
    }
    if a.to > MAX_SPEED_RAD_S {
        bail!("--to {}: speeds must be ≤ {MAX_SPEED_RAD_S} rad/s", a.to);
    }
    if a.points < 2 {
        bail!("--points {}: need at least 2 speeds", a.points);
    }
    if a.points > 100_000 {
        bail!("--points {}: at most 100000", a.points);
    }
    if !(a.duration.is_finite() && a.duration >= 0.2 && a.duration <= 1000.0) {
        bail!("--duration {}: must be between 0.2 and 1000 s", a.duration);
    }
    if !(a.load_torque.is_finite() && a.load_torque >= 0.0) {
        bail!("--load-torque {}: must be a finite number ≥ 0 N·m", a.load_torque);
    }
    if !(a.current_noise.is_finite() && a.current_noise >= 0.0) {
        bail!("--current-noise {}: must be a finite number ≥ 0 A", a.current_noise);
    }
    if a.substeps == 0 || a.substeps > 1000 {
        bail!("--substeps {}: must be in 1..=1000", a.substeps);
    }
    let modes = parse_modes(&a.mode)?;
    let compensations = parse_compensations(&a.compensation)?;
    if compensations.contains(&Compensation::Estimated) && !modes.contains(&Mode::OpenLoop) {
        bail!("--mode {} --compensation estimated: {ESTIMATED_IS_OPEN_LOOP_ONLY}", a.mode);
    }
    let window = (a.duration / 3.0).min(0.5);
    Ok(SweepSpec {
        speeds_rad_s: linear_grid(a.from, a.to, a.points),
        modes,
        compensations,
        run: RunSpec { speed_rad_s: a.from, dwell_s: 0.05, ramp_s: 0.1, duration_s: a.duration, window_s: window },
        options: SimOptions {
            substeps: a.substeps,
            current_noise_a: a.current_noise,
            seed: a.seed,
            load_torque_nm: a.load_torque,
            ..SimOptions::default()
        },
    })
}

/// Resonance markers for a profile's detent orders.
pub fn resonance_markers(p: &Profile) -> Vec<Marker> {
    let mut orders: Vec<u16> = p.motor.detent.iter().map(|h| h.order).collect();
    if orders.is_empty() {
        orders = vec![4, 2, 1];
    }
    orders.sort_unstable_by(|a, b| b.cmp(a));
    orders.iter().map(|&k| Marker { x: p.resonance_speed_rad_s(k), label: format!("k={k}") }).collect()
}

/// Runs `stepdamp sweep`: checks everything, then simulates, then writes the outputs
/// (to temporary names, moved into place together; a new output directory is removed
/// again if anything fails).
pub fn run(a: SweepArgs, g: &Global) -> Result<()> {
    let motor = load_motor(&a.motor)?;
    let (controller, controller_name) = match &a.controller_motor {
        Some(c) => (load_motor(c).context("--controller-motor")?, c.as_str()),
        None => (motor.clone(), a.motor.as_str()),
    };
    let spec = spec_of(&a)?;
    spec.validate(&motor, &a.motor, &controller, controller_name).map_err(|e| match e {
        // The run's duration is the option's; the speeds are --from/--to.
        SimError::Option { what: "duration", reason } => anyhow!("--duration {reason}"),
        e => e.into(),
    })?;
    if spec.modes.contains(&Mode::Servo) && spec.compensations.contains(&Compensation::Estimated) {
        eprintln!("note: estimated compensation is run in open loop only (servo uses the encoder angle)");
    }
    let mut files = AtomicFiles::in_dir_removed_on_failure(&a.out)?;
    let lanes = spec.runs();
    let pb = progress(lanes as u64, g.quiet, "sweep");
    let t0 = Instant::now();
    let rows = sweep(&motor, &controller, &spec, &|| pb.inc(1))?;
    pb.finish_and_clear();
    let wall = t0.elapsed().as_secs_f64();

    let csv_path = a.out.join("sweep.csv");
    let tmp = files.stage(&csv_path)?;
    write_table(&tmp, &rows).with_context(|| format!("{}: cannot write", csv_path.display()))?;
    let svg = a.out.join("sweep.svg");
    let png = a.out.join("sweep.png");
    let (tsvg, tpng) = (files.stage(&svg)?, files.stage(&png)?);
    let mut title = format!("{}: velocity error vs speed", motor.name);
    if a.load_torque > 0.0 {
        title += &format!(", load {} N·m", a.load_torque);
    }
    if a.controller_motor.is_some() {
        title += &format!(", controller model {}", controller.name);
    }
    sweep_plot(&rows, &resonance_markers(&motor), &title, &tsvg, &tpng)?;
    let written = files.commit()?;

    out!("{}", summary(&motor, &rows));
    let simulated = lanes as f64 * spec.run.duration_s;
    outln!(
        "{lanes} runs, {simulated:.0} s simulated in {wall:.2} s wall ({:.0} simulated s per wall s)",
        simulated / wall
    );
    for w in written {
        outln!("wrote {}", w.display());
    }
    Ok(())
}

/// Writes the sweep table of design.md §6.
pub fn write_table(path: &std::path::Path, rows: &[SweepRow]) -> Result<()> {
    let mut w = csv::Writer::from_path(path)?;
    for r in rows {
        w.serialize(r)?;
    }
    w.flush()?;
    Ok(())
}

/// Peak-to-peak velocity error of the highest point within ±10 % of `speed` (a diverged,
/// NaN, point counts as the highest).
fn peak_near(rows: &[SweepRow], mode: &str, comp: &str, speed: f64) -> Option<(f64, f64)> {
    rows.iter()
        .filter(|r| r.mode == mode && r.compensation == comp && (r.speed_cmd_rad_s - speed).abs() <= 0.1 * speed)
        .map(|r| (r.speed_cmd_rad_s, r.vel_err_pp_rad_s))
        .max_by(|a, b| nan_high(a.1).total_cmp(&nan_high(b.1)))
}

fn nan_high(v: f64) -> f64 {
    if v.is_nan() { f64::INFINITY } else { v }
}

/// Median of the RMS velocity errors (NaN, from a diverged run, counts as the highest).
fn median_rms(rows: &[&SweepRow]) -> f64 {
    let mut x: Vec<f64> = rows.iter().map(|r| nan_high(r.vel_err_rms_rad_s)).collect();
    if x.is_empty() {
        return f64::NAN;
    }
    x.sort_by(f64::total_cmp);
    0.5 * (x[x.len() / 2] + x[(x.len() - 1) / 2])
}

/// Worst peak-to-peak velocity error and its speed (NaN counts as infinite).
fn worst_pp(rows: &[&SweepRow]) -> (f64, f64) {
    rows.iter()
        .map(|r| (nan_high(r.vel_err_pp_rad_s), r.speed_cmd_rad_s))
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap_or((f64::NAN, f64::NAN))
}

/// `off / on` as "12.3x less" (or "more").
fn ratio(off: f64, on: f64) -> String {
    let r = off / on;
    if !r.is_finite() || r <= 0.0 {
        "ratio n/a".to_string()
    } else if r >= 1.0 {
        format!("{r:.1}x less")
    } else {
        format!("{:.1}x more", 1.0 / r)
    }
}

/// The printed summary (issue 3's metrics): the resonance speeds; per mode and
/// compensation the median RMS and the worst peak-to-peak velocity error over the sweep,
/// with their ratios to compensation off; and the peak-to-peak error near each
/// resonance.
pub fn summary(motor: &Profile, rows: &[SweepRow]) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let wn = motor.natural_frequency_rad_s();
    let _ = writeln!(
        s,
        "{}: ω_n = {wn:.1} rad/s ({:.1} Hz), damping ratio {:.4}",
        motor.name,
        wn / std::f64::consts::TAU,
        motor.damping_ratio()
    );
    let markers = resonance_markers(motor);
    let _ = writeln!(
        s,
        "resonance speeds ω_n/(k·Nr): {}",
        markers.iter().map(|m| format!("{} {:.2} rad/s", m.label, m.x)).collect::<Vec<_>>().join(", ")
    );
    let (modes, comps) = crate::plot::modes_and_compensations(rows);
    for mode in modes {
        let _ = writeln!(s, "{mode}: velocity error over {:.2}..{:.2} rad/s", first_speed(rows), last_speed(rows));
        let lane = |comp: &str| -> Vec<&SweepRow> {
            rows.iter().filter(|r| r.mode == mode && r.compensation == comp).collect()
        };
        let off = lane("off");
        for comp in &comps {
            let this = lane(comp);
            if this.is_empty() {
                continue;
            }
            let (med, (worst, at)) = (median_rms(&this), worst_pp(&this));
            let lost = this.iter().filter(|r| r.lost_sync).count();
            let mut line = format!(
                "  {comp:>9}: median rms {med:.4} rad/s, worst pp {worst:.4} rad/s at {at:.2} rad/s, lost sync {lost}/{}",
                this.len()
            );
            if *comp != "off" && !off.is_empty() {
                let _ = write!(
                    line,
                    "; vs off: median rms {}, worst pp {}",
                    ratio(median_rms(&off), med),
                    ratio(worst_pp(&off).0, worst)
                );
            }
            let _ = writeln!(s, "{line}");
        }
        for m in &markers {
            let mut parts = Vec::new();
            for comp in &comps {
                let Some((_, pp)) = peak_near(rows, mode, comp, m.x) else { continue };
                let mut part = format!("{comp} {pp:.4}");
                if *comp != "off" {
                    if let Some((_, off_pp)) = peak_near(rows, mode, "off", m.x) {
                        let _ = write!(part, " ({})", ratio(off_pp, pp));
                    }
                }
                parts.push(part);
            }
            if !parts.is_empty() {
                let _ = writeln!(s, "  pp near {} {:.2} rad/s ±10 %, rad/s: {}", m.label, m.x, parts.join(", "));
            }
        }
    }
    s
}

fn first_speed(rows: &[SweepRow]) -> f64 {
    rows.iter().map(|r| r.speed_cmd_rad_s).fold(f64::INFINITY, f64::min)
}

fn last_speed(rows: &[SweepRow]) -> f64 {
    rows.iter().map(|r| r.speed_cmd_rad_s).fold(f64::NEG_INFINITY, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(mode: &'static str, compensation: &'static str, w: f64, rms: f64, pp: f64) -> SweepRow {
        SweepRow {
            mode,
            compensation,
            speed_cmd_rad_s: w,
            vel_err_rms_rad_s: rms,
            vel_err_pp_rad_s: pp,
            lost_sync: pp.is_nan(),
        }
    }

    #[test]
    fn the_summary_gives_median_rms_and_worst_pp_ratios_and_the_peaks_near_each_resonance() {
        let p = Profile::preset("patent-motor").unwrap();
        let w4 = p.resonance_speed_rad_s(4);
        let mut rows = Vec::new();
        for (i, w) in [w4, 6.0, 10.0].into_iter().enumerate() {
            rows.push(row("servo", "off", w, [1.0, 2.0, 3.0][i], [10.0, 4.0, 6.0][i]));
            rows.push(row("servo", "patent", w, [0.1, 0.2, 0.3][i], [1.0, 2.0, 0.5][i]));
        }
        let s = summary(&p, &rows);
        // Median rms 2.0 vs 0.2, worst pp 10 vs 2.
        assert!(s.contains("median rms 2.0000 rad/s, worst pp 10.0000 rad/s at 4.22 rad/s, lost sync 0/3"), "{s}");
        assert!(s.contains("vs off: median rms 10.0x less, worst pp 5.0x less"), "{s}");
        assert!(s.contains("pp near k=4 4.22 rad/s ±10 %, rad/s: off 10.0000, patent 1.0000 (10.0x less)"), "{s}");
        // A diverged run is the worst and counts as lost.
        rows.push(row("servo", "patent", 12.0, f64::NAN, f64::NAN));
        let s = summary(&p, &rows);
        assert!(s.contains("worst pp inf rad/s at 12.00 rad/s, lost sync 1/4"), "{s}");
        assert!(!s.contains("-inf"), "{s}");
    }
}
