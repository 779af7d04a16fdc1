//! The design matrix of the fit: one row per used sample, the columns the logs' levels can
//! separate (see the module documentation of [`crate::fit`], *Friction terms* and *Inertia*).

use super::prepare::Prepared;
use super::thresholds::MIN_BLOCKS_PER_LOG;
use super::{Effort, FitError, FitOptions, RunSummary, SPEED_RATIO, Warning};
use crate::kinematics;
use crate::lsq::{self, Design};
use std::borrow::Cow;
use std::f64::consts::TAU;

/// Column indices of the unknowns: `a_k, b_k` per order (`0..2·nh`), then `Fs`, `[D]`,
/// `[c]`, `[J]`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Columns {
    /// `Fs`.
    pub fs: usize,
    /// `D`, when fitted.
    pub d: Option<usize>,
    /// The constant torque `c`, when fitted.
    pub c: Option<usize>,
    /// `J`, when fitted.
    pub j: Option<usize>,
    /// Number of columns.
    pub p: usize,
}

/// The least-squares problem of one pass, with what the result needs besides the solution.
pub(super) struct Built {
    pub design: Design,
    pub cols: Columns,
    /// Electrical angle of each used sample, `[0, 2π)`.
    pub theta_e: Vec<f64>,
    /// `dω/dt` of each used sample (the inertial torque is `J` times it).
    pub alpha: Vec<f64>,
    /// Per-log summaries (`inertial_share` still 0).
    pub runs: Vec<RunSummary>,
    /// Warnings about the data so far.
    pub warnings: Vec<Warning>,
    /// The only direction logged, when only one is.
    pub one_direction: Option<&'static str>,
    /// Whether `D` is a column.
    pub fit_d: bool,
}

/// Builds the design of one pass; `d_ripple` is the `D` of the viscous torque of the speed
/// ripple subtracted from the data.
pub(super) fn build(prepared: &[&Prepared], o: &FitOptions, d_ripple: f64) -> Result<Built, FitError> {
    let (one_direction, mut warnings) = direction_warnings(prepared, o);
    let terms = friction_terms(prepared, o.viscous_fallback_nm_s_per_rad);
    let fit_d = terms.fit_d;
    warnings.extend(terms.warning);
    let cols = Columns::layout(o.orders.len(), fit_d, terms.fit_c, o.fit_inertia);
    let mut rows = Rows::new(cols, prepared.iter().map(|p| p.hi - p.lo).sum());
    // The viscous torque of the mean speed, taken out of the data when `D` is not a column.
    let d_fixed = if fit_d { 0.0 } else { o.viscous_fallback_nm_s_per_rad };
    let mut runs = Vec::with_capacity(prepared.len());
    for prep in prepared {
        let counts = rows.push_log(prep, o, d_ripple, d_fixed).map_err(|e| match e {
            RowError::NoCommand(e) => e,
            RowError::NonFinite(what) => super::solve::non_finite(prepared, o, what),
        })?;
        let (run, run_warnings) = summarise(prep, o, counts);
        warnings.extend(run_warnings);
        runs.push(run);
    }
    let Rows { design, theta_e, alpha, .. } = rows;
    Ok(Built { design, cols, theta_e, alpha, runs, warnings, one_direction, fit_d })
}

/// Which directions the logs cover: the only direction logged (when only one is), and the
/// warnings for a single direction or too few electrical periods in one.
fn direction_warnings(prepared: &[&Prepared], o: &FitOptions) -> (Option<&'static str>, Vec<Warning>) {
    let mut warnings = Vec::new();
    let (mut fwd_periods, mut rev_periods) = (0.0, 0.0);
    for p in prepared {
        if p.speed > 0.0 {
            fwd_periods += p.periods;
        } else {
            rev_periods += p.periods;
        }
    }
    let one_direction = match (fwd_periods > 0.0, rev_periods > 0.0) {
        (true, true) => None,
        (true, false) => Some("forward"),
        _ => Some("reverse"),
    };
    if let Some(direction) = one_direction {
        warnings.push(Warning::OneDirection { direction });
    }
    for (dir, per) in [("forward", fwd_periods), ("reverse", rev_periods)] {
        if per > 0.0 && per < o.recommended_periods {
            warnings.push(Warning::FewPeriods { direction: dir, periods: per, recommended: o.recommended_periods });
        }
    }
    (one_direction, warnings)
}

