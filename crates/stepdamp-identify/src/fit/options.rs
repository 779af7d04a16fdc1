//! The options of the fit and their checks.

use super::FitError;
use stepdamp_profile::Profile;

/// Which signal is the loop's effort.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Effort {
    /// The measured q current `i_q_a` (the torque the motor actually made).
    #[default]
    MeasuredIq,
    /// The loop's q current command `iq_cmd_a` (what the loop asked for).
    CommandIq,
}

stepdamp_core::named_choice!(Effort, "effort", "measured, command", [
    MeasuredIq => "measured",
    CommandIq => "command",
]);

/// Options of the fit.
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Harmonic orders `k` of the electrical angle to fit (distinct, ≥ 1).
    pub orders: Vec<u16>,
    /// Rotor pole pairs `Nr`.
    pub pole_pairs: u16,
    /// Torque constant `Km` in N·m/A.
    pub km_nm_per_a: f64,
    /// Rotor + load inertia `J` in kg·m² for the `J·dω/dt` term: the value held when
    /// [`FitOptions::fit_inertia`] is off (0 = ignore inertia), and the reference the fitted
    /// `J` is compared with when it is on.
    pub inertia_kg_m2: f64,
    /// Fit `J` as one more regressor on `dω/dt` (see the module documentation, *Inertia*)
    /// instead of holding [`FitOptions::inertia_kg_m2`].
    pub fit_inertia: bool,
    /// With [`FitOptions::fit_inertia`]: warn when the fitted `J` differs from
    /// [`FitOptions::inertia_kg_m2`] by more than this fraction.
    pub max_inertia_disagreement: f64,
    /// Encoder counts per revolution (for the quantisation correction and the smoothing
    /// corner); `None` when unknown.
    pub counts_per_rev: Option<u32>,
    /// Servo position-loop bandwidth in Hz (for the "too fast" warning); `None` when unknown.
    pub servo_bandwidth_hz: Option<f64>,
    /// `D` in N·m·s/rad used when the logs cannot separate it from `Fs` (one speed).
    pub viscous_fallback_nm_s_per_rad: f64,
    /// Effort signal.
    pub effort: Effort,
    /// Samples with `|ω| <` this fraction of the log's mean speed are left out (stiction).
    pub min_speed_fraction: f64,
    /// Fewest electrical periods in each direction before a warning.
    pub recommended_periods: f64,
    /// Fit against the edge-timed angle of [`crate::stick`] (between encoder edges, the
    /// angle interpolated in time) instead of the logged, quantised `θ_fb`, and leave out
    /// stuck samples (see the module documentation, *Choices*). Right for logs without
    /// feed-forward (the torque follows the true angle); off for feed-forward-on logs,
    /// whose fixed point is the feed-forward in the controller's own (quantised) angle.
    pub correct_quantisation: bool,
    /// Low-pass the effort with the filter that gives `dω/dt` (see the module
    /// documentation, *Inertia*). Right for logs without feed-forward; off for
    /// feed-forward-on logs, whose effort carries the feed-forward as a staircase in the
    /// encoder angle that must stay aligned with the regressors.
    pub smooth_effort: bool,
    /// Warn when more than this fraction of the encoder steps go against the direction of
    /// travel (the servo's quantisation jitter reverses the rotor, and friction is then
    /// underestimated).
    pub max_back_step_fraction: f64,
    /// Warn when `J·dω/dt` is more than this share of the fitted ripple.
    pub max_inertial_share: f64,
    /// Warn when a term's variance inflation factor exceeds this.
    pub max_inflation: f64,
    /// Stuck-sample detection ([`crate::stick`]).
    pub stick: crate::stick::StickOptions,
    /// How `J` is obtained when [`FitOptions::fit_inertia`] allows fitting it
    /// ([`crate::conditions`]).
    pub inertia: crate::conditions::InertiaMode,
}

impl FitOptions {
    /// Options for a motor profile (its `Km`, `Nr`, `J`, encoder, servo bandwidth and `D` as
    /// the fallback) and the given orders.
    pub fn for_profile(p: &Profile, orders: &[u16]) -> Self {
        FitOptions {
            orders: orders.to_vec(),
            pole_pairs: p.motor.pole_pairs,
            km_nm_per_a: p.motor.km_nm_per_a,
            inertia_kg_m2: p.motor.inertia_kg_m2,
            fit_inertia: true,
            max_inertia_disagreement: 0.2,
            counts_per_rev: Some(p.encoder.counts_per_rev),
            servo_bandwidth_hz: Some(p.servo.bandwidth_hz),
            viscous_fallback_nm_s_per_rad: p.motor.viscous_nm_s_per_rad,
            effort: Effort::MeasuredIq,
            min_speed_fraction: 0.1,
            recommended_periods: 10.0,
            correct_quantisation: true,
            smooth_effort: true,
            max_back_step_fraction: 0.02,
            max_inertial_share: 0.75,
            max_inflation: 50.0,
            stick: crate::stick::StickOptions::default(),
            inertia: crate::conditions::InertiaMode::Auto,
        }
    }
}

impl FitOptions {
    pub(super) fn check(&self) -> Result<(), FitError> {
        let bad = |m: String| Err(FitError::Options(m));
        if self.orders.is_empty() {
            return bad("no harmonic orders to fit".into());
        }
        for (i, &k) in self.orders.iter().enumerate() {
            if k == 0 || usize::from(k) > stepdamp_core::MAX_HARMONIC_ORDER {
                return bad(format!("harmonic order {k}: must be in 1..={}", stepdamp_core::MAX_HARMONIC_ORDER));
            }
            if self.orders[..i].contains(&k) {
                return bad(format!("harmonic order {k} is listed twice"));
            }
        }
        if self.pole_pairs == 0 {
            return bad("pole pairs must be ≥ 1".into());
        }
        if !(self.km_nm_per_a.is_finite() && self.km_nm_per_a > 0.0) {
            return bad(format!("Km = {}: must be > 0", self.km_nm_per_a));
        }
        if !(self.inertia_kg_m2.is_finite() && self.inertia_kg_m2 >= 0.0) {
            return bad(format!("J = {}: must be ≥ 0", self.inertia_kg_m2));
        }
        if !(self.min_speed_fraction.is_finite() && (0.0..1.0).contains(&self.min_speed_fraction)) {
            return bad(format!("min_speed_fraction = {}: must be in [0, 1)", self.min_speed_fraction));
        }
        Ok(())
    }
}
