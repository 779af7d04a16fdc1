//! The rotor's electrical angle from the drive's own voltages and currents (no sensor).
//!
//! The winding equations (docs/design.md#the-plant, docs/sensorless.md) are `v = R i + L di/dt + dλ/dt`
//! with the rotor flux linkage `λ = (Km/Nr)(cos θe, sin θe)` (its derivative is the
//! back-EMF `Km ω (−sin θe, cos θe)`). So
//!
//! ```text
//! λ(t) = ∫₀ᵗ (v − R i) dt − L i(t) + c
//! ```
//!
//! traces a circle of radius `Km/Nr` about the unknown integration constant `c`, and the
//! rotor's electrical angle is the angle of `λ − c`. Unlike the back-EMF itself, the flux
//! does not vanish at low speed and needs no differentiation of the noisy current.
//!
//! 1. **R trim** at standstill: holding `I_hold` at rest, `v = R i` (the back-EMF and
//!    `L di/dt` average out), so `R = v̄·ī / |ī|²` with the means over the standstill after its first
//!    [`FluxOptions::settle_fraction`], pooled over the runs ([`pooled_resistance`]): the
//!    angle error `ΔR·I/(Km·ω)` makes even 10⁻⁴ of `R` matter at the slow run (a torque
//!    error of 0.2 mN·m on patent-motor at 0.74 rad/s, which is 30 % of `D·ω`). Without a standstill of at least
//!    [`FluxOptions::min_standstill_s`], the base profile's `R` is used and the report says
//!    so: an error `ΔR` then turns the angle by about `ΔR·I/(Km·ω)` rad (electrical) — at
//!    1 rad/s on patent-motor 10 % of `R` is 0.57 rad.
//!    **Current offset**: an offset `ε` of the sampled currents (a sensor's, or PWM ripple
//!    sampled off its mean) makes the loop hold `ī_true = ī − ε`, so the standstill reads
//!    `v̄ = R·(ī − ε)` and whole commanded periods of running read `v̄_run = −R·ε`
//!    ([`running_mean_voltage`]); [`Standstill::offset_corrected`] takes `v̄_run` off, and
//!    [`super::estimate`] takes `ε = −v̄_run/R` off every sample.
//! 2. **Integration**: the voltage is the mean over each period (as logged), the current
//!    the trapezoid of the samples at its ends.
//! 3. **Centre** `c`: a circle fit (Kåsa: linear least squares in `c` and `r² − |c|²`) over
//!    windows of [`FluxOptions::window_periods`] commanded electrical periods, interpolated
//!    linearly in time between the windows' centres, held before the first and after the
//!    last. The fit is geometric: the rotor's speed ripple moves the points along the circle
//!    and does not bias it (a high-pass filter would: the first harmonic's ripple puts a
//!    sideband at zero frequency).
//!
//! What limits it (measured figures in docs/sensorless.md): `L` enters as `L·i`, comparable
//! to the rotor flux (`L·I_hold = 4.75 mWb` against `Km/Nr = 6 mWb` on patent-motor), so
//! an error in `L` distorts the angle with the current's direction; the trimmed `R` must be
//! the winding's at the time of the run (copper heats by 0.39 %/K).

use super::log::SensorlessLog;
use nalgebra::{Matrix3, Vector3};
use std::f64::consts::TAU;

/// Options of the angle estimate.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FluxOptions {
    /// Shortest standstill at the start of a log that trims `R`, s.
    pub min_standstill_s: f64,
    /// Share of the standstill left out at its start (current loop and rotor settling).
    pub settle_fraction: f64,
    /// Commanded electrical periods per centre window.
    pub window_periods: f64,
}

impl Default for FluxOptions {
    fn default() -> Self {
        FluxOptions { min_standstill_s: 0.02, settle_fraction: 0.25, window_periods: 2.0 }
    }
}

/// The motor constants the estimate needs (from the base profile: a datasheet or a
/// multimeter gives them).
#[derive(Clone, Debug, PartialEq)]
pub struct Winding {
    /// Pole pairs `Nr`.
    pub pole_pairs: u16,
    /// Phase resistance in Ω (used when the log has no standstill to trim it).
    pub resistance_ohm: f64,
    /// Phase inductance in H.
    pub inductance_h: f64,
    /// The flux linkage's shape when it is not a pure sine (the base profile's
    /// `[motor.flux]`, docs/design.md#real-motors-flux-harmonics): the angle is then the one
    /// whose linkage points where `λ − c` does ([`angle_on_shape`]), and the torque is
    /// `τ = −Km·(i_a·S_a + (1 + g)·i_b·S_b)` rather than `Km·i_q`. `None`: the circle.
    pub shape: Option<stepdamp_profile::flux::FluxShape>,
}

