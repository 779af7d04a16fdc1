//! Aggregation of a results table: the distribution of the reduction at each resonance,
//! the share of variants where compensation makes things worse, the share that holds the
//! threshold at every resonance, and the worst variants with their parameters.
//!
//! A NaN reduction (both runs diverged) counts as 0 (not reduced) everywhere here.

use crate::run::Table;
use crate::spec::{Study, StudyError};
use serde::Serialize;

/// Percentile levels reported, in %.
pub const PERCENTILES: [f64; 7] = [1.0, 5.0, 10.0, 25.0, 50.0, 75.0, 95.0];

/// The reduction at one resonance over all variants.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ResonanceStats {
    /// Detent order `k`.
    pub order: u16,
    /// Nominal resonance speed `ω_n/(k·Nr)`, rad/s.
    pub nominal_speed_rad_s: f64,
    /// `(level %, reduction)` at each of [`PERCENTILES`] (linear interpolation between
    /// order statistics).
    pub percentiles: Vec<(f64, f64)>,
    /// Smallest reduction.
    pub min: f64,
    /// Share of variants (0–1) where compensation made the peak larger (reduction < 1).
    pub share_worse: f64,
    /// Share of variants (0–1) with reduction ≥ the threshold.
    pub share_at_threshold: f64,
}

/// A variant among the worst for one mode and compensation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WorstVariant {
    /// Variant index.
    pub variant: u64,
    /// Its smallest reduction over the resonances.
    pub min_reduction: f64,
    /// The order where that happened.
    pub order: u16,
    /// Its parameters, `(column, value)`.
    pub params: Vec<(String, f64)>,
}

/// Results of one mode and compensation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PairSummary {
    /// Control mode.
    pub mode: String,
    /// Compensation.
    pub compensation: String,
    /// Per resonance, in the study's order.
    pub resonances: Vec<ResonanceStats>,
    /// Share of variants (0–1) with reduction ≥ threshold at every resonance.
    pub share_hold_all: f64,
    /// Share of variants (0–1) where compensation made some resonance worse.
    pub share_worse_any: f64,
    /// Worst variants by smallest reduction, worst first.
    pub worst: Vec<WorstVariant>,
}

/// The study's summary.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StudySummary {
    /// Nominal motor name.
    pub motor: String,
    /// Number of variants.
    pub variants: usize,
    /// Reduction a variant must reach.
    pub threshold: f64,
    /// Per mode and compensation other than off.
    pub pairs: Vec<PairSummary>,
}

/// Percentile `q` (0–100) of sorted `x` by linear interpolation between order statistics.
pub fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = (q / 100.0).clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - lo as f64)
}

fn not_nan(v: f64) -> f64 {
    if v.is_nan() { 0.0 } else { v }
}