impl Columns {
    /// The columns for `nh` orders: `a_k, b_k` per order, then `Fs`, and `D`, `c`, `J`
    /// where fitted, in that order.
    fn layout(nh: usize, fit_d: bool, fit_c: bool, fit_j: bool) -> Self {
        let fs = 2 * nh;
        let d = fit_d.then_some(fs + 1);
        let c = fit_c.then_some(fs + 1 + usize::from(fit_d));
        let j = fit_j.then_some(fs + 1 + usize::from(fit_d) + usize::from(fit_c));
        let p = fs + 1 + usize::from(fit_d) + usize::from(fit_c) + usize::from(fit_j);
        Columns { fs, d, c, j, p }
    }

    /// Fills the harmonic and friction columns of `row` for a sample whose `sin, cos(k·θe)`
    /// per order are `sc`, with each order's regressors scaled by its `gain` (the effort's
    /// filter), in a log of mean speed `wbar` rad/s. The `J` column is left as it is.
    fn fill(&self, row: &mut [f64], sc: &[f64], gain: &[f64], wbar: f64) {
        for (j, g) in gain.iter().enumerate() {
            row[2 * j] = sc[2 * j] * g;
            row[2 * j + 1] = sc[2 * j + 1] * g;
        }
        row[self.fs] = wbar.signum();
        if let Some(cd) = self.d {
            row[cd] = wbar;
        }
        if let Some(cc) = self.c {
            row[cc] = 1.0;
        }
    }
}

/// What a log's rows could not be built for.
enum RowError {
    /// The effort asked for is not in the log.
    NoCommand(FitError),
    /// A torque or `dω/dt` is not finite (what and where).
    NonFinite(String),
}

/// How many samples of a log's window went into the design, and how many were left out
/// (too slow or stuck).
struct LogCounts {
    used: usize,
    stalled: usize,
}

/// The rows of the design as they are built, log by log, with the angle and `dω/dt` of each.
struct Rows {
    cols: Columns,
    design: Design,
    /// Electrical angle of each row's sample, `[0, 2π)`.
    theta_e: Vec<f64>,
    /// `dω/dt` of each row's sample (the inertial torque is `J` times it).
    alpha: Vec<f64>,
    /// The row being filled, `cols.p` values.
    row: Vec<f64>,
    /// First block label of the next log (each log's blocks follow the previous log's).
    block_base: u32,
}

impl Rows {
    /// Room for `total` rows.
    fn new(cols: Columns, total: usize) -> Self {
        let mut design = Design::new(cols.p);
        design.x.reserve(total * cols.p);
        design.y.reserve(total);
        design.block.reserve(total);
        Rows {
            cols,
            design,
            theta_e: Vec::with_capacity(total),
            alpha: Vec::with_capacity(total),
            row: vec![0.0; cols.p],
            block_base: 0,
        }
    }

    /// Appends a row for each sample of the window of `prep` that moves at least
    /// [`FitOptions::min_speed_fraction`] of the mean speed in its direction and is kept:
    /// the torque `Km·i − J·dω/dt − d_ripple·(ω − ω̄) − d_fixed·ω̄` (N·m; `J·dω/dt` only when
    /// `J` is not a column) against the columns.
    fn push_log(
        &mut self,
        prep: &Prepared,
        o: &FitOptions,
        d_ripple: f64,
        d_fixed: f64,
    ) -> Result<LogCounts, RowError> {
        let (log, kin, cols) = (prep.log, &prep.kin, self.cols);
        let (effort, harmonic_gain) = filtered_effort(prep, o)?;
        let wbar = prep.speed;
        let blocks = Blocks::of(prep, f64::from(o.pole_pairs));
        // The instrument for J: the part of dω/dt periodic in the fitted orders, this log's
        // own (see the module documentation, *Inertia*).
        let alpha_periodic = if cols.j.is_some() {
            prep.periodic.get_or_init(|| periodic_part(prep, o.orders.len())).as_ref()
        } else {
            None
        };
        let nr = f64::from(o.pole_pairs);
        let (mut used, mut stalled, mut max_block) = (0usize, 0usize, 0u32);
        for i in prep.lo..prep.hi {
            if !prep.moves(i, o.min_speed_fraction) {
                stalled += 1;
                continue;
            }
            let w = kin.omega_rad_s[i];
            let th = prep.theta[i];
            let sc = prep.harmonics_at(i);
            cols.fill(&mut self.row, sc, &harmonic_gain, wbar);
            let alpha = kin.alpha_rad_s2[i];
            let j_alpha = match cols.j {
                Some(cj) => {
                    self.row[cj] = alpha_periodic.map_or(0.0, |c| c.at(sc));
                    0.0
                }
                None => o.inertia_kg_m2 * alpha,
            };
            let y = o.km_nm_per_a * effort[i] - j_alpha - d_ripple * (w - wbar) - d_fixed * wbar;
            if !(y.is_finite() && alpha.is_finite()) {
                let what = format!("{}: the torque Km·i − J·dω/dt at t = {} s", log.source, log.t_s[i]);
                return Err(RowError::NonFinite(what));
            }
            let b = blocks.index(th);
            max_block = max_block.max(b);
            self.design.push(&self.row, y, self.block_base + b);
            self.theta_e.push((nr * th).rem_euclid(TAU));
            self.alpha.push(alpha);
            used += 1;
        }
        self.block_base += max_block + 1;
        Ok(LogCounts { used, stalled })
    }
}

