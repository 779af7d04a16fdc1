//! The motor's ripple in N·m and the head that carries it, identified from accelerometer
//! captures: an `M974` speed sweep per direction (and/or `M973` baselines without a trial at
//! two or more speeds), recorded with the correction off
//! (`docs/accelerometer.md#identifying-the-ripple-from-captures`).
//!
//! **Model** ([`AxisModel`]): the ripple `T(θe) = −A·sin(k·θe + φ)` (torque on the rotor, the
//! profile's convention, `θe` the rotor's electrical angle) drives the rotor, held in open
//! loop by `K = Km·I·Nr·cos λ` with inertia `J_t = J_rotor + m·r²` and viscous `c`; the head's
//! acceleration is `r·α` through the belt mode (`ω_b`, `ζ`). Against the **commanded** angle
//! the rotor runs `λ` behind ([`load_angle_rad`]: Coulomb and viscous load on `Km·I`), so the
//! response of harmonic `k` at the signed speed `v` is
//!
//! ```text
//! Y_k(v) = G(w)·(e^{i·k·λ(v)}·T_k + Km·I·cos λ·U_k),   w = k·Nr·2π·v,   T_k = −A·e^{iφ}
//! ```
//!
//! with `G` = [`AxisModel::acceleration_per_torque`] and `U_k` an `M973` trial's shift of
//! harmonic `k` (rad; 0 without one): a **known** torque that fixes the scale of `G`, which
//! a sweep above the rotor's resonance determines only weakly (there `G ≈ r/J_t·belt`, and
//! `T_k/J_t` is what the sweep measures). Known: `r`, `Km`, `I`, `Nr`, `J_rotor`,
//! `Fc` (the base profile and the run current). Fitted: `J_t`, `ω_b`, `ζ` (shared),
//! the rotor's effective damping `c` (the base profile's viscous
//! damping is its start: the drive's current loop adds damping through the back-EMF), and
//! one `T_k` per order and direction, by weighted least squares over the lock-in blocks
//! ([`crate::lockin::block_responses`], weight = samples) in the band `k·Nr·|v| < 0.4·f_s`.
//! 95 % intervals: the covariance `σ²·(JᵀWJ)⁻¹` (`σ²` from the weighted residuals) through the
//! delta method (normal quantile 1.96; for `T_k` a disc of radius `√(5.99·λ_max)`).

mod display;
pub mod file;
mod fit;

use crate::capture::{AccelCapture, CaptureError, Gcode, MAX_HARMONIC, Reconstruction};
use crate::complex::Complex;
use crate::head::{AxisModel, load_angle_rad};
use crate::lockin::block_responses;
use fit::{Fixed, Point};
use std::f64::consts::TAU;

/// The normal distribution's two-sided 95 % quantile.
const Z95: f64 = 1.959_964;
/// The χ² distribution's 95 % quantile with 2 degrees of freedom, `−2·ln 0.05`.
const CHI2_2_95: f64 = 5.991_465;
/// The fewest blocks an order and direction needs to be fitted.
pub const MIN_BLOCKS: usize = 8;
/// The shift delays (s) a drive can have, for choosing the sensor's sign: its computation
/// and current loop take a few of its 50 µs control periods (the simulated drive 1–2,
/// docs/accelerometer.md#identifying-the-ripple-from-captures); up to 500 µs is ten, and
/// down to −50 µs leaves room for the fit's scatter around 0. A delay is never negative.
pub const SHIFT_DELAY_RANGE_S: (f64, f64) = (-5e-5, 5e-4);

/// The largest relative half-width of `J_t`'s and `ω_b`'s 95 % intervals an identification
/// accepts: wider is refused as ill-determined.
pub const MAX_RELATIVE_HALF_WIDTH: f64 = 0.3;

/// The belt travel per motor revolution (mm) a front end accepts (`identify --accel`, `accel refine`,
/// and Python) before it derives
/// [`RippleOptions::pulley_radius_m`] (= mm / 2π / 1000) from it: a pitch radius of 1–50 mm.
pub const MM_PER_REV_RANGE: (f64, f64) = (6.3, 314.0);

