//! Model-based prediction: the peak-to-peak velocity error at each resonance of a profile,
//! without compensation and with a given one, from short simulator runs, and the
//! [`Verdict`] on it: a reduction is printed only where the simulation shows one of at
//! least [`CONFIRMED_DB`].

use crate::ExportError;
use rayon::prelude::*;
use serde::Serialize;
use stepdamp_core::{Compensation, Config, CorrectionTable, Mode};
use stepdamp_sim::{ClosedLoop, Profile, RunSpec, SimOptions, run};

/// One resonance.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ResonanceRow {
    /// Detent order k (resonance at `ω_n/(k·Nr)`).
    pub order: u16,
    /// Speed of the largest uncompensated error near the resonance, rad/s.
    pub speed_rad_s: f64,
    /// Largest p-p velocity error near the resonance without compensation, rad/s.
    pub pp_off_rad_s: f64,
    /// The same with the correction, rad/s.
    pub pp_with_rad_s: f64,
}

impl ResonanceRow {
    /// Reduction in dB: `20·log10(off/with)`.
    pub fn reduction_db(&self) -> f64 {
        20.0 * (self.pp_off_rad_s / self.pp_with_rad_s).log10()
    }
}

/// A prediction for one compensation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Prediction {
    /// Compensation name (`table`, `angle`, `patent`…).
    pub compensation: String,
    /// One row per detent order of the profile.
    pub rows: Vec<ResonanceRow>,
}

/// The smallest change of a resonance's p-p error, dB, that a prediction calls a
/// reduction (or, negated, a worsening); smaller changes are "no measurable change". The
/// prediction's runs are deterministic, but 1 dB (12 %) is the least a user could measure
/// on a real motor, and what the drives' rounding and the runs' windows can move.
pub const CONFIRMED_DB: f64 = 1.0;

/// What a prediction says of a correction as a whole.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub enum Verdict {
    /// At least one resonance reduced by ≥ [`CONFIRMED_DB`], none worse by as much.
    Better,
    /// No resonance changed by [`CONFIRMED_DB`] or more.
    NoMeasurableChange,
    /// These orders are worse by ≥ [`CONFIRMED_DB`]: `(order, change in dB, negative)`.
    Worse(Vec<(u16, f64)>),
}

impl ResonanceRow {
    /// The row's change in words: a reduction, a worsening, or no measurable change.
    pub fn change(&self) -> String {
        let db = self.reduction_db();
        if !db.is_finite() {
            "not measured".into()
        } else if db >= CONFIRMED_DB {
            format!("{db:.1} dB lower")
        } else if db <= -CONFIRMED_DB {
            format!("WORSE by {:.1} dB", -db)
        } else {
            format!("no measurable change: under {CONFIRMED_DB} dB either way")
        }
    }
}

impl Prediction {
    /// The verdict on all rows.
    pub fn verdict(&self) -> Verdict {
        let worse: Vec<(u16, f64)> = self
            .rows
            .iter()
            .map(|r| (r.order, r.reduction_db()))
            .filter(|&(_, db)| db <= -CONFIRMED_DB || db.is_nan())
            .collect();
        if !worse.is_empty() {
            Verdict::Worse(worse)
        } else if self.rows.iter().any(|r| r.reduction_db() >= CONFIRMED_DB) {
            Verdict::Better
        } else {
            Verdict::NoMeasurableChange
        }
    }
}

impl std::fmt::Display for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Verdict::Better => write!(f, "the simulation confirms a reduction"),
            Verdict::NoMeasurableChange => write!(
                f,
                "the simulated motor is not measurably better with this correction (no resonance changes by \
                 {CONFIRMED_DB} dB or more)"
            ),
            Verdict::Worse(w) => {
                let o: Vec<String> = w.iter().map(|(k, db)| format!("order {k} by {:.1} dB", -db)).collect();
                write!(f, "the simulated motor is WORSE with this correction: {}", o.join(", "))
            }
        }
    }
}

