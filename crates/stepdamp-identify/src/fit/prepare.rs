//! The logs made ready for the fit: the angle, the kinematics, the steady window and the
//! samples where the rotor moves.

use super::design::Periodic;
use super::thresholds::{MIN_STEADY_SAMPLES, STEADY_SPEED_FRACTION};
use super::{FitError, FitOptions};
use crate::kinematics::{self, Kinematics};
use crate::log::RunLog;
use std::cell::OnceCell;
use std::f64::consts::TAU;

/// A log with its kinematics and the window of it that is used.
pub(super) struct Prepared<'a> {
    pub(super) log: &'a RunLog,
    /// The angle the fit uses, rad: edge-timed or the logged `θ_fb` ([`crate::stick`]).
    pub(super) theta: Vec<f64>,
    /// Samples where the rotor moves (not stuck, not within the margin of a stick).
    pub(super) keep: Vec<bool>,
    /// Whether the drive reacts to each encoder count ([`crate::conditions::reacts_to_counts`]).
    pub(super) reacts_to_counts: bool,
    pub(super) kin: Kinematics,
    /// Used window `[lo, hi)`: steady running, away from the filter's start-up.
    pub(super) lo: usize,
    pub(super) hi: usize,
    /// Mean speed over the window, rad/s.
    pub(super) speed: f64,
    /// Electrical periods over the window.
    pub(super) periods: f64,
    /// Electrical periods' worth of the window's samples the fit uses ([`Prepared::moves`]):
    /// `periods` times the share of the window used (see [`crate::conditions`]).
    pub(super) moving_periods: f64,
    /// Encoder steps against the direction of travel in the window, and all steps.
    pub(super) back_steps: usize,
    pub(super) steps: usize,
    /// `sin(k·Nr·θ), cos(k·Nr·θ)` for each of the fit's orders `k` at each sample of the
    /// window, `2·orders` values per sample ([`Prepared::harmonics_at`]): every pass of the
    /// fit reads the same values, so they are computed once.
    harmonics: Vec<f64>,
    /// The periodic part of `dω/dt`, the instrument for `J` ([`super::design`]): the same
    /// in every pass that fits `J`, so solved once, when first needed.
    pub(super) periodic: OnceCell<Option<Periodic>>,
}

impl Prepared<'_> {
    /// Whether the fit uses sample `i` (in `lo..hi`): the rotor moves there at least
    /// [`FitOptions::min_speed_fraction`] of the mean speed in its direction, and is not
    /// stuck ([`crate::stick`]). A speed that is not a number is not "too slow": the row is
    /// built and its torque reported as not finite.
    #[inline]
    pub(super) fn moves(&self, i: usize, min_speed_fraction: f64) -> bool {
        let too_slow = self.kin.omega_rad_s[i] * self.speed.signum() < min_speed_fraction * self.speed.abs();
        !too_slow && self.keep[i]
    }

    /// `sin(k·Nr·θ), cos(k·Nr·θ)` per order of the fit at sample `i` (in `lo..hi`), in the
    /// order of [`FitOptions::orders`].
    #[inline]
    pub(super) fn harmonics_at(&self, i: usize) -> &[f64] {
        let m = self.harmonics.len() / (self.hi - self.lo);
        &self.harmonics[(i - self.lo) * m..(i - self.lo + 1) * m]
    }
}

/// `sin, cos(k·Nr·θ)` of each order for each angle in `theta`, rad, row by row.
fn harmonics(theta: &[f64], nr: f64, orders: &[u16]) -> Vec<f64> {
    let mut out = Vec::with_capacity(theta.len() * 2 * orders.len());
    for &th in theta {
        let te = nr * th;
        for &k in orders {
            let (s, c) = (f64::from(k) * te).sin_cos();
            out.push(s);
            out.push(c);
        }
    }
    out
}

