//! Parallel velocity-error sweeps over a speed grid (rayon). Deterministic: every run has
//! its own noise seed derived from the sweep seed and its index, so the table is the same
//! on any number of threads.
//!
//! Estimated-angle compensation exists in open loop only: a sweep of both modes runs it in
//! open loop and skips its servo runs; a servo-only sweep that asks for it is an error.

use crate::closed_loop::ClosedLoop;
use crate::lanes::LANES;
use crate::lockstep::run_lockstep_while;
use crate::options::{SimError, SimOptions, check_mode_compensation, check_same_hardware};
use crate::profile::Profile;
use crate::scenario::{RunSpec, check_speed, max_speed_rad_s};
use rayon::prelude::*;
use serde::Serialize;
use stepdamp_core::{Compensation, Config, CorrectionTable, Mode};

/// What to sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepSpec {
    /// Speeds in rad/s.
    pub speeds_rad_s: Vec<f64>,
    /// Control modes.
    pub modes: Vec<Mode>,
    /// Compensations.
    pub compensations: Vec<Compensation>,
    /// Run shape (its speed is replaced by each grid speed).
    pub run: RunSpec,
    /// Simulation options (its seed is the base of the runs' seeds).
    pub options: SimOptions,
    /// The correction table that [`Compensation::Table`] replays (required when the
    /// compensations include it; the other compensations ignore it).
    pub table: Option<CorrectionTable>,
}

/// One row of the sweep table (docs/files.md; column names are the field names).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepRow {
    /// Control mode (`open-loop` or `servo` in the table).
    pub mode: Mode,
    /// Compensation (`off`, `patent` or `estimated` in the table).
    pub compensation: Compensation,
    /// Commanded speed in rad/s.
    pub speed_cmd_rad_s: f64,
    /// RMS velocity error in rad/s.
    pub vel_err_rms_rad_s: f64,
    /// Peak-to-peak velocity error in rad/s.
    pub vel_err_pp_rad_s: f64,
    /// The rotor slipped.
    pub lost_sync: bool,
}

/// Most points of a speed grid ([`linear_grid`]) and most speeds of a sweep
/// ([`SweepSpec::validate`]): 100 000, far beyond any resolution a sweep needs (the README's
/// has 60), and small enough that the grid and the sweep's table fit in memory. Every
/// front end (CLI, Python) refuses more with the same bound.
pub const MAX_POINTS: usize = 100_000;

/// Checks the size `points` of a grid or a list of speeds (the argument named `what` in the
/// error) against [`MAX_POINTS`], before anything of that size is allocated.
pub fn check_points(what: &'static str, points: usize) -> Result<(), SimError> {
    if points <= MAX_POINTS {
        Ok(())
    } else {
        Err(SimError::Option { what, reason: format!("{points} must be in 0..={MAX_POINTS}") })
    }
}

/// The first item of `items` that an earlier one equals (found within the first few items
/// of a long list of few distinct values).
fn first_repeat<T: PartialEq + Copy>(items: &[T]) -> Option<T> {
    (1..items.len()).find(|&i| items[..i].contains(&items[i])).map(|i| items[i])
}

/// `points` speeds evenly spaced from `from` to `to` rad/s inclusive; more than
/// [`MAX_POINTS`] is an error ([`check_points`]).
pub fn linear_grid(from: f64, to: f64, points: usize) -> Result<Vec<f64>, SimError> {
    check_points("points", points)?;
    Ok(match points {
        0 => vec![],
        1 => vec![from],
        _ => (0..points).map(|i| from + (to - from) * i as f64 / (points - 1) as f64).collect(),
    })
}

impl SweepSpec {
    /// The (mode, compensation) pairs the sweep runs, in table order: every pair but servo
    /// with estimated-angle compensation, which exists in open loop only.
    pub fn pairs(&self) -> Vec<(Mode, Compensation)> {
        let mut out = Vec::new();
        for &mode in &self.modes {
            for &comp in &self.compensations {
                if check_mode_compensation(mode, comp).is_ok() {
                    out.push((mode, comp));
                }
            }
        }
        out
    }

