//! The ripple the compensation cancels, at the operating point: a part that does not depend
//! on current (the detent) and parts proportional to the rotor-frame currents, which a real
//! motor's flux harmonics and unequal phases make (docs/design.md#real-motors-flux-harmonics).
//!
//! At the rotor's electrical angle `θe` and rotor-frame currents `(i_d, i_q)` the torque on
//! the rotor is `Km·i_q + T0(θe) + i_d·D(θe) + i_q·Q̃(θe)`: the mean torque constant `Km`
//! and three harmonic lists in the detent's convention (each harmonic puts
//! `−A·sin(k·θe + φ)` on the rotor): `T0` in N·m, `D` and `Q̃` in N·m per A (`Q̃` is the
//! torque constant's own harmonics, without its mean). [`RippleModel`] stores them scaled
//! by `1/Km`, as the currents that cancel them: `c0` in A, `cd`, `cq` in A per A, so the
//! drive cancels the ripple at `(i_d, i_q)` by supplying the torque of
//!
//! ```text
//! S(θe, i_d, i_q) = c0(θe) + i_d·cd(θe) + i_q·cq(θe)        (A, along the rotor's q axis)
//! ```
//!
//! and the torque per ampere of `i_q` at `θe` is `Km·(1 − cq(θe))`. The laws
//! ([`crate::drive`] applies them; all `S` go through the current-loop inverse first):
//!
//! - **Servo** (at `θ_fb`, `i_d = 0`, no d-current bias): `i_comp = S(θ_fb, 0, i_q,ctrl) /
//!   (1 − cq(θ_fb))`, with `i_q,ctrl` this period's feedback and friction feed-forward
//!   (before the compensation is added), so there is no algebraic loop; the division makes
//!   the compensation current's own ripple cancel too: `Km·(1 − cq)·(i_q,ctrl + i_comp)`
//!   plus the ripple is `Km·i_q,ctrl`.
//! - **Open loop at `θ_cmd`** (the patent's law, and the angle law): `S(θ_cmd, I_hold, 0)`,
//!   folded into one table when the configuration is built (no cost per period).
//! - **Estimated angle** (open loop at `θ̂e = θc − δ̂`): the drive's current `I_hold` on the
//!   d axis of `θc` is `(I_hold·cos δ̂, I_hold·sin δ̂)` in the rotor's frame, and a current
//!   `i_comp` on the q axis of `θc` is `(−i_comp·sin δ̂, i_comp·cos δ̂)`, whose torque is
//!   `Km·i_comp·[cos δ̂·(1 − cq) + sin δ̂·cd]`. So `i_comp = S(θ̂e, I_hold·cos δ̂,
//!   I_hold·sin δ̂) / [cos δ̂·(1 − cq(θ̂e)) + sin δ̂·cd(θ̂e)]`, times `Km/K̂m`. Without the
//!   current parts this is the `S/cos δ̂` of [`crate::observer`].
//!
//! **The divisor is bounded below by [`MIN_DIVISOR`] = ½** (so the compensation is at most
//! twice `S`; NaN gives ½). Below it the motor's torque per ampere at that angle would be
//! under half its mean (or the rotor more than 60° off the current): a broken motor or a
//! lost estimate, where a larger current would not help. Measured motors have `|cq|` below
//! about 0.1 (`3·h3 + 5·h5 + g/2` at thirds of 1.5 %, fifths of 0.6 %, phases 4 % apart),
//! so the bound never acts on them; it is the bound the estimated law already put on
//! `cos δ̂`.
//!
//! A model without current parts ([`CurrentRipple::NONE`]) runs exactly the code and the
//! bits of the detent-only laws.
//!
//! [`total_ripple`] gives the total ripple at one operating point, `T0 + i_d·D + i_q·Q̃`
//! harmonic by harmonic (no controller involved: what the C API's `sd_motor_ripple` returns).

