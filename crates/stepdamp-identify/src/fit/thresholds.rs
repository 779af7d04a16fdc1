//! The fixed numbers of the fit, named, with where each comes from.
//!
//! Numbers a user may want to change are fields of [`super::FitOptions`] instead (their
//! defaults are set, and documented, in [`super::FitOptions::for_profile`]). The ones here
//! are properties of the method. Those marked *heuristic* were chosen when the fit was
//! written (commit `1d8a1ba`) and have no measurement recorded behind them; the tests of
//! the crate (patent-motor, 50 random motors, `tests/stress_family.rs`) pass with them, and
//! changing one is a behaviour change to be measured with those tests.

/// Fewest samples of steady running a log must leave (after the speed filter's start-up at
/// each end is dropped; [`super::FitError::TooShort`] and [`super::FitError::Unsteady`]
/// quote it as "more than 16"). Heuristic: a floor against degenerate logs; the
/// least-squares solve checks the rows against the unknowns separately ([`crate::lsq`]).
pub(crate) const MIN_STEADY_SAMPLES: usize = 17;

/// The steady window of a log runs from the first to the last sample whose smoothed speed
/// is at least this fraction of the log's mean speed in its direction: it drops the start
/// from rest, the ramp and a final stop. Heuristic (the speed ripple at identification
/// speeds is tens of percent, so the bar sits below it).
pub(crate) const STEADY_SPEED_FRACTION: f64 = 0.8;

/// Warn ([`super::Warning::Stalled`]) when more than this fraction of a log's steady window
/// is left out as (nearly) stopped or stuck. Heuristic: 2 % of the samples is where the
/// friction estimate starts to depend on the stick detection.
pub(crate) const MAX_STALLED_FRACTION: f64 = 0.02;

/// Warn ([`super::Warning::SlowForEncoder`]) when the encoder's count rate is below this
/// fraction of the servo bandwidth in rad/s (`2π·f_b`). The module documentation records
/// why (too slow a count rate underestimates `Fs` by 10–40 %); the factor 0.7 below 1 is
/// heuristic margin, so that the plan's slow speed (chosen at about the bandwidth) does not
/// warn.
pub(crate) const MIN_COUNT_RATE_PER_BANDWIDTH: f64 = 0.7;

/// Warn ([`super::Warning::TooFast`]) when the highest fitted harmonic runs above this
/// fraction of the servo bandwidth in Hz: the loop no longer follows it and the fit relies
/// on `J·dω/dt`. Heuristic (the same statement is made by the plan, [`crate::plan`], at the
/// bandwidth itself).
pub(crate) const MAX_HARMONIC_PER_BANDWIDTH: f64 = 0.8;

/// Fewest blocks of the robust covariance per log ([`crate::lsq`]). A log of at least this
/// many electrical periods gets one block per period; a shorter one is cut into this many.
/// Ten blocks per log keep the block count well above the columns (the robust estimate
/// needs `B ≥ 2p` blocks, [`crate::lsq::solve`]).
pub(crate) const MIN_BLOCKS_PER_LOG: f64 = 10.0;

/// The 97.5 % quantile of the standard normal distribution: a standard deviation times this
/// is the 95 % two-sided half-width.
pub(crate) const Z_95: f64 = 1.96;