/// The effort of a log the fit uses (`Km` times it is the motor torque), through the filter
/// `dω/dt` went through when [`FitOptions::smooth_effort`] (see the module documentation,
/// *Inertia*), and the filter's gain at each order's frequency (≥ 0.998 by the choice of the
/// corner; 1 without the filter), by which the harmonic regressors are scaled too.
fn filtered_effort<'a>(prep: &Prepared<'a>, o: &FitOptions) -> Result<(Cow<'a, [f64]>, Vec<f64>), RowError> {
    let log = prep.log;
    let effort = match o.effort {
        Effort::MeasuredIq => &log.i_q_a,
        Effort::CommandIq => log.iq_cmd_a.as_ref().ok_or_else(|| {
            RowError::NoCommand(FitError::Options(format!(
                "{}: no iq_cmd_a column, needed for the command effort",
                log.source
            )))
        })?,
    };
    let mut harmonic_gain = vec![1.0; o.orders.len()];
    if !o.smooth_effort {
        return Ok((Cow::Borrowed(effort), harmonic_gain));
    }
    let nr = f64::from(o.pole_pairs);
    let mut v = effort.clone();
    let (fs, fc) = kinematics::smooth(&log.t_s, &mut v, prep.kin.corner_hz);
    for (g, &k) in harmonic_gain.iter_mut().zip(&o.orders) {
        *g = kinematics::smooth_gain(f64::from(k) * nr * prep.speed.abs() / TAU, fc, fs);
    }
    Ok((Cow::Owned(v), harmonic_gain))
}

/// The blocks of a log for the robust covariance ([`crate::lsq`]): one electrical period
/// each, or a tenth ([`MIN_BLOCKS_PER_LOG`]) of the window's angle when it is shorter.
struct Blocks {
    /// Angle at the window's start, rad.
    th0: f64,
    /// Angle per block, rad.
    per_block: f64,
}

impl Blocks {
    fn of(prep: &Prepared, nr: f64) -> Self {
        let theta = &prep.log.theta_fb_rad;
        let span = (theta[prep.hi - 1] - theta[prep.lo]).abs();
        let per_block = if prep.periods >= MIN_BLOCKS_PER_LOG { TAU / nr } else { span / MIN_BLOCKS_PER_LOG }
            .max(f64::MIN_POSITIVE);
        Blocks { th0: theta[prep.lo], per_block }
    }

    /// The block (from 0 at the window's start) of a sample at angle `th`, rad.
    fn index(&self, th: f64) -> u32 {
        ((th - self.th0).abs() / self.per_block) as u32
    }
}

/// The summary of a log's part in the design (`inertial_share` still 0) and the warnings
/// about it (stalls, back steps, a harmonic beyond the servo).
fn summarise(prep: &Prepared, o: &FitOptions, counts: LogCounts) -> (RunSummary, Vec<Warning>) {
    let (log, wbar) = (prep.log, prep.speed);
    let nr = f64::from(o.pole_pairs);
    let kmax = *o.orders.iter().max().expect("checked non-empty");
    let considered = (prep.hi - prep.lo).max(1);
    let stalled_fraction = counts.stalled as f64 / considered as f64;
    let back = prep.back_steps as f64 / prep.steps.max(1) as f64;
    let highest_harmonic_hz = f64::from(kmax) * nr * wbar.abs() / TAU;
    let warnings = super::warnings::of_run(&log.source, o, stalled_fraction, back, wbar, kmax, highest_harmonic_hz);
    let run = RunSummary {
        source: log.source.clone(),
        mean_speed_rad_s: wbar,
        duration_s: log.t_s[prep.hi - 1] - log.t_s[prep.lo],
        electrical_periods: prep.periods,
        samples_used: counts.used,
        samples: log.len(),
        highest_harmonic_hz,
        inertial_share: 0.0,
        back_step_fraction: back,
    };
    (run, warnings)
}