/// What the identification is given besides the captures (SI units; the base profile's values
/// and the run current).
#[derive(Debug, Clone, PartialEq)]
pub struct RippleOptions {
    /// Electrical periods per revolution `Nr` (the profile's pole pairs).
    pub periods_per_rev: u32,
    /// Pulley pitch radius `r` (m).
    pub pulley_radius_m: f64,
    /// The rotor's inertia (kg·m²).
    pub rotor_inertia_kg_m2: f64,
    /// `Km` (N·m/A).
    pub km_nm_per_a: f64,
    /// The run current `I` (A, peak).
    pub current_peak_a: f64,
    /// The rotor's viscous damping `c` (N·m·s/rad).
    pub viscous_nm_s_per_rad: f64,
    /// The rotor's Coulomb friction `Fc` (N·m).
    pub coulomb_friction_nm: f64,
    /// The orders to identify, each 1..=16.
    pub orders: Vec<u32>,
    /// Whole electrical periods per lock-in block.
    pub periods_per_block: u32,
    /// The share of the sampling rate a harmonic may reach (`plan::MAX_BAND_FRACTION`, 0.4).
    pub band_fraction: f64,
    /// The least share of the response the fit must explain, else it is refused.
    pub min_explained: f64,
    /// The firmware's table scale (rad of shift per table unit: 4 for ≥ 6.3.1,
    /// `stepdamp_export::prusa::Firmware::scale`): an `M973` trial `(C, A)` shifts the
    /// current vector by `U = scale·C·e^{iA}`, a known torque `K·U/Nr` that fixes the scale of
    /// the head's response (and so `J_t`).
    pub trial_scale: f64,
    /// The size of the printed acceleration per acceleration of the motor's belt: 1 where the
    /// sensor reads the belt's direction, `1/√2` on a Prusa CoreXY axis
    /// ([`crate::prusa::sensor_gain`]). Its sign (how the sensor and the motor's phase are
    /// wired, which no capture says) is fitted: [`RippleFit::sensor_gain`].
    pub sensor_gain: f64,
}

impl RippleOptions {
    /// Orders 1–16, 4 periods per block, the planner's band, at least 90 % explained.
    pub fn new(periods_per_rev: u32, pulley_radius_m: f64, current_peak_a: f64) -> Self {
        RippleOptions {
            periods_per_rev,
            pulley_radius_m,
            rotor_inertia_kg_m2: 0.0,
            km_nm_per_a: 0.0,
            current_peak_a,
            viscous_nm_s_per_rad: 0.0,
            coulomb_friction_nm: 0.0,
            orders: (1..=MAX_HARMONIC).collect(),
            periods_per_block: 4,
            band_fraction: crate::plan::MAX_BAND_FRACTION,
            min_explained: 0.9,
            trial_scale: 4.0,
            sensor_gain: 1.0,
        }
    }
}

/// The motor's phase direction of a capture: `R ≤ 0` forward (phase up, the `F` table),
/// `R > 0` backward (the `B` table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Direction {
    /// Phase up, the forward table.
    Forward,
    /// Phase down, the backward table.
    Backward,
}

impl Direction {
    /// `"forward"` or `"backward"`.
    pub fn name(self) -> &'static str {
        match self {
            Direction::Forward => "forward",
            Direction::Backward => "backward",
        }
    }
}

/// A value and its 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interval95 {
    /// The estimate.
    pub value: f64,
    /// Lower bound.
    pub low: f64,
    /// Upper bound.
    pub high: f64,
}

/// The head as identified.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifiedHead {
    /// `J_t = J_rotor + m·r²` (kg·m²).
    pub total_inertia_kg_m2: Interval95,
    /// `m = (J_t − J_rotor)/r²` (kg).
    pub carriage_mass_kg: Interval95,
    /// The belt mode's natural frequency (Hz).
    pub belt_hz: Interval95,
    /// The belt mode's damping ratio.
    pub belt_damping_ratio: Interval95,
    /// `k = m·ω_b²` (N/m) at the estimates.
    pub belt_stiffness_n_per_m: f64,
    /// The rotor's effective damping `c` (N·m·s/rad): the viscous friction plus the damping
    /// the drive's current loop adds through the back-EMF, which the base profile's
    /// `viscous_nm_s_per_rad` leaves out; it sets the response's phase near the rotor's
    /// resonance.
    pub rotor_damping_nm_s_per_rad: Interval95,
    /// How late (s) the drive applies a shift of the commanded angle (an `M973` trial): its
    /// computation and current loop; fitted from the trials' phase.
    pub shift_delay_s: Interval95,
}

