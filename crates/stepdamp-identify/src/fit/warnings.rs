//! What the data cannot tell the fit: the warnings, their text, and the checks that raise them.

use super::design::Columns;
use super::thresholds::{MAX_HARMONIC_PER_BANDWIDTH, MAX_STALLED_FRACTION, MIN_COUNT_RATE_PER_BANDWIDTH};
use super::{Estimate, FitOptions};
use crate::lsq;
use std::f64::consts::TAU;

/// Why the data cannot fully separate the model's terms (the fit still ran).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub enum Warning {
    /// Few electrical periods in a direction.
    FewPeriods {
        /// `forward` or `reverse`.
        direction: &'static str,
        /// Periods logged.
        periods: f64,
        /// Periods recommended.
        recommended: f64,
    },
    /// Only one direction of travel: `Fs` (and `D`) absorb any constant torque.
    OneDirection {
        /// The direction logged.
        direction: &'static str,
    },
    /// One speed only: `D` is not separable from `Fs`.
    SingleSpeed {
        /// The speed in rad/s.
        speed_rad_s: f64,
        /// The `D` used instead, N·m·s/rad.
        viscous_used: f64,
    },
    /// Both directions, but one speed in each (and different speeds): two levels for `Fs`,
    /// `D` and `c`, so `D` is held and `Fs` and `c` are fitted.
    OneSpeedPerDirection {
        /// Mean `|ω̄|` of the forward logs, rad/s.
        forward_rad_s: f64,
        /// Mean `|ω̄|` of the reverse logs, rad/s.
        reverse_rad_s: f64,
        /// The `D` used instead, N·m·s/rad.
        viscous_used: f64,
        /// A run that would separate `D`: its direction (`forward` or `reverse`) and speed
        /// in rad/s.
        add_run: (&'static str, f64),
    },
    /// The fitted `Fs` is negative (clamped to 0 in the profile) or not significantly above
    /// zero.
    CoulombNotPositive {
        /// Fitted `Fs`, N·m.
        value_nm: f64,
        /// Its 95 % half-width, N·m.
        ci95_nm: f64,
        /// The only direction logged, when `c` could not be fitted.
        one_direction: Option<&'static str>,
        /// The `D` held (not fitted), N·m·s/rad.
        viscous_held: Option<f64>,
    },
    /// The fitted `D` is negative (clamped to 0 in the profile).
    ViscousNegative {
        /// Fitted `D`, N·m·s/rad.
        value: f64,
        /// Its 95 % half-width, N·m·s/rad.
        ci95: f64,
    },
    /// A harmonic is too fast for the servo to follow.
    TooFast {
        /// Log.
        source: String,
        /// Harmonic order.
        order: u16,
        /// Its frequency at the log's speed, Hz.
        harmonic_hz: f64,
        /// Servo bandwidth, Hz.
        bandwidth_hz: f64,
    },
    /// Inertia carries a large share of the ripple (the loop did not hold the speed).
    InertialShare {
        /// Log.
        source: String,
        /// Share (see [`RunSummary::inertial_share`]).
        share: f64,
    },
    /// The encoder stepped backwards: servo jitter reverses the rotor faster than the
    /// smoothed speed shows, so friction is underestimated.
    Reversing {
        /// Log.
        source: String,
        /// Fraction of encoder steps that went backwards.
        fraction: f64,
    },
    /// The encoder counts slower than the servo reacts: quantisation jitter makes the rotor
    /// stop and start within a count, and friction comes out low.
    SlowForEncoder {
        /// Log.
        source: String,
        /// Encoder counts per second at the log's speed.
        count_rate_hz: f64,
        /// Counts per second recommended: the servo bandwidth in rad/s.
        needed_hz: f64,
    },
    /// Many samples left out because the rotor was (nearly) stopped.
    Stalled {
        /// Log.
        source: String,
        /// Fraction left out.
        fraction: f64,
    },
    /// A term is strongly correlated with others.
    Confounded {
        /// The term.
        term: String,
        /// Its variance inflation factor.
        inflation: f64,
    },
    /// The fitted `J` differs from the base profile's by more than
    /// [`FitOptions::max_inertia_disagreement`].
    InertiaDisagrees {
        /// Fitted `J`, kg·m².
        value: f64,
        /// Its 95 % half-width, kg·m².
        ci95: f64,
        /// The base profile's `J`, kg·m².
        base: f64,
    },
    /// The fitted `J` is not positive or its interval is wide: the logs hold too little
    /// acceleration that is not periodic with the detent.
    InertiaUncertain {
        /// Fitted `J`, kg·m².
        value: f64,
        /// Its 95 % half-width, kg·m².
        ci95: f64,
    },
    /// A harmonic smaller than its own uncertainty.
    NotSignificant {
        /// Order.
        order: u16,
    },
    /// A condition of the logs ([`crate::conditions`]).
    Condition(crate::conditions::Condition),
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::FewPeriods { direction, periods, recommended } => write!(
                f,
                "only {periods:.1} electrical periods logged {direction} (≥ {recommended:.0} recommended): harmonics are poorly averaged"
            ),
            Warning::OneDirection { direction } => write!(
                f,
                "only {direction} travel logged: Fs is confounded with any constant torque (load, current offset) and reported as the mean friction of that direction"
            ),
            Warning::SingleSpeed { speed_rad_s, viscous_used } => write!(
                f,
                "one speed only (|ω| ≈ {speed_rad_s:.3} rad/s): D cannot be separated from Fs; D held at {viscous_used:.3e} N·m·s/rad (log a second speed at least 1.3× apart)"
            ),
            Warning::OneSpeedPerDirection { forward_rad_s, reverse_rad_s, viscous_used, add_run: (dir, speed) } => {
                write!(
                    f,
                    "forward at {forward_rad_s:.3} rad/s and reverse at {reverse_rad_s:.3} rad/s only: with one speed per direction D·ω cannot be separated from Fs·sgn(ω) and the constant torque; D held at {viscous_used:.3e} N·m·s/rad, Fs and the constant torque fitted (log a second speed in one direction, e.g. {dir} at {speed:.3} rad/s)"
                )
            }
            Warning::CoulombNotPositive { value_nm, ci95_nm, one_direction, viscous_held } => {
                let (v, ci) = (1e3 * value_nm, 1e3 * ci95_nm);
                if *value_nm < 0.0 {
                    write!(
                        f,
                        "Fs fitted negative ({v:.3} ± {ci:.3} mN·m) and clamped to 0 in the profile: friction cannot drive the rotor"
                    )?;
                } else {
                    write!(f, "Fs = {v:.3} ± {ci:.3} mN·m is not significantly above 0")?;
                }
                match one_direction {
                    Some(dir) => write!(
                        f,
                        "; likely a constant torque (a load, or a current-sensor offset) counted as friction because only {dir} travel is logged (log the other direction too), or too little data"
                    )?,
                    None => write!(f, "; likely too little data or too much noise (log longer runs)")?,
                }
                match viscous_held {
                    Some(d) => write!(f, ", or the D held ({d:.3e} N·m·s/rad) is too large"),
                    None => Ok(()),
                }
            }
            Warning::ViscousNegative { value, ci95 } => write!(
                f,
                "D fitted negative ({value:.3e} ± {ci95:.1e} N·m·s/rad) and clamped to 0 in the profile: likely too little data, or speeds too close together to separate D from Fs"
            ),
            Warning::TooFast { source, order, harmonic_hz, bandwidth_hz } => write!(
                f,
                "{source}: harmonic {order} at {harmonic_hz:.1} Hz is not well inside the servo bandwidth {bandwidth_hz:.0} Hz: the loop does not follow it and the result leans on J·dω/dt from the encoder (run slower)"
            ),
            Warning::InertialShare { source, share } => write!(
                f,
                "{source}: J·dω/dt is {:.0} % of the detent ripple (the loop did not hold the speed): a 10 % error in J moves the harmonics by about {:.0} %",
                100.0 * share,
                10.0 * share
            ),
            Warning::Reversing { source, fraction } => write!(
                f,
                "{source}: {:.1} % of the encoder steps go backwards: the servo's jitter reverses the rotor, so Fs comes out low (run faster: count rate ≥ servo bandwidth in rad/s, or soften the servo)",
                100.0 * fraction
            ),
            Warning::SlowForEncoder { source, count_rate_hz, needed_hz } => write!(
                f,
                "{source}: the encoder counts {count_rate_hz:.0} times/s, fewer than the servo bandwidth in rad/s ({needed_hz:.0}): quantisation jitter stalls the rotor within a count and Fs comes out low (run faster)"
            ),
            Warning::Stalled { source, fraction } => write!(
                f,
                "{source}: rotor nearly stopped in {:.0} % of the samples (left out: static friction)",
                100.0 * fraction
            ),
            Warning::Confounded { term, inflation } => write!(
                f,
                "{term} is hard to separate from the other terms (variance inflation {inflation:.0}); its interval is wide"
            ),
            Warning::InertiaDisagrees { value, ci95, base } => write!(
                f,
                "J identified {value:.3e} ± {ci95:.1e} kg·m² differs from the base profile's {base:.3e} kg·m² by {:+.0} % (a load coupled to the rotor, or a wrong profile): the identified J is written to the profile; plan the servo again with it",
                100.0 * (value / base - 1.0)
            ),
            Warning::InertiaUncertain { value, ci95 } => write!(
                f,
                "J identified {value:.3e} ± {ci95:.1e} kg·m² is poorly determined (the rotor hardly accelerated apart from the detent ripple): the harmonics lean on it; log runs at two speeds in both directions"
            ),
            Warning::NotSignificant { order } => {
                write!(f, "harmonic {order} is smaller than its own 95 % interval: not detected")
            }
            Warning::Condition(c) => c.fmt(f),
        }
    }
}