    /// Number of runs in the sweep.
    pub fn runs(&self) -> usize {
        self.pairs().len() * self.speeds_rad_s.len()
    }

    /// Checks everything the sweep needs before anything is simulated, and builds the
    /// controller of every (mode, compensation) pair: the same hardware in both profiles
    /// ([`check_same_hardware`], naming them `motor_name` and `controller_name`), at least
    /// one mode, compensation and speed, none of them twice, at most [`MAX_POINTS`] speeds, every speed and the run shape ([`RunSpec::check`]
    /// at the lowest speed), the options ([`SimOptions::check`]), a table when the
    /// compensations include [`Compensation::Table`], and the controller configurations
    /// ([`Profile::controller_config`]). What it returns runs the sweep without checking
    /// again ([`CheckedSweep::run`]).
    pub fn validate<'a>(
        &'a self,
        motor: &'a Profile,
        motor_name: &str,
        controller: &Profile,
        controller_name: &str,
    ) -> Result<CheckedSweep<'a>, SimError> {
        check_same_hardware(motor, motor_name, controller, controller_name)?;
        let empty = |what: &'static str| Err(SimError::Option { what, reason: "the list is empty".to_string() });
        if self.modes.is_empty() {
            return empty("modes");
        }
        if self.compensations.is_empty() {
            return empty("compensations");
        }
        if self.speeds_rad_s.is_empty() {
            return empty("speeds");
        }
        check_points("speeds", self.speeds_rad_s.len())?;
        // Each mode and compensation once: a list repeats no (mode, compensation) pair, so
        // the number of runs stays within the distinct pairs times the speeds.
        if let Some(m) = first_repeat(&self.modes) {
            return Err(SimError::Option { what: "modes", reason: format!("{} is listed twice", m.name()) });
        }
        if let Some(c) = first_repeat(&self.compensations) {
            return Err(SimError::Option { what: "compensations", reason: format!("{} is listed twice", c.name()) });
        }
        if !self.modes.contains(&Mode::OpenLoop) {
            for &comp in &self.compensations {
                check_mode_compensation(Mode::Servo, comp)?;
            }
        }
        let nr = motor.motor.pole_pairs;
        for &w in &self.speeds_rad_s {
            check_speed(w, max_speed_rad_s(motor.drive.pwm_hz, nr))?;
        }
        // The longest electrical period is at the lowest speed: if that one fits, all do.
        let lowest = self.speeds_rad_s.iter().copied().fold(f64::INFINITY, |a, w| a.min(w.abs()));
        RunSpec { speed_rad_s: lowest, ..self.run }.check(motor.drive.pwm_hz, nr)?;
        self.options.check()?;
        if self.compensations.contains(&Compensation::Table) && self.table.is_none() {
            return Err(SimError::Option {
                what: "compensation",
                reason: "table compensation needs a table (--table FILE)".to_string(),
            });
        }
        let configs = self
            .pairs()
            .into_iter()
            .map(|(mode, comp)| Ok((mode, comp, controller.controller_config(mode, comp, self.table.as_ref())?)))
            .collect::<Result<_, SimError>>()?;
        Ok(CheckedSweep { motor, spec: self, configs })
    }
}

/// A sweep whose specification and profiles passed [`SweepSpec::validate`], with the
/// controller of each of its (mode, compensation) pairs.
#[derive(Clone, Debug)]
pub struct CheckedSweep<'a> {
    motor: &'a Profile,
    spec: &'a SweepSpec,
    configs: Vec<(Mode, Compensation, Config)>,
}