/// One order's ripple in one direction, at the run current.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifiedHarmonic {
    /// The order `k`.
    pub order: u32,
    /// The direction.
    pub direction: Direction,
    /// `A` (N·m): torque on the rotor `−A·sin(k·θe + φ)`.
    pub amplitude_nm: Interval95,
    /// `φ` (rad, in (−π, π]), relative to the reconstruction's start angle.
    pub phase_rad: Interval95,
    /// Radius (N·m) of the 95 % disc around the phasor `−A·e^{iφ}`.
    pub radius95_nm: f64,
    /// The lock-in blocks fitted.
    pub blocks: usize,
    /// The speeds they span (rev/s, absolute).
    pub speeds_rev_s: (f64, f64),
    /// The share of this order's response (weighted `Σ|Y|²`) the model explains.
    pub explained_share: f64,
}

/// An order and direction the captures cannot identify, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct NotIdentified {
    /// The order.
    pub order: u32,
    /// The direction.
    pub direction: Direction,
    /// Its lock-in blocks in band (fewer than [`MIN_BLOCKS`]).
    pub blocks: usize,
    /// The fastest speed (rev/s) that puts it in band, `band_fraction·f_s/(k·Nr)`; `None` when
    /// no capture ran in this direction.
    pub band_limit_rev_s: Option<f64>,
    /// Why, in words.
    pub reason: String,
}

/// What [`identify_ripple`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct RippleFit {
    /// The head.
    pub head: IdentifiedHead,
    /// The axis model at the estimates (for predictions).
    pub axis: AxisModel,
    /// Per order and direction, sorted by direction then order.
    pub harmonics: Vec<IdentifiedHarmonic>,
    /// What could not be identified.
    pub not_identified: Vec<NotIdentified>,
    /// The share of the vibration at the fitted harmonics the model explains:
    /// `1 − Σw|Y − Ŷ|² / Σw|Y|²` over every block.
    pub explained_share: f64,
    /// The blocks fitted.
    pub blocks: usize,
    /// The captures used.
    pub captures: usize,
    /// The printed acceleration per acceleration of the belt (`axis`'s head acceleration):
    /// [`RippleOptions::sensor_gain`] with the sign that fits the captures better. A sensor
    /// (or a motor's phase) turned the other way flips every response, baseline and trial
    /// alike; fitted with the wrong sign, the trial's known torque would not match.
    pub sensor_gain: f64,
    /// Whether that sign was told apart: both signs fitted and the one kept has a drive's
    /// shift delay ([`SHIFT_DELAY_RANGE_S`]). Without a trial it cannot be (the flipped
    /// captures fit as well with the ripple flipped), and it is taken as `+`.
    pub sensor_sign_fitted: bool,
}

/// Why the ripple cannot be identified; one line each.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RippleError {
    /// A capture could not be analysed.
    #[error(transparent)]
    Capture(#[from] CaptureError),
    /// A parameter is out of range.
    #[error("{what} = {value}: must be {allowed}")]
    Parameter {
        /// The parameter.
        what: &'static str,
        /// Its value.
        value: String,
        /// The allowed range.
        allowed: &'static str,
    },
    /// The captures do not determine the answer.
    #[error("ill-determined: {0}")]
    IllDetermined(String),
}

