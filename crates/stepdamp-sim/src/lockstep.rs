//! Several runs in lock-step: each lane has its own controller, sensors, noise and speed
//! profile; their plants are integrated together over the [`crate::lanes`] SIMD lanes.
//! A lane's result is bit-identical to running it alone with [`crate::scenario::run`]
//! (tested): the controllers are stepped one by one as in a single run, and the plant
//! integrator has no cross-lane arithmetic.

use crate::closed_loop::ClosedLoop;
use crate::lanes::{Integrator, StateLanes};
use crate::metrics::{RunMetrics, VelocityErrorMeter};
use crate::options::SimError;
use crate::scenario::RunSpec;

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
    run_lockstep_while::<N>(loops, specs, pwm_hz, &|| false)
}

/// [`run_lockstep`] that asks `stop` before every control period and ends all the runs
/// with the outer error [`SimError::Stopped`] when it returns true (a cancellation hook,
/// e.g. for Ctrl-C; it does not change the periods that are run).
pub fn run_lockstep_while<const N: usize>(
    loops: &mut [ClosedLoop],
    specs: &[RunSpec],
    pwm_hz: f64,
    stop: &(dyn Fn() -> bool + Sync),
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
    let mut meters: Vec<VelocityErrorMeter> =
        specs.iter().map(|s| VelocityErrorMeter::new(s.periods(pwm_hz, nr), pwm_hz, nr)).collect();
    let n = meters[0].periods();
    if meters.iter().any(|w| w.periods() != n) {
        return Err(mismatch("the runs differ in length"));
    }
    let mut failed: Vec<Option<SimError>> = (0..N).map(|_| None).collect();
    let (mut va, mut vb, mut load) = ([0.0; N], [0.0; N], [0.0; N]);
    // The plants live in the lanes; each loop gets a copy of its lane to sample.
    let mut x = StateLanes::<N>::from_states(&std::array::from_fn(|i| loops[i].x));
    for k in 0..n {
        if stop() {
            return Err(SimError::Stopped { t_s: meters[0].time(k) });
        }
        for i in 0..N {
            let w_cmd = specs[i].speed_at(meters[i].time(k));
            let (rec, a, b) = loops[i].control(w_cmd);
            (va[i], vb[i], load[i]) = (a, b, loops[i].load_torque_now());
            if failed[i].is_none() {
                // Against the speed the controller was commanded (as `scenario::run`).
                let w_ctl = f64::from(loops[i].controller_state().speed_command_rad_s());
                if let Err(e) = meters[i].add_sample(k, w_ctl, rec.plant, rec.signals.theta_cmd) {
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
    Ok(meters
        .iter()
        .zip(failed)
        .map(|(w, f)| match f {
            Some(e) => Err(e),
            None => Ok(w.finish()),
        })
        .collect())
}