/// Runs the sweep of `motor` driven by a controller configured from `controller`: checks it
/// ([`SweepSpec::validate`], naming the profiles by their `name`), then runs it
/// ([`CheckedSweep::run`]).
pub fn sweep(
    motor: &Profile,
    controller: &Profile,
    spec: &SweepSpec,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<SweepRow>, SimError> {
    sweep_until(motor, controller, spec, tick, &|| false)
}

/// [`sweep`] with a cancellation hook: `stop` is asked before every control period
/// ([`CheckedSweep::run_until`]).
pub fn sweep_until(
    motor: &Profile,
    controller: &Profile,
    spec: &SweepSpec,
    tick: &(dyn Fn() + Sync),
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<Vec<SweepRow>, SimError> {
    spec.validate(motor, &motor.name, controller, &controller.name)?.run_until(tick, stop)
}

impl CheckedSweep<'_> {
    /// Runs the sweep; `tick` is called once per finished run (from any thread). Runs go
    /// [`LANES`] at a time in lock-step ([`crate::lockstep::run_lockstep`], one run per SIMD lane); a run
    /// that diverges makes the sweep fail with [`SimError::Diverged`] naming it. Rows come
    /// ordered by mode, then compensation, then speed; servo runs with estimated-angle
    /// compensation are not made ([`SweepSpec::pairs`]).
    pub fn run(&self, tick: &(dyn Fn() + Sync)) -> Result<Vec<SweepRow>, SimError> {
        self.run_until(tick, &|| false)
    }

    /// [`CheckedSweep::run`] that asks `stop` before every control period (from any
    /// thread) and, once it returns true, ends the sweep with [`SimError::Stopped`] within
    /// one period of each run in progress (a cancellation hook, e.g. for Ctrl-C).
    pub fn run_until(
        &self,
        tick: &(dyn Fn() + Sync),
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Result<Vec<SweepRow>, SimError> {
        let (motor, spec) = (self.motor, self.spec);
        let mut runs = Vec::new();
        for &(mode, comp, ref cfg) in &self.configs {
            for &w in &spec.speeds_rad_s {
                runs.push((mode, comp, cfg, w));
            }
        }
        let pwm = motor.drive.pwm_hz;
        // Groups of LANES runs go in lock-step (bit-identical to running each alone); a short
        // last group repeats its last run to fill the lanes and drops the copies' results.
        let groups: Vec<Result<Vec<Result<SweepRow, SimError>>, SimError>> = runs
            .par_chunks(LANES)
            .enumerate()
            .map(|(g, chunk)| {
                let lane = |j: usize| (g * LANES + j.min(chunk.len() - 1), chunk[j.min(chunk.len() - 1)]);
                let mut loops = Vec::with_capacity(LANES);
                let mut specs = Vec::with_capacity(LANES);
                for j in 0..LANES {
                    let (i, (_, _, cfg, w)) = lane(j);
                    let opts = SimOptions { seed: derived_seed(spec.options.seed, i as u64), ..spec.options };
                    // `validate` accepted this set-up; an error here would still be reported,
                    // not panicked on.
                    loops.push(ClosedLoop::with_config(motor, *cfg, &opts)?);
                    specs.push(RunSpec { speed_rad_s: w, ..spec.run });
                }
                let metrics = run_lockstep_while::<LANES>(&mut loops, &specs, pwm, stop)?;
                let rows = chunk
                    .iter()
                    .zip(metrics)
                    .map(|(&(mode, comp, _, w), m)| {
                        tick();
                        let m = m.map_err(|e| match e {
                            SimError::Diverged { t_s, what } => SimError::Diverged {
                                t_s,
                                what: format!("{} {} at {w} rad/s: {what}", mode.name(), comp.name()),
                            },
                            e => e,
                        })?;
                        Ok(SweepRow {
                            mode,
                            compensation: comp,
                            speed_cmd_rad_s: w,
                            vel_err_rms_rad_s: m.vel_err_rms_rad_s,
                            vel_err_pp_rad_s: m.vel_err_pp_rad_s,
                            lost_sync: m.lost_sync,
                        })
                    })
                    .collect();
                Ok(rows)
            })
            .collect();
        // The first error in table order, whatever thread met it first.
        let mut rows = Vec::with_capacity(runs.len());
        for group in groups {
            for row in group? {
                rows.push(row?);
            }
        }
        Ok(rows)
    }
}

/// The seed of run `index` of a batch with seed `base` (SplitMix64 of the two): deterministic
/// and independent of the number of threads. Sweeps seed their runs with it, and so do
/// the identification runs of `stepdamp-identify`.
pub fn derived_seed(base: u64, index: u64) -> u64 {
    let mut z = base.wrapping_add(index.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}