/// Refuses options the model cannot use.
fn check(o: &RippleOptions) -> Result<(), RippleError> {
    let bad = |what, value: f64, allowed| Err(RippleError::Parameter { what, value: value.to_string(), allowed });
    let pos = |v: f64| v.is_finite() && v > 0.0;
    let checks: [(&'static str, f64, bool, &'static str); 10] = [
        ("sensor_gain", o.sensor_gain, o.sensor_gain > 0.0 && o.sensor_gain <= 1.0, "in (0, 1] (its sign is fitted)"),
        ("trial_scale", o.trial_scale, pos(o.trial_scale), "positive (4 for firmware ≥ 6.3.1)"),
        ("periods_per_rev", f64::from(o.periods_per_rev), o.periods_per_rev >= 1, "at least 1"),
        ("pulley_radius_m", o.pulley_radius_m, (1e-3..=0.05).contains(&o.pulley_radius_m), "in 0.001..=0.05 m"),
        ("rotor_inertia_kg_m2", o.rotor_inertia_kg_m2, pos(o.rotor_inertia_kg_m2), "positive"),
        ("km_nm_per_a", o.km_nm_per_a, pos(o.km_nm_per_a), "positive"),
        ("current_peak_a", o.current_peak_a, pos(o.current_peak_a), "positive"),
        ("viscous_nm_s_per_rad", o.viscous_nm_s_per_rad, o.viscous_nm_s_per_rad >= 0.0, "≥ 0"),
        ("coulomb_friction_nm", o.coulomb_friction_nm, o.coulomb_friction_nm >= 0.0, "≥ 0"),
        ("band_fraction", o.band_fraction, o.band_fraction > 0.0 && o.band_fraction < 0.5, "in (0, 0.5)"),
    ];
    for (what, v, ok, allowed) in checks {
        if !(v.is_finite() && ok) {
            return bad(what, v, allowed);
        }
    }
    if o.periods_per_block == 0 {
        return bad("periods_per_block", 0.0, "at least 1");
    }
    if let Some(&k) = o.orders.iter().find(|&&k| !(1..=MAX_HARMONIC).contains(&k)) {
        return bad("orders", f64::from(k), "each in 1..=16");
    }
    if o.orders.is_empty() || !(0.0..1.0).contains(&o.min_explained) {
        return bad("orders / min_explained", o.min_explained, "at least one order, min_explained in [0, 1)");
    }
    Ok(())
}

/// What the fit needs of one recording: a Prusa capture ([`AccelCapture`], its motion
/// rebuilt from its G-code) or a stretch of a Klipper log ([`crate::klipper::Segment`], its
/// motion read from the stepper's queue).
pub trait RippleCapture {
    /// Where it comes from, for messages (`file:line`).
    fn origin(&self) -> String;
    /// Its sampling rate (Hz): the band limit's reference.
    fn sampling_freq_hz(&self) -> f64;
    /// Its direction and its trial `(H, U)` (`U` the shift phasor, rad, at `trial_scale` rad
    /// per table unit; `None` without a trial), or why it cannot be used.
    fn direction_and_trial(&self, trial_scale: f64) -> Result<(Direction, Option<(u32, Complex)>), RippleError>;
    /// The lock-in blocks of `harmonic` ([`crate::lockin::block_responses`]).
    fn blocks(
        &self,
        r: &Reconstruction,
        harmonic: u32,
        periods_per_block: u32,
    ) -> Result<Vec<crate::lockin::BlockResponse>, CaptureError>;
}

impl RippleCapture for AccelCapture {
    fn origin(&self) -> String {
        format!("{}:{}", self.source, self.line)
    }

    fn sampling_freq_hz(&self) -> f64 {
        self.annotations.sampling_freq_hz
    }

    /// An `M973` whose trial sweeps cannot be used.
    fn direction_and_trial(&self, scale: f64) -> Result<(Direction, Option<(u32, Complex)>), RippleError> {
        let g = self.require_gcode()?;
        let trial = match g {
            Gcode::ParamSweep { .. } => {
                let (h, _, _, mag, pha) = self.constant_trial("identifying the ripple")?;
                (mag != 0.0).then(|| (h, Complex::from_polar(scale * mag, pha)))
            }
            Gcode::SpeedSweep { .. } => None,
        };
        Ok((if g.phase_direction() > 0.0 { Direction::Forward } else { Direction::Backward }, trial))
    }

    fn blocks(
        &self,
        r: &Reconstruction,
        harmonic: u32,
        periods_per_block: u32,
    ) -> Result<Vec<crate::lockin::BlockResponse>, CaptureError> {
        block_responses(self, r, harmonic, periods_per_block)
    }
}

/// The blocks to fit, their (order, direction) groups, and what is left out.
type Collected = (Vec<Point>, Vec<(u32, Direction)>, Vec<NotIdentified>);

