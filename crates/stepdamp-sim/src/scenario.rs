//! Constant-speed runs from rest and their velocity-error metrics.
//!
//! A run starts at rest with the command at the rotor, holds the motor energised at
//! standstill for `dwell_s` (as a drive does when it is enabled before it moves; the
//! estimated-angle observer trims its resistance there), ramps the commanded speed
//! linearly to the target in `ramp_s`, holds it to `duration_s`, and measures `ω − ω_cmd` over the
//! last whole number of electrical periods that fit in `window_s` and start at least
//! [`SETTLE_S`] after the ramp (at least one period: [`RunSpec::check`] tells whether the run
//! is long enough for that). `lost_sync` is set when the rotor was ever more than half an
//! electrical period (π electrical rad, two full steps) from the command after the ramp
//! started: it has slipped past the unstable equilibrium. A run whose plant diverges
//! (a non-finite sample) is stopped with [`SimError::Diverged`].

use crate::closed_loop::{ClosedLoop, PeriodRecord};
use crate::metrics::{RunMetrics, VelocityErrorMeter};
use crate::options::SimError;
use std::ops::ControlFlow;

/// Largest commanded speed in rad/s a run of a motor with `pole_pairs` at `pwm_hz` accepts
/// (either sign): the controller's own limit ([`stepdamp_core::max_speed_rad_s`]; beyond it
/// the controller would clamp the command, and the run would measure against a speed that
/// was never commanded).
pub fn max_speed_rad_s(pwm_hz: f64, pole_pairs: u16) -> f64 {
    f64::from(stepdamp_core::max_speed_rad_s(pole_pairs, 1.0 / pwm_hz as f32))
}

/// Least time in s from the end of the ramp to the start of the measurement window.
pub const SETTLE_S: f64 = 0.05;

/// A constant-speed run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunSpec {
    /// Target speed in rad/s (sign = direction).
    pub speed_rad_s: f64,
    /// Standstill time with the holding current on before the ramp, s.
    pub dwell_s: f64,
    /// Ramp time from rest to the target in s.
    pub ramp_s: f64,
    /// Total simulated time in s.
    pub duration_s: f64,
    /// Longest measurement window at the end of the run in s.
    pub window_s: f64,
}

impl RunSpec {
    /// Standstill time of the default run shape, s: 50 ms energised at rest before the ramp,
    /// as a drive is enabled before it moves; the estimated-angle observer trims its
    /// resistance estimate there (README, "Resistance trim").
    pub const DWELL_S: f64 = 0.05;
    /// Ramp time of the default run shape, s: rest to the target speed in 0.1 s, short
    /// against the run, so that most of it is spent at the target speed.
    pub const RAMP_S: f64 = 0.1;
    /// Total time of the default run, s: the README sweep's 1.5 s runs.
    pub const DURATION_S: f64 = 1.5;
    /// Longest measurement window of the default run shape, s: the last 0.5 s of a 1.5 s
    /// run; a shorter run is measured over its last third ([`RunSpec::window_for`]).
    pub const WINDOW_MAX_S: f64 = 0.5;

    /// The default sweep run: [`RunSpec::for_duration`] of [`RunSpec::DURATION_S`] (50 ms
    /// at standstill, 0.1 s ramp, 1.5 s in all, measured over the last ≤ 0.5 s).
    pub fn at(speed_rad_s: f64) -> Self {
        Self::for_duration(speed_rad_s, Self::DURATION_S)
    }

    /// The run shape of the CLI's `sweep` and `simulate`, the study and the Python binding
    /// for a run of `duration_s` s at `speed_rad_s` rad/s: [`RunSpec::DWELL_S`] at
    /// standstill, a [`RunSpec::RAMP_S`] ramp, measured over [`RunSpec::window_for`]
    /// `duration_s`.
    pub fn for_duration(speed_rad_s: f64, duration_s: f64) -> Self {
        RunSpec {
            speed_rad_s,
            dwell_s: Self::DWELL_S,
            ramp_s: Self::RAMP_S,
            duration_s,
            window_s: Self::window_for(duration_s),
        }
    }

    /// Measurement window of the default run shape for a run of `duration_s` s: its last
    /// third, at most [`RunSpec::WINDOW_MAX_S`].
    pub fn window_for(duration_s: f64) -> f64 {
        (duration_s / 3.0).min(Self::WINDOW_MAX_S)
    }