use crate::config::{Compensation, ConfigError, Mode, MotorModel, Reason};
use crate::detent::{Harmonic, HarmonicSeries, MAX_HARMONIC_ORDER};
use crate::limits::{CURRENT_RIPPLE_NM_PER_A, CURRENT_RIPPLE_PHASE_RAD};
use crate::park::Dq;

/// Smallest divisor of the operating-point laws (module doc): the compensation is at most
/// twice the ripple current `S`.
pub const MIN_DIVISOR: f32 = 0.5;

/// The ripple that grows with the current, as the controller is given it: harmonics in the
/// detent's convention (torque on the rotor `−A·sin(k·θe + φ)`), with `amplitude_nm` in
/// **N·m per ampere** of rotor-frame current. Orders `1..=MAX_HARMONIC_ORDER`, amplitudes
/// within [`CURRENT_RIPPLE_NM_PER_A`], phases within [`CURRENT_RIPPLE_PHASE_RAD`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentRipple<'a> {
    /// Ripple per ampere of `i_d`, `D(θe)`.
    pub per_amp_d: &'a [Harmonic],
    /// Ripple per ampere of `i_q` without its mean (the mean is `Km`), `Q̃(θe)`.
    pub per_amp_q: &'a [Harmonic],
}

impl CurrentRipple<'static> {
    /// No ripple that grows with the current: a pure-sine motor with equal phases.
    pub const NONE: CurrentRipple<'static> = CurrentRipple { per_amp_d: &[], per_amp_q: &[] };
}

/// The three tables scaled by `1/Km` (module doc), arranged for the configured law.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RippleModel {
    /// `c0` in A, or, for the open-loop laws at `θ_cmd`, `c0 + I_hold·cd`.
    pub(crate) fixed: HarmonicSeries,
    /// `cd` in A/A (zero where the law does not use it).
    pub(crate) per_amp_d: HarmonicSeries,
    /// `cq` in A/A (zero where the law does not use it).
    pub(crate) per_amp_q: HarmonicSeries,
    /// Whether the step evaluates `cd`, `cq` at its operating point (else only `fixed`).
    pub(crate) current_dependent: bool,
}

/// The model at one angle and operating point ([`RippleModel::eval`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RippleValue {
    /// `S(θe, i_d, i_q)` in A.
    pub current_a: f32,
    /// `dS/dθe` at fixed currents, A/rad.
    pub slope: f32,
    /// `d²S/dθe²` at fixed currents, A/rad².
    pub curvature: f32,
    /// `cd(θe)`, A/A.
    pub per_amp_d: f32,
    /// `cq(θe)`, A/A.
    pub per_amp_q: f32,
    /// `dcd/dθe`, A/A per rad ([`RippleModel::eval_with_emf_slopes`] only, else 0).
    pub per_amp_d_slope: f32,
    /// `dcq/dθe`, A/A per rad ([`RippleModel::eval_with_emf_slopes`] only, else 0).
    pub per_amp_q_slope: f32,
}

impl RippleModel {
    /// The model of `detent` (N·m) and `ripple` (N·m/A), scaled by `1/Km`, arranged for
    /// `mode` and `compensation`: nothing when the compensation is off; open loop at
    /// `θ_cmd` (every law but the estimated one) folds `I_hold·cd` into the fixed table;
    /// servo keeps `cq` (its `i_d` is 0); the estimated open loop keeps both.
    pub(crate) fn new(
        detent: HarmonicSeries,
        ripple: &CurrentRipple<'_>,
        inv_km: f32,
        holding_current_a: f32,
        mode: Mode,
        compensation: Compensation,
    ) -> Result<RippleModel, ConfigError> {
        let table = |h| HarmonicSeries::within_limits(h, inv_km, &CURRENT_RIPPLE_NM_PER_A, &CURRENT_RIPPLE_PHASE_RAD);
        let (d, q) = (table(ripple.per_amp_d)?, table(ripple.per_amp_q)?);
        let zero = HarmonicSeries::default();
        let m = match (compensation, mode) {
            (Compensation::Off, _) => RippleModel::default(),
            (Compensation::Estimated, Mode::OpenLoop) => RippleModel {
                fixed: detent,
                per_amp_d: d,
                per_amp_q: q,
                current_dependent: d.max_order() > 0 || q.max_order() > 0,
            },
            (_, Mode::OpenLoop) => RippleModel {
                fixed: detent.plus_scaled(&d, holding_current_a),
                per_amp_d: zero,
                per_amp_q: zero,
                current_dependent: false,
            },
            (_, Mode::Servo) => {
                RippleModel { fixed: detent, per_amp_d: zero, per_amp_q: q, current_dependent: q.max_order() > 0 }
            }
        };
        Ok(m)
    }