/// Iterations of [`angle_on_shape`]: each shrinks the error by the shape's angular
/// distortion's slope (`Σ (n−1)·h_n·(1+…)` ≈ 5 % for the largest harmonics a profile may
/// give), so 6 leave under 10⁻⁷ of the distortion.
pub const SHAPE_ITERATIONS: usize = 6;

/// The electrical angle whose linkage direction `arg ψ(θ)` is `a` (rad, in (−π, π]): the
/// fixed point `θ ← θ + wrap(a − arg ψ(θ))` from `θ = a`, which converges for any shape
/// whose harmonics turn the linkage by less than its own turning (`|d arg ψ/dθ − 1| < 1`).
pub fn angle_on_shape(shape: &stepdamp_profile::flux::FluxShape, a: f64) -> f64 {
    let mut th = a;
    for _ in 0..SHAPE_ITERATIONS {
        let (pa, pb) = shape.linkage(th);
        th += wrap(a - pb.atan2(pa));
    }
    th
}

/// Where the resistance came from.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ResistanceSource {
    /// Trimmed at the log's standstill.
    Standstill,
    /// The base profile's (the log's standstill was too short).
    Base,
}

/// The angle estimate of one log and how it was made.
#[derive(Clone, Debug, PartialEq)]
pub struct RotorAngle {
    /// The rotor's electrical angle `θe` at each sample, rad, continuous (unwrapped), and
    /// within ±π of the commanded `Nr·θ_cmd` at the first sample.
    pub theta_e_rad: Vec<f64>,
    /// Standstill samples at the start of the log (commanded angle unchanged).
    pub standstill_samples: usize,
    /// Mean radius of the flux circle, Wb (the model's `Km/Nr`).
    pub flux_wb: f64,
    /// Standard deviation of the radius about its mean over the moving part, as a fraction
    /// of the mean: what the noise and errors in `R` and `L` leave (0 for exact data).
    pub radius_ripple: f64,
    /// The radius per unit of the shape's own at the estimated angle (1 for the circle),
    /// Wb, at each sample after the standstill (`theta_e_rad[standstill_samples..]`): its
    /// harmonics in `θe` measure the shape's error ([`super::shape`]).
    pub radius_wb: Vec<f64>,
    /// Centre windows fitted.
    pub windows: usize,
}

/// Why no angle could be estimated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FluxError {
    /// The commanded angle covers less than one centre window.
    #[error(
        "{log}: the command covers {periods:.2} electrical periods after the standstill; the sensorless angle needs at least {needed} (run longer or faster)"
    )]
    TooShort {
        /// The log.
        log: String,
        /// Commanded electrical periods covered.
        periods: f64,
        /// Periods needed.
        needed: f64,
    },
    /// The currents at standstill are zero: nothing to trim `R` with.
    #[error(
        "{log}: the phase currents at standstill are zero: the drive must hold I_hold before the run (the sensorless route trims R there)"
    )]
    NoStandstillCurrent {
        /// The log.
        log: String,
    },
    /// A window's circle fit failed (the flux did not turn: the rotor stalled).
    #[error(
        "{log}: around t = {t_s:.3} s the flux vector does not turn about a centre (the rotor stalled or the voltages are not the applied ones)"
    )]
    NoCircle {
        /// The log.
        log: String,
        /// Time of the window, s.
        t_s: f64,
    },
    /// The standstill gives an `R` far from the base's (too little current, voltages that
    /// are not the applied ones, or the wrong base).
    #[error(
        "{log}: the standstill gives R = {value_ohm:.4} Ω, outside {min_ohm:.4}–{max_ohm:.4} Ω (1/{MAX_R_TRIM_RATIO}–{MAX_R_TRIM_RATIO} × the base's): is the holding current on at standstill, and are v_a_v, v_b_v the applied voltages in V?"
    )]
    Resistance {
        /// The log.
        log: String,
        /// The resistance its standstill gives, Ω.
        value_ohm: f64,
        /// The lowest accepted, Ω.
        min_ohm: f64,
        /// The highest accepted, Ω.
        max_ohm: f64,
    },
    /// The estimated rotor angle does not follow the command: the rotor stalled or lost
    /// steps (or the voltages are not the applied ones).
    #[error(
        "{log}: the estimated rotor does not follow the command (mean |load angle| {mean_rad:.2} rad electrical, beyond π/2 where the rotor pulls out): the rotor stalled or lost steps, or v_a_v, v_b_v are not the applied voltages"
    )]
    NotFollowing {
        /// The log.
        log: String,
        /// Mean `|θe_cmd − θe|` over the moving part, rad.
        mean_rad: f64,
    },
    /// The command steps further between two rows than the controller can.
    #[error(
        "{log}: at t = {t_s} s theta_cmd_rad steps by {step_rad:.4e} rad in one row, more than {max_rad:.4e} rad (a quarter electrical turn): not one continuous run"
    )]
    CommandJump {
        /// The log.
        log: String,
        /// Time of the row after the step, s.
        t_s: f64,
        /// The step, rad (mechanical).
        step_rad: f64,
        /// The largest step accepted, rad.
        max_rad: f64,
    },
}

