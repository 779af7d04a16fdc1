//! Several runs in lock-step: each lane has its own controller, sensors, noise and speed
//! profile; their plants are integrated together over the [`crate::lanes`] SIMD lanes.
//! A lane's result is bit-identical to running it alone with [`crate::scenario::run`]
//! (tested): the controllers are stepped one by one as in a single run, and the plant
//! integrator has no cross-lane arithmetic.
//!
//! Also home of the per-run metrics accumulator (`Window`) and the divergence stop that
//! single runs and lock-step runs share.

use crate::closed_loop::{ClosedLoop, PeriodRecord, SimError};
use crate::lanes::{Integrator, StateLanes};
use crate::plant::PlantState;
use crate::scenario::{RunMetrics, RunSpec};
use stepdamp_core::Position;
use stepdamp_core::angle::UNITS_PER_ELECTRICAL_REV;

/// Electrical rad per unit of the controller's fixed-point position.
const RAD_PER_UNIT: f64 = std::f64::consts::TAU / UNITS_PER_ELECTRICAL_REV;

/// Velocity-error metrics of one run, accumulated period by period.
#[derive(Clone, Debug)]
pub(crate) struct Window {
    n: usize,
    start: usize,
    nr: u16,
    ts: f64,
    sum2: f64,
    lo: f64,
    hi: f64,
    max_angle: f64,
}

impl Window {
    /// The accumulator of `spec` on a drive at `pwm_hz` with `nr` pole pairs.
    pub(crate) fn new(spec: &RunSpec, pwm_hz: f64, nr: u16) -> Self {
        let (n, start) = spec.periods(pwm_hz, nr);
        Window { n, start, nr, ts: 1.0 / pwm_hz, sum2: 0.0, lo: f64::INFINITY, hi: f64::NEG_INFINITY, max_angle: 0.0 }
    }

    /// Periods in the run.
    pub(crate) fn periods(&self) -> usize {
        self.n
    }

    /// Start time of period `k` in s.
    pub(crate) fn time(&self, k: usize) -> f64 {
        k as f64 * self.ts
    }

    /// Adds period `k`, run with command `w_cmd` rad/s. A non-finite sampled plant state
    /// stops the run: [`SimError::Diverged`] at the period's time.
    #[inline]
    pub(crate) fn add(&mut self, k: usize, w_cmd: f64, rec: &PeriodRecord) -> Result<(), SimError> {
        self.add_sample(k, w_cmd, rec.plant, rec.signals.theta_cmd)
    }

    /// [`Window::add`] from the two fields of the record it reads: the sampled plant and
    /// the controller's command angle. The lock-step loop passes them by value, so the
    /// record itself is never built in memory (its copy from the controller's output,
    /// written field by field and read back whole, stalled store-to-load forwarding).
    #[inline(always)]
    pub(crate) fn add_sample(
        &mut self,
        k: usize,
        w_cmd: f64,
        plant: PlantState,
        theta_cmd: Position,
    ) -> Result<(), SimError> {
        check_finite(self.time(k), plant)?;
        // The command the controller used this period, against the sampled rotor.
        // Electrical: the command's fixed-point angle less Nr·θ (no division per period).
        let theta_cmd_e = theta_cmd.0 as f64 * RAD_PER_UNIT;
        let angle = (theta_cmd_e - f64::from(self.nr) * plant.theta).abs();
        self.max_angle = self.max_angle.max(angle);
        if k >= self.start {
            let e = plant.omega - w_cmd;
            self.sum2 += e * e;
            self.lo = self.lo.min(e);
            self.hi = self.hi.max(e);
        }
        Ok(())
    }

    /// The metrics of the run.
    pub(crate) fn finish(&self) -> RunMetrics {
        let lost_sync = self.max_angle > std::f64::consts::PI;
        if self.n == self.start {
            // Nothing measured (a run that fails `RunSpec::check`).
            return RunMetrics {
                vel_err_rms_rad_s: f64::NAN,
                vel_err_pp_rad_s: f64::NAN,
                lost_sync,
                max_load_angle_e_rad: self.max_angle,
            };
        }
        RunMetrics {
            vel_err_rms_rad_s: (self.sum2 / (self.n - self.start) as f64).sqrt(),
            vel_err_pp_rad_s: self.hi - self.lo,
            lost_sync,
            max_load_angle_e_rad: self.max_angle,
        }
    }
}

/// Largest phase current in A a simulation may reach before it counts as diverged: a
/// thousand times the largest current of any stepper drive (1 kA), far beyond what the
/// plant model means but well below where `f64` arithmetic breaks down.
pub const DIVERGED_CURRENT_A: f64 = 1.0e6;

/// Largest rotor speed in rad/s a simulation may reach before it counts as diverged (about
/// 10 million rpm): over a thousand times the fastest command a run accepts
/// ([`crate::scenario::max_speed_rad_s`], 628 rad/s for the patent motor at 20 kHz).
pub const DIVERGED_SPEED_RAD_S: f64 = 1.0e6;