/// The warnings about one log (its share of stalled samples, reversing steps, and speed for
/// the encoder and the servo); `wbar` is its mean speed, rad/s.
pub(super) fn of_run(
    source: &str,
    o: &FitOptions,
    stalled_fraction: f64,
    back: f64,
    wbar: f64,
    kmax: u16,
    highest_harmonic_hz: f64,
) -> Vec<Warning> {
    let mut warnings = Vec::new();
    if stalled_fraction > MAX_STALLED_FRACTION {
        warnings.push(Warning::Stalled { source: source.to_string(), fraction: stalled_fraction });
    }
    if back > o.max_back_step_fraction {
        warnings.push(Warning::Reversing { source: source.to_string(), fraction: back });
    }
    if let (Some(bw), Some(cpr)) = (o.servo_bandwidth_hz, o.counts_per_rev) {
        let count_rate = f64::from(cpr) * wbar.abs() / TAU;
        if count_rate < MIN_COUNT_RATE_PER_BANDWIDTH * TAU * bw {
            warnings.push(Warning::SlowForEncoder {
                source: source.to_string(),
                count_rate_hz: count_rate,
                needed_hz: TAU * bw,
            });
        }
    }
    if let Some(bw) = o.servo_bandwidth_hz
        && highest_harmonic_hz > MAX_HARMONIC_PER_BANDWIDTH * bw
    {
        warnings.push(Warning::TooFast {
            source: source.to_string(),
            order: kmax,
            harmonic_hz: highest_harmonic_hz,
            bandwidth_hz: bw,
        });
    }
    warnings
}

