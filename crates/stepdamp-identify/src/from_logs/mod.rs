//! Identification from run logs in one call, the entry the CLI (`stepdamp identify --log …`)
//! and Python (`stepdamp.identify`) both use (docs/files.md#run-log-csv):
//! read every log once ([`read_logs`]), take the route its headers call for ([`Route`]:
//! encoder logs have `theta_fb_rad`, sensorless ones do not; or the route forced by
//! [`IdentifyOptions::route`]), fit, and return one [`IdentifyReport`] with all that is
//! printed: the fit and its validation, the warnings, the route, the sensorless route's
//! trimmed `R` and current offset, and the identified profile.
//!
//! Needs no simulator (works without the feature `simulate`).

mod read;

pub use read::{LogSource, LogSummary, Logs, Route, STDIN_NAME, read_logs};

use crate::conditions::InertiaMode;
use crate::emf::{EmfError, EmfOptions, FluxFit, fit_flux};
use crate::fit::{Effort, FeedForwardCheck, Fit, FitError, FitOptions, FitReport, fit};
use crate::log::LogError;
use crate::model::Model;
use crate::sensorless::flux::FluxOptions;
use crate::sensorless::report::SensorlessReport;
use crate::sensorless::{SensorlessError, fit_options as sensorless_fit_options, identify as identify_sensorless};
use std::fmt;
use std::time::Instant;
use stepdamp_profile::{Profile, ProfileError};

/// Suffix of the identified profile's default name (`<base name>-identified`).
pub const DEFAULT_NAME_SUFFIX: &str = "identified";

/// The choices of [`identify`] (the command line's options of `stepdamp identify`).
#[derive(Clone, Debug, PartialEq)]
pub struct IdentifyOptions {
    /// Harmonic orders to identify (distinct, each in 1..=32).
    pub orders: Vec<u16>,
    /// The route to take whatever the headers say (`None`: from the headers). A forced
    /// sensorless route reads encoder logs without their `theta_fb_rad`, to compare routes.
    pub route: Option<Route>,
    /// The effort signal (encoder route only: anything but the default is refused on the
    /// sensorless route).
    pub effort: Effort,
    /// How `J` is obtained ([`crate::conditions`]).
    pub inertia: InertiaMode,
    /// Servo position-loop bandwidth of the logged runs, Hz (`None`: the base profile's);
    /// encoder route only, used for warnings.
    pub servo_bandwidth_hz: Option<f64>,
    /// The logs were recorded with the base profile's detent and `Fs` fed forward: raw
    /// effort, `J` held at the base's, and the remaining ripple reported (encoder route only).
    pub feed_forward_on: bool,
    /// Name of the identified profile (`None`: `<base name>-`[`DEFAULT_NAME_SUFFIX`]).
    pub name: Option<String>,
    /// Where the identified profile is going (e.g. its file), named if it fails validation.
    pub destination: String,
}

impl IdentifyOptions {
    /// The defaults (the CLI's) for `orders`: route from the headers, measured effort, `J`
    /// decided automatically, no feed-forward.
    pub fn new(orders: &[u16]) -> Self {
        IdentifyOptions {
            orders: orders.to_vec(),
            route: None,
            effort: Effort::default(),
            inertia: InertiaMode::Auto,
            servo_bandwidth_hz: None,
            feed_forward_on: false,
            name: None,
            destination: "the identified profile".to_string(),
        }
    }

    /// Refuses a bandwidth that is not a positive number of Hz.
    fn check(&self) -> Result<(), IdentifyError> {
        match self.servo_bandwidth_hz {
            Some(bw) if !(bw.is_finite() && bw > 0.0) => Err(IdentifyError::ServoBandwidth(bw)),
            _ => Ok(()),
        }
    }

    /// The encoder route's fit options for `base` (what [`identify`] fits encoder logs with,
    /// and what refinement refits with).
    pub fn encoder_fit_options(&self, base: &Profile) -> FitOptions {
        let mut fo = FitOptions::for_profile(base, &self.orders);
        fo.effort = self.effort;
        fo.inertia = self.inertia;
        if let Some(bw) = self.servo_bandwidth_hz {
            fo.servo_bandwidth_hz = Some(bw);
        }
        if self.feed_forward_on {
            // Feed-forward-on logs: raw effort, J held at the base profile's (the one whose
            // feed-forward ran, normally identified from feed-forward-off logs).
            fo.correct_quantisation = false;
            fo.smooth_effort = false;
            fo.fit_inertia = false;
        }
        fo
    }

