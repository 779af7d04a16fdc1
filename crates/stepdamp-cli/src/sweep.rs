//! `stepdamp sweep`: velocity error against speed, with and without compensation.

use crate::Global;
use crate::common::{AtomicFiles, load_motor, parse_compensations, parse_modes, progress};
use crate::plot::{Marker, sweep_plot};
use anyhow::{Context, Result, bail};
use std::path::PathBuf;
use std::time::Instant;
use stepdamp_sim::{Profile, RunSpec, SimOptions, SweepRow, SweepSpec, linear_grid, sweep};

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
    /// Comma list of off, patent (alias on), estimated; both = off,patent.
    #[arg(long, default_value = "both")]
    pub compensation: String,
    /// Lowest speed in rad/s.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub from: f64,
    /// Highest speed in rad/s.
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true)]
    pub to: f64,
    /// Number of speeds.
    #[arg(long, default_value_t = 60)]
    pub points: usize,
    /// Simulated time per run in s (50 ms standstill, 0.1 s ramp, error measured over the
    /// last ≤ 0.5 s).
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
    let window = (a.duration / 3.0).min(0.5);
    Ok(SweepSpec {
        speeds_rad_s: linear_grid(a.from, a.to, a.points),
        modes: parse_modes(&a.mode)?,
        compensations: parse_compensations(&a.compensation)?,
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

/// Runs `stepdamp sweep`.
pub fn run(a: SweepArgs, g: &Global) -> Result<()> {
    let motor = load_motor(&a.motor)?;
    let controller = match &a.controller_motor {
        Some(c) => load_motor(c).context("--controller-motor")?,
        None => motor.clone(),
    };
    let spec = spec_of(&a)?;
    let mut files = AtomicFiles::in_dir(&a.out)?;
    let lanes = spec.speeds_rad_s.len() * spec.modes.len() * spec.compensations.len();
    let pb = progress(lanes as u64, g.quiet, "sweep");
    let t0 = Instant::now();
    let rows = sweep(&motor, &controller, &spec, &|| pb.inc(1))?;
    pb.finish_and_clear();
    let wall = t0.elapsed().as_secs_f64();

    let csv_path = a.out.join("sweep.csv");
    let tmp = files.stage(&csv_path);
    write_table(&tmp, &rows).with_context(|| format!("{}: cannot write", csv_path.display()))?;
    let svg = a.out.join("sweep.svg");
    let png = a.out.join("sweep.png");
    let (tsvg, tpng) = (files.stage(&svg), files.stage(&png));
    let mut title = format!("{}: velocity error vs speed", motor.name);
    if a.load_torque > 0.0 {
        title += &format!(", load {} N·m", a.load_torque);
    }
    if a.controller_motor.is_some() {
        title += &format!(", controller model {}", controller.name);
    }
    sweep_plot(&rows, &resonance_markers(&motor), &title, &tsvg, &tpng)?;
    let written = files.commit()?;

    print!("{}", summary(&motor, &rows));
    let simulated = lanes as f64 * spec.run.duration_s;
    println!(
        "{lanes} runs, {simulated:.0} s simulated in {wall:.2} s wall ({:.0} simulated s per wall s)",
        simulated / wall
    );
    for w in written {
        println!("wrote {}", w.display());
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

/// Peak-to-peak velocity error of the highest point within ±10 % of `speed`.
fn peak_near(rows: &[SweepRow], mode: &str, comp: &str, speed: f64) -> Option<(f64, f64)> {
    rows.iter()
        .filter(|r| r.mode == mode && r.compensation == comp && (r.speed_cmd_rad_s - speed).abs() <= 0.1 * speed)
        .map(|r| (r.speed_cmd_rad_s, r.vel_err_pp_rad_s))
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

/// The printed summary: resonance speeds, peaks with and without compensation, ratios.
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
    let mut modes: Vec<&str> = rows.iter().map(|r| r.mode).collect();
    modes.dedup();
    let mut comps: Vec<&str> = rows.iter().map(|r| r.compensation).collect();
    comps.sort_unstable();
    comps.dedup();
    for mode in modes {
        let _ = writeln!(s, "{mode}:");
        for comp in &comps {
            let of = |f: fn(&SweepRow) -> f64| {
                rows.iter().filter(|r| r.mode == mode && r.compensation == *comp).map(f).fold(0.0, f64::max)
            };
            let lost = rows.iter().filter(|r| r.mode == mode && r.compensation == *comp && r.lost_sync).count();
            let _ = writeln!(
                s,
                "  {comp:>9}: worst pp {:8.4} rad/s, worst rms {:8.4} rad/s, lost sync in {lost} runs",
                of(|r| r.vel_err_pp_rad_s),
                of(|r| r.vel_err_rms_rad_s)
            );
        }
        if comps.contains(&"off") {
            for m in &markers {
                let Some((w, off)) = peak_near(rows, mode, "off", m.x) else { continue };
                let mut line = format!("  near {} ({:.2} rad/s): off {off:.4} at {w:.2}", m.label, m.x);
                for comp in comps.iter().filter(|c| **c != "off") {
                    if let Some((_, on)) = peak_near(rows, mode, comp, m.x) {
                        let _ = write!(line, ", {comp} {on:.4} ({:.1}x less)", off / on);
                    }
                }
                let _ = writeln!(s, "{line}");
            }
        }
    }
    s
}
