//! Model-based prediction: the peak-to-peak velocity error at each resonance of a profile,
//! without compensation and with a given one, from short simulator runs.

use crate::ExportError;
use rayon::prelude::*;
use serde::Serialize;
use stepdamp_core::{Compensation, Config, CorrectionTable, Mode};
use stepdamp_sim::{ClosedLoop, Profile, RunSpec, SimOptions, controller_config, run};

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

impl std::fmt::Display for Prediction {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "predicted p-p velocity error at each resonance (simulated: {}):", self.compensation)?;
        for r in &self.rows {
            writeln!(
                f,
                "  order {:>2} at {:7.3} rad/s: {:.4} rad/s without, {:.4} rad/s with ({:+.1} dB)",
                r.order,
                r.speed_rad_s,
                r.pp_off_rad_s,
                r.pp_with_rad_s,
                r.reduction_db()
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
    let cfg = match (comp, table) {
        (Compensation::Table, Some(t)) => stepdamp_sim::controller_config_with_table(p, mode, t),
        (Compensation::Table, None) => return Err(ExportError::Invalid("table compensation needs a table".into())),
        _ => controller_config(p, mode, comp),
    };
    cfg.map_err(|e| ExportError::Sim(e.to_string()))
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
    let mut orders = p.detent_orders();
    orders.sort_unstable_by(|a, b| b.cmp(a));
    let mut jobs: Vec<(usize, u16, f64)> = Vec::new(); // (config index, order, speed)
    for &k in &orders {
        let w = p.resonance_speed_rad_s(k);
        for g in GRID {
            for ci in 0..=comps.len() {
                jobs.push((ci, k, w * g));
            }
        }
    }
    let results: Vec<Result<f64, ExportError>> = jobs
        .par_iter()
        .map(|&(ci, _, speed)| pp(p, if ci == 0 { off } else { comps[ci - 1].1 }, speed, duration_s))
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
            for (j, r) in jobs.iter().zip(&results) {
                if j.1 == k && j.0 == ci + 1 {
                    if let Ok(v) = r {
                        with = f64::max(with, *v);
                    }
                }
            }
            rows.push(ResonanceRow { order: k, speed_rad_s: at, pp_off_rad_s: best_off, pp_with_rad_s: with });
        }
        out.push(Prediction { compensation: name.clone(), rows });
    }
    Ok(out)
}