/// Fourier coefficients (sin, cos per order, then the mean) of a log's `dω/dt` against the
/// electrical angle over its used window.
#[derive(Clone, Debug)]
pub(super) struct Periodic {
    coef: Vec<f64>,
}

impl Periodic {
    /// The value at a sample whose `sin, cos(k·θe)` per order are `sc`
    /// ([`Prepared::harmonics_at`]).
    fn at(&self, sc: &[f64]) -> f64 {
        let mut v = self.coef[sc.len()];
        for (j, sc) in sc.chunks_exact(2).enumerate() {
            v += self.coef[2 * j] * sc[0] + self.coef[2 * j + 1] * sc[1];
        }
        v
    }
}

/// The least-squares fit of `dω/dt` over the window of `prep` on `sin, cos(k·Nr·θ)` of the
/// fit's `nh` orders and a constant; `None` when it cannot be solved.
fn periodic_part(prep: &Prepared, nh: usize) -> Option<Periodic> {
    let m = 2 * nh + 1;
    let mut design = Design::new(m);
    let mut row = vec![0.0; m];
    for i in (prep.lo..prep.hi).filter(|&i| prep.keep[i]) {
        row[..m - 1].copy_from_slice(prep.harmonics_at(i));
        row[m - 1] = 1.0;
        // One block: only the coefficients are used, not their covariance.
        design.push(&row, prep.kin.alpha_rad_s2[i], 0);
    }
    let coef = lsq::solve(&design).ok()?.beta;
    coef.iter().all(|v| v.is_finite()).then_some(Periodic { coef })
}

/// The friction and constant terms the logs' levels (direction, `|ω̄|`) can separate, and
/// the warning for the term held (see the module documentation, *Friction terms*).
struct FrictionTerms {
    fit_d: bool,
    fit_c: bool,
    warning: Option<Warning>,
}

fn friction_terms(prepared: &[&Prepared], viscous_fallback: f64) -> FrictionTerms {
    // (min, max, mean) of |ω̄| over the logs of one direction.
    let range = |forward: bool| {
        let speeds: Vec<f64> = prepared.iter().filter(|p| (p.speed > 0.0) == forward).map(|p| p.speed.abs()).collect();
        (!speeds.is_empty()).then(|| {
            let (lo, hi) = speeds.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
            (lo, hi, speeds.iter().sum::<f64>() / speeds.len() as f64)
        })
    };
    let two_speeds = |r: Option<(f64, f64, f64)>| r.is_some_and(|(lo, hi, _)| hi >= SPEED_RATIO * lo);
    let (fwd, rev) = (range(true), range(false));
    let fit_d = two_speeds(fwd) || two_speeds(rev);
    let fit_c = fwd.is_some() && rev.is_some();
    let warning = if fit_d {
        None
    } else {
        match (fwd, rev) {
            (Some((f0, f1, fm)), Some((r0, r1, rm))) if f1.max(r1) >= SPEED_RATIO * f0.min(r0) => {
                // One speed per direction, different: the extreme pair spans the directions.
                // Adding the faster speed in the slower direction separates D.
                let add_run = if r1 / f0 >= f1 / r0 { ("forward", r1) } else { ("reverse", f1) };
                Some(Warning::OneSpeedPerDirection {
                    forward_rad_s: fm,
                    reverse_rad_s: rm,
                    viscous_used: viscous_fallback,
                    add_run,
                })
            }
            _ => {
                let smax = fwd.iter().chain(&rev).map(|r| r.1).fold(0.0, f64::max);
                Some(Warning::SingleSpeed { speed_rad_s: smax, viscous_used: viscous_fallback })
            }
        }
    };
    FrictionTerms { fit_d, fit_c, warning }
}
