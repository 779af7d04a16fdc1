//! The captures to record for an influence-coefficient step (docs/accelerometer.md#planning-captures):
//! per harmonic and direction, an `M973` without a trial and one with a known constant trial,
//! at a speed where the harmonic is well inside the accelerometer's band, with the reason for
//! every choice. What it prints is G-code a printer runs: numbers and fixed words only.

use crate::capture::{Axis, Gcode, MAX_HARMONIC, TrialSweep};
use std::fmt;

/// The share of the accelerometer's sampling rate a planned harmonic may reach: 0.4, below
/// the Nyquist frequency (0.5) with room for the sensor's own low-pass roll-off.
pub const MAX_BAND_FRACTION: f64 = 0.4;

/// The largest trial, in table units: `4 × 0.03 = 0.12` rad of shift in firmware ≥ 6.3.1, within
/// the ±0.195 rad its int8 table holds (docs/exporters.md#the-table-and-its-scale) with room
/// for the table already in use.
pub const MAX_TRIAL_MAG: f64 = 0.03;

/// The trial when the model gives none, in table units: `4 × 0.005 = 0.02` rad of shift,
/// about the correction a 4 % detent asks for at the holding current.
pub const DEFAULT_TRIAL_MAG: f64 = 0.005;

/// What to plan for.
#[derive(Clone, Debug, PartialEq)]
pub struct CapturePlanOptions {
    /// The motor (`X` or `Y`; on CoreXY the A or B motor).
    pub axis: Axis,
    /// Electrical periods per motor revolution (the rotor's pole pairs, 50 for a 1.8° motor).
    pub pole_pairs: u16,
    /// The harmonics to correct, each 1..=[`MAX_HARMONIC`], with the trial for each: the
    /// table item `(mag, pha)` the model expects to cancel it (its size is a trial that moves
    /// the response measurably and stays safe), or `None` for [`DEFAULT_TRIAL_MAG`] at phase 0.
    pub harmonics: Vec<(u32, Option<(f64, f64)>)>,
    /// The accelerometer's nominal sampling rate, Hz (1344 for the LIS2DH12 of the XL and
    /// Core One).
    pub rate_hz: f64,
    /// The fastest speed to plan, motor rev/s.
    pub max_speed_rev_s: f64,
    /// Time at constant speed in each capture, s.
    pub steady_s: f64,
    /// Also plan an `M974` speed sweep per direction, from the fastest planned speed `F` to
    /// `2F` and back over `4F` revolutions, for the ripple in N·m (`identify --accel`,
    /// docs/accelerometer.md#identifying-the-ripple-from-captures).
    pub sweeps: bool,
}

impl CapturePlanOptions {
    /// The defaults for `axis` and `pole_pairs`: harmonics 1, 2 and 4 with default trials, a
    /// 1344 Hz accelerometer, at most 2 rev/s, 3 s at speed, and the sweeps.
    pub fn new(axis: Axis, pole_pairs: u16) -> Self {
        CapturePlanOptions {
            axis,
            pole_pairs,
            harmonics: vec![(1, None), (2, None), (4, None)],
            rate_hz: 1344.0,
            max_speed_rev_s: 2.0,
            steady_s: 3.0,
            sweeps: true,
        }
    }
}

/// One capture to record.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannedCapture {
    /// The G-code to send.
    pub gcode: Gcode,
    /// Why this capture.
    pub reason: String,
}

/// The plan.
#[derive(Clone, Debug, PartialEq)]
pub struct CapturePlan {
    /// The captures, in the order to record them.
    pub captures: Vec<PlannedCapture>,
}

/// Why a plan could not be made: one line naming the option, its value and the range.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("{what}: {value} must be {range}")]
pub struct PlanError {
    /// The option.
    pub what: &'static str,
    /// Its value as given.
    pub value: String,
    /// The allowed range.
    pub range: String,
}

fn check(ok: bool, what: &'static str, value: impl fmt::Display, range: impl Into<String>) -> Result<(), PlanError> {
    if ok { Ok(()) } else { Err(PlanError { what, value: value.to_string(), range: range.into() }) }
}

/// `v` rounded down to `1/per` (e.g. `per = 100`: to 0.01), as the nearest `f64` of that
/// decimal: what the G-code prints is short and on the safe side of a limit.
fn round_down(v: f64, per: f64) -> f64 {
    (v * per).floor() / per
}

/// `v` rounded to the nearest `1/per`, as the nearest `f64` of that decimal.
fn round_to(v: f64, per: f64) -> f64 {
    (v * per).round() / per
}

