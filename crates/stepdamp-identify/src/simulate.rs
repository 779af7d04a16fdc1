//! Running an identification plan on the simulator (feature `simulate`): the logs a real
//! drive would record, in parallel with deterministic seeds.

use crate::log::RunLog;
use crate::plan::{Plan, PlanError, PlanOptions, PlannedRun, plan};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use stepdamp_core::Mode;
use stepdamp_profile::Profile;
use stepdamp_profile::runlog::SensorlessRow;
use stepdamp_sim::runlog::{FromRecord, LogRow, write_csv};
use stepdamp_sim::{ClosedLoop, Compensation, RunSpec, SimError, SimOptions, run};

/// Seed of run `index` from the base seed: [`stepdamp_sim::sweep::derived_seed`], the same
/// mixing as the sweep's lanes (deterministic, independent of the number of threads).
pub fn run_seed(base: u64, index: u64) -> u64 {
    stepdamp_sim::sweep::derived_seed(base, index)
}

/// Simulates one planned run of `motor` (the simulated plant) with a servo controller
/// configured from `controller` and compensation `comp`; returns the run log rows.
pub fn simulate_run(
    motor: &Profile,
    controller: &Profile,
    comp: Compensation,
    r: &PlannedRun,
    current_noise_a: f64,
    seed: u64,
) -> Result<Vec<LogRow>, SimError> {
    let opts = SimOptions { current_noise_a, seed, ..SimOptions::default() };
    let mut lp = ClosedLoop::new(motor, controller, Mode::Servo, comp, &opts)?;
    record(&mut lp, motor, r)
}

/// Simulates one run of a sensorless plan ([`crate::sensorless::plan`]) on `motor`: open
/// loop at the holding current with the controller of `controller` (the base profile:
/// same hardware), compensation off, `current_noise_a` of sensor noise; returns its log
/// rows (with the applied voltages).
pub fn simulate_open_loop_run(
    motor: &Profile,
    controller: &Profile,
    r: &PlannedRun,
    current_noise_a: f64,
    seed: u64,
) -> Result<Vec<LogRow>, SimError> {
    let opts = SimOptions { current_noise_a, seed, ..SimOptions::default() };
    let mut lp = ClosedLoop::new(motor, controller, Mode::OpenLoop, Compensation::Off, &opts)?;
    record(&mut lp, motor, r)
}

/// Runs `r` on `lp` and keeps every period's row.
fn record(lp: &mut ClosedLoop, motor: &Profile, r: &PlannedRun) -> Result<Vec<LogRow>, SimError> {
    let mut spec = RunSpec::at(r.speed_rad_s);
    spec.dwell_s = r.dwell_s;
    spec.ramp_s = r.ramp_s;
    spec.duration_s = r.duration_s;
    spec.window_s = (r.duration_s - r.dwell_s - r.ramp_s).max(0.0);
    let pwm = motor.drive.pwm_hz;
    let nr = motor.motor.pole_pairs;
    let mut rows = Vec::with_capacity((r.duration_s * pwm) as usize + 1);
    run(lp, &spec, pwm, |k, rec| rows.push(LogRow::from_record(k, pwm, nr, rec)))?;
    Ok(rows)
}

/// Simulates every run of `plan` on `motor` in parallel (seed of run `i`:
/// [`run_seed`]`(seed, i)`), with the controller of `controller` and `comp`, and hands each
/// run's rows to `each` as soon as it is done; returns what `each` returned, in plan order.
/// The set-up is checked once before the parallel part, so a bad one fails early.
fn for_each_run<T: Send, E: From<SimError> + Send>(
    motor: &Profile,
    controller: &Profile,
    comp: Compensation,
    plan: &Plan,
    current_noise_a: f64,
    seed: u64,
    each: impl Fn(&PlannedRun, Vec<LogRow>) -> Result<T, E> + Sync,
) -> Result<Vec<T>, E> {
    ClosedLoop::new(motor, controller, Mode::Servo, comp, &SimOptions { current_noise_a, ..SimOptions::default() })?;
    plan.runs
        .par_iter()
        .enumerate()
        .map(|(i, r)| each(r, simulate_run(motor, controller, comp, r, current_noise_a, run_seed(seed, i as u64))?))
        .collect()
}