/// The blocks of every capture in band, grouped by (order, direction), and what is left out.
fn collect<C: RippleCapture>(captures: &[C], r: &Reconstruction, o: &RippleOptions) -> Result<Collected, RippleError> {
    let holding = o.km_nm_per_a * o.current_peak_a;
    let k_mag = holding * f64::from(o.periods_per_rev);
    let mut by_group: Vec<((u32, Direction), Vec<Point>)> = Vec::new();
    let mut fastest = [0.0_f64; 2];
    for c in captures {
        let (dir, trial) = c.direction_and_trial(o.trial_scale)?;
        let fs = c.sampling_freq_hz();
        for &k in &o.orders {
            for b in c.blocks(r, k, o.periods_per_block)? {
                fastest[dir as usize] = fastest[dir as usize].max(b.speed_rev_s.abs());
                let w = f64::from(k) * f64::from(o.periods_per_rev) * TAU * b.speed_rev_s;
                if w.abs() / TAU >= o.band_fraction * fs || b.speed_rev_s == 0.0 {
                    continue;
                }
                let Some(lag) = load_angle_rad(b.speed_rev_s, o.coulomb_friction_nm, o.viscous_nm_s_per_rad, holding)
                else {
                    return Err(RippleError::IllDetermined(format!(
                        "{}: at {:.2} rev/s the base profile's friction exceeds Km·I: a wrong profile or current",
                        c.origin(),
                        b.speed_rev_s
                    )));
                };
                let point = Point {
                    group: 0,
                    w,
                    lag: Complex::from_polar(1.0, f64::from(k) * lag),
                    stiffness: k_mag * lag.cos(),
                    known: match trial {
                        Some((h, u)) if h == k => u.scale(holding * lag.cos()),
                        _ => Complex::default(),
                    },
                    y: b.value,
                    weight: b.samples as f64,
                };
                match by_group.iter_mut().find(|(g, _)| *g == (k, dir)) {
                    Some((_, v)) => v.push(point),
                    None => by_group.push(((k, dir), vec![point])),
                }
            }
        }
    }
    by_group.sort_by_key(|(g, _)| (g.1, g.0));
    let mut missing = Vec::new();
    let mut groups = Vec::new();
    let mut points = Vec::new();
    for dir in [Direction::Forward, Direction::Backward] {
        for &k in &o.orders {
            let n = by_group.iter().find(|(g, _)| *g == (k, dir)).map_or(0, |(_, v)| v.len());
            if n >= MIN_BLOCKS {
                continue;
            }
            let limit = o.band_fraction * captures.first().map_or(0.0, |c| c.sampling_freq_hz())
                / (f64::from(k) * f64::from(o.periods_per_rev));
            let band_limit_rev_s = (fastest[dir as usize] > 0.0).then_some(limit);
            let reason = match band_limit_rev_s {
                None => "no capture in this direction".to_string(),
                Some(_) => format!(
                    "{n} block(s) in band (fewer than {MIN_BLOCKS}): order {k} is below {:.0} % of the sampling rate at or below {limit:.2} rev/s",
                    100.0 * o.band_fraction
                ),
            };
            missing.push(NotIdentified { order: k, direction: dir, blocks: n, band_limit_rev_s, reason });
        }
    }
    for ((key, mut v), index) in by_group.into_iter().filter(|(_, v)| v.len() >= MIN_BLOCKS).zip(0..) {
        v.iter_mut().for_each(|p| p.group = index);
        groups.push(key);
        points.extend(v);
    }
    Ok((points, groups, missing))
}