/// [`SimError::Diverged`] at `t_s` naming the first variable of `x` that is NaN, infinite
/// or beyond [`DIVERGED_CURRENT_A`] / [`DIVERGED_SPEED_RAD_S`] (a plant that left the
/// physical range does not come back: its metrics would be overflowed numbers).
///
/// The test runs every period of every run: it is inlined, and the naming of the variable
/// is a separate cold function.
#[inline(always)]
fn check_finite(t_s: f64, x: PlantState) -> Result<(), SimError> {
    let (ci, cw) = (DIVERGED_CURRENT_A, DIVERGED_SPEED_RAD_S);
    // `<=` is false for NaN.
    if x.i_a.abs() <= ci && x.i_b.abs() <= ci && x.omega.abs() <= cw && x.theta.is_finite() {
        return Ok(());
    }
    Err(diverged(t_s, x))
}

/// The [`SimError::Diverged`] of a state that failed [`check_finite`].
#[cold]
#[inline(never)]
fn diverged(t_s: f64, x: PlantState) -> SimError {
    let (ci, cw) = (DIVERGED_CURRENT_A, DIVERGED_SPEED_RAD_S);
    let vars = [
        (x.i_a, ci, "phase A current i_a", "A"),
        (x.i_b, ci, "phase B current i_b", "A"),
        (x.theta, f64::INFINITY, "rotor angle θ", "rad"),
        (x.omega, cw, "rotor speed ω", "rad/s"),
    ];
    let (v, limit, name, unit) =
        vars.into_iter().find(|&(v, lim, _, _)| v.is_nan() || v.abs() > lim).unwrap_or(vars[3]);
    let what = if v.is_finite() {
        format!("{name} = {v:e} {unit}, beyond ±{limit:e} {unit}")
    } else {
        format!("{name} = {v} {unit}")
    };
    SimError::Diverged { t_s, what }
}

/// Runs `specs[i]` on `loops[i]` (each fresh from [`ClosedLoop::new`]) for every lane
/// `i < N`, integrating the plants together. Every loop must simulate the same motor with
/// the same step (`substeps`, PWM frequency) and every run have the same length: only the
/// controller, options (seed, noise, load) and speed may differ. A lane that diverges
/// gets its [`SimError::Diverged`] and the others go on.
///
/// The outer error is for loops or runs that cannot go in lock-step.
pub fn run_lockstep<const N: usize>(
    loops: &mut [ClosedLoop],
    specs: &[RunSpec],
    pwm_hz: f64,
) -> Result<Vec<Result<RunMetrics, SimError>>, SimError> {
    let mismatch = |reason: &str| SimError::Option { what: "lock-step runs", reason: reason.to_string() };
    if loops.len() != N || specs.len() != N {
        return Err(mismatch(&format!("{} loops and {} runs for {N} lanes", loops.len(), specs.len())));
    }
    let first = &loops[0];
    let mut integrator = Integrator::<N>::new(first.plant());
    let same_step = |l: &ClosedLoop| l.h == first.h && l.band == first.band && l.substeps == first.substeps;
    if !loops.iter().all(|l| same_step(l) && integrator.is_for(l.plant()) && l.pole_pairs() == first.pole_pairs()) {
        return Err(mismatch("the loops simulate different motors or integration steps"));
    }
    let nr = first.pole_pairs();
    let (h, band, substeps) = (first.h, first.band, first.substeps);
    let mut windows: Vec<Window> = specs.iter().map(|s| Window::new(s, pwm_hz, nr)).collect();
    let n = windows[0].periods();
    if windows.iter().any(|w| w.periods() != n) {
        return Err(mismatch("the runs differ in length"));
    }
    let mut failed: Vec<Option<SimError>> = (0..N).map(|_| None).collect();
    let (mut va, mut vb, mut load) = ([0.0; N], [0.0; N], [0.0; N]);
    // The plants live in the lanes; each loop gets a copy of its lane to sample.
    let mut x = StateLanes::<N>::from_states(&std::array::from_fn(|i| loops[i].x));
    for k in 0..n {
        for i in 0..N {
            let w_cmd = specs[i].speed_at(windows[i].time(k));
            let (rec, a, b) = loops[i].control(w_cmd);
            (va[i], vb[i], load[i]) = (a, b, loops[i].load_torque_now());
            if failed[i].is_none() {
                // Against the speed the controller was commanded (as `scenario::run`).
                let w_ctl = f64::from(loops[i].controller_state().speed_command_rad_s());
                if let Err(e) = windows[i].add_sample(k, w_ctl, rec.plant, rec.signals.theta_cmd) {
                    failed[i] = Some(e);
                }
            }
        }
        if failed.iter().all(Option::is_some) {
            break;
        }
        for _ in 0..substeps {
            integrator.rk4(&mut x, &va, &vb, &load, h, band);
        }
        for (i, lp) in loops.iter_mut().enumerate() {
            lp.x = x.lane(i);
        }
    }
    Ok(windows
        .iter()
        .zip(failed)
        .map(|(w, f)| match f {
            Some(e) => Err(e),
            None => Ok(w.finish()),
        })
        .collect())
}
