//! The result of a fit, its errors, and the polar form of a harmonic with its interval.

use super::Warning;
use super::thresholds::Z_95;
use crate::lsq::LsqError;
use std::f64::consts::{PI, TAU};

/// A value with its 95 % confidence half-width.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Estimate {
    /// The value.
    pub value: f64,
    /// Half-width of the 95 % confidence interval (same unit).
    pub ci95: f64,
}

/// One identified detent harmonic.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct HarmonicEstimate {
    /// Order `k`.
    pub order: u16,
    /// Amplitude `A_k` in N·m with its 95 % half-width.
    pub amplitude_nm: Estimate,
    /// Phase `φ_k` in rad, in `(−π, π]`, profile convention, with its 95 % half-width.
    pub phase_rad: Estimate,
    /// `a_k = A_k cos φ_k` in N·m (coefficient of `sin kθe`).
    pub a_nm: f64,
    /// `b_k = A_k sin φ_k` in N·m (coefficient of `cos kθe`).
    pub b_nm: f64,
}

/// What a log contributed.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RunSummary {
    /// Source name.
    pub source: String,
    /// Mean speed in rad/s (slope of the line through `θ_fb(t)`).
    pub mean_speed_rad_s: f64,
    /// Duration of the steady window used, s.
    pub duration_s: f64,
    /// Electrical periods in the steady window.
    pub electrical_periods: f64,
    /// Samples used in the fit.
    pub samples_used: usize,
    /// Samples in the log.
    pub samples: usize,
    /// Frequency of the highest fitted harmonic at the mean speed, Hz.
    pub highest_harmonic_hz: f64,
    /// RMS of `J·dω/dt` over RMS of the detent ripple fitted (0–1+): how much the loop
    /// failed to hold the speed. A relative error `x` in `J` moves the harmonics by about
    /// `x·share`.
    pub inertial_share: f64,
    /// Fraction of the encoder steps against the direction of travel.
    pub back_step_fraction: f64,
}

/// Result of a fit.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Fit {
    /// Harmonics in the order asked for.
    pub harmonics: Vec<HarmonicEstimate>,
    /// Coulomb friction `Fs` in N·m.
    pub coulomb_friction_nm: Estimate,
    /// Viscous friction `D` in N·m·s/rad; `None` when not separable (the fallback was used).
    pub viscous_nm_s_per_rad: Option<Estimate>,
    /// `D` used in the model (fitted or the fallback), N·m·s/rad.
    pub viscous_used: f64,
    /// Constant torque `c` in N·m (both directions logged only).
    pub offset_nm: Option<Estimate>,
    /// Rotor + load inertia `J` in kg·m² when fitted ([`FitOptions::fit_inertia`]).
    pub inertia_kg_m2: Option<Estimate>,
    /// `J` used in the model (fitted, or [`FitOptions::inertia_kg_m2`] held), kg·m².
    pub inertia_used: f64,
    /// RMS of the fit residual in N·m.
    pub residual_rms_nm: f64,
    /// RMS of the fitted detent ripple `Σ A sin(…)` over the samples, N·m.
    pub ripple_rms_nm: f64,
    /// Samples used.
    pub samples_used: usize,
    /// Condition number of the scaled regressors.
    pub condition: f64,
    /// Per-log summaries.
    pub runs: Vec<RunSummary>,
    /// Warnings.
    pub warnings: Vec<Warning>,
    /// Which `J` was used and why ([`crate::conditions`]).
    pub decisions: Vec<crate::conditions::Decision>,
    /// The samples used, for reports: electrical angle `Nr·θ_fb` (rad, wrapped to
    /// `[0, 2π)`), the torque the model explains (`Km·i − J·α` minus friction and `c`,
    /// N·m), and the residual (N·m).
    #[serde(skip)]
    pub samples: FitSamples,
}

/// Per-sample data of a fit (for plots and spectra).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FitSamples {
    /// Electrical angle in rad, `[0, 2π)`.
    pub theta_e_rad: Vec<f64>,
    /// Periodic part of the needed torque (needed torque minus friction and offset), N·m.
    pub ripple_nm: Vec<f64>,
    /// Residual of the fit, N·m.
    pub residual_nm: Vec<f64>,
}

