//! The design matrix of the fit: one row per used sample, the columns the logs' levels can
//! separate (see the module documentation of [`crate::fit`], *Friction terms* and *Inertia*).

use super::prepare::Prepared;
use super::thresholds::MIN_BLOCKS_PER_LOG;
use super::{Effort, FitError, FitOptions, RunSummary, SPEED_RATIO, Warning};
use crate::kinematics;
use crate::lsq::{self, Design};
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
    let nr = f64::from(o.pole_pairs);
    let kmax = *o.orders.iter().max().expect("checked non-empty");

    // Which terms the data can separate.
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
    let terms = friction_terms(prepared, o.viscous_fallback_nm_s_per_rad);
    let (fit_d, both) = (terms.fit_d, terms.fit_c);
    warnings.extend(terms.warning);

    // Columns: a_k, b_k per order; Fs; [D]; [c]; [J].
    let nh = o.orders.len();
    let col_fs = 2 * nh;
    let col_d = fit_d.then_some(col_fs + 1);
    let col_c = both.then_some(col_fs + 1 + usize::from(fit_d));
    let col_j = o.fit_inertia.then_some(col_fs + 1 + usize::from(fit_d) + usize::from(both));
    let p = col_fs + 1 + usize::from(fit_d) + usize::from(both) + usize::from(o.fit_inertia);
    let cols = Columns { fs: col_fs, d: col_d, c: col_c, j: col_j, p };
    let total: usize = prepared.iter().map(|p| p.hi - p.lo).sum();
    let mut design = Design::new(p);
    design.x.reserve(total * p);
    design.y.reserve(total);
    design.block.reserve(total);
    let mut theta_e_used = Vec::with_capacity(total);
    // dω/dt of each used sample (the inertial torque is J times it).
    let mut alpha_used = Vec::with_capacity(total);
    let mut row = vec![0.0; p];
    let mut block_base = 0u32;
    let mut runs = Vec::new();
    let d_fixed = if fit_d { 0.0 } else { o.viscous_fallback_nm_s_per_rad };
    let non_finite = |what: String| super::solve::non_finite(prepared, o, what);
    for prep in prepared {
        let (log, kin) = (prep.log, &prep.kin);
        let effort = match o.effort {
            Effort::MeasuredIq => &log.i_q_a,
            Effort::CommandIq => log.iq_cmd_a.as_ref().ok_or_else(|| {
                FitError::Options(format!("{}: no iq_cmd_a column, needed for the command effort", log.source))
            })?,
        };
        // The effort through the filter `dω/dt` went through (see the module documentation,
        // *Inertia*).
        // The harmonics in it are scaled by the filter's gain at their frequency (≥ 0.998 by
        // the choice of the corner), and so are their regressors.
        let wbar = prep.speed;
        let smoothed;
        let mut harmonic_gain = vec![1.0; o.orders.len()];
        let effort = if o.smooth_effort {
            let mut v = effort.clone();
            let (fs, fc) = kinematics::smooth(&log.t_s, &mut v, kin.corner_hz);
            for (g, &k) in harmonic_gain.iter_mut().zip(&o.orders) {
                *g = kinematics::smooth_gain(f64::from(k) * nr * wbar.abs() / TAU, fc, fs);
            }
            smoothed = v;
            &smoothed
        } else {
            effort
        };
        let vmin = o.min_speed_fraction * wbar.abs();
        // Blocks of one electrical period (at least 10 blocks per log).
        let span = (log.theta_fb_rad[prep.hi - 1] - log.theta_fb_rad[prep.lo]).abs();
        let per_block = if prep.periods >= MIN_BLOCKS_PER_LOG { TAU / nr } else { span / MIN_BLOCKS_PER_LOG }
            .max(f64::MIN_POSITIVE);
        let th0 = log.theta_fb_rad[prep.lo];
        // The instrument for J: the part of dω/dt periodic in the fitted orders, this log's
        // own (see the module documentation, *Inertia*).
        let alpha_periodic = if col_j.is_some() {
            prep.periodic.get_or_init(|| periodic_part(prep, o.orders.len())).as_ref()
        } else {
            None
        };
        let (mut used, mut stalled, mut max_block) = (0usize, 0usize, 0u32);
        #[allow(clippy::needless_range_loop)] // five parallel arrays are read at i
        for i in prep.lo..prep.hi {
            let w = kin.omega_rad_s[i];
            if w * wbar.signum() < vmin || !prep.keep[i] {
                stalled += 1;
                continue;
            }
            let th = prep.theta[i];
            let te = nr * th;
            let sc = prep.harmonics_at(i);
            for (j, g) in harmonic_gain.iter().enumerate() {
                row[2 * j] = sc[2 * j] * g;
                row[2 * j + 1] = sc[2 * j + 1] * g;
            }
            row[col_fs] = wbar.signum();
            if let Some(cd) = col_d {
                row[cd] = wbar;
            }
            if let Some(cc) = col_c {
                row[cc] = 1.0;
            }
            let alpha = kin.alpha_rad_s2[i];
            let j_alpha = match col_j {
                Some(cj) => {
                    row[cj] = alpha_periodic.map_or(0.0, |c| c.at(sc));
                    0.0
                }
                None => o.inertia_kg_m2 * alpha,
            };
            let y = o.km_nm_per_a * effort[i] - j_alpha - d_ripple * (w - wbar) - d_fixed * wbar;
            if !(y.is_finite() && alpha.is_finite()) {
                return Err(non_finite(format!("{}: the torque Km·i − J·dω/dt at t = {} s", log.source, log.t_s[i])));
            }
            let b = ((th - th0).abs() / per_block) as u32;
            max_block = max_block.max(b);
            design.push(&row, y, block_base + b);
            theta_e_used.push(te.rem_euclid(TAU));
            alpha_used.push(alpha);
            used += 1;
        }
        block_base += max_block + 1;
        let considered = (prep.hi - prep.lo).max(1);
        let stalled_fraction = stalled as f64 / considered as f64;
        let back = prep.back_steps as f64 / prep.steps.max(1) as f64;
        let highest_harmonic_hz = f64::from(kmax) * nr * wbar.abs() / TAU;
        warnings.extend(super::warnings::of_run(
            &log.source,
            o,
            stalled_fraction,
            back,
            wbar,
            kmax,
            highest_harmonic_hz,
        ));
        runs.push(RunSummary {
            source: log.source.clone(),
            mean_speed_rad_s: wbar,
            duration_s: log.t_s[prep.hi - 1] - log.t_s[prep.lo],
            electrical_periods: prep.periods,
            samples_used: used,
            samples: log.len(),
            highest_harmonic_hz,
            inertial_share: 0.0,
            back_step_fraction: back,
        });
    }
    Ok(Built { design, cols, theta_e: theta_e_used, alpha: alpha_used, runs, warnings, one_direction, fit_d })
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