/// Simulates every run of `plan` on `motor` (in parallel; seeds from `seed`), with the
/// controller of `controller` (the plan's profile for identification runs) and `comp`.
/// Returns the logs in plan order. `tick` is called once per finished run.
pub fn simulate_plan(
    motor: &Profile,
    controller: &Profile,
    comp: Compensation,
    plan: &Plan,
    current_noise_a: f64,
    seed: u64,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<RunLog>, SimError> {
    for_each_run(motor, controller, comp, plan, current_noise_a, seed, |r, rows| {
        tick();
        Ok(RunLog::from_rows(&rows, &r.name))
    })
}

/// What [`run_plan`] did.
#[derive(Clone, Debug)]
pub struct PlanRun {
    /// The plan.
    pub plan: Plan,
    /// The log files written, in plan order.
    pub files: Vec<PathBuf>,
}

/// Plans the identification from the `base` profile (what the user knows of the motor: its
/// `J` and detent may be guesses, see [`plan`]), simulates the runs on `motor` (the plant:
/// servo mode with the plan's controller, compensation off, the options' current noise, the
/// motor's encoder) in parallel with deterministic seeds (the same as [`simulate_plan`]
/// with `o.seed`), and writes one run-log CSV per run into `out_dir` (`<run name>.csv`,
/// docs/files.md columns), creating it if needed. Each file is written to a temporary name
/// and renamed when complete; on an error, the files already written are removed again.
pub fn run_plan(
    motor: &Profile,
    base: &Profile,
    out_dir: &Path,
    o: &PlanOptions,
    tick: &(dyn Fn() + Sync),
) -> Result<PlanRun, PlanError> {
    let plan = plan(base, o)?;
    let (p, noise, seed) = (&plan.profile, o.current_noise_a, o.seed);
    ClosedLoop::new(
        motor,
        p,
        Mode::Servo,
        Compensation::Off,
        &SimOptions { current_noise_a: noise, ..SimOptions::default() },
    )?;
    let files = write_runs(out_dir, &plan.runs, tick, |i, r| {
        simulate_run(motor, p, Compensation::Off, r, noise, run_seed(seed, i as u64))
    })?;
    Ok(PlanRun { plan, files })
}

/// Simulates the runs of a sensorless plan on `motor` (open loop, the controller of `base`,
/// compensation off, `current_noise_a` of sensor noise; seed of run `i`:
/// [`run_seed`]`(seed, i)`) in parallel and writes one log per run into `out_dir`
/// (`<run name>.csv`: the columns a drive without an encoder has,
/// [`stepdamp_profile::runlog::SensorlessRow`]), as [`run_plan`] does. Returns the files in
/// plan order.
pub fn run_sensorless_plan(
    motor: &Profile,
    base: &Profile,
    out_dir: &Path,
    plan: &crate::sensorless::plan::SensorlessPlan,
    current_noise_a: f64,
    seed: u64,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<PathBuf>, PlanError> {
    let opts = SimOptions { current_noise_a, ..SimOptions::default() };
    ClosedLoop::new(motor, base, Mode::OpenLoop, Compensation::Off, &opts)?;
    write_runs(out_dir, &plan.runs, tick, |i, r| {
        let rows = simulate_open_loop_run(motor, base, r, current_noise_a, run_seed(seed, i as u64))?;
        Ok(rows.iter().map(SensorlessRow::from).collect())
    })
}

/// Simulates `runs` in parallel with `sim` (given the run's index) and writes each run's
/// rows to `out_dir/<name>.csv` as soon as it is done (creating the directory); `tick` once
/// per run. On an error the files already written are removed again.
fn write_runs<R: serde::Serialize>(
    out_dir: &Path,
    runs: &[PlannedRun],
    tick: &(dyn Fn() + Sync),
    sim: impl Fn(usize, &PlannedRun) -> Result<Vec<R>, SimError> + Sync,
) -> Result<Vec<PathBuf>, PlanError> {
    std::fs::create_dir_all(out_dir).map_err(|source| PlanError::Write { path: out_dir.to_path_buf(), source })?;
    let written = std::sync::Mutex::new(Vec::new());
    let done: Result<Vec<PathBuf>, PlanError> = runs
        .par_iter()
        .enumerate()
        .map(|(i, r)| {
            let rows = sim(i, r)?;
            let path = out_dir.join(format!("{}.csv", r.name));
            write_rows_atomic(&path, &rows)?;
            written.lock().unwrap_or_else(std::sync::PoisonError::into_inner).push(path.clone());
            tick();
            Ok(path)
        })
        .collect();
    if done.is_err() {
        for f in written.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner) {
            let _ = std::fs::remove_file(f);
        }
    }
    done
}

/// Writes log rows to `path` through a temporary file in the same directory (a device,
/// FIFO or `-` straight through; see [`stepdamp_out::Output`]): complete or not at all,
/// also when the process is interrupted.
pub fn write_rows_atomic<R: serde::Serialize>(path: &Path, rows: &[R]) -> Result<(), PlanError> {
    let io_err = |source| PlanError::Write { path: path.to_path_buf(), source };
    // The output's message names the path already; keep only its reason here.
    let out_err = |e: stepdamp_out::OutError| match e.kind {
        stepdamp_out::OutErrorKind::Io(source) => io_err(source),
        _ => io_err(std::io::Error::other(e.to_string())),
    };
    let mut out = stepdamp_out::Output::create(path).map_err(out_err)?;
    write_csv(&mut out, rows).map_err(|e| io_err(std::io::Error::other(e)))?;
    out.commit().map_err(out_err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_differ_per_run_and_repeat() {
        assert_ne!(run_seed(1, 0), run_seed(1, 1));
        assert_eq!(run_seed(7, 3), run_seed(7, 3));
    }
}
