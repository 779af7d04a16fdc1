//! The sensorless route's report: how the angle was estimated, then the fit's report.

use super::flux::ResistanceSource;
use super::turn::TURN_MIN_SPEED;
use super::{AngleReport, SensorlessFit};
use crate::fit::FitReport;
use serde::Serialize;
use stepdamp_profile::flux::FluxSection;

/// Warn when the flux circle's `Km` differs from the base profile's by more than this
/// fraction (a wrong `Km` scales every identified torque; a wrong `L` shows here too).
pub const KM_DISAGREEMENT: f64 = 0.1;

/// Note a log whose flux radius ripples by more than this fraction of its mean (0.2–0.5 % on
/// the simulator at 5 mA; an `L` 20 % off gives about 4 %).
pub const MAX_RADIUS_RIPPLE: f64 = 0.05;

/// What `stepdamp identify` prints on the sensorless route (text: `Display`; JSON:
/// `Serialize`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SensorlessReport {
    /// Always `"sensorless"` (tells a script which route ran).
    pub route: &'static str,
    /// The resistance used, Ω.
    pub resistance_ohm: f64,
    /// Where it came from.
    pub resistance_source: ResistanceSource,
    /// The base profile's resistance, Ω.
    pub base_resistance_ohm: f64,
    /// The base profile's `Km`, N·m/A (what the fit uses).
    pub base_km_nm_per_a: f64,
    /// Per log.
    pub angles: Vec<AngleReport>,
    /// Cautions about the estimate.
    pub notes: Vec<String>,
    /// The flux shape's error the radius showed against the base's shape (`None`: fewer than
    /// two logs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flux_shape: Option<Box<super::shape::ShapeFit>>,
    /// The `[motor.flux]` section written, when it differs from the base's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flux_written: Option<stepdamp_profile::flux::FluxSection>,
    /// The turn runs, left out of the torque fit.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub turn_logs: Vec<String>,
    /// The turn runs' last `X₅ − X₃` measurement ([`super::turn`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub turn: Option<Box<super::turn::TurnFit>>,
    /// How many turn-run measurements were applied to the section written.
    pub turn_passes: usize,
    /// Whether the section the angles were estimated with has a third or a fifth: without
    /// either (a sine motor) the turn runs have nothing to split.
    pub turn_has_split: bool,
    /// The fit's report, as on the servo route.
    pub fit: FitReport,
}

impl SensorlessReport {
    /// The report of `f`, identified from a base profile with `R = base_resistance_ohm` and
    /// `Km = base_km`.
    pub fn new(base: &str, base_resistance_ohm: f64, base_km: f64, base_flux: &FluxSection, f: &SensorlessFit) -> Self {
        let e = &f.estimated;
        let mut notes = Vec::new();
        for a in &e.angles {
            let rel = a.km_from_flux_nm_per_a / base_km - 1.0;
            if rel.abs() > KM_DISAGREEMENT {
                notes.push(format!(
                    "{}: the flux circle gives Km = {:.4} N·m/A, {:+.0} % from the base's {base_km:.4}: check Km and L in the base profile (the fit uses its Km, and L enters the angle)",
                    a.log,
                    a.km_from_flux_nm_per_a,
                    100.0 * rel
                ));
            }
        }
        for a in e.angles.iter().filter(|a| a.radius_ripple > MAX_RADIUS_RIPPLE) {
            notes.push(format!(
                "{}: the flux circle's radius ripples by {:.1} % (more than {:.0} %): the angle is unreliable there (a jump in the log, a wrong L, voltages that are not the applied ones?)",
                a.log,
                100.0 * a.radius_ripple,
                100.0 * MAX_RADIUS_RIPPLE
            ));
        }
        if e.resistance_source == ResistanceSource::Base {
            notes.push(format!(
                "no log starts with a standstill of at least {:.2} s: R is the base's {base_resistance_ohm:.4} Ω, untrimmed; its error turns the angle by ΔR·I/(Km·ω) (docs/sensorless.md)",
                super::flux::FluxOptions::default().min_standstill_s
            ));
        }
        let flux_written = (f.flux != *base_flux).then(|| f.flux.clone());
        for why in &f.turn_left_out {
            notes.push(format!(
                "turn run left out of the split: {why} (run it again with a slower ramp or more current)"
            ));
        }
        if f.turn_passes == 0
            && f.turn.is_none()
            && flux_written.as_ref().is_some_and(|w| w.harmonics != base_flux.harmonics)
        {
            notes.push(format!(
                "the flux radius gives the third and fifth harmonics' sum only: {:.0} % of it is written to the third, as on measured motors (no turn runs split it: docs/sensorless.md#the-split-from-a-fast-run); the ripple that grows with the current (open loop and servo) is uncertain by that split",
                100.0 * super::shape::THIRD_SHARE
            ));
        }
        notes.extend(f.shape_refused.clone());
        if f.only_turn_runs {
            notes.push(format!(
                "every log is a turn run (electrical speed at least {TURN_MIN_SPEED} × the base's natural frequency): fitted as ordinary runs, though far above the resonance the rotor hardly follows the ripple, so the detent and the ripple are poorly determined and the third/fifth split is not measured; record the plan's quasi-static runs too (docs/sensorless.md#the-split-from-a-fast-run)"
            ));
        }
        if let Some(s) = f.shape.as_ref().filter(|s| s.sin2_stands_out()) {
            notes.push(format!(
                "the flux radius has a sin 2θe term of {:.4} ± {:.4}, which no flux gain makes: check the phase currents' and voltages' gains and timing, R and L (docs/sensorless.md#the-flux-shape-without-a-sensor)",
                s.radius_sin2.value, s.radius_sin2.ci95
            ));
        }
        SensorlessReport {
            route: "sensorless",
            resistance_ohm: e.resistance_ohm,
            resistance_source: e.resistance_source,
            base_resistance_ohm,
            base_km_nm_per_a: base_km,
            angles: e.angles.clone(),
            notes,
            flux_shape: f.shape.clone().map(Box::new),
            flux_written,
            turn_logs: f.turn_logs.clone(),
            turn: f.turn.clone().map(Box::new),
            turn_passes: f.turn_passes,
            turn_has_split: f.flux.harmonics.iter().any(|h| h.order == 3 || h.order == 5),
            fit: FitReport::new(base, f.fit.clone()),
        }
    }
}