/// The warnings about the estimates: `J` uncertain or far from the base's, `Fs` not
/// positive, `D` negative, terms confounded (variance inflation).
#[allow(clippy::too_many_arguments)] // the estimates of one solve, named
pub(super) fn of_estimates(
    o: &FitOptions,
    cols: &Columns,
    sol: &lsq::Solution,
    coulomb: Estimate,
    viscous: Option<Estimate>,
    inertia: Option<Estimate>,
    one_direction: Option<&'static str>,
    fit_d: bool,
) -> Vec<Warning> {
    let mut warnings = Vec::new();
    if let Some(j) = inertia {
        if !(j.value > 0.0 && j.ci95 < o.max_inertia_disagreement * j.value) {
            warnings.push(Warning::InertiaUncertain { value: j.value, ci95: j.ci95 });
        } else if o.inertia_kg_m2 > 0.0 && (j.value / o.inertia_kg_m2 - 1.0).abs() > o.max_inertia_disagreement {
            warnings.push(Warning::InertiaDisagrees { value: j.value, ci95: j.ci95, base: o.inertia_kg_m2 });
        }
    }
    if coulomb.value < coulomb.ci95 {
        warnings.push(Warning::CoulombNotPositive {
            value_nm: coulomb.value,
            ci95_nm: coulomb.ci95,
            one_direction,
            viscous_held: (!fit_d).then_some(o.viscous_fallback_nm_s_per_rad),
        });
    }
    if let Some(d) = viscous
        && d.value < 0.0
    {
        warnings.push(Warning::ViscousNegative { value: d.value, ci95: d.ci95 });
    }
    for (c, name) in [(Some(cols.fs), "Fs"), (cols.d, "D"), (cols.c, "the constant torque"), (cols.j, "J")] {
        if let Some(c) = c
            && sol.inflation[c] > o.max_inflation
        {
            warnings.push(Warning::Confounded { term: name.to_string(), inflation: sol.inflation[c] });
        }
    }
    for (j, &k) in o.orders.iter().enumerate() {
        let inf = sol.inflation[2 * j].max(sol.inflation[2 * j + 1]);
        if inf > o.max_inflation {
            warnings.push(Warning::Confounded { term: format!("harmonic {k}"), inflation: inf });
        }
    }
    warnings
}
