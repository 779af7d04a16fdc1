//! One influence step on a Trinamic driver's wave table from Klipper logs
//! (`docs/accelerometer.md#refining-a-trinamic-table`): the response of harmonic `H` in the
//! steady stretches of logs recorded with the table in use and with a trial table, the
//! influence of the table's shift on it, and the shift that leaves the least of it.
//!
//! A Trinamic table turns the current vector only by `ε·sin(H·θe)`, a **real** `ε` (its sine
//! phase, `docs/exporters.md#trinamic-microstep-table-through-klipper`), and the same table runs
//! both ways. So the step is a real least squares over every pair of stretches (both
//! directions): with `Y₀` the response with the table in use (`ε₀`), `Y₁` with the trial
//! (`ε₁`) and `C = (Y₁ − Y₀)/(ε₁ − ε₀)`, the new shift is
//! `ε = ε₀ − Σ Re(C̄·Y₀) / Σ|C|²`. A ripple whose phase is not the table's keeps the part of
//! `Y₀` across `C`, `|Im(C̄·Y₀)|/|C|` (the **floor**), whatever the table.

use super::{Log, Segment};
use crate::influence::{Complex, InfluenceError, Response, f2_quantile_95, influence};
use crate::lockin::{BlockResponse, window_blocks};
use crate::ripple::Direction;

/// A stretch is measured as one response when its commanded speed stays within this share of
/// its mean (a steady move; a sweep's stretches are not used).
pub const STEADY_SPREAD: f64 = 0.01;

/// Stretches pool, and the two logs' responses pair up, when their mean speeds agree within
/// this share.
pub const SAME_SPEED: f64 = 0.01;

/// One pair of stretches: the same direction and speed, with the table in use and the trial.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairStep {
    /// The direction.
    pub direction: Direction,
    /// The baseline stretch's mean speed (rev/s, signed like the electrical angle).
    pub speed_rev_s: f64,
    /// The response with the table in use (m/s²).
    pub baseline: Response,
    /// The response with the trial table (m/s²).
    pub trial: Response,
    /// `C` (m/s² per rad of shift) and its 95 % radius.
    pub coefficient: Complex,
    /// See [`Self::coefficient`].
    pub coefficient_radius95: f64,
    /// The response the linear model expects with the new table, `Y₀ + C·(ε − ε₀)` (m/s²).
    pub predicted: Complex,
    /// The part no sine-phase table removes, `|Im(C̄·Y₀)|/|C|` (m/s²).
    pub floor_m_s2: f64,
}

/// The step: the shifts and every pair.
#[derive(Debug, Clone, PartialEq)]
pub struct TableStep {
    /// The harmonic `H`.
    pub harmonic: u32,
    /// `ε₀`, the table in use's shift at `H` (rad).
    pub in_use_rad: f64,
    /// `ε₁`, the trial table's (rad).
    pub trial_rad: f64,
    /// The pairs measured.
    pub pairs: Vec<PairStep>,
    /// The new shift `ε` (rad).
    pub new_rad: f64,
    /// Its 95 % half-width, to first order in the responses' radii (rad).
    pub new_radius95_rad: f64,
}

/// The blocks of `harmonic` in a steady stretch (of `per_block` whole periods), with the
/// stretch's mean speed; `None` for a stretch that is not steady.
fn steady_blocks(s: &Segment, harmonic: u32, per_block: u32) -> Option<(f64, Vec<BlockResponse>)> {
    let c = &s.log.commanded[s.range.clone()];
    let mean = c.iter().map(|x| x.speed_rev_s).sum::<f64>() / c.len() as f64;
    if c.iter().any(|x| (x.speed_rev_s - mean).abs() > STEADY_SPREAD * mean.abs()) {
        return None;
    }
    Some((mean, window_blocks(c, &s.log.accel_m_s2[s.range.clone()], s.span_s(), harmonic, per_block)))
}

/// The response of pooled blocks: their mean and 95 % radius as
/// [`crate::influence::harmonic_response`] computes them; `None` below 3 blocks.
fn pooled(blocks: &[BlockResponse], harmonic: u32, per_block: u32, speed_rev_s: f64) -> Option<Response> {
    if blocks.len() < 3 {
        return None;
    }
    let b = blocks.len() as f64;
    let value = blocks.iter().fold(Complex::default(), |a, x| a + x.value).scale(1.0 / b);
    let spread: f64 = blocks.iter().map(|x| (x.value - value).norm_sqr()).sum();
    let radius95 = (f2_quantile_95(2.0 * (b - 1.0)) * spread / (b * (b - 1.0))).sqrt();
    Some(Response { harmonic, value, radius95, blocks: blocks.len(), periods_per_block: per_block, speed_rev_s })
}