impl Study {
    /// Summarises a results table of this study (rows in any order; each variant once).
    pub fn summarize(&self, table: &Table) -> Result<StudySummary, StudyError> {
        let cols = self.columns();
        if table.columns != cols {
            return Err(StudyError::Table(format!(
                "its columns are not this study's (expected {} columns starting {:?})",
                cols.len(),
                &cols[..cols.len().min(3)]
            )));
        }
        if let Some(r) = table.rows.iter().find(|r| r.len() != cols.len()) {
            return Err(StudyError::Table(format!("a row has {} values for {} columns", r.len(), cols.len())));
        }
        let mut rows: Vec<&Vec<f64>> = table.rows.iter().collect();
        rows.sort_by(|a, b| a[0].total_cmp(&b[0]));
        if rows.windows(2).any(|w| w[0][0] == w[1][0]) {
            return Err(StudyError::Table("a variant appears twice".into()));
        }
        let col = |name: &str| cols.iter().position(|c| c == name).expect("own column");
        let n_params = 1 + cols.iter().skip(1).take_while(|c| !c.starts_with("resonance_k")).count();
        let thr = self.spec.report.threshold;
        let n = rows.len();
        let share = |count: usize| if n == 0 { f64::NAN } else { count as f64 / n as f64 };
        let mut pairs = Vec::new();
        for (m, c) in self.pairs().into_iter().filter(|p| p.1 != "off") {
            let idx: Vec<usize> = self.orders.iter().map(|k| col(&format!("reduction_{m}_{c}_k{k}"))).collect();
            let mut resonances = Vec::new();
            for (g, &k) in self.orders.iter().enumerate() {
                let mut x: Vec<f64> = rows.iter().map(|r| not_nan(r[idx[g]])).collect();
                x.sort_by(f64::total_cmp);
                resonances.push(ResonanceStats {
                    order: k,
                    nominal_speed_rad_s: self.nominal.resonance_speed_rad_s(k),
                    percentiles: PERCENTILES.iter().map(|&q| (q, percentile(&x, q))).collect(),
                    min: x.first().copied().unwrap_or(f64::NAN),
                    share_worse: share(x.iter().filter(|&&v| v < 1.0).count()),
                    share_at_threshold: share(x.iter().filter(|&&v| v >= thr).count()),
                });
            }
            // Each variant's smallest reduction and where.
            let mut mins: Vec<(f64, u16, &Vec<f64>)> = rows
                .iter()
                .map(|r| {
                    let (g, v) = idx
                        .iter()
                        .enumerate()
                        .map(|(g, &i)| (g, not_nan(r[i])))
                        .min_by(|a, b| a.1.total_cmp(&b.1))
                        .expect("at least one order");
                    (v, self.orders[g], *r)
                })
                .collect();
            let share_hold_all = share(mins.iter().filter(|m| m.0 >= thr).count());
            let share_worse_any = share(mins.iter().filter(|m| m.0 < 1.0).count());
            mins.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.2[0].total_cmp(&b.2[0])));
            let worst = mins
                .iter()
                .take(self.spec.report.worst)
                .map(|&(v, k, r)| WorstVariant {
                    variant: r[0] as u64,
                    min_reduction: v,
                    order: k,
                    params: cols[1..n_params].iter().cloned().zip(r[1..n_params].iter().copied()).collect(),
                })
                .collect();
            pairs.push(PairSummary {
                mode: m.into(),
                compensation: c.into(),
                resonances,
                share_hold_all,
                share_worse_any,
                worst,
            });
        }
        Ok(StudySummary { motor: self.nominal.name.clone(), variants: n, threshold: thr, pairs })
    }
}

impl StudySummary {
    /// The summary as JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a summary always serialises")
    }

    /// The printed report (the CLI's and Python's `str()`).
    pub fn report(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "{} variants of {}; reduction = peak-to-peak velocity error off / on near each resonance",
            self.variants, self.motor
        );
        for p in &self.pairs {
            let _ = writeln!(
                s,
                "{} {}: holds ≥ {}x at every resonance in {:.1} % of variants; worse somewhere in {:.1} %",
                p.mode,
                p.compensation,
                self.threshold,
                100.0 * p.share_hold_all,
                100.0 * p.share_worse_any
            );
            for r in &p.resonances {
                let pct: Vec<String> = r.percentiles.iter().map(|(q, v)| format!("p{q:.0} {v:.1}x")).collect();
                let _ = writeln!(
                    s,
                    "  k={} ({:.2} rad/s nominal): min {:.2}x, {}; worse in {:.1} %, ≥ {}x in {:.1} %",
                    r.order,
                    r.nominal_speed_rad_s,
                    r.min,
                    pct.join(", "),
                    100.0 * r.share_worse,
                    self.threshold,
                    100.0 * r.share_at_threshold
                );
            }
            for w in &p.worst {
                let params: Vec<String> = w.params.iter().map(|(k, v)| format!("{k} {v:.4e}")).collect();
                let _ = writeln!(
                    s,
                    "  worst: variant {} {:.2}x at k={}: {}",
                    w.variant,
                    w.min_reduction,
                    w.order,
                    params.join(", ")
                );
            }
        }
        s
    }
}