    /// Commanded speed at time `t` s.
    #[inline]
    pub fn speed_at(&self, t: f64) -> f64 {
        let t = t - self.dwell_s;
        if t <= 0.0 {
            0.0
        } else if t >= self.ramp_s {
            self.speed_rad_s
        } else {
            self.speed_rad_s * t / self.ramp_s
        }
    }

    /// Number of control periods in the run and the index where measurement starts: the
    /// last whole number of electrical periods (at least one) within `window_s` and after
    /// the ramp and [`SETTLE_S`]. For a run that fails [`RunSpec::check`] the window is one
    /// electrical period, cut short at the end of the ramp.
    pub fn periods(&self, pwm_hz: f64, pole_pairs: u16) -> (usize, usize) {
        let (n, settled, te) = self.layout(pwm_hz, pole_pairs);
        let ramp = ((self.dwell_s + self.ramp_s) * pwm_hz).ceil() as usize;
        let window = (self.window_s * pwm_hz).min(n.saturating_sub(settled) as f64);
        let whole = (window / te).floor().max(1.0);
        let w = ((whole * te).round() as usize).min(n.saturating_sub(ramp)).max(1).min(n);
        (n, n - w)
    }

    /// Periods in the run, the first period after the ramp and the settling time, and the
    /// electrical period in control periods.
    fn layout(&self, pwm_hz: f64, pole_pairs: u16) -> (usize, usize, f64) {
        let n = (self.duration_s * pwm_hz).round() as usize;
        let settled = ((self.dwell_s + self.ramp_s + SETTLE_S) * pwm_hz - 1e-9).ceil().max(0.0) as usize;
        let te = std::f64::consts::TAU / (f64::from(pole_pairs) * self.speed_rad_s.abs().max(1e-12)) * pwm_hz;
        (n, settled, te)
    }

    /// Checks the run before it is simulated: a finite non-zero speed within
    /// ±[`max_speed_rad_s`], finite non-negative times, and a duration long enough that at
    /// least one whole electrical period fits after the standstill, the ramp and
    /// [`SETTLE_S`] (the error says the least duration that does).
    pub fn check(&self, pwm_hz: f64, pole_pairs: u16) -> Result<(), SimError> {
        let bad = |what: &'static str, reason: String| Err(SimError::Option { what, reason });
        let w = self.speed_rad_s;
        check_speed(w, max_speed_rad_s(pwm_hz, pole_pairs))?;
        for (what, v) in [("dwell", self.dwell_s), ("ramp", self.ramp_s), ("measurement window", self.window_s)] {
            if !(v.is_finite() && (0.0..=1e6).contains(&v)) {
                return bad(what, format!("{v} s must be a finite time ≥ 0 s"));
            }
        }
        if !(self.duration_s > 0.0 && self.duration_s <= 1e6) {
            return bad("duration", format!("{} s must be a finite time > 0 s", self.duration_s));
        }
        if !(pwm_hz.is_finite() && pwm_hz > 0.0 && pole_pairs > 0) {
            return bad("drive", format!("PWM {pwm_hz} Hz and {pole_pairs} pole pairs must be > 0"));
        }
        let (n, settled, te) = self.layout(pwm_hz, pole_pairs);
        if (n.saturating_sub(settled) as f64) < te {
            let need = (settled as f64 + te.ceil()) / pwm_hz;
            let need_ms = (need * 1e3).ceil() / 1e3;
            return bad(
                "duration",
                format!(
                    "{} s is too short to measure at {w} rad/s: after the {} s standstill, {} s ramp and {SETTLE_S} s \
                     settling it must hold one whole electrical period ({:.4} s); the duration must be at least {need_ms} s",
                    self.duration_s,
                    self.dwell_s,
                    self.ramp_s,
                    te / pwm_hz
                ),
            );
        }
        Ok(())
    }
}

/// Checks a commanded speed: non-zero, finite, within ±`max` rad/s ([`max_speed_rad_s`]).
pub fn check_speed(w: f64, max: f64) -> Result<(), SimError> {
    if w.is_finite() && w != 0.0 && w.abs() <= max {
        Ok(())
    } else {
        Err(SimError::Option {
            what: "speed",
            reason: format!(
                "{w} rad/s must be non-zero, finite and within ±{max:.1} rad/s (the controller's limit: a quarter \
                 electrical turn per control period)"
            ),
        })
    }
}