/// Plans the captures: for each harmonic `n`, the speed `F = min(max speed,
/// 0.4·rate/(n·Nr))` (rounded down to 0.01 rev/s), so that the harmonic's frequency `n·Nr·F`
/// stays within [`MAX_BAND_FRACTION`] of the sampling rate; `R = F·steady` revolutions; in
/// each direction (`R < 0`: phase up, the forward table; `R > 0`: phase down, the backward
/// table) a baseline (`C = D = 0`) and a constant trial (`A = B`, `C = D`).
pub fn plan_captures(o: &CapturePlanOptions) -> Result<CapturePlan, PlanError> {
    check(o.pole_pairs >= 1, "pole pairs", o.pole_pairs, "at least 1")?;
    check(o.rate_hz.is_finite() && (100.0..=100_000.0).contains(&o.rate_hz), "rate", o.rate_hz, "in 100..=100000 Hz")?;
    let speed_ok = o.max_speed_rev_s.is_finite() && (0.05..=10.0).contains(&o.max_speed_rev_s);
    check(speed_ok, "max speed", o.max_speed_rev_s, "in 0.05..=10 rev/s")?;
    check(o.steady_s.is_finite() && (0.5..=60.0).contains(&o.steady_s), "steady time", o.steady_s, "in 0.5..=60 s")?;
    check(!o.harmonics.is_empty(), "harmonics", "none", "at least one")?;
    let mut captures = Vec::new();
    for (i, &(n, trial)) in o.harmonics.iter().enumerate() {
        check((1..=MAX_HARMONIC).contains(&n), "harmonic", n, format!("in 1..={MAX_HARMONIC} (M973's H)"))?;
        check(o.harmonics[..i].iter().all(|h| h.0 != n), "harmonic", n, "listed once")?;
        let (mag, pha) = trial.unwrap_or((DEFAULT_TRIAL_MAG, 0.0));
        let trial_ok = mag.is_finite() && mag > 0.0 && pha.is_finite() && pha.abs() <= std::f64::consts::PI;
        check(trial_ok, "trial", format!("({mag}, {pha})"), "a magnitude > 0 and a phase in [−π, π]")?;
        // The G-code carries 5 decimals of the magnitude, 4 of the phase.
        let (mag, capped) =
            if mag > MAX_TRIAL_MAG { (MAX_TRIAL_MAG, true) } else { (round_to(mag, 1e5).max(1e-5), false) };
        let band = MAX_BAND_FRACTION * o.rate_hz / (f64::from(n) * f64::from(o.pole_pairs));
        let speed = round_down(band.min(o.max_speed_rev_s), 100.0);
        check(speed >= 0.01, "harmonic", n, format!("slow enough to run: its band limit is {band:.4} rev/s"))?;
        let revs = -round_down(-speed * o.steady_s, 10.0);
        let hz = f64::from(n) * f64::from(o.pole_pairs) * speed;
        let why_speed = format!(
            "{speed} rev/s puts harmonic {n} at {hz:.0} Hz, {:.0} % of the {:.0} Hz sampling rate{}",
            100.0 * hz / o.rate_hz,
            o.rate_hz,
            if band < o.max_speed_rev_s { " (the band's limit)" } else { " (the fastest planned speed)" }
        );
        let why_trial = match (trial, capped) {
            (_, true) => format!("trial capped at {MAX_TRIAL_MAG} (the model asks for more)"),
            (Some(_), false) => "trial = the model's correction: it moves the response by about its own size".into(),
            (None, false) => format!("trial {DEFAULT_TRIAL_MAG} at phase 0 (no model for this harmonic)"),
        };
        for (dir, r, table) in [("forward", -revs, "F"), ("backward", revs, "B")] {
            let sweep = |m: f64, p: f64| TrialSweep { harmonic: n, pha_start: p, pha_end: p, mag_start: m, mag_end: m };
            for (what, t) in [("baseline", sweep(0.0, 0.0)), ("trial", sweep(mag, round_to(pha, 1e4)))] {
                let gcode = Gcode::ParamSweep { axis: o.axis, speed, revs: r, trial: t };
                let reason = match what {
                    "baseline" => {
                        format!("harmonic {n}, {dir} ({table} table): the response without a trial; {why_speed}")
                    }
                    _ => format!("harmonic {n}, {dir}: the same with a known trial, for its influence; {why_trial}"),
                };
                captures.push(PlannedCapture { gcode, reason });
            }
        }
    }
    if o.sweeps {
        captures.extend(sweep_captures(o));
    }
    Ok(CapturePlan { captures })
}

