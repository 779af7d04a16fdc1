//! Constant-speed runs from rest and their velocity-error metrics.
//!
//! A run starts at rest with the command at the rotor, holds the motor energised at
//! standstill for `dwell_s` (as a drive does when it is enabled before it moves; the
//! estimated-angle observer trims its resistance there), ramps the commanded speed
//! linearly to the target in `ramp_s`, holds it to `duration_s`, and measures `ω − ω_cmd` over the
//! last whole number of electrical periods that fit in `window_s` (at least one, if the
//! run is long enough after the ramp). `lost_sync` is set when the rotor was ever more
//! than half an electrical period (π electrical rad, two full steps) from the command
//! after the ramp started: it has slipped past the unstable equilibrium.

use crate::closed_loop::{ClosedLoop, PeriodRecord};

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
    /// The default sweep run: 50 ms at standstill, 0.1 s ramp, 1.5 s in all, measured
    /// over the last ≤ 0.5 s.
    pub fn at(speed_rad_s: f64) -> Self {
        RunSpec { speed_rad_s, dwell_s: 0.05, ramp_s: 0.1, duration_s: 1.5, window_s: 0.5 }
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

    /// Number of control periods in the run and the index where measurement starts.
    pub fn periods(&self, pwm_hz: f64, pole_pairs: u16) -> (usize, usize) {
        let n = (self.duration_s * pwm_hz).round() as usize;
        let ramp = ((self.dwell_s + self.ramp_s) * pwm_hz).ceil() as usize;
        let te = std::f64::consts::TAU / (f64::from(pole_pairs) * self.speed_rad_s.abs().max(1e-12));
        let whole = (self.window_s / te).floor().max(1.0);
        let w = ((whole * te * pwm_hz).round() as usize).min(n.saturating_sub(ramp)).max(1).min(n);
        (n, n - w)
    }
}

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

/// Runs `spec` on `lp` (fresh from [`ClosedLoop::new`]); `observe` sees every period.
pub fn run(
    lp: &mut ClosedLoop,
    spec: &RunSpec,
    pwm_hz: f64,
    mut observe: impl FnMut(usize, &PeriodRecord),
) -> RunMetrics {
    let nr = lp.pole_pairs();
    let (n, start) = spec.periods(pwm_hz, nr);
    let ts = 1.0 / pwm_hz;
    let (mut sum2, mut lo, mut hi) = (0.0, f64::INFINITY, f64::NEG_INFINITY);
    let mut max_angle: f64 = 0.0;
    for k in 0..n {
        let t = k as f64 * ts;
        let w_cmd = spec.speed_at(t);
        let rec = lp.period(w_cmd);
        // The command the controller used this period, against the sampled rotor.
        let theta_cmd = rec.signals.theta_cmd.mechanical_rad_f64(nr);
        let angle = (f64::from(nr) * (theta_cmd - rec.plant.theta)).abs();
        // A diverged (NaN) plant counts as lost sync.
        max_angle = if angle.is_nan() { f64::INFINITY } else { max_angle.max(angle) };
        if k >= start {
            let e = rec.plant.omega - w_cmd;
            sum2 += e * e;
            lo = lo.min(e);
            hi = hi.max(e);
        }
        observe(k, &rec);
    }
    let m = (n - start) as f64;
    RunMetrics {
        vel_err_rms_rad_s: (sum2 / m).sqrt(),
        vel_err_pp_rad_s: hi - lo,
        lost_sync: max_angle > std::f64::consts::PI,
        max_load_angle_e_rad: max_angle,
    }
}
