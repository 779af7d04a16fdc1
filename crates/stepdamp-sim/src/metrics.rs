//! A run's velocity-error metrics ([`RunMetrics`]) and the meter that accumulates them
//! period by period, shared by single runs ([`crate::scenario::run`]) and lock-step runs
//! ([`crate::lockstep::run_lockstep`]), with the divergence stop of both.

use crate::closed_loop::PeriodRecord;
use crate::options::SimError;
use crate::plant::PlantState;
use stepdamp_core::Position;
use stepdamp_core::angle::UNITS_PER_ELECTRICAL_REV;

/// Velocity-error metrics of a run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RunMetrics {
    /// RMS of `ω − ω_cmd` over the window in rad/s.
    pub vel_err_rms_rad_s: f64,
    /// Peak-to-peak of `ω − ω_cmd` over the window in rad/s.
    pub vel_err_pp_rad_s: f64,
    /// The rotor slipped (more than π electrical rad from the command).
    pub lost_sync: bool,
    /// Largest `|Nr(θ_cmd − θ)|` after the start, electrical rad.
    pub max_load_angle_e_rad: f64,
}

/// Electrical rad per unit of the controller's fixed-point position.
const RAD_PER_UNIT: f64 = std::f64::consts::TAU / UNITS_PER_ELECTRICAL_REV;

/// Measures one run's velocity error period by period and gives its [`RunMetrics`]: the
/// RMS and peak-to-peak of `ω − ω_cmd` over the measurement window, the largest load
/// angle, and the divergence stop ([`SimError::Diverged`]).
#[derive(Clone, Debug)]
pub(crate) struct VelocityErrorMeter {
    n: usize,
    start: usize,
    nr: u16,
    ts: f64,
    sum2: f64,
    lo: f64,
    hi: f64,
    max_angle: f64,
}

impl VelocityErrorMeter {
    /// The meter of a run of `n` control periods measured from period `start` on (what
    /// [`crate::scenario::RunSpec::periods`] gives), on a drive at `pwm_hz` with `nr` pole pairs.
    pub(crate) fn new((n, start): (usize, usize), pwm_hz: f64, nr: u16) -> Self {
        VelocityErrorMeter {
            n,
            start,
            nr,
            ts: 1.0 / pwm_hz,
            sum2: 0.0,
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
            max_angle: 0.0,
        }
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

    /// [`VelocityErrorMeter::add`] from the two fields of the record it reads: the sampled plant and
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