/// Identifies the head and the ripple from `captures` (Prusa captures with their G-code, or
/// the segments of a Klipper log, [`crate::klipper::Log::segments`]; recorded with the
/// correction off; module doc). Without any trial (a Klipper log, or Prusa sweeps alone) the
/// shift delay has nothing to be fitted from: it is reported as 0 with an infinite interval,
/// and the scale of the response comes from the sweeps alone. The sign of the sensor's gain
/// is fitted where a trial can tell it ([`RippleFit::sensor_gain`]). Refuses with [`RippleError::IllDetermined`] when no order
/// has blocks in band, when the normal equations are singular, when `J_t` or `ω_b` is known
/// to worse than ±[`MAX_RELATIVE_HALF_WIDTH`], when `J_t` comes out below the rotor's own, or
/// when the model explains less than [`RippleOptions::min_explained`] of the response.
pub fn identify_ripple<C: RippleCapture>(
    captures: &[C],
    r: &Reconstruction,
    o: &RippleOptions,
) -> Result<RippleFit, RippleError> {
    check(o)?;
    let (points, groups, not_identified) = collect(captures, r, o)?;
    if groups.is_empty() {
        return Err(RippleError::IllDetermined(format!(
            "no order has {MIN_BLOCKS} lock-in blocks in band: record an M974 sweep per direction (identify plan --accel)"
        )));
    }
    let heaviest = o.rotor_inertia_kg_m2 + 20.0 * o.pulley_radius_m * o.pulley_radius_m;
    // Both signs of the sensor's gain, where a trial can tell them: the one whose shift delay
    // is a drive's (SHIFT_DELAY_RANGE_S), then the smaller residual. A delay of half a period
    // of the trial's harmonic flips the trial as a flipped sensor does: with trials at one
    // order and speed the two fits explain the captures equally (1.25 ms for order 4 at
    // 2 rev/s). Without a trial the flipped captures fit as well with the ripple flipped.
    let solve = |sign: f64| {
        let fixed = Fixed { radius_m: sign * o.sensor_gain * o.pulley_radius_m, viscous: o.viscous_nm_s_per_rad };
        fit::solve(&fixed, &points, groups.len(), (o.rotor_inertia_kg_m2 * 1.01, heaviest)).map(|s| (sign, s))
    };
    let plausible = |s: &fit::Solution| {
        let delay_s = s.x[fit::NL - 1] * fit::DELAY_UNIT_S;
        (SHIFT_DELAY_RANGE_S.0..=SHIFT_DELAY_RANGE_S.1).contains(&delay_s)
    };
    let residual = |s: &fit::Solution| {
        let r = s.residual.iter().sum::<f64>();
        if r.is_nan() { f64::INFINITY } else { r }
    };
    let any_trial = points.iter().any(|p| p.known != Complex::default());
    let (best, compared) = match (solve(1.0), if any_trial { solve(-1.0) } else { None }) {
        (Some(a), Some(b)) => {
            let key = |s: &fit::Solution| (!plausible(s), residual(s));
            (Some(if key(&b.1) < key(&a.1) { b } else { a }), true)
        }
        (a, b) => (a.or(b), false),
    };
    let Some((sign, sol)) = best else {
        return Err(RippleError::IllDetermined(
            "the captures do not separate the head's inertia, belt frequency and damping (singular normal equations): add a sweep over a wider speed range".into(),
        ));
    };
    let head = head_of(&sol, o)?;
    let explained_share = 1.0 - sol.residual.iter().sum::<f64>() / sol.total.iter().sum::<f64>();
    if explained_share.is_nan() || explained_share < o.min_explained {
        return Err(RippleError::IllDetermined(format!(
            "the model explains {:.1} % of the vibration at the motor's harmonics (at least {:.0} % needed): another mechanism, a correction left on, or wrong captures",
            100.0 * explained_share,
            100.0 * o.min_explained
        )));
    }
    let harmonics = groups
        .iter()
        .enumerate()
        .map(|(g, &(order, direction))| harmonic_of(&sol, &points, g, order, direction, o.periods_per_rev))
        .collect();
    let axis = AxisModel {
        pulley_radius_m: o.pulley_radius_m,
        total_inertia_kg_m2: head.total_inertia_kg_m2.value,
        belt_omega_rad_s: TAU * head.belt_hz.value,
        belt_damping_ratio: head.belt_damping_ratio.value,
        stiffness_nm_per_rad: o.km_nm_per_a * o.current_peak_a * f64::from(o.periods_per_rev),
        viscous_nm_s_per_rad: head.rotor_damping_nm_s_per_rad.value,
    };
    Ok(RippleFit {
        head,
        axis,
        harmonics,
        not_identified,
        explained_share,
        blocks: points.len(),
        captures: captures.len(),
        sensor_gain: sign * o.sensor_gain,
        sensor_sign_fitted: compared && plausible(&sol),
    })
}