/// A standstill's `R` must be within this factor of the base profile's (copper's `R` moves
/// 0.39 %/K: a factor 2 is 250 K; beyond it the standstill, not the motor, is wrong).
pub const MAX_R_TRIM_RATIO: f64 = 2.0;

/// The standstill at the start of a log and what it says about `R`: from its settled
/// part's mean voltage and current.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Standstill {
    /// Samples with the commanded angle unchanged from the first.
    pub samples: usize,
    /// Its duration, s.
    pub duration_s: f64,
    /// `n·v̄·ī` (W) and `n·|ī|²` (A²) over its settled part of `n` samples (`v̄`, `ī` the
    /// mean voltage and current vectors), when it is long enough
    /// ([`FluxOptions::min_standstill_s`]); `R` is their ratio.
    pub sums: Option<(f64, f64)>,
    /// Mean sampled current vector over the settled part, A (zero without sums).
    pub mean_current_a: (f64, f64),
    /// Samples in the settled part (zero without sums).
    pub settled_samples: usize,
}

impl Standstill {
    /// Finds the standstill of `log` and sums its settled part.
    pub fn of(log: &SensorlessLog, o: &FluxOptions) -> Result<Standstill, FluxError> {
        let cmd0 = log.theta_cmd_rad.first().copied().unwrap_or(0.0);
        let samples = log.theta_cmd_rad.iter().take_while(|&&c| (c - cmd0).abs() <= 1e-12 * (1.0 + cmd0.abs())).count();
        let duration_s = if samples > 1 { log.t_s[samples - 1] - log.t_s[0] } else { 0.0 };
        if duration_s < o.min_standstill_s {
            return Ok(Standstill { samples, duration_s, sums: None, mean_current_a: (0.0, 0.0), settled_samples: 0 });
        }
        let from = (samples as f64 * o.settle_fraction) as usize;
        // Means first, then the products: the sums of products `Σ v·i`, `Σ i·i` take in the
        // noise's covariances (`σ²` in `Σ i·i`; the loop's voltage answering the sensor
        // noise against the sampled current), which bias `R` by −1e-4 to −3e-4 at 5 mA.
        let (mut va, mut vb, mut ia, mut ib) = (0.0, 0.0, 0.0, 0.0);
        for k in from..samples {
            (va, vb) = (va + log.v_a_v[k], vb + log.v_b_v[k]);
            (ia, ib) = (ia + log.i_a_a[k], ib + log.i_b_a[k]);
        }
        let m = (samples - from).max(1) as f64;
        let (vi, ii) = ((va * ia + vb * ib) / m, (ia * ia + ib * ib) / m);
        if ii <= 1e-6 * (samples - from) as f64 {
            return Err(FluxError::NoStandstillCurrent { log: log.source.clone() });
        }
        Ok(Standstill {
            samples,
            duration_s,
            sums: Some((vi, ii)),
            mean_current_a: (ia / m, ib / m),
            settled_samples: samples - from,
        })
    }

    /// The sums with the running mean voltage `v_run` ([`running_mean_voltage`]) taken
    /// off the standstill's: the sampled currents' offset `ε` makes the standstill read
    /// `v̄ = R·(ī − ε)` and the running part `v̄_run = −R·ε`, so `R = (v̄ − v̄_run)·ī/|ī|²`
    /// whatever `ε`.
    pub fn offset_corrected(&self, v_run: (f64, f64)) -> Standstill {
        let n = self.settled_samples as f64;
        let (ia, ib) = self.mean_current_a;
        Standstill { sums: self.sums.map(|(vi, ii)| (vi - n * (v_run.0 * ia + v_run.1 * ib), ii)), ..*self }
    }
}