impl std::fmt::Display for SensorlessReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "route: sensorless (the logs have no theta_fb_rad): the rotor angle from ∫(v − R·i)dt − L·i (docs/sensorless.md)"
        )?;
        match self.resistance_source {
            ResistanceSource::Standstill => writeln!(
                f,
                "R trimmed at standstill: {:.5} Ω ({:+.2} % from the base's {:.5} Ω), written to the identified profile",
                self.resistance_ohm,
                100.0 * (self.resistance_ohm / self.base_resistance_ohm - 1.0),
                self.base_resistance_ohm
            )?,
            ResistanceSource::Base => writeln!(f, "R: the base's {:.5} Ω (not trimmed)", self.resistance_ohm)?,
        }
        for a in &self.angles {
            write!(f, "  {}: standstill {:.2} s", a.log, a.standstill_s)?;
            if let Some(r) = a.resistance_ohm {
                write!(f, " (R {r:.5} Ω)")?;
            }
            writeln!(
                f,
                ", Km from the flux {:.4} N·m/A (base {:.4}), radius ripple {:.2} %",
                a.km_from_flux_nm_per_a,
                self.base_km_nm_per_a,
                100.0 * a.radius_ripple
            )?;
        }
        if let Some(s) = &self.flux_shape {
            write!(
                f,
                "flux shape from the radius over {} logs (against the base's): g {:+.4} ± {:.4}, third + fifth {:.4} ± {:.4} at {:+.3} rad",
                s.logs,
                s.phase_b_gain.value,
                s.phase_b_gain.ci95,
                s.sum_ratio.value,
                s.sum_ratio.ci95,
                s.sum_phase_rad.value
            )?;
            let out = s.left_out();
            if !out.is_empty() {
                write!(f, "; within the noise, left out: {}", out.join(", "))?;
            }
            writeln!(f)?;
        }
        if !self.turn_logs.is_empty() {
            writeln!(
                f,
                "turn runs, left out of the torque fit and the radius (docs/sensorless.md#the-split-from-a-fast-run): {}",
                self.turn_logs.join(", ")
            )?;
        }
        if let Some(t) = &self.turn {
            write!(
                f,
                "fifth − third from the turn runs' angle, over {} runs: {:.4} ± {:.4} at {:+.3} rad, ",
                t.logs, t.ratio.value, t.ratio.ci95, t.phase_rad.value
            )?;
            match self.turn_passes {
                0 if !self.turn_has_split => writeln!(f, "nothing to split: the flux section has no third or fifth")?,
                0 => writeln!(
                    f,
                    "within the noise of the {:.0} % split, which stands",
                    100.0 * super::shape::THIRD_SHARE
                )?,
                n => writeln!(
                    f,
                    "the last of {} measurements; split onto the third and fifth in {n} pass(es){}",
                    super::TURN_PASSES,
                    if t.stands_out() { "" } else { ", what is left within the noise" }
                )?,
            }
        }
        for n in &self.notes {
            writeln!(f, "note: {n}")?;
        }
        write!(f, "{}", self.fit)
    }
}