/// The response of `harmonic` per direction and speed in the steady stretches of `logs`: the
/// blocks of every stretch of one direction whose mean speed is within [`SAME_SPEED`] of the
/// group's first are pooled (the lock-in is against the logs' own electrical angle, so moves
/// back and forth add up), the speed is their mean. Groups of fewer than 3 blocks are left out.
pub fn steady_responses(logs: &[Log], harmonic: u32, per_block: u32) -> Vec<(Direction, Response)> {
    let mut groups: Vec<(Direction, f64, f64, Vec<BlockResponse>)> = Vec::new();
    for s in logs.iter().flat_map(Log::segments) {
        let Some((v, blocks)) = steady_blocks(&s, harmonic, per_block) else { continue };
        let same = |g: &&mut (Direction, f64, f64, Vec<BlockResponse>)| {
            g.0 == s.direction && (g.1 - v).abs() <= SAME_SPEED * v.abs()
        };
        let w = blocks.len() as f64;
        match groups.iter_mut().find(same) {
            Some(g) => {
                g.2 += v * w;
                g.3.extend(blocks);
            }
            None => groups.push((s.direction, v, v * w, blocks)),
        }
    }
    groups
        .into_iter()
        .filter_map(|(d, _, sum_v, blocks)| {
            let v = sum_v / blocks.len().max(1) as f64;
            pooled(&blocks, harmonic, per_block, v).map(|r| (d, r))
        })
        .collect()
}

/// The trial logs' common shift at `harmonic` (rad, signed): each must carry a trial of that
/// order in sine phase (`PHI` 0 or π), all the same.
fn trial_shift(trial: &[Log], harmonic: u32) -> Result<f64, InfluenceError> {
    let bad = |s: String| InfluenceError::Indeterminate(s);
    let mut shift = None;
    for l in trial {
        let Some(t) = l.trial else { return Err(bad(format!("{}: a trial log without its trial", l.source))) };
        let sine = t.phase_rad.sin().abs() < 1e-6;
        if t.harmonic != harmonic || !sine {
            return Err(bad(format!(
                "{}: trial {},{},{}: a Trinamic table turns order {harmonic} in sine phase only (PHI 0 or π)",
                l.source, t.harmonic, t.amplitude_rad, t.phase_rad
            )));
        }
        let u = t.amplitude_rad * t.phase_rad.cos().signum();
        if shift.is_some_and(|s| s != u) {
            return Err(bad(format!(
                "{}: trial {u} rad, the other trial logs {} rad: one trial",
                l.source,
                shift.unwrap_or(u)
            )));
        }
        shift = Some(u);
    }
    shift.ok_or_else(|| bad("no trial log".into()))
}

