//! `stepdamp sweep`: velocity error against speed, with and without compensation.

use crate::Global;
use crate::common::{
    AtomicFiles, ChoiceList, Format, load_motor, parse_compensations, parse_modes, print_json, progress,
    sim_error_with_flag,
};
use crate::plot::{Marker, sweep_plot};
use anyhow::{Context, Result, bail};
use std::path::PathBuf;
use std::time::Instant;
use stepdamp_core::Mode;
use stepdamp_sim::{
    Compensation, MAX_POINTS, RunSpec, SimError, SimOptions, SweepRow, SweepSpec, SweepSummary, check_substeps,
    linear_grid,
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
    #[arg(long, default_value = "both", value_parser = parse_modes)]
    pub mode: ChoiceList<Mode>,
    /// Comma list of off, patent (alias on), estimated (open loop only); both = off,patent.
    #[arg(long, default_value = "both", value_parser = parse_compensations)]
    pub compensation: ChoiceList<Compensation>,
    /// Lowest speed in rad/s.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub from: f64,
    /// Highest speed in rad/s (at most the controller's limit, (π/2)/(Nr·Ts): 628 rad/s for
    /// 50 pole pairs at 20 kHz).
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true)]
    pub to: f64,
    /// Number of speeds.
    #[arg(long, default_value_t = 60, allow_negative_numbers = true)]
    pub points: i64,
    /// Simulated time per run in s (50 ms standstill, 0.1 s ramp, error measured over the
    /// last ≤ 0.5 s in whole electrical periods, at least 50 ms after the ramp).
    #[arg(long, default_value_t = RunSpec::DURATION_S, allow_negative_numbers = true)]
    pub duration: f64,
    /// Constant load torque in N·m opposing the direction of travel.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub load_torque: f64,
    /// Current-sensor noise, standard deviation in A.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub current_noise: f64,
    /// RK4 steps per PWM period.
    #[arg(long, default_value_t = i64::from(SimOptions::default().substeps), allow_negative_numbers = true)]
    pub substeps: i64,
    /// Seed of the noise generators.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub seed: u64,
    /// Correction table replayed by `--compensation table`: a Prusa correction file, M973
    /// lines or M972 output, or a Klipper block with driver_MSLUT0… (see `stepdamp export`).
    #[arg(long, value_name = "FILE")]
    pub table: Option<PathBuf>,
    /// Output directory: sweep.csv, sweep.svg, sweep.png.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// Summary on standard output: text, or json (the summary only, for scripts).
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

/// Builds the sweep specification after checking the arguments that only the command line
/// has (the grid, the duration's bounds, the substeps as written); the rest is checked by
/// [`SweepSpec::validate`] ([`flag_error`] names the flags).
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
    if a.points > MAX_POINTS as i64 {
        bail!("--points {}: at most {MAX_POINTS}", a.points);
    }
    if !(a.duration.is_finite() && a.duration >= 0.2 && a.duration <= 1000.0) {
        bail!("--duration {}: must be between 0.2 and 1000 s", a.duration);
    }
    let substeps = check_substeps(a.substeps).map_err(flag_error)?;
    Ok(SweepSpec {
        speeds_rad_s: linear_grid(a.from, a.to, a.points as usize)?,
        modes: a.mode.items.clone(),
        compensations: a.compensation.items.clone(),
        run: RunSpec::for_duration(a.from, a.duration),
        options: SimOptions {
            substeps,
            current_noise_a: a.current_noise,
            seed: a.seed,
            load_torque_nm: a.load_torque,
            ..SimOptions::default()
        },
        table: None,
    })
}

/// A sweep's [`SimError`] naming the flag that set the value: the run's duration is
/// `--duration`, and a speed out of range is the grid's highest, `--to`.
fn flag_error(e: SimError) -> anyhow::Error {
    sim_error_with_flag(e, &[("duration", "--duration"), ("speed", "--to")])
}

/// Resonance markers for the plot.
fn resonance_markers(s: &SweepSummary) -> Vec<Marker> {
    s.resonances.iter().map(|r| Marker { x: r.speed_rad_s, label: format!("k={}", r.order) }).collect()
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
    let mut spec = spec_of(&a)?;
    spec.table = match &a.table {
        Some(path) => {
            let (t, kind) = stepdamp_export::load_table_file(path, None).context("--table")?;
            eprintln!("note: --table {}: {kind}", path.display());
            Some(t)
        }
        None => None,
    };
    let checked = spec.validate(&motor, &a.motor, &controller, controller_name).map_err(flag_error)?;
    if spec.modes.contains(&Mode::Servo) && spec.compensations.contains(&Compensation::Estimated) {
        eprintln!("note: estimated compensation is run in open loop only (servo uses the encoder angle)");
    }
    let mut files = AtomicFiles::in_dir_removed_on_failure(&a.out)?;
    let runs = spec.runs();
    let pb = progress(runs as u64, g.quiet, "sweep");
    let t0 = Instant::now();
    let rows = checked.run(&|| pb.inc(1))?;
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
    let summary = SweepSummary::new(&motor, &rows);
    sweep_plot(&rows, &resonance_markers(&summary), &title, &tsvg, &tpng)?;
    let written = files.commit()?;

    if a.format == Format::Json {
        return print_json(&summary);
    }
    out!("{summary}");
    let simulated = runs as f64 * spec.run.duration_s;
    outln!(
        "{runs} runs, {simulated:.0} s simulated in {wall:.2} s wall ({:.0} simulated s per wall s)",
        simulated / wall
    );
    for w in written {
        outln!("wrote {}", w.display());
    }
    Ok(())
}

/// Writes the sweep table (docs/files.md, docs/design.md#file-formats).
pub fn write_table(path: &std::path::Path, rows: &[SweepRow]) -> Result<()> {
    let mut w = csv::Writer::from_path(path)?;
    for r in rows {
        w.serialize(r)?;
    }
    w.flush()?;
    Ok(())
}