/// The head's estimates and intervals (the log-parametrised unknowns `x[0..3]`), refused
/// when ill-determined.
fn head_of(sol: &fit::Solution, o: &RippleOptions) -> Result<IdentifiedHead, RippleError> {
    let log_interval = |i: usize| {
        let s = sol.covariance[i][i].max(0.0).sqrt();
        Interval95 { value: sol.x[i].exp(), low: (sol.x[i] - Z95 * s).exp(), high: (sol.x[i] + Z95 * s).exp() }
    };
    let (j, wb, z, c) = (log_interval(0), log_interval(1), log_interval(2), log_interval(3));
    for (what, iv) in [("the total inertia J_t", j), ("the belt frequency", wb)] {
        let half = 0.5 * (iv.high - iv.low) / iv.value;
        if half.is_nan() || half > MAX_RELATIVE_HALF_WIDTH {
            return Err(RippleError::IllDetermined(format!(
                "{what} is known to ±{:.0} % only (at most ±{:.0} %): sweep over a wider speed range, or one that crosses the belt mode",
                100.0 * half,
                100.0 * MAX_RELATIVE_HALF_WIDTH
            )));
        }
    }
    let (jr, r2) = (o.rotor_inertia_kg_m2, o.pulley_radius_m * o.pulley_radius_m);
    if j.value <= jr {
        return Err(RippleError::IllDetermined(format!(
            "the fitted inertia {:.3e} kg·m² is not above the rotor's {jr:.3e}: a wrong base profile, current or pulley",
            j.value
        )));
    }
    let mass = |v: f64| ((v - jr) / r2).max(0.0);
    let hz = |v: f64| v / TAU;
    let m = Interval95 { value: mass(j.value), low: mass(j.low), high: mass(j.high) };
    Ok(IdentifiedHead {
        total_inertia_kg_m2: j,
        carriage_mass_kg: m,
        belt_hz: Interval95 { value: hz(wb.value), low: hz(wb.low), high: hz(wb.high) },
        belt_damping_ratio: z,
        belt_stiffness_n_per_m: m.value * wb.value * wb.value,
        rotor_damping_nm_s_per_rad: c,
        shift_delay_s: if sol.delay_fitted {
            let (v, s) = (sol.x[4] * fit::DELAY_UNIT_S, sol.covariance[4][4].max(0.0).sqrt() * fit::DELAY_UNIT_S);
            Interval95 { value: v, low: v - Z95 * s, high: v + Z95 * s }
        } else {
            Interval95 { value: 0.0, low: f64::NEG_INFINITY, high: f64::INFINITY }
        },
    })
}

/// Group `g`'s ripple in the profile's convention with its intervals (delta method).
fn harmonic_of(
    sol: &fit::Solution,
    points: &[Point],
    g: usize,
    order: u32,
    direction: Direction,
    nr: u32,
) -> IdentifiedHarmonic {
    let (i, q) = (fit::NL + 2 * g, fit::NL + 1 + 2 * g);
    let t = Complex::new(sol.x[i], sol.x[q]);
    let (cii, ciq, cqq) = (sol.covariance[i][i], sol.covariance[i][q], sol.covariance[q][q]);
    let a = t.abs();
    // ∇|T| = (re, im)/|T|; ∇arg T = (−im, re)/|T|².
    let var_a = (t.re * t.re * cii + 2.0 * t.re * t.im * ciq + t.im * t.im * cqq) / (a * a);
    let var_p = (t.im * t.im * cii - 2.0 * t.re * t.im * ciq + t.re * t.re * cqq) / (a * a * a * a);
    let lambda_max = 0.5 * (cii + cqq) + (0.25 * (cii - cqq) * (cii - cqq) + ciq * ciq).sqrt();
    let phase = (-t).arg();
    let (sa, sp) = (Z95 * var_a.max(0.0).sqrt(), Z95 * var_p.max(0.0).sqrt());
    let mine = || points.iter().filter(|p| p.group == g);
    let speed = |p: &Point| p.w.abs() / (f64::from(order) * f64::from(nr) * TAU);
    let speeds = mine().fold((f64::MAX, 0.0_f64), |(lo, hi), p| (lo.min(speed(p)), hi.max(speed(p))));
    IdentifiedHarmonic {
        order,
        direction,
        amplitude_nm: Interval95 { value: a, low: (a - sa).max(0.0), high: a + sa },
        phase_rad: Interval95 { value: phase, low: phase - sp, high: phase + sp },
        radius95_nm: (CHI2_2_95 * lambda_max).sqrt(),
        blocks: mine().count(),
        speeds_rev_s: speeds,
        explained_share: 1.0 - sol.residual[g] / sol.total[g],
    }
}

#[cfg(test)]
mod tests;