    /// Refuses the options that apply to encoder logs only, naming the first one given
    /// (by its command-line flag).
    fn check_sensorless(&self) -> Result<(), IdentifyError> {
        for (given, flag) in [
            (self.feed_forward_on, "--ff-on"),
            (self.servo_bandwidth_hz.is_some(), "--servo-bandwidth"),
            (self.effort != Effort::MeasuredIq, "--effort"),
        ] {
            if given {
                return Err(IdentifyError::EncoderOnly(flag));
            }
        }
        Ok(())
    }
}

/// Why [`identify`] failed. One line each, naming the log (and line and column) where one
/// is at fault.
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    /// No log was given.
    #[error("no logs given: pass the run logs (CSV)")]
    NoLogs,
    /// The same file given twice (it would count its rows twice and narrow the intervals).
    #[error(
        "{again}: given twice (first as {first}); give each log once (a log counted twice makes the intervals falsely narrow)"
    )]
    GivenTwice {
        /// The first name it was given by.
        first: String,
        /// The second.
        again: String,
    },
    /// Standard input given twice.
    #[error("{STDIN_NAME}: standard input (-) is given twice; it can be read once")]
    StdinTwice,
    /// The headers call for two routes.
    #[error("{log} {has}, but {first} {first_has}: give logs of one route")]
    MixedRoutes {
        /// The first log of the other route.
        log: String,
        /// What it has.
        has: &'static str,
        /// The first log.
        first: String,
        /// What that has.
        first_has: &'static str,
    },
    /// An option of the encoder route on sensorless logs.
    #[error("{0}: the logs are sensorless (no theta_fb_rad), and {0} applies to servo logs only")]
    EncoderOnly(&'static str),
    /// A servo bandwidth that is not a positive number of Hz.
    #[error("--servo-bandwidth {0}: must be a positive number of Hz")]
    ServoBandwidth(f64),
    /// A log could not be read. Its message is the whole line (an I/O error's text
    /// included), so it is not given as a source as well.
    #[error("{0}")]
    Log(LogError),
    /// The encoder route's fit failed.
    #[error(transparent)]
    Fit(#[from] FitError),
    /// The sensorless route failed.
    #[error(transparent)]
    Sensorless(#[from] SensorlessError),
    /// The back-EMF fit of the flux linkage failed.
    #[error(transparent)]
    Emf(#[from] EmfError),
    /// The identified profile is not valid.
    #[error(transparent)]
    Profile(#[from] ProfileError),
}

impl From<LogError> for IdentifyError {
    fn from(e: LogError) -> Self {
        IdentifyError::Log(e)
    }
}

/// The route's own report.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(untagged)]
pub enum RouteReport {
    /// The encoder route: the fit's report.
    Encoder(FitReport),
    /// The sensorless route: the angle estimate, then the fit's report.
    Sensorless(SensorlessReport),
}

/// Everything [`identify`] found, as the CLI and Python print it: `Display` is the CLI's
/// text (the ignored columns, then the route's report); the route's report alone
/// ([`IdentifyReport::result`]) is the CLI's JSON.
#[derive(Clone, Debug, PartialEq)]
pub struct IdentifyReport {
    /// The route taken.
    pub route: Route,
    /// Per log, in the order given.
    pub logs: Vec<LogSummary>,
    /// The route's report (the fit, its validation, warnings and decisions).
    pub result: RouteReport,
    /// Sensorless route: the offset `(ε_a, ε_b)` of the sampled phase currents taken off
    /// every sample, A.
    pub current_offset_a: Option<(f64, f64)>,
    /// The base profile with what was identified (and, sensorless, `R` trimmed).
    pub profile: Profile,
    /// Wall time reading the logs, s.
    pub read_s: f64,
    /// Wall time of the fit (and, sensorless, the angle estimate), s.
    pub fit_s: f64,
}

impl IdentifyReport {
    /// The fit's report (on the sensorless route, the one inside its report).
    pub fn fit_report(&self) -> &FitReport {
        match &self.result {
            RouteReport::Encoder(r) => r,
            RouteReport::Sensorless(r) => &r.fit,
        }
    }

    /// The fit.
    pub fn fit(&self) -> &Fit {
        &self.fit_report().fit
    }

    /// Sensorless route: the resistance used, Ω (trimmed at standstill, or the base's).
    pub fn resistance_ohm(&self) -> Option<f64> {
        match &self.result {
            RouteReport::Encoder(_) => None,
            RouteReport::Sensorless(r) => Some(r.resistance_ohm),
        }
    }

    /// Data rows read over all logs.
    pub fn rows(&self) -> usize {
        self.logs.iter().map(|l| l.rows).sum()
    }

    /// One line with the logs, rows and wall times (the CLI prints it after the report).
    pub fn timing(&self) -> String {
        let (n, rows) = (self.logs.len(), self.rows());
        match self.route {
            Route::Encoder => {
                format!("{n} logs, {rows} rows: read in {:.3} s, fitted in {:.3} s", self.read_s, self.fit_s)
            }
            Route::Sensorless => {
                format!("{n} logs, {rows} rows: read and identified in {:.3} s", self.read_s + self.fit_s)
            }
        }
    }
}

impl fmt::Display for IdentifyReport {
    /// A note per log with unknown columns, then the route's report.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for l in self.logs.iter().filter(|l| !l.ignored_columns.is_empty()) {
            writeln!(f, "note: {}: ignored unknown columns: {}", l.source, l.ignored_columns.join(", "))?;
        }
        match &self.result {
            RouteReport::Encoder(r) => write!(f, "{r}"),
            RouteReport::Sensorless(r) => write!(f, "{r}"),
        }
    }
}

/// Identifies the detent harmonics, `Fs`, `D`, `J` (and, sensorless, `R`) of the motor
/// described by `base` from the logs `inputs`: each read once ([`read_logs`]), the route
/// from their headers (or [`IdentifyOptions::route`]), fitted, validated, and applied to
/// `base` (its `Km`, `Nr`, encoder and servo settings kept).
pub fn identify(
    inputs: &[LogSource<'_>],
    base: &Profile,
    o: &IdentifyOptions,
) -> Result<IdentifyReport, IdentifyError> {
    o.check()?;
    let t0 = Instant::now();
    let logs = read_logs(inputs, base.motor.pole_pairs, o.route)?;
    let read_s = t0.elapsed().as_secs_f64();
    let summaries = logs.summaries();
    let name = o.name.clone().unwrap_or_else(|| format!("{}-{DEFAULT_NAME_SUFFIX}", base.name));
    let (result, model, with_flux, current_offset_a) = match &logs {
        Logs::Encoder(l) => {
            let (report, model, with_flux) = encoder_route(l, base, o)?;
            (RouteReport::Encoder(report), model, with_flux, None)
        }
        Logs::Sensorless(l) => {
            o.check_sensorless()?;
            let fo = FitOptions { inertia: o.inertia, ..sensorless_fit_options(base, &o.orders) };
            let sf = identify_sensorless(l, base, &fo, &FluxOptions::default())?;
            let report = SensorlessReport::new(
                &base.name,
                base.motor.resistance_ohm,
                base.motor.km_nm_per_a,
                &base.motor.flux,
                &sf,
            );
            let with_flux = if sf.flux == base.motor.flux {
                None
            } else {
                Some(base.edited(&base.name, |d| d.motor.flux = sf.flux.clone())?)
            };
            (RouteReport::Sensorless(report), sf.model(), with_flux, Some(sf.estimated.current_offset_a))
        }
    };
    let fit_s = t0.elapsed().as_secs_f64() - read_s;
    let profile = model.apply_to(with_flux.as_ref().unwrap_or(base), Some(&name), &o.destination)?;
    Ok(IdentifyReport { route: logs.route(), logs: summaries, result, current_offset_a, profile, read_s, fit_s })
}

#[cfg(test)]
mod tests;

/// The encoder route on logs already read: the flux section from the back-EMF runs, if any
/// ([`crate::emf`]), then the torque fit with that shape; returns the report, the model and
/// the base with the identified flux section (`None` without back-EMF runs).
pub fn encoder_route(
    logs: &[crate::log::RunLog],
    base: &Profile,
    o: &IdentifyOptions,
) -> Result<(FitReport, Model, Option<Profile>), IdentifyError> {
    let (flux, with_flux) = flux_from_back_emf(logs, base)?;
    let base_used = with_flux.as_ref().unwrap_or(base);
    let shaped = with_flux_torque(logs, base_used);
    let f = fit(shaped.as_deref().unwrap_or(logs), &o.encoder_fit_options(base_used))?;
    let model = Model::from_fit(&f);
    let note = flux.is_none().then(|| no_back_emf_note(base));
    let mut report = FitReport::new(&base.name, f).with_flux(flux).with_flux_note(note);
    if o.feed_forward_on {
        let check = FeedForwardCheck::new(base, &report.fit);
        report = report.with_feed_forward(check);
    }
    Ok((report, model, with_flux))
}

/// What the fit knows of the ripple that grows with the current when no log is a back-EMF
/// run (docs/identification.md#the-flux-linkage-from-the-back-emf).
fn no_back_emf_note(base: &Profile) -> String {
    if base.motor.flux.is_default() {
        "no back-EMF run among the logs (the plan's run-N-emf-…): the flux shape is not measured, so a real motor's ripple that grows with the current is fitted as detent at the logs' own current and is known there only; record the plan's back-EMF run to know it at every current (docs/identification.md#the-flux-linkage-from-the-back-emf)".into()
    } else {
        "no back-EMF run among the logs: the base's [motor.flux] is used as given, not measured (docs/identification.md#the-flux-linkage-from-the-back-emf)".into()
    }
}

/// The flux section from the back-EMF runs among `logs` ([`crate::emf`]; the torque fit
/// leaves those runs out) and the base with that section; `(None, None)` without such runs.
fn flux_from_back_emf(
    logs: &[crate::log::RunLog],
    base: &Profile,
) -> Result<(Option<FluxFit>, Option<Profile>), IdentifyError> {
    let Some(flux) = fit_flux(logs, &EmfOptions::for_profile(base))? else {
        return Ok((None, None));
    };
    let with_flux = base.edited(&base.name, |d| d.motor.flux = flux.section())?;
    Ok((Some(flux), Some(with_flux)))
}

/// Encoder logs of a motor whose base has a `[motor.flux]` section, with each `i_q` (and
/// `iq_cmd`) replaced by the torque per `Km` the flux shape gives, so that the fit's effort
/// `Km·i_q` is the motor's torque and the ripple that grows with the current is not fitted
/// as detent (docs/design.md#real-motors-flux-harmonics). The phase currents are put back
/// from `i_q` and the log's measured `i_d` ([`crate::log::RunLog::i_d_a`]; 0, the servo runs'
/// command (docs/files.md#plan-csv), when the log has none) at the encoder angle they were
/// measured at; the shape is taken at the rotor's edge-timed angle
/// ([`crate::stick::edge_timed_angle`]), not the count's centre: inside a count the current
/// is up to half a count off the rotor's q axis, which biased the 4th harmonic by 1.6 % on
/// a drive that reacts to every count (docs/identification.md#a-motor-with-flux-harmonics).
/// `None` without the section.
fn with_flux_torque(logs: &[crate::log::RunLog], base: &Profile) -> Option<Vec<crate::log::RunLog>> {
    if base.motor.flux.is_default() {
        return None;
    }
    let shape = stepdamp_profile::flux::FluxShape::new(&base.motor.flux);
    let nr = f64::from(base.motor.pole_pairs);
    let torque = |l: &crate::log::RunLog, iq: &[f64]| -> Vec<f64> {
        // A log's vectors are as long as each other (RunLog); `None` is i_d = 0.
        let id = l.i_d_a.iter().flatten().copied().chain(std::iter::repeat(0.0));
        let rotor = crate::stick::edge_timed_angle(&l.t_s, &l.theta_fb_rad).theta_rad;
        l.theta_fb_rad
            .iter()
            .zip(&rotor)
            .zip(iq)
            .zip(id)
            .map(|(((&t, &r), &q), d)| {
                let (s, c) = (nr * t).sin_cos();
                shape.torque_nm(1.0, nr * r, d * c - q * s, d * s + q * c)
            })
            .collect()
    };
    Some(
        logs.iter()
            .map(|l| crate::log::RunLog {
                i_q_a: torque(l, &l.i_q_a),
                iq_cmd_a: l.iq_cmd_a.as_ref().map(|c| torque(l, c)),
                ..l.clone()
            })
            .collect(),
    )
}
