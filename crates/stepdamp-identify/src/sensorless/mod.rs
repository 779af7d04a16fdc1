//! The sensorless route: the detent and friction from open-loop runs logged by the drive
//! itself, with no encoder (docs/sensorless.md).
//!
//! 1. [`log`]: the open-loop log (`t_s, theta_cmd_rad, i_a_a, i_b_a, v_a_v, v_b_v`).
//! 2. [`flux`]: the rotor's electrical angle from `∫(v − R i) dt − L i`, with `R` trimmed
//!    at the run's standstill.
//! 3. [`estimate`]: that angle and the Park current in it make an ordinary run log, and
//!    the torque balance is the servo route's ([`crate::fit`]) with [`fit_options`]: the
//!    angle is continuous (no quantisation correction, no stuck-sample detection on
//!    encoder edges) and the smoothing corner follows the harmonics only.
//! 4. [`plan`](mod@plan): the runs to record, with reasons.
//! 5. [`turn`]: the plan's turn runs, far above the resonance, split the flux's third from
//!    its fifth; the torque fit leaves them out.
//!
//! Before 2., [`balance`] refuses logs whose phase currents differ in amplitude (a sensor's
//! gain error, which the fit would report as detent order 2).
//!
//! In open loop (`i_d = I_hold`, `i_q = 0` in the command frame) the torque is
//! `Km·I_hold·sin δ` with `δ = θe_cmd − θe`; the fit sees the same equation as on a servo
//! log, `J·dω/dt = Km·i_q − Σ A_k sin(kθe + φ_k) − Fs·sgn ω − D·ω`, with `i_q` the Park
//! transform of the measured currents at the estimated angle.

pub mod balance;
pub mod flux;
pub mod log;
pub mod plan;
pub mod report;
pub mod shape;
pub mod turn;

use crate::fit::FitOptions;
use crate::log::{IqSource, RunLog};
use flux::{FluxError, FluxOptions, ResistanceSource, Standstill, Winding, pooled_resistance, rotor_angle};
use log::SensorlessLog;
use stepdamp_profile::Profile;

/// The winding constants of a base profile, with its flux shape when it has a
/// `[motor.flux]` section.
pub fn winding(base: &Profile) -> Winding {
    winding_with(base, &base.motor.flux)
}

/// The winding constants of a base profile with the flux section `flux` instead of its own.
pub fn winding_with(base: &Profile, flux: &stepdamp_profile::flux::FluxSection) -> Winding {
    Winding {
        pole_pairs: base.motor.pole_pairs,
        resistance_ohm: base.motor.resistance_ohm,
        inductance_h: base.motor.inductance_h,
        shape: (!flux.is_default()).then(|| stepdamp_profile::flux::FluxShape::new(flux)),
    }
}

/// Fit options for estimated-angle logs of a motor described by `base`: the servo route's
/// ([`FitOptions::for_profile`]) without the encoder-specific parts (no counts per
/// revolution, no quantisation correction, no servo bandwidth, no warning about encoder
/// steps against the travel: the estimated angle is continuous, its noise is not a servo's
/// jitter).
pub fn fit_options(base: &Profile, orders: &[u16]) -> FitOptions {
    FitOptions {
        counts_per_rev: None,
        servo_bandwidth_hz: None,
        correct_quantisation: false,
        max_back_step_fraction: f64::INFINITY,
        ..FitOptions::for_profile(base, orders)
    }
}

/// What the angle estimate of one log found (a line of the report).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct AngleReport {
    /// The log.
    pub log: String,
    /// Standstill at the start of the log, s.
    pub standstill_s: f64,
    /// `R` trimmed at this log's standstill alone, Ω (`None`: too short).
    pub resistance_ohm: Option<f64>,
    /// `Km` implied by the flux circle's radius, `Nr·|λ|`, N·m/A (compare with the base's).
    pub km_from_flux_nm_per_a: f64,
    /// Radius ripple as a fraction of the radius ([`flux::RotorAngle::radius_ripple`]).
    pub radius_ripple: f64,
}