/// The `M974` sweeps of [`CapturePlanOptions::sweeps`], one per direction.
fn sweep_captures(o: &CapturePlanOptions) -> Vec<PlannedCapture> {
    let a = round_down(o.max_speed_rev_s, 100.0);
    let (b, revs) = (2.0 * a, round_to(4.0 * a, 10.0));
    let low = f64::from(o.pole_pairs) * a;
    let reason = |dir: &str| {
        format!(
            "{dir}: a sweep {a} -> {b} -> {a} rev/s for the head and the ripple in N·m (identify --accel): harmonic 1 from {low:.0} to {:.0} Hz, each harmonic used up to {:.0} % of the {:.0} Hz rate",
            2.0 * low,
            100.0 * MAX_BAND_FRACTION,
            o.rate_hz
        )
    };
    [("forward", -revs), ("backward", revs)]
        .into_iter()
        .map(|(dir, r)| PlannedCapture {
            gcode: Gcode::SpeedSweep { axis: o.axis, start_speed: a, end_speed: b, revs: r },
            reason: reason(dir),
        })
        .collect()
}

impl fmt::Display for CapturePlan {
    /// G-code a printer can run as it is: each capture's line, its reason as a `;` comment.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "; stepdamp capture plan: send each line, save the printed samples (docs/accelerometer.md)")?;
        for c in &self.captures {
            writeln!(f, "; {}", c.reason)?;
            writeln!(f, "{}", c.gcode)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prusa::read_captures;

    #[test]
    fn every_harmonic_gets_a_baseline_and_a_trial_in_each_direction_inside_the_band() {
        let p = plan_captures(&CapturePlanOptions::new(Axis::X, 50)).unwrap();
        assert_eq!(p.captures.len(), 3 * 4 + 2, "and a sweep per direction");
        for c in &p.captures[..12] {
            let Gcode::ParamSweep { speed, revs, trial, .. } = c.gcode else { panic!("not M973") };
            let hz = f64::from(trial.harmonic) * 50.0 * speed;
            assert!(hz <= MAX_BAND_FRACTION * 1344.0 && speed <= 2.0 && revs.abs() >= 3.0 * speed, "{c:?}");
            assert!(trial.constant().is_some(), "{c:?}");
        }
        // Harmonic 16 must slow down to stay in the band: 0.4·1344/(16·50) = 0.672 rev/s.
        let o = CapturePlanOptions { harmonics: vec![(16, Some((0.01, 0.5)))], ..CapturePlanOptions::new(Axis::Y, 50) };
        let p = plan_captures(&o).unwrap();
        let Gcode::ParamSweep { speed, trial, .. } = p.captures[1].gcode else { panic!() };
        assert_eq!((speed, trial.mag_start, trial.pha_start), (0.67, 0.01, 0.5));
        assert!(p.to_string().contains("M973 Y F0.67 R2.1 H16 A0.5 B0.5 C0.01 D0.01"), "{p}");
    }

    #[test]
    fn the_printed_plan_is_gcode_the_capture_reader_recognises() {
        let p = plan_captures(&CapturePlanOptions::new(Axis::X, 50)).unwrap();
        let text = p.to_string();
        assert!(
            text.lines().all(|l| l.starts_with("; ") || l.starts_with("M973 X F") || l.starts_with("M974 X A2 B4 R")),
            "{text}"
        );
        assert!(text.contains("M974 X A2 B4 R-8\n") && text.contains("M974 X A2 B4 R8\n"), "{text}");
        // Each line, echoed by a host before a capture, is taken as that capture's G-code
        // (the firmware accepts it: the reader takes only G-code the firmware would run).
        let capture = "0, 0.01532\n1, -0.04597\nsampling_freq: 1344.52\r\nmovement_ok: true\r\n\
            accel_error: 0\r\nstart_marker: 0.20\r\nend_marker: 5.85\r\nsignal_start: 0.43\r\nsignal_end: 5.43\r\n";
        for c in &p.captures {
            let log = format!("Send: {}\r\n{capture}", c.gcode);
            let caps = read_captures(log.as_bytes(), "plan").unwrap();
            assert_eq!(caps[0].gcode, Some(c.gcode), "{}", c.gcode);
        }
    }

    #[test]
    fn bad_options_are_refused_naming_the_value_and_range() {
        let base = CapturePlanOptions::new(Axis::X, 50);
        let e = plan_captures(&CapturePlanOptions { harmonics: vec![(17, None)], ..base.clone() }).unwrap_err();
        assert_eq!(e.to_string(), "harmonic: 17 must be in 1..=16 (M973's H)");
        let e = plan_captures(&CapturePlanOptions { harmonics: vec![(4, None), (4, None)], ..base.clone() });
        assert_eq!(e.unwrap_err().to_string(), "harmonic: 4 must be listed once");
        let e = plan_captures(&CapturePlanOptions { rate_hz: f64::NAN, ..base.clone() }).unwrap_err();
        assert_eq!(e.to_string(), "rate: NaN must be in 100..=100000 Hz");
        let p = plan_captures(&CapturePlanOptions { harmonics: vec![(4, Some((0.5, 0.0)))], ..base }).unwrap();
        assert!(p.captures[1].reason.contains("capped at 0.03"), "{:?}", p.captures[1]);
    }
}