impl std::fmt::Display for Prediction {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "predicted p-p velocity error at each resonance (simulated: {}):", self.compensation)?;
        for r in &self.rows {
            writeln!(
                f,
                "  order {:>2} at {:7.3} rad/s: {:.4} rad/s without, {:.4} rad/s with ({})",
                r.order,
                r.speed_rad_s,
                r.pp_off_rad_s,
                r.pp_with_rad_s,
                r.change()
            )?;
        }
        Ok(())
    }
}

/// Relative speeds around each resonance where the error is measured (the largest counts).
const GRID: [f64; 5] = [0.92, 0.96, 1.0, 1.04, 1.08];

fn pp(p: &Profile, cfg: Config, speed: f64, duration_s: f64) -> Result<f64, ExportError> {
    let mut lp =
        ClosedLoop::with_config(p, cfg, &SimOptions::default()).map_err(|e| ExportError::Sim(e.to_string()))?;
    let spec = RunSpec { duration_s, window_s: duration_s * 0.4, ..RunSpec::at(speed) };
    spec.check(p.drive.pwm_hz, p.motor.pole_pairs).map_err(|e| ExportError::Sim(e.to_string()))?;
    let m = run(&mut lp, &spec, p.drive.pwm_hz, |_, _| {})
        .map_err(|e| ExportError::Sim(format!("at {speed} rad/s: {e}")))?;
    if m.vel_err_pp_rad_s.is_finite() {
        Ok(m.vel_err_pp_rad_s)
    } else {
        Err(ExportError::Sim(format!("the run at {speed} rad/s diverged")))
    }
}

/// The open-loop controller of `p` with `comp`; `table` for [`Compensation::Table`].
pub fn config(p: &Profile, comp: Compensation, table: Option<&CorrectionTable>) -> Result<Config, ExportError> {
    config_in(p, Mode::OpenLoop, comp, table)
}

/// [`config`] in `mode` (servo for a drive that runs on its encoder, as SimpleFOC does).
pub fn config_in(
    p: &Profile,
    mode: Mode,
    comp: Compensation,
    table: Option<&CorrectionTable>,
) -> Result<Config, ExportError> {
    if comp == Compensation::Table && table.is_none() {
        return Err(ExportError::Invalid("table compensation needs a table".into()));
    }
    p.controller_config(mode, comp, table).map_err(|e| ExportError::Sim(e.to_string()))
}

/// Predicts each compensation in `comps` against none (open loop), on `p`, at every detent order's
/// resonance; runs of `duration_s` (≥ 1 s is what the figures use).
pub fn predict(p: &Profile, comps: &[(String, Config)], duration_s: f64) -> Result<Vec<Prediction>, ExportError> {
    predict_against(p, config(p, Compensation::Off, None)?, comps, duration_s)
}