/// The mean winding voltages over the whole commanded electrical periods that end the log,
/// within the last half of its moving part (after the `still` standstill samples; the
/// plan's ramp is over by then), V, and the samples they cover; `None` when that is less
/// than one period. Over whole periods the commanded current, the back-EMF and `L di/dt`
/// average to (nearly) zero; what is left is `−R·ε`, `ε` the offset of the sampled currents
/// (a sensor's offset; the PWM ripple sampled off its mean).
pub fn running_mean_voltage(log: &SensorlessLog, still: usize, pole_pairs: u16) -> Option<((f64, f64), usize)> {
    let n = log.len();
    let end = n.checked_sub(1)?;
    let half = still + (n.saturating_sub(still)) / 2;
    let th = &log.theta_cmd_rad;
    let span = (th[end] - th.get(half)?).abs();
    let period = TAU / f64::from(pole_pairs);
    let periods = (span / period).floor();
    if periods < 1.0 {
        return None;
    }
    let start = (half..end).rev().find(|&k| (th[end] - th[k]).abs() >= periods * period)?;
    let m = (end - start) as f64;
    let va = log.v_a_v[start..end].iter().sum::<f64>() / m;
    let vb = log.v_b_v[start..end].iter().sum::<f64>() / m;
    Some(((va, vb), end - start))
}

/// `R` = the ratio of the [`Standstill::sums`] pooled over the standstills that have them (one winding, several
/// runs: pooling divides the noise by the square root of the runs), else `base_ohm`.
pub fn pooled_resistance(
    logs: &[SensorlessLog],
    standstills: &[Standstill],
    base_ohm: f64,
) -> Result<(f64, ResistanceSource), FluxError> {
    let (min_ohm, max_ohm) = (base_ohm / MAX_R_TRIM_RATIO, base_ohm * MAX_R_TRIM_RATIO);
    for (log, s) in logs.iter().zip(standstills) {
        if let Some((vi, ii)) = s.sums {
            let value_ohm = vi / ii;
            if !(value_ohm >= min_ohm && value_ohm <= max_ohm) {
                return Err(FluxError::Resistance { log: log.source.clone(), value_ohm, min_ohm, max_ohm });
            }
        }
    }
    let (vi, ii) = standstills.iter().filter_map(|s| s.sums).fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    Ok(if ii > 0.0 { (vi / ii, ResistanceSource::Standstill) } else { (base_ohm, ResistanceSource::Base) })
}