/// Runs `spec` on `lp` (fresh from [`ClosedLoop::new`]); `observe` sees every period.
/// A run whose plant state becomes infinite or NaN is stopped there with
/// [`SimError::Diverged`] (the diverged period is not observed).
pub fn run(
    lp: &mut ClosedLoop,
    spec: &RunSpec,
    pwm_hz: f64,
    mut observe: impl FnMut(usize, &PeriodRecord),
) -> Result<RunMetrics, SimError> {
    run_while(lp, spec, pwm_hz, |k, rec| {
        observe(k, rec);
        ControlFlow::Continue(())
    })
}

/// [`run`] whose `observe` may end the run early: after a period it returns
/// [`ControlFlow::Break`] for, the run stops with [`SimError::Stopped`] (a cancellation
/// hook, e.g. for Ctrl-C; the periods before are the same as [`run`]'s).
pub fn run_while(
    lp: &mut ClosedLoop,
    spec: &RunSpec,
    pwm_hz: f64,
    mut observe: impl FnMut(usize, &PeriodRecord) -> ControlFlow<()>,
) -> Result<RunMetrics, SimError> {
    let mut meter = VelocityErrorMeter::new(spec.periods(pwm_hz, lp.pole_pairs()), pwm_hz, lp.pole_pairs());
    for k in 0..meter.periods() {
        let w_cmd = spec.speed_at(meter.time(k));
        let rec = lp.period(w_cmd);
        // Measured against the speed the controller was commanded (f32, within its limit
        // by `check`), not the f64 one asked for.
        let w_ctl = f64::from(lp.controller_state().speed_command_rad_s());
        meter.add(k, w_ctl, &rec)?;
        if observe(k, &rec).is_break() {
            return Err(SimError::Stopped { t_s: meter.time(k) });
        }
    }
    Ok(meter.finish())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Compensation, Profile, SimOptions};
    use stepdamp_core::Mode;

    #[test]
    fn a_run_too_short_for_one_settled_electrical_period_is_rejected_with_the_least_duration() {
        let p = Profile::preset("patent-motor").unwrap();
        let (pwm, nr) = (p.drive.pwm_hz, p.motor.pole_pairs);
        // 2 rad/s: one electrical period is 2π/100 = 62.8 ms; 0.2 s leaves 0 s after the
        // 0.05 s standstill, 0.1 s ramp and 0.05 s settling.
        let spec = RunSpec { duration_s: 0.2, window_s: 0.07, ..RunSpec::at(2.0) };
        let e = spec.check(pwm, nr).unwrap_err();
        assert!(matches!(e, SimError::Option { what: "duration", .. }), "{e:?}");
        let msg = e.to_string();
        assert!(msg.contains("at least 0.263 s") && msg.contains("electrical period"), "{msg}");
        // The least duration it names passes, and measures one whole electrical period.
        let ok = RunSpec { duration_s: 0.263, ..spec };
        ok.check(pwm, nr).unwrap();
        let (n, start) = ok.periods(pwm, nr);
        let te = std::f64::consts::TAU / (f64::from(nr) * 2.0) * pwm;
        assert!(((n - start) as f64 - te).abs() <= 0.5, "{} periods vs {te}", n - start);
        assert!(start as f64 >= (0.05 + 0.1 + SETTLE_S) * pwm - 1e-6);
        // A very low speed needs a long run.
        let e = RunSpec::at(0.01).check(pwm, nr).unwrap_err().to_string();
        assert!(e.contains("at least 12.767 s"), "{e}");
        RunSpec { duration_s: 12.767, ..RunSpec::at(0.01) }.check(pwm, nr).unwrap();
    }

    #[test]
    fn nonsense_runs_are_rejected() {
        let p = Profile::preset("patent-motor").unwrap();
        let (pwm, nr) = (p.drive.pwm_hz, p.motor.pole_pairs);
        for (spec, what) in [
            (RunSpec::at(0.0), "speed"),
            (RunSpec::at(f64::NAN), "speed"),
            (RunSpec::at(-max_speed_rad_s(pwm, nr) * 1.01), "speed"),
            (RunSpec::at(700.0), "speed"),
            (RunSpec { ramp_s: -1.0, ..RunSpec::at(5.0) }, "ramp"),
            (RunSpec { duration_s: f64::INFINITY, ..RunSpec::at(5.0) }, "duration"),
        ] {
            let e = spec.check(pwm, nr).unwrap_err();
            assert!(matches!(e, SimError::Option { what: w, .. } if w == what), "{spec:?}: {e:?}");
        }
        RunSpec::at(-max_speed_rad_s(pwm, nr)).check(pwm, nr).unwrap();
        RunSpec::at(628.0).check(pwm, nr).unwrap();
        RunSpec::at(1.0).check(pwm, nr).unwrap();
    }

    #[test]
    fn the_default_run_shape_measures_the_last_third_of_a_short_run_and_the_last_half_second_of_a_long_one() {
        assert_eq!(RunSpec::at(3.0), RunSpec::for_duration(3.0, RunSpec::DURATION_S));
        assert_eq!(RunSpec::at(3.0).window_s, 0.5);
        let short = RunSpec::for_duration(-2.0, 0.6);
        assert_eq!((short.speed_rad_s, short.dwell_s, short.ramp_s, short.duration_s), (-2.0, 0.05, 0.1, 0.6));
        assert!((short.window_s - 0.2).abs() < 1e-15);
        assert_eq!(RunSpec::for_duration(1.0, 30.0).window_s, RunSpec::WINDOW_MAX_S);
        assert_eq!(RunSpec::window_for(1.5), RunSpec::WINDOW_MAX_S);
    }

    #[test]
    fn the_default_window_is_whole_electrical_periods_after_settling() {
        let p = Profile::preset("patent-motor").unwrap();
        let (pwm, nr) = (p.drive.pwm_hz, p.motor.pole_pairs);
        for w in [1.0, 4.22, 8.4, 16.9, 40.0] {
            let spec = RunSpec::at(w);
            let (n, start) = spec.periods(pwm, nr);
            let te = std::f64::consts::TAU / (f64::from(nr) * w) * pwm;
            let k = (n - start) as f64 / te;
            assert!((k - k.round()).abs() * te <= 0.5 && k.round() >= 1.0, "{w}: {k} periods");
            assert!((n - start) as f64 <= spec.window_s * pwm + 0.5);
        }
    }

    #[test]
    fn a_diverged_run_stops_with_the_time_and_the_variable() {
        let p = Profile::preset("patent-motor").unwrap();
        let mut lp = ClosedLoop::new(&p, &p, Mode::OpenLoop, Compensation::Off, &SimOptions::default()).unwrap();
        let spec = RunSpec { duration_s: 0.3, window_s: 0.1, ..RunSpec::at(5.0) };
        let mut seen = 0;
        // 10 periods run normally, then the rotor is kicked to a speed it cannot have.
        for _ in 0..10 {
            lp.period(0.0);
        }
        lp.kick_rotor(0.0, f64::INFINITY);
        let e = run(&mut lp, &spec, p.drive.pwm_hz, |_, _| seen += 1).unwrap_err();
        assert!(matches!(e, SimError::Diverged { t_s, .. } if t_s == 0.0), "{e:?}");
        assert_eq!(e.to_string(), "the simulation diverged at t = 0 s (rotor speed ω = inf rad/s)");
        assert_eq!(seen, 0, "the diverged period was observed");
        // A load torque no motor could meet: it diverges once the command moves (the load
        // opposes travel, so at rest there is none), and says when.
        let opts = SimOptions { load_torque_nm: 1e300, ..SimOptions::default() };
        let mut lp = ClosedLoop::new(&p, &p, Mode::OpenLoop, Compensation::Off, &opts).unwrap();
        let e = run(&mut lp, &spec, p.drive.pwm_hz, |_, _| {}).unwrap_err();
        let &SimError::Diverged { t_s, .. } = &e else { panic!("{e:?}") };
        assert!(t_s > spec.dwell_s && t_s < spec.dwell_s + 0.01, "{t_s}");
        assert!(e.to_string().starts_with("the simulation diverged at t = 0.05"), "{e}");
    }
}