/// The sensorless logs made ready for the fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimated {
    /// One run log per sensorless log: `θ_fb` the estimated angle (`θe/Nr`), `i_q` the
    /// measured currents' Park transform at it.
    pub logs: Vec<RunLog>,
    /// Per log, what the estimate found.
    pub angles: Vec<AngleReport>,
    /// The resistance used for every log, Ω ([`flux::pooled_resistance`]).
    pub resistance_ohm: f64,
    /// Where it came from.
    pub resistance_source: ResistanceSource,
    /// The offset of the sampled phase currents `(ε_a, ε_b)` found from the running mean
    /// voltages ([`flux::running_mean_voltage`]) and taken off every sample, A.
    pub current_offset_a: (f64, f64),
    /// Per log whose radius determines them, the flux radius's harmonics
    /// ([`shape::RadiusHarmonics`]).
    pub radius: Vec<shape::RadiusHarmonics>,
}

impl Estimated {
    /// The resistance to write into the identified profile: the trimmed one, `None` when
    /// the base's was used.
    pub fn measured_resistance_ohm(&self) -> Option<f64> {
        (self.resistance_source == ResistanceSource::Standstill).then_some(self.resistance_ohm)
    }
}

/// Estimates the rotor angle of every log (`R` pooled over their standstills) and makes the
/// run logs the fit reads.
pub fn estimate(logs: &[SensorlessLog], w: &Winding, o: &FluxOptions) -> Result<Estimated, FluxError> {
    let still = logs.iter().map(|l| Standstill::of(l, o)).collect::<Result<Vec<_>, _>>()?;
    let running: Vec<_> =
        logs.iter().zip(&still).map(|(l, s)| flux::running_mean_voltage(l, s.samples, w.pole_pairs)).collect();
    let corrected: Vec<_> =
        still.iter().zip(&running).map(|(s, r)| r.map_or(*s, |(v, _)| s.offset_corrected(v))).collect();
    let (resistance_ohm, resistance_source) = pooled_resistance(logs, &corrected, w.resistance_ohm)?;
    // The sampled currents' offset, pooled over the runs: `ε = −v̄_run/R`.
    let (sa, sb, sn) = running
        .iter()
        .flatten()
        .fold((0.0, 0.0, 0.0), |a, &((va, vb), n)| (a.0 + va * n as f64, a.1 + vb * n as f64, a.2 + n as f64));
    let current_offset_a = if sn > 0.0 { (-sa / sn / resistance_ohm, -sb / sn / resistance_ohm) } else { (0.0, 0.0) };
    let nr = f64::from(w.pole_pairs);
    let mut out = Vec::with_capacity(logs.len());
    let mut angles = Vec::with_capacity(logs.len());
    let mut radius = Vec::with_capacity(logs.len());
    for (log, st) in logs.iter().zip(&corrected) {
        let mut log = log.clone();
        log.i_a_a.iter_mut().for_each(|i| *i -= current_offset_a.0);
        log.i_b_a.iter_mut().for_each(|i| *i -= current_offset_a.1);
        let log = &log;
        let a = rotor_angle(log, w, resistance_ohm, o)?;
        radius.extend(shape::RadiusHarmonics::of(&a.theta_e_rad[a.standstill_samples..], &a.radius_wb));
        // The torque per Km: the Park transform's i_q for the circle; with a flux shape the
        // model's own torque, so the current-proportional ripple is not fitted as detent.
        let i_q_a = a
            .theta_e_rad
            .iter()
            .zip(log.i_a_a.iter().zip(&log.i_b_a))
            .map(|(&th, (&ia, &ib))| match &w.shape {
                Some(shape) => shape.torque_nm(1.0, th, ia, ib),
                None => {
                    let (s, c) = th.sin_cos();
                    -ia * s + ib * c
                }
            })
            .collect();
        angles.push(AngleReport {
            log: log.source.clone(),
            standstill_s: st.duration_s,
            resistance_ohm: st.sums.map(|(vi, ii)| vi / ii),
            km_from_flux_nm_per_a: a.flux_wb * nr,
            radius_ripple: a.radius_ripple,
        });
        out.push(RunLog {
            source: log.source.clone(),
            t_s: log.t_s.clone(),
            theta_fb_rad: a.theta_e_rad.iter().map(|th| th / nr).collect(),
            i_q_a,
            iq_cmd_a: None,
            // `i_q_a` is already the whole torque per Km, the d current's part included.
            i_d_a: None,
            iq_source: IqSource::Park,
            ignored_columns: log.ignored_columns.clone(),
            phases: None,
        });
    }
    Ok(Estimated { logs: out, angles, resistance_ohm, resistance_source, current_offset_a, radius })
}