/// The step from `baseline` logs (the table in use, shift `in_use_rad` at `harmonic`, no
/// trial) and `trial` logs (each with its [`super::TrialShift`], the trial table's shift):
/// the trial logs' responses per direction and speed ([`steady_responses`]) paired with the
/// baseline's of the same direction and speed ([`SAME_SPEED`]). Refuses: no pair, a trial that moved a pair's response within
/// the noise ([`influence`]), trials of another order or phase.
pub fn table_step(
    baseline: &[Log],
    trial: &[Log],
    harmonic: u32,
    in_use_rad: f64,
    per_block: u32,
) -> Result<TableStep, InfluenceError> {
    let bad = |s: String| InfluenceError::Indeterminate(s);
    if let Some(l) = baseline.iter().find(|l| l.trial.is_some()) {
        return Err(bad(format!("{}: a baseline log with a trial: the baseline runs the table in use", l.source)));
    }
    if !in_use_rad.is_finite() || harmonic == 0 || per_block == 0 {
        return Err(bad(format!("table in use {in_use_rad} rad, harmonic {harmonic}, {per_block} periods per block")));
    }
    let trial_rad = trial_shift(trial, harmonic)?;
    let t = trial_rad - in_use_rad;
    if t.abs() < 1e-6 {
        return Err(bad(format!("the trial's shift {trial_rad} rad is the table in use's: no change to measure")));
    }
    let base = steady_responses(baseline, harmonic, per_block);
    let mut pairs = Vec::new();
    for (direction, y1) in steady_responses(trial, harmonic, per_block) {
        let same = |(d, r): &&(Direction, Response)| {
            *d == direction && (r.speed_rev_s - y1.speed_rev_s).abs() <= SAME_SPEED * y1.speed_rev_s.abs()
        };
        let Some(&(_, y0)) = base.iter().find(same) else { continue };
        // The pair's speeds agree within SAME_SPEED: compare them as one speed.
        let i = influence(&y0, &Response { speed_rev_s: y0.speed_rev_s, ..y1 }, Complex::new(t, 0.0))?;
        let c = i.coefficient;
        pairs.push(PairStep {
            direction,
            speed_rev_s: y0.speed_rev_s,
            baseline: y0,
            trial: y1,
            coefficient: c,
            coefficient_radius95: i.coefficient_radius95,
            predicted: Complex::default(),
            floor_m_s2: (c.conj() * y0.value).im.abs() / c.abs(),
        });
    }
    if pairs.is_empty() {
        return Err(bad(format!(
            "no steady stretch of a trial log has one of the same direction and speed (within {} %) in a baseline log",
            100.0 * SAME_SPEED
        )));
    }
    let d: f64 = pairs.iter().map(|p| p.coefficient.norm_sqr()).sum();
    let n: f64 = pairs.iter().map(|p| (p.coefficient.conj() * p.baseline.value).re).sum();
    let delta = -n / d;
    // First order: dΔ = −Re(C̄·dY₀)/D + Re(B̄·dC), B = −Y₀/D + 2N·C/D², dC = (dY₁ − dY₀)/t.
    let mut var = 0.0;
    for p in &mut pairs {
        p.predicted = p.baseline.value + p.coefficient.scale(delta);
        let b = (p.coefficient.scale(2.0 * n / (d * d)) - p.baseline.value.scale(1.0 / d)).scale(1.0 / t);
        let k0 = (p.coefficient.scale(1.0 / d) + b).abs();
        var += (k0 * p.baseline.radius95).powi(2) + (b.abs() * p.trial.radius95).powi(2);
    }
    Ok(TableStep { harmonic, in_use_rad, trial_rad, pairs, new_rad: in_use_rad + delta, new_radius95_rad: var.sqrt() })
}

/// [`table_step`] from the logs as read, told apart by their trial: those without one are the
/// baseline, those with one the trial. Refuses logs that are all of one kind.
pub fn table_step_of_logs(
    logs: &[Log],
    harmonic: u32,
    in_use_rad: f64,
    per_block: u32,
) -> Result<TableStep, InfluenceError> {
    let (trial, baseline): (Vec<Log>, Vec<Log>) = logs.iter().cloned().partition(|l| l.trial.is_some());
    if baseline.is_empty() || trial.is_empty() {
        let which = if baseline.is_empty() { "every log is a trial log" } else { "no log has a trial" };
        return Err(InfluenceError::Indeterminate(format!(
            "{which}: the step needs logs recorded with the table in use and with the trial table"
        )));
    }
    table_step(&baseline, &trial, harmonic, in_use_rad, per_block)
}

impl std::fmt::Display for TableStep {
    /// The step as a report: the shifts, then per pair the responses with their 95 % radii,
    /// the influence, what the linear model expects and the floor; one line each, ASCII
    /// apart from units (m/s²), so that it can also go into a config file's comments.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "harmonic {}: table in use {:+.4} rad, trial {:+.4} rad -> new shift {:+.4} +- {:.4} rad (95 %)",
            self.harmonic, self.in_use_rad, self.trial_rad, self.new_rad, self.new_radius95_rad
        )?;
        for p in &self.pairs {
            writeln!(
                f,
                "  {} at {:+.3} rev/s: {:.4} +- {:.4} m/s² in use, {:.4} +- {:.4} with the trial; influence {:.3} +- {:.3} m/s² per rad; expected {:.4} m/s², of which {:.4} no sine-phase table removes",
                p.direction.name(),
                p.speed_rev_s,
                p.baseline.value.abs(),
                p.baseline.radius95,
                p.trial.value.abs(),
                p.trial.radius95,
                p.coefficient.abs(),
                p.coefficient_radius95,
                p.predicted.abs(),
                p.floor_m_s2
            )?;
        }
        Ok(())
    }
}