    /// All coefficients finite (a scale of `1/Km` can overflow them).
    pub fn is_finite(&self) -> bool {
        self.fixed.is_finite() && self.per_amp_d.is_finite() && self.per_amp_q.is_finite()
    }

    /// Whether the step evaluates the current parts at its operating point.
    pub fn is_current_dependent(&self) -> bool {
        self.current_dependent
    }

    /// The table the step evaluates when [`RippleModel::is_current_dependent`] is false.
    pub fn fixed(&self) -> &HarmonicSeries {
        &self.fixed
    }

    /// `S`, its derivatives in `θe` and `cd`, `cq` at `(sin θe, cos θe)` and rotor-frame
    /// currents `i_d`, `i_q` (A), in one pass over the orders (one rotation per order, as
    /// [`HarmonicSeries::eval_with_derivatives`]). Kept out of line: only a motor with
    /// current parts calls it, and the step inlines its two callers (open loop, servo).
    /// The slopes of `cd`, `cq` are left 0: only the estimated law needs them
    /// ([`RippleModel::eval_with_emf_slopes`]), and the servo law does not pay for them.
    #[inline(never)]
    pub fn eval(&self, s1: f32, c1: f32, i_d: f32, i_q: f32) -> RippleValue {
        self.eval_impl::<false>(s1, c1, i_d, i_q)
    }

    /// [`RippleModel::eval`] with the slopes of `cd`, `cq` in `θe` as well
    /// ([`back_emf_angle_rad`] needs them).
    #[inline(never)]
    pub fn eval_with_emf_slopes(&self, s1: f32, c1: f32, i_d: f32, i_q: f32) -> RippleValue {
        self.eval_impl::<true>(s1, c1, i_d, i_q)
    }

    #[inline(always)]
    fn eval_impl<const SLOPES: bool>(&self, s1: f32, c1: f32, i_d: f32, i_q: f32) -> RippleValue {
        let (f, d, q) = (&self.fixed, &self.per_amp_d, &self.per_amp_q);
        let orders = f.max_order.max(d.max_order).max(q.max_order).min(MAX_HARMONIC_ORDER);
        let (mut sk, mut ck) = (s1, c1);
        let mut v = RippleValue::default();
        for k in 0..orders {
            let kf = k as f32 + 1.0;
            let a = f.sin_coef[k] + i_d * d.sin_coef[k] + i_q * q.sin_coef[k];
            let b = f.cos_coef[k] + i_d * d.cos_coef[k] + i_q * q.cos_coef[k];
            let term = a * sk + b * ck;
            v.current_a += term;
            v.slope += kf * (a * ck - b * sk);
            v.curvature -= kf * kf * term;
            v.per_amp_d += d.sin_coef[k] * sk + d.cos_coef[k] * ck;
            v.per_amp_q += q.sin_coef[k] * sk + q.cos_coef[k] * ck;
            if SLOPES {
                v.per_amp_d_slope += kf * (d.sin_coef[k] * ck - d.cos_coef[k] * sk);
                v.per_amp_q_slope += kf * (q.sin_coef[k] * ck - q.cos_coef[k] * sk);
            }
            let next_s = sk * c1 + ck * s1;
            ck = ck * c1 - sk * s1;
            sk = next_s;
        }
        v
    }
}