/// Estimates the rotor's electrical angle over `log` (module documentation) with the
/// winding resistance `resistance_ohm` (from [`pooled_resistance`]).
pub fn rotor_angle(
    log: &SensorlessLog,
    w: &Winding,
    resistance_ohm: f64,
    o: &FluxOptions,
) -> Result<RotorAngle, FluxError> {
    let n = log.len();
    let nr = f64::from(w.pole_pairs);
    let name = || log.source.clone();
    if n < 3 {
        return Err(FluxError::TooShort { log: name(), periods: 0.0, needed: o.window_periods });
    }
    let cmd0 = log.theta_cmd_rad[0];
    let still = Standstill::of(log, o)?.samples;
    // A quarter electrical turn per row is the controller's limit (π/2 per period).
    let max_rad = 0.25 * TAU / nr;
    if let Some(k) = log.theta_cmd_rad.windows(2).position(|w| (w[1] - w[0]).abs() > max_rad) {
        let step_rad = (log.theta_cmd_rad[k + 1] - log.theta_cmd_rad[k]).abs();
        return Err(FluxError::CommandJump { log: name(), t_s: log.t_s[k + 1], step_rad, max_rad });
    }
    // 2. Flux without its constant.
    let mut lam = Vec::with_capacity(n);
    let (mut px, mut py) = (0.0, 0.0);
    for k in 0..n {
        lam.push((px - w.inductance_h * log.i_a_a[k], py - w.inductance_h * log.i_b_a[k]));
        if k + 1 < n {
            let dt = log.t_s[k + 1] - log.t_s[k];
            px += dt * (log.v_a_v[k] - resistance_ohm * 0.5 * (log.i_a_a[k] + log.i_a_a[k + 1]));
            py += dt * (log.v_b_v[k] - resistance_ohm * 0.5 * (log.i_b_a[k] + log.i_b_a[k + 1]));
        }
    }
    // 3. Centres over windows of the commanded angle after the standstill.
    let span = o.window_periods * TAU / nr;
    let mut centres: Vec<(f64, f64, f64)> = Vec::new(); // (t, cx, cy)
    let first = still.min(n - 1);
    let mut start = first;
    for k in first..n {
        if (log.theta_cmd_rad[k] - log.theta_cmd_rad[start]).abs() >= span {
            let t_mid = 0.5 * (log.t_s[start] + log.t_s[k]);
            let (cx, cy) =
                kasa_centre(&lam[start..=k]).ok_or_else(|| FluxError::NoCircle { log: name(), t_s: t_mid })?;
            centres.push((t_mid, cx, cy));
            start = k;
        }
    }
    if centres.is_empty() {
        let periods = nr * (log.theta_cmd_rad[n - 1] - log.theta_cmd_rad[first]).abs() / TAU;
        return Err(FluxError::TooShort { log: name(), periods, needed: o.window_periods });
    }
    // The angle about the interpolated centre, unwrapped.
    let mut theta_e_rad = Vec::with_capacity(n);
    let mut radius = Vec::with_capacity(n);
    let mut w_i = 0;
    for (k, (&t, l)) in log.t_s.iter().zip(&lam).enumerate() {
        while w_i + 1 < centres.len() && centres[w_i + 1].0 <= t {
            w_i += 1;
        }
        let (cx, cy) = centre_at(&centres, w_i, t);
        let (x, y) = (l.0 - cx, l.1 - cy);
        let a = match &w.shape {
            Some(shape) => angle_on_shape(shape, y.atan2(x)),
            None => y.atan2(x),
        };
        let th = match theta_e_rad.last() {
            None => a + TAU * ((nr * cmd0 - a) / TAU).round(),
            Some(&prev) => prev + wrap(a - prev),
        };
        theta_e_rad.push(th);
        if k >= still {
            // The radius per unit of the shape's own at this angle (1 for the circle).
            let unit = w.shape.as_ref().map_or(1.0, |sh| {
                let (pa, pb) = sh.linkage(th);
                pa.hypot(pb)
            });
            radius.push(x.hypot(y) / unit);
        }
    }
    // A rotor that follows keeps |δ| = |θe_cmd − θe| below π/2 (pull-out); a stalled one sits
    // at π (the flux estimate is then −L·i, opposite the current) or slips ever further.
    let moving = theta_e_rad.len().saturating_sub(still).max(1) as f64;
    let mean_rad =
        theta_e_rad.iter().zip(&log.theta_cmd_rad).skip(still).map(|(th, c)| (nr * c - th).abs()).sum::<f64>() / moving;
    if mean_rad.is_nan() || mean_rad > 0.5 * std::f64::consts::PI {
        return Err(FluxError::NotFollowing { log: name(), mean_rad });
    }
    let m = radius.len().max(1) as f64;
    let flux_wb = radius.iter().sum::<f64>() / m;
    let var = radius.iter().map(|r| (r - flux_wb).powi(2)).sum::<f64>() / m;
    Ok(RotorAngle {
        theta_e_rad,
        standstill_samples: still,
        flux_wb,
        radius_ripple: var.sqrt() / flux_wb,
        radius_wb: radius,
        windows: centres.len(),
    })
}

/// The centre at time `t`: linear between the window centres `i` and `i + 1`, held outside.
fn centre_at(c: &[(f64, f64, f64)], i: usize, t: f64) -> (f64, f64) {
    let a = c[i];
    match c.get(i + 1) {
        Some(b) if t > a.0 => {
            let s = ((t - a.0) / (b.0 - a.0)).clamp(0.0, 1.0);
            (a.1 + s * (b.1 - a.1), a.2 + s * (b.2 - a.2))
        }
        _ => (a.1, a.2),
    }
}

/// `x` wrapped into `(−π, π]`.
fn wrap(x: f64) -> f64 {
    x - TAU * (x / TAU).round()
}

/// Kåsa circle fit: the centre minimising `Σ (|p|² − 2 c·p − k)²`; `None` when the points
/// do not determine one (fewer than three, or on a line or a point).
fn kasa_centre(p: &[(f64, f64)]) -> Option<(f64, f64)> {
    // Centred on the mean for conditioning.
    let m = p.len() as f64;
    if m < 3.0 {
        return None;
    }
    let (mx, my) = p.iter().fold((0.0, 0.0), |s, q| (s.0 + q.0 / m, s.1 + q.1 / m));
    let mut a = Matrix3::<f64>::zeros();
    let mut b = Vector3::<f64>::zeros();
    for q in p {
        let (x, y) = (q.0 - mx, q.1 - my);
        let row = Vector3::new(2.0 * x, 2.0 * y, 1.0);
        a += row * row.transpose();
        b += row * (x * x + y * y);
    }
    let sol = a.lu().solve(&b)?;
    let (cx, cy) = (sol[0] + mx, sol[1] + my);
    (cx.is_finite() && cy.is_finite() && sol[2] + sol[0].powi(2) + sol[1].powi(2) > 0.0).then_some((cx, cy))
}