/// Why the sensorless route failed.
#[derive(Debug, thiserror::Error)]
pub enum SensorlessError {
    /// No angle could be estimated from a log.
    #[error(transparent)]
    Angle(#[from] FluxError),
    /// The phase currents' amplitudes differ (a sensor's gain is off).
    #[error(transparent)]
    Imbalance(#[from] balance::Imbalance),
    /// The fit failed.
    #[error(transparent)]
    Fit(#[from] crate::fit::FitError),
}

/// The sensorless route's result: the angle estimates and the fit.
#[derive(Clone, Debug)]
pub struct SensorlessFit {
    /// The angle estimates and the run logs made from them.
    pub estimated: Estimated,
    /// The torque-balance fit of those logs.
    pub fit: crate::fit::Fit,
    /// The flux shape's error the radius showed against the base's shape, over all passes
    /// ([`shape::ShapeFit::total_since`]; `None`: fewer than two logs determine it).
    pub shape: Option<shape::ShapeFit>,
    /// Why a correction of the shape was not applied, if one was refused.
    pub shape_refused: Option<String>,
    /// The flux section the angles and torques were computed with: the base's, corrected by
    /// [`shape::ShapeFit::corrected`] when something stood out, then by
    /// [`turn::TurnFit::corrected`].
    pub flux: stepdamp_profile::flux::FluxSection,
    /// The last measurement of the turn runs' `X₅ − X₃` against the shape their angles were
    /// estimated with; when it stood out, its correction is in `flux` (`None`: fewer than two
    /// turn runs, or their measurement failed).
    pub turn: Option<turn::TurnFit>,
    /// The logs taken as turn runs ([`turn::is_turn_run`]): left out of the torque fit and
    /// of the radius.
    pub turn_logs: Vec<String>,
    /// Why turn runs were left out of the split too, one line each naming the log: the
    /// estimated angle did not follow the command (a stall on the ramp: the estimate's own
    /// check, or [`turn::followed`]), or their angle could not be estimated.
    pub turn_left_out: Vec<String>,
    /// How many of the turn runs' measurements were applied to `flux` (0..=[`TURN_PASSES`]).
    pub turn_passes: usize,
    /// Every log was a turn run: they were fitted as ordinary runs, and nothing was split.
    pub only_turn_runs: bool,
}

impl SensorlessFit {
    /// The identified model: the fit's, with the trimmed `R` when there was a standstill.
    pub fn model(&self) -> crate::model::Model {
        crate::model::Model {
            resistance_ohm: self.estimated.measured_resistance_ohm(),
            ..crate::model::Model::from_fit(&self.fit)
        }
    }
}

/// Passes of the shape correction: the first measures the shape's error against the base's,
/// the next ones what is left with the corrected shape (its second-order terms); each pass
/// estimates every angle again.
pub const SHAPE_PASSES: usize = 3;

/// The whole route: [`balance::check`] the phase currents, [`estimate`] the angles with the
/// base's winding, correct its flux shape from the radius ([`shape`]) and estimate again
/// (at most [`SHAPE_PASSES`] times, until nothing stands out), then [`crate::fit::fit`] with
/// `fit` (normally [`fit_options`]).
pub fn identify(
    logs: &[SensorlessLog],
    base: &Profile,
    fit: &FitOptions,
    o: &FluxOptions,
) -> Result<SensorlessFit, SensorlessError> {
    balance::check(logs, base.motor.pole_pairs)?;
    let (turns, rest): (Vec<SensorlessLog>, Vec<SensorlessLog>) =
        logs.iter().cloned().partition(|l| turn::is_turn_run(l, base));
    // Only turn runs: nothing else to fit, so they are fitted as ordinary runs (and noted).
    let only_turn_runs = rest.is_empty();
    let (turns, logs) = if only_turn_runs { (Vec::new(), turns) } else { (turns, rest) };
    let logs = &logs[..];
    let mut flux = base.motor.flux.clone();
    let mut estimated = estimate(logs, &winding_with(base, &flux), o)?;
    let mut pass = shape::ShapeFit::of(&estimated.radius);
    let mut shape_refused = None;
    for _ in 0..SHAPE_PASSES {
        let Some(next) = pass.as_ref().map(|p| p.corrected(&flux)).filter(|n| *n != flux) else { break };
        // A section outside the profile's limits is not a magnet's (a wrong L or R, a sensor's
        // gain): the angle on it may not converge, and no profile could hold it.
        if let Err(e) = base.edited(&base.name, |d| d.motor.flux = next.clone()) {
            shape_refused = Some(format!(
                "the flux radius asks for a [motor.flux] the profile refuses ({e}); kept the previous shape: check L, R and the sensors' gains"
            ));
            break;
        }
        match estimate(logs, &winding_with(base, &next), o) {
            Ok(e) => {
                flux = next;
                estimated = e;
                pass = shape::ShapeFit::of(&estimated.radius);
            }
            Err(e) => {
                shape_refused = Some(format!("no angle on the corrected flux shape ({e}); kept the previous shape"));
                break;
            }
        }
    }
    let shape = pass.map(|last| last.total_since(&base.motor.flux, &flux));
    let fitted = crate::fit::fit(&estimated.logs, fit)?;
    let mut f = SensorlessFit {
        estimated,
        fit: fitted,
        shape,
        flux,
        shape_refused,
        turn: None,
        turn_logs: turns.iter().map(|l| l.source.clone()).collect(),
        turn_left_out: Vec::new(),
        turn_passes: 0,
        only_turn_runs,
    };
    if turns.len() >= 2 {
        split_by_turn(&mut f, logs, &turns, base, fit, o)?;
    }
    Ok(f)
}

/// Passes of the split by the turn runs: the first measures `X₅ − X₃`, the second what is
/// left with the rotor's motion predicted from the corrected shape's ripple.
pub const TURN_PASSES: usize = 2;

/// Corrects `f`'s third and fifth with the turn runs `turns` ([`turn`]): measures, splits,
/// estimates `logs` again and fits them, at most [`TURN_PASSES`] times.
fn split_by_turn(
    f: &mut SensorlessFit,
    logs: &[SensorlessLog],
    turns: &[SensorlessLog],
    base: &Profile,
    fit: &FitOptions,
    o: &FluxOptions,
) -> Result<(), SensorlessError> {
    let nr = f64::from(base.motor.pole_pairs);
    let w = winding_with(base, &f.flux);
    let mut kept = Vec::new();
    for l in turns {
        match estimate(std::slice::from_ref(l), &w, o) {
            Ok(e) if turn::followed(l, &e.logs[0].theta_fb_rad, nr) => kept.push(l.clone()),
            Ok(_) => f.turn_left_out.push(format!(
                "{}: θe_est − θe_cmd spans more than a quarter electrical period over the steady part: the rotor slipped",
                l.source
            )),
            Err(e) => f.turn_left_out.push(e.to_string()),
        }
    }
    let turns = kept;
    if turns.len() < 2 {
        return Ok(());
    }
    let turns = &turns[..];
    for _ in 0..TURN_PASSES {
        let Ok(with) = base.edited(&base.name, |d| d.motor.flux = f.flux.clone()) else { break };
        let Ok(id) = f.model().apply_to(&with, None, "turn") else { break };
        let Ok(est) = estimate(turns, &winding_with(base, &f.flux), o) else { break };
        f.turn = turn::TurnFit::of(turns, &est, &id);
        let Some(next) = f.turn.as_ref().map(|t| t.corrected(&f.flux)).filter(|n| *n != f.flux) else { break };
        if base.edited(&base.name, |d| d.motor.flux = next.clone()).is_err() {
            break;
        }
        let Ok(e) = estimate(logs, &winding_with(base, &next), o) else { break };
        f.fit = crate::fit::fit(&e.logs, fit)?;
        f.estimated = e;
        f.flux = next;
        f.turn_passes += 1;
    }
    Ok(())
}

#[cfg(all(test, feature = "simulate"))]
mod tests;