/// [`predict`] against the baseline controller `off` (e.g. servo mode without compensation).
pub fn predict_against(
    p: &Profile,
    off: Config,
    comps: &[(String, Config)],
    duration_s: f64,
) -> Result<Vec<Prediction>, ExportError> {
    let at: Vec<(String, ConfigAt<'_>)> =
        comps.iter().map(|(n, c)| (n.clone(), Box::new(move |_: f64| Ok(*c)) as ConfigAt<'_>)).collect();
    predict_at(p, off, &at, duration_s)
}

/// A controller as a function of the run's commanded speed (mechanical rad/s): for a law
/// whose timing error depends on speed, such as a feed-forward evaluated once per loop.
pub type ConfigAt<'a> = Box<dyn Fn(f64) -> Result<Config, ExportError> + Sync + 'a>;

/// [`predict_against`] with each compensation's controller built per run speed.
pub fn predict_at(
    p: &Profile,
    off: Config,
    comps: &[(String, ConfigAt<'_>)],
    duration_s: f64,
) -> Result<Vec<Prediction>, ExportError> {
    predict_in(p, off, comps, duration_s, Directions::Forward)
}

/// The directions a prediction runs in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Directions {
    /// Positive speeds only (a correction that does not depend on the direction).
    Forward,
    /// Both signs of every speed (a correction with a table per direction): each row is
    /// the worse of the two directions.
    Both,
}

/// [`predict_at`] in `directions`.
pub fn predict_in(
    p: &Profile,
    off: Config,
    comps: &[(String, ConfigAt<'_>)],
    duration_s: f64,
    directions: Directions,
) -> Result<Vec<Prediction>, ExportError> {
    let mut orders = p.detent_orders();
    orders.sort_unstable_by(|a, b| b.cmp(a));
    let signs: &[f64] = match directions {
        Directions::Forward => &[1.0],
        Directions::Both => &[1.0, -1.0],
    };
    let mut jobs: Vec<(usize, u16, f64)> = Vec::new(); // (config index, order, speed)
    for &k in &orders {
        let w = p.resonance_speed_rad_s(k);
        for g in GRID {
            for &sign in signs {
                for ci in 0..=comps.len() {
                    jobs.push((ci, k, sign * w * g));
                }
            }
        }
    }
    let results: Vec<Result<f64, ExportError>> = jobs
        .par_iter()
        .map(|&(ci, _, speed)| pp(p, if ci == 0 { off } else { (comps[ci - 1].1)(speed)? }, speed, duration_s))
        .collect();
    let mut out = Vec::new();
    for (ci, (name, _)) in comps.iter().enumerate() {
        let mut rows = Vec::new();
        for &k in &orders {
            let (mut best_off, mut at, mut with) = (f64::NEG_INFINITY, 0.0, 0.0);
            for (j, r) in jobs.iter().zip(&results) {
                if j.1 != k || (j.0 != 0 && j.0 != ci + 1) {
                    continue;
                }
                let v = match r {
                    Ok(v) => *v,
                    Err(e) => return Err(ExportError::Sim(e.to_string())),
                };
                if j.0 == 0 && v > best_off {
                    best_off = v;
                    at = j.2;
                }
            }
            // A failed or diverged run with the correction is an error, never a zero error
            // (which would read as an infinite reduction).
            for (j, r) in jobs.iter().zip(&results) {
                if j.1 == k && j.0 == ci + 1 {
                    match r {
                        Ok(v) => with = f64::max(with, *v),
                        Err(e) => return Err(ExportError::Sim(format!("{name}: {e}"))),
                    }
                }
            }
            rows.push(ResonanceRow { order: k, speed_rad_s: at, pp_off_rad_s: best_off, pp_with_rad_s: with });
        }
        out.push(Prediction { compensation: name.clone(), rows });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pred(dbs: &[f64]) -> Prediction {
        let rows = dbs
            .iter()
            .enumerate()
            .map(|(i, db)| ResonanceRow {
                order: i as u16 + 1,
                speed_rad_s: 1.0,
                pp_off_rad_s: 1.0,
                pp_with_rad_s: 10f64.powf(-db / 20.0),
            })
            .collect();
        Prediction { compensation: "x".into(), rows }
    }

    #[test]
    fn a_gain_is_printed_only_where_the_simulation_shows_one() {
        let p = pred(&[18.0, 0.4, -0.3]);
        assert_eq!(p.verdict(), Verdict::Better);
        let text = p.to_string();
        assert!(text.contains("(18.0 dB lower)") && text.matches("no measurable change").count() == 2, "{text}");
        assert_eq!(pred(&[0.9, -0.9]).verdict(), Verdict::NoMeasurableChange);
        let worse = pred(&[18.0, -6.0]);
        assert!(matches!(worse.verdict(), Verdict::Worse(ref w) if w.len() == 1 && w[0].0 == 2));
        assert!(worse.to_string().contains("WORSE by 6.0 dB") && !worse.to_string().contains("+"), "{worse}");
        assert!(worse.verdict().to_string().contains("WORSE with this correction: order 2 by 6.0 dB"));
    }
}