/// The divisor of the operating-point laws (module doc), `cos δ·(1 − cq) + sin δ·cd`,
/// bounded below by [`MIN_DIVISOR`] (NaN gives it). Servo: `δ = 0`.
#[inline]
pub fn divisor(v: &RippleValue, sin_delta: f32, cos_delta: f32) -> f32 {
    crate::at_least(cos_delta * (1.0 - v.per_amp_q) + sin_delta * v.per_amp_d, MIN_DIVISOR)
}

/// The angle `ε` by which a real motor's back-EMF leads its rotor's q axis (towards +d) at
/// the rotor angle `lag` rad (electrical) behind the one `v` was evaluated at, electrical
/// rad: `ε ≈ −cd/(1 − cq)` (the back-EMF per rad/s is the torque per ampere,
/// docs/design.md#real-motors-flux-harmonics), moved along its slope
/// `ε' = −(cd' − ε·cq')/(1 − cq)` by `−ε'·lag` (first order: `lag` is a few mrad, at most
/// 0.1 rad from the observer). 0 for a pure sine (`cd`, `cq` and their slopes 0). `v` must
/// come from [`RippleModel::eval_with_emf_slopes`]: [`RippleModel::eval`] leaves the slopes 0,
/// and the lag would be ignored. `1 − cq` is bounded below by [`MIN_DIVISOR`].
#[inline(always)]
pub fn back_emf_angle_rad(v: &RippleValue, lag: f32) -> f32 {
    let den = crate::at_least(1.0 - v.per_amp_q, MIN_DIVISOR);
    let eps = -v.per_amp_d / den;
    let slope = -(v.per_amp_d_slope - eps * v.per_amp_q_slope) / den;
    eps - slope * lag
}

/// The back-EMF of the ripple's current parts at the rotor angle of `v`, in V, in the
/// control frame `θc` that is `δ` ahead of the rotor (`sin δ`, `cos δ`): what the estimated
/// law feeds forward into the current loop (docs/design.md#the-ripples-back-emf).
///
/// The back-EMF per rad/s (mechanical) is the torque per ampere (power balance,
/// `e·i = τ·ω`), so in the rotor's frame the ripple's part of it is
/// `K̂m·ω·(−cd(θe), −cq(θe))`; `km_omega_v` is `K̂m·ω` in V. The mean, `K̂m·ω` on the rotor's
/// q axis, is left to the current loop's integrators, which follow it (it moves with the
/// load angle only); its harmonics, at 2, 4, 6… times the electrical speed in that frame,
/// they do not.
#[inline(always)]
pub fn ripple_back_emf_v(v: &RippleValue, km_omega_v: f32, sin_delta: f32, cos_delta: f32) -> Dq {
    let (d, q) = (-v.per_amp_d * km_omega_v, -v.per_amp_q * km_omega_v);
    // A rotor-frame vector in the frame δ ahead: turned back by δ.
    Dq { d: d * cos_delta + q * sin_delta, q: q * cos_delta - d * sin_delta }
}

/// The total ripple of a motor at one operating point ([`total_ripple`]): harmonics in the
/// detent's convention (torque on the rotor `−A·sin(k·θe + φ)`), `amplitude_nm` in N·m
/// (> 0), `phase_rad` in (−π, π], ascending orders; an order whose total is 0 is left out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TotalRipple {
    harmonics: [Harmonic; MAX_HARMONIC_ORDER],
    len: usize,
}

impl TotalRipple {
    /// The harmonics, at most [`MAX_HARMONIC_ORDER`].
    pub fn harmonics(&self) -> &[Harmonic] {
        self.harmonics.get(..self.len).unwrap_or(&[])
    }
}