/// Why a fit could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// No logs given.
    #[error("no logs to fit")]
    NoLogs,
    /// Bad options.
    #[error("{0}")]
    Options(String),
    /// A log too short for the fit (whether or not the rotor moves).
    #[error(
        "{log}: too short: {samples} samples ({duration_s:.3} s, mean speed {speed:.3e} rad/s); at least {needed} are needed (more than 16 at steady speed, after the speed filter's start-up at each end): log a longer constant-speed run"
    )]
    TooShort {
        /// Log.
        log: String,
        /// Samples in the log.
        samples: usize,
        /// Its duration, s.
        duration_s: f64,
        /// Its mean speed, rad/s.
        speed: f64,
        /// Samples needed at this speed and sample rate.
        needed: usize,
    },
    /// A log in which the rotor (almost) does not move: at most one electrical period.
    #[error(
        "{log}: the rotor does not move: {periods:.2} electrical periods over the log (mean speed {speed:.3e} rad/s; more than one needed, and many for a good fit): identification needs constant-speed runs"
    )]
    NoMotion {
        /// Log.
        log: String,
        /// Its mean speed, rad/s.
        speed: f64,
        /// Electrical periods covered at that speed over the log.
        periods: f64,
    },
    /// A log long enough and moving, but not at a steady speed.
    #[error(
        "{log}: the speed is not steady: only {steady} samples lie between the first and the last sample running at ≥ 80 % of the mean speed {speed:.3e} rad/s (more than 16 needed): identification needs constant-speed runs"
    )]
    Unsteady {
        /// Log.
        log: String,
        /// Its mean speed, rad/s.
        speed: f64,
        /// Samples in the steady window found.
        steady: usize,
    },
    /// A value of the data or of the result is infinite or not a number: the data are out of
    /// range (too large to square in `f64`) or not numbers.
    #[error(
        "{what} is not finite (logs: {logs}; {detail}): values in the data are out of range (e.g. a current of 1e200 A) or not numbers; check the units and the columns"
    )]
    NonFinite {
        /// What is not finite.
        what: String,
        /// The logs fitted (their source names).
        logs: String,
        /// Where the data are largest (or not a number).
        detail: String,
    },
    /// Friction, damping or inertia came out significantly negative: the logs' current and
    /// angle disagree in sign (docs/identification.md#signs).
    #[error(
        "{terms} (logs: {logs}): friction, damping and inertia cannot be negative beyond their 95 % interval, so the current and the angle disagree in sign: likely a reversed current or angle sign (i_q_a or theta_fb_rad), swapped phases (A and B) or a sensor of reversed polarity; a positive i_q must turn the rotor towards positive theta_fb_rad: check by commanding a small positive i_q (or stepping theta_cmd forward in open loop) and watching theta_fb_rad grow, then fix the drive's or the logger's sign and log again (docs/identification.md#signs)"
    )]
    Unphysical {
        /// The negative terms with their values and intervals, e.g. `Fs = -8.1 ± 0.1 mN·m`.
        terms: String,
        /// The logs fitted (their source names).
        logs: String,
    },
    /// Too few usable samples, or the terms cannot be separated at all. The cause is part
    /// of the message, not a `source`, so an error chain prints it once.
    #[error("least squares failed: {0}")]
    Lsq(LsqError),
}

impl From<LsqError> for FitError {
    fn from(e: LsqError) -> Self {
        FitError::Lsq(e)
    }
}

/// Wraps an angle to `(−π, π]`.
pub fn wrap_pi(x: f64) -> f64 {
    let y = x.rem_euclid(TAU);
    if y > PI { y - TAU } else { y }
}

/// Amplitude and phase of `a sin x + b cos x = A sin(x + φ)` with 95 % half-widths by the
/// delta method from the covariance `[[vaa, vab], [vab, vbb]]` of `(a, b)`.
pub fn polar_with_ci(a: f64, b: f64, vaa: f64, vab: f64, vbb: f64) -> (Estimate, Estimate) {
    let amp = a.hypot(b);
    let (sd_a, sd_p) = if amp > 0.0 {
        let (ga, gb) = (a / amp, b / amp);
        let (ha, hb) = (-b / (amp * amp), a / (amp * amp));
        (
            (ga * ga * vaa + 2.0 * ga * gb * vab + gb * gb * vbb).max(0.0).sqrt(),
            (ha * ha * vaa + 2.0 * ha * hb * vab + hb * hb * vbb).max(0.0).sqrt(),
        )
    } else {
        ((vaa + vbb).max(0.0).sqrt(), PI)
    };
    (Estimate { value: amp, ci95: Z_95 * sd_a }, Estimate { value: wrap_pi(b.atan2(a)), ci95: (Z_95 * sd_p).min(PI) })
}