pub(super) fn prepare<'a>(log: &'a RunLog, o: &FitOptions, kmax: u16) -> Result<Prepared<'a>, FitError> {
    let n = log.len();
    let nr = f64::from(o.pole_pairs);
    let (_, _, w_all) = kinematics::line_fit(&log.t_s, &log.theta_fb_rad);
    let too_short = |needed: usize| FitError::TooShort {
        log: log.source.clone(),
        samples: n,
        duration_s: log.duration_s(),
        speed: w_all,
        needed,
    };
    if n < MIN_STEADY_SAMPLES {
        return Err(too_short(MIN_STEADY_SAMPLES));
    }
    let moved = w_all.abs() * log.duration_s() * nr;
    if !moved.is_finite() {
        return Err(FitError::NonFinite {
            what: "the mean speed".into(),
            logs: log.source.clone(),
            detail: format!("duration {:.3e} s, mean speed {w_all:.3e} rad/s", log.duration_s()),
        });
    }
    if moved <= TAU {
        return Err(FitError::NoMotion { log: log.source.clone(), speed: w_all, periods: moved / TAU });
    }
    let ts = kinematics::median_step(&log.t_s);
    let fc = kinematics::corner_hz(w_all, o.counts_per_rev, kmax, o.pole_pairs, 1.0 / ts);
    let edges = o.correct_quantisation.then(|| crate::stick::edge_timed_angle(&log.t_s, &log.theta_fb_rad));
    let theta = edges.as_ref().map_or_else(|| log.theta_fb_rad.clone(), |e| e.theta_rad.clone());
    let kin = kinematics::estimate(&log.t_s, &theta, fc);
    // Steady window: from the first to the last sample running at ≥ 80 % of the mean speed
    // in its direction (drops the start from rest, the ramp and a final stop).
    let running = |i: &usize| kin.omega_rad_s[*i] * w_all.signum() >= STEADY_SPEED_FRACTION * w_all.abs();
    let (e0, e1) = (kin.edge.min(n), n.saturating_sub(kin.edge));
    if e1 < e0 + MIN_STEADY_SAMPLES {
        return Err(too_short(2 * kin.edge + MIN_STEADY_SAMPLES));
    }
    let lo = (e0..e1).find(running);
    let hi = (e0..e1).rev().find(running).map(|i| i + 1);
    let (lo, hi) = match (lo, hi) {
        (Some(a), Some(b)) if b >= a + MIN_STEADY_SAMPLES => (a, b),
        (a, b) => {
            let steady = match (a, b) {
                (Some(a), Some(b)) => b.saturating_sub(a),
                _ => 0,
            };
            return Err(FitError::Unsteady { log: log.source.clone(), speed: w_all, steady });
        }
    };
    let (_, _, speed) = kinematics::line_fit(&log.t_s[lo..hi], &log.theta_fb_rad[lo..hi]);
    let periods = nr * (log.theta_fb_rad[hi - 1] - log.theta_fb_rad[lo]).abs() / TAU;
    let (mut back_steps, mut steps) = (0, 0);
    for w in log.theta_fb_rad[lo..hi].windows(2) {
        let d = w[1] - w[0];
        if d != 0.0 {
            steps += 1;
            if d * speed < 0.0 {
                back_steps += 1;
            }
        }
    }
    let reacts_to_counts = edges.as_ref().is_some_and(|e| {
        let mean = log.i_q_a[lo..hi].iter().sum::<f64>() / (hi - lo) as f64 * speed.signum();
        crate::conditions::reacts_to_counts(crate::stick::count_rise(e, &log.i_q_a, lo, hi, speed.signum()), mean)
    });
    let keep = edges
        .map_or_else(|| vec![true; n], |e| crate::stick::moving_mask(&e, speed, kin.corner_hz, 1.0 / ts, &o.stick));
    let harmonics = harmonics(&theta[lo..hi], nr, &o.orders);
    let mut p = Prepared {
        log,
        theta,
        keep,
        reacts_to_counts,
        kin,
        lo,
        hi,
        speed,
        periods,
        moving_periods: 0.0,
        back_steps,
        steps,
        harmonics,
        periodic: OnceCell::new(),
    };
    let used = (lo..hi).filter(|&i| p.moves(i, o.min_speed_fraction)).count();
    p.moving_periods = periods * used as f64 / (hi - lo) as f64;
    Ok(p)
}