/// The ripple torque on the rotor of `motor` at rotor-frame currents `(i_d_a, i_q_a)` in A,
/// detent plus the ripple that grows with the current, harmonic by harmonic (module doc:
/// the ripple is linear in the currents at each angle, so each order is the complex sum
/// `T0_k + i_d·D_k + i_q·Q̃_k`). Open loop at the holding current is `(I_hold, 0)`, a servo
/// `(0, i_q)`. The same total as `stepdamp_profile::ripple::ripple` in `f32` from the
/// controller's tables (docs/design.md#real-motors-flux-harmonics).
///
/// Errors: a table the controller would refuse (as [`crate::Config::new`]: orders,
/// duplicates, amplitude and phase ranges); a non-finite current, or a current vector
/// beyond `current_limit_a` (A, each component and the magnitude, as the command line's
/// `motor ripple`), is [`ConfigError::Invalid`] naming `i_d_a` or `i_q_a`. No allocation,
/// never panics; `f32` rounding only (relative ~1e-7 of the largest term per order).
pub fn total_ripple(
    motor: &MotorModel<'_>,
    current_limit_a: f32,
    i_d_a: f32,
    i_q_a: f32,
) -> Result<TotalRipple, ConfigError> {
    let refuse = |field, value, why| Err(ConfigError::Invalid { field, value, reason: Reason::Other(why) });
    let within = |v: f32| v.is_finite() && libm::fabsf(v) <= current_limit_a;
    if !within(i_d_a) {
        return refuse("i_d_a", i_d_a, "must be finite and within ±drive.current_limit_a");
    }
    if !within(i_q_a) {
        return refuse("i_q_a", i_q_a, "must be finite and within ±drive.current_limit_a");
    }
    // The components passed, so the limit is not NaN (a NaN limit refuses every current).
    if libm::hypotf(i_d_a, i_q_a) > current_limit_a {
        return refuse("i_q_a", i_q_a, "the current vector (i_d_a, i_q_a) must be within drive.current_limit_a");
    }
    let table = |h| HarmonicSeries::within_limits(h, 1.0, &CURRENT_RIPPLE_NM_PER_A, &CURRENT_RIPPLE_PHASE_RAD);
    let (d, q) = (table(motor.current_ripple.per_amp_d)?, table(motor.current_ripple.per_amp_q)?);
    let total = HarmonicSeries::new(motor.detent, 1.0)?.plus_scaled(&d, i_d_a).plus_scaled(&q, i_q_a);
    let mut out = TotalRipple { harmonics: [Harmonic::default(); MAX_HARMONIC_ORDER], len: 0 };
    for (k, (&a, &b)) in total.sin_coef.iter().zip(&total.cos_coef).enumerate() {
        let (amplitude_nm, phase_rad) = polar(a, b);
        if !amplitude_nm.is_finite() {
            // Only for a current limit far beyond the controller's (f32 overflow).
            return refuse("i_q_a", i_q_a, "the ripple at this current is not finite in f32");
        }
        if amplitude_nm == 0.0 {
            continue;
        }
        if let Some(slot) = out.harmonics.get_mut(out.len) {
            *slot = Harmonic { order: k as u16 + 1, amplitude_nm, phase_rad };
            out.len += 1;
        }
    }
    Ok(out)
}

/// `(A, φ)` with `a·sin x + b·cos x = A·sin(x + φ)`: `A = |(a, b)|`, `φ = atan2(b, a)` in
/// (−π, π] (atan2's −π, from a `b` of −0 or below its rounding, is π; a phase of −0 is 0).
fn polar(a: f32, b: f32) -> (f32, f32) {
    let phase = libm::atan2f(b, a) + 0.0;
    (libm::hypotf(a, b), if phase <= -core::f32::consts::PI { core::f32::consts::PI } else { phase })
}

#[cfg(test)]
mod tests;
