//! The static route (docs/files.md, "Static torque table"): a torque-versus-angle table → FFT → detent harmonics.
//!
//! # Input
//!
//! CSV with a header row and the columns `theta_rad, torque_nm` (any order, other columns
//! ignored): the **mechanical** angle in rad and the torque in N·m, measured at standstill
//! (a torque sensor or a calibrated load) over a **whole number of electrical periods**
//! (`2π/Nr` each), angles strictly increasing, uniformly or non-uniformly spaced. The last
//! point may repeat the first one a period on (`θ_last = θ_first + P·2π/Nr`) or stop one
//! step short; both are recognised.
//!
//! # Sign
//!
//! A sensor between a fixed frame and the unpowered rotor measures either the torque
//! **on the rotor** ([`TorqueSign::OnRotor`]: `τ = −Σ A_k sin(k·Nr·θ + φ_k)`, the detent
//! itself), or the torque that must be **applied to hold** the rotor
//! ([`TorqueSign::Holding`]: `τ = +Σ A_k sin(k·Nr·θ + φ_k)`, what a servo supplies). Say which;
//! the harmonics come out in the profile's convention either way.
//!
//! # Method
//!
//! A table must end within half a mean step of a whole number of periods (read either
//! way), have at least 3 points per electrical period, and span at most [`MAX_PERIODS`];
//! order `k` is reported only when `k·P` is below half the number of points (Nyquist).
//! Non-uniform tables are resampled on a uniform grid of as many points by periodic linear interpolation
//! (the interpolation error of a harmonic sampled `m` times per its period is about
//! `(π/m)²/6` of its amplitude: 0.2 % at 30 points per period). Then a real FFT
//! (`realfft`): with the table spanning `P` electrical periods, bin `m = k·P` is harmonic
//! `k`: `A_k = 2|X_m|/M`, `φ_k = arg X_m + π/2 − k·Nr·θ_first`. A constant (mean) torque and
//! bins between whole orders are reported as the non-periodic rest.

use crate::fit::wrap_pi;
use crate::log::{CsvFailure, MAX_COLUMNS, SHOWN_CHARS, bounded_csv, column_list, header_names};
use realfft::RealFftPlanner;
use realfft::num_complex::Complex;
use std::f64::consts::{FRAC_PI_2, TAU};
use std::path::Path;
use stepdamp_out::input::printable;

/// Most electrical periods a table may span (a million points at 100 per period).
pub const MAX_PERIODS: f64 = 10_000.0;

/// Largest `|torque|` a table may hold, N·m: far above any stepper's (the largest hybrid
/// steppers hold about 50 N·m), and small enough that the FFT of a million points stays
/// finite (a value near `f64::MAX` made the harmonics infinite).
pub const MAX_TORQUE_NM: f64 = 1e6;

/// Which torque the table holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TorqueSign {
    /// Torque on the rotor, `−Σ A sin(k·Nr·θ + φ)` (the detent).
    OnRotor,
    /// Torque needed to hold the rotor, `+Σ A sin(k·Nr·θ + φ)`.
    Holding,
}

stepdamp_core::named_choice!(TorqueSign, "torque sign", "on-rotor, holding", [
    OnRotor => "on-rotor",
    Holding => "holding",
]);

/// A harmonic from the table.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct StaticHarmonic {
    /// Order `k`.
    pub order: u16,
    /// Amplitude `A_k` in N·m.
    pub amplitude_nm: f64,
    /// Phase `φ_k` in rad, `(−π, π]`, profile convention.
    pub phase_rad: f64,
}

/// Result of the analysis.
#[derive(Clone, Debug, PartialEq)]
pub struct StaticCurve {
    /// Harmonics of orders `1..=max_order` (every order the grid resolves, largest first is
    /// not implied: in order of `k`).
    pub harmonics: Vec<StaticHarmonic>,
    /// Mean torque in the table's sign, N·m (friction of the measurement, a sensor offset).
    pub mean_nm: f64,
    /// RMS of what is not a whole-order harmonic (nor the mean), N·m.
    pub rest_rms_nm: f64,
    /// Electrical periods the table spans.
    pub electrical_periods: u32,
}

impl StaticCurve {
    /// The harmonics of the listed orders. Orders the table cannot resolve (`k·P` at or
    /// above half the number of points, with `P` periods) are left out.
    pub fn select(&self, orders: &[u16]) -> Vec<StaticHarmonic> {
        orders.iter().filter_map(|&k| self.harmonics.iter().find(|h| h.order == k).copied()).collect()
    }
}

/// What `stepdamp identify static` prints: the table's size and the harmonics of the asked
/// orders from [`analyse`]. `Display` is the CLI's text, `Serialize` its `--format json`.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StaticReport {
    /// The table, as named in messages (its path).
    pub source: String,
    /// Points in the table.
    pub points: usize,
    /// Electrical periods the table spans.
    pub electrical_periods: u32,
    /// The harmonics of the asked orders the table resolves ([`StaticCurve::select`]).
    pub harmonics: Vec<StaticHarmonic>,
    /// Mean torque in the table's sign, N·m.
    pub mean_nm: f64,
    /// RMS of what is not a whole-order harmonic (nor the mean), N·m.
    pub rest_rms_nm: f64,
}

impl StaticReport {
    /// The report of `curve` (from a table of `points` points named `source`) for `orders`.
    pub fn new(source: &str, points: usize, curve: &StaticCurve, orders: &[u16]) -> Self {
        StaticReport {
            source: source.to_string(),
            points,
            electrical_periods: curve.electrical_periods,
            harmonics: curve.select(orders),
            mean_nm: curve.mean_nm,
            rest_rms_nm: curve.rest_rms_nm,
        }
    }
}

impl std::fmt::Display for StaticReport {
    /// Amplitudes and torques in mN·m, phases in rad (profile convention).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "{}: {} points, {} electrical periods", self.source, self.points, self.electrical_periods)?;
        writeln!(f, "  order   amplitude mN·m   phase rad")?;
        for h in &self.harmonics {
            writeln!(f, "  {:>5}   {:10.4}       {:+8.4}", h.order, 1e3 * h.amplitude_nm, h.phase_rad)?;
        }
        write!(
            f,
            "  mean torque {:.4} mN·m, rest (other orders) {:.4} mN·m RMS",
            1e3 * self.mean_nm,
            1e3 * self.rest_rms_nm
        )
    }
}

/// Why a table could not be analysed; messages name the file and the line (1 = header).
#[derive(Debug, thiserror::Error)]
pub enum StaticError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A needed column is missing.
    #[error("{path}: line 1 (header): missing column '{column}'; the header has: {found}")]
    MissingColumn {
        /// The file.
        path: String,
        /// The column.
        column: &'static str,
        /// What was found.
        found: String,
    },
    /// A value is not a finite number.
    #[error("{path}: line {line}, column '{column}': {value:?} is not a finite number")]
    BadValue {
        /// The file.
        path: String,
        /// Line number.
        line: u64,
        /// The column.
        column: &'static str,
        /// The text.
        value: String,
    },
    /// Angles must increase.
    #[error(
        "{path}: line {line}, column 'theta_rad': angle {theta} rad is not after the previous {prev} rad (angles must increase)"
    )]
    NotIncreasing {
        /// The file.
        path: String,
        /// Line number.
        line: u64,
        /// This angle.
        theta: f64,
        /// Previous angle.
        prev: f64,
    },
    /// The table does not span a whole number of electrical periods (or too few points).
    #[error("{path}: {reason}")]
    Span {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// Malformed CSV.
    #[error("{path}: line {line}: malformed CSV: {message}")]
    Csv {
        /// The file.
        path: String,
        /// Line number.
        line: u64,
        /// The parser's message.
        message: String,
    },
}

/// Reads a `theta_rad, torque_nm` table, streaming (lines bounded by
/// [`crate::log::MAX_LINE_BYTES`], header by [`crate::log::MAX_COLUMNS`]); returns the points.
pub fn read_table(path: &Path) -> Result<Vec<(f64, f64)>, StaticError> {
    let name = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|source| StaticError::Io { path: name.clone(), source })?;
    parse_table(file, &name)
}

/// Parses a `theta_rad, torque_nm` table from a reader; `source` names it in errors. Text
/// from the file is quoted with control characters escaped and cut (see [`crate::log`]).
pub fn parse_table<R: std::io::Read>(reader: R, source: &str) -> Result<Vec<(f64, f64)>, StaticError> {
    let path = source.to_string();
    let mut rdr = bounded_csv(reader);
    let mut rec = csv::ByteRecord::new();
    let csv_err = |e: csv::Error| match CsvFailure::of(e) {
        CsvFailure::LineTooLong { line, limit } => StaticError::Csv {
            path: path.clone(),
            line,
            message: format!("line longer than {limit} bytes: not a theta_rad, torque_nm table"),
        },
        CsvFailure::Io(source) => StaticError::Io { path: path.clone(), source },
        CsvFailure::Malformed { line, message } => StaticError::Csv { path: path.clone(), line, message },
    };
    if !rdr.read_byte_record(&mut rec).map_err(csv_err)? {
        return Err(StaticError::Span {
            path,
            reason: "empty file: expected a header row theta_rad, torque_nm".into(),
        });
    }
    if rec.len() > MAX_COLUMNS {
        return Err(StaticError::Csv {
            path,
            line: 1,
            message: format!("header of {} columns, at most {MAX_COLUMNS} are accepted", rec.len()),
        });
    }
    let header = header_names(&rec);
    let col = |name: &'static str| {
        header.iter().position(|h| h == name).ok_or_else(|| StaticError::MissingColumn {
            path: path.clone(),
            column: name,
            found: column_list(&header),
        })
    };
    let (ct, cq) = (col("theta_rad")?, col("torque_nm")?);
    let mut pts: Vec<(f64, f64)> = Vec::new();
    let mut line = 1;
    loop {
        match rdr.read_byte_record(&mut rec) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(csv_err(e)),
        }
        line = rec.position().map_or(line + 1, |p| p.line());
        let get = |c: usize, column: &'static str| {
            let text = rec.get(c).unwrap_or(b"");
            let v = std::str::from_utf8(text).ok().and_then(|t| t.parse::<f64>().ok());
            v.filter(|v| v.is_finite()).ok_or_else(|| StaticError::BadValue {
                path: path.clone(),
                line,
                column,
                value: printable(text, SHOWN_CHARS),
            })
        };
        let (th, tq) = (get(ct, "theta_rad")?, get(cq, "torque_nm")?);
        if let Some(&(prev, _)) = pts.last()
            && th <= prev
        {
            return Err(StaticError::NotIncreasing { path, line, theta: th, prev });
        }
        pts.push((th, tq));
    }
    Ok(pts)
}

/// Analyses a table of `(θ mechanical rad, torque N·m)` points of a motor with `pole_pairs`
/// pole pairs, returning harmonics up to `max_order` in the profile convention. `source`
/// names the table in errors.
pub fn analyse(
    points: &[(f64, f64)],
    pole_pairs: u16,
    sign: TorqueSign,
    max_order: u16,
    source: &str,
) -> Result<StaticCurve, StaticError> {
    let span_err = |reason: String| StaticError::Span { path: source.to_string(), reason };
    check_points(points, pole_pairs, max_order).map_err(span_err)?;
    let OneSpan { periods, pts } = whole_periods(points, pole_pairs).map_err(span_err)?;
    let p = periods as usize;
    let th0 = points[0].0;
    let span = periods * (TAU / f64::from(pole_pairs));
    let sgn = match sign {
        TorqueSign::OnRotor => -1.0,
        TorqueSign::Holding => 1.0,
    };
    let mut grid = uniform_grid(pts, th0, span, sgn);
    let m = grid.len();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(m);
    let mut spec = fft.make_output_vec();
    fft.process(&mut grid, &mut spec).map_err(|e| span_err(format!("FFT: {e}")))?;
    let harmonics = harmonics_of(&spec, m, p, f64::from(pole_pairs), max_order, th0);
    let harmonic_power = harmonics.iter().fold(0.0, |sum, h| sum + h.amplitude_nm * h.amplitude_nm / 2.0);
    let mf = m as f64;
    let mean = spec[0].re / mf * sgn;
    // Total power (Parseval) minus mean and harmonics.
    let total: f64 = spec
        .iter()
        .enumerate()
        .skip(1)
        .map(|(i, c)| {
            let w = if i == m / 2 { 1.0 } else { 2.0 };
            w * c.norm_sqr() / (mf * mf)
        })
        .sum();
    Ok(StaticCurve {
        harmonics,
        mean_nm: mean,
        rest_rms_nm: (total - harmonic_power).max(0.0).sqrt(),
        electrical_periods: p as u32,
    })
}

/// Checks what [`analyse`] needs of its arguments before looking at the span: at least 8
/// points, pole pairs and highest order ≥ 1, finite angles, torques within
/// ±[`MAX_TORQUE_NM`], angles increasing. The error is the reason.
fn check_points(points: &[(f64, f64)], pole_pairs: u16, max_order: u16) -> Result<(), String> {
    let n = points.len();
    if n < 8 {
        return Err(format!("{n} points: at least 8 are needed"));
    }
    if pole_pairs == 0 || max_order == 0 {
        return Err("pole pairs and the highest order must be ≥ 1".into());
    }
    if let Some((i, &(th, tq))) =
        points.iter().enumerate().find(|(_, p)| !(p.0.is_finite() && p.1.abs() <= MAX_TORQUE_NM))
    {
        return Err(format!(
            "point {} (θ = {th} rad): torque {tq} N·m is not a finite value within ±{MAX_TORQUE_NM:e} N·m (is it in N·m?)",
            i + 1
        ));
    }
    for w in points.windows(2) {
        if w[1].0.partial_cmp(&w[0].0) != Some(std::cmp::Ordering::Greater) {
            return Err(format!("angles must increase ({} then {})", w[0].0, w[1].0));
        }
    }
    Ok(())
}

/// A table cut to one span of whole electrical periods.
struct OneSpan<'a> {
    /// The number of periods `P` (a whole number).
    periods: f64,
    /// The points of the span, the last one before `θ_first + P·2π/Nr`.
    pts: &'a [(f64, f64)],
}

/// The whole number of electrical periods `P` the table spans and the points of one span
/// (without the last point when it repeats the first a span on), checked against
/// [`MAX_PERIODS`] and for at least 3 points per period. The error is the reason.
fn whole_periods(points: &[(f64, f64)], pole_pairs: u16) -> Result<OneSpan<'_>, String> {
    let n = points.len();
    let te = TAU / f64::from(pole_pairs);
    let (th0, thn) = (points[0].0, points[n - 1].0);
    let inclusive = (thn - th0) / te;
    if inclusive > MAX_PERIODS {
        return Err(format!(
            "the table spans {inclusive:.4e} electrical periods (2π/{pole_pairs} rad each); at most {MAX_PERIODS} are \
             analysed (is theta_rad the mechanical angle in radians?)"
        ));
    }
    // One mean step, in periods. The table ends either at θ_first + P·2π/Nr (the last point
    // repeats the first a span on) or one step before it; within half a step either way.
    let step = inclusive / (n - 1) as f64;
    let whole = |x: f64| x.round() >= 1.0 && (x - x.round()).abs() < 0.5 * step;
    let (periods, pts) = if whole(inclusive) {
        (inclusive.round(), &points[..n - 1])
    } else if whole(inclusive + step) {
        ((inclusive + step).round(), points)
    } else {
        return Err(format!(
            "the table spans {inclusive:.3} electrical periods (2π/{pole_pairs} rad each): it must span a whole number, \
             ending at or one step before θ_first + P·2π/{pole_pairs} (within half a step)"
        ));
    };
    // The grid has as many points as the table: a uniform table is analysed exactly, a
    // non-uniform one is resampled without inventing resolution it does not have.
    let (p, m) = (periods as usize, pts.len());
    if m < 2 * p + 1 {
        return Err(format!(
            "{m} points over {p} electrical periods ({:.2} per period): at least 3 per period are needed to resolve \
             order 1 (is theta_rad the mechanical angle in radians?)",
            m as f64 / periods
        ));
    }
    Ok(OneSpan { periods, pts })
}

/// `sgn ×` the torque of `pts` linearly interpolated (periodically, over `span` rad) on a
/// uniform grid of as many points over `[th0, th0 + span)`.
fn uniform_grid(pts: &[(f64, f64)], th0: f64, span: f64, sgn: f64) -> Vec<f64> {
    let m = pts.len();
    let mut grid = Vec::with_capacity(m);
    let mut j = 0usize;
    for i in 0..m {
        let x = th0 + span * i as f64 / m as f64;
        while j + 1 < pts.len() && pts[j + 1].0 <= x {
            j += 1;
        }
        let (xa, ya) = pts[j];
        let (xb, yb) = if j + 1 < pts.len() { pts[j + 1] } else { (pts[0].0 + span, pts[0].1) };
        let f = if xb > xa { (x - xa) / (xb - xa) } else { 0.0 };
        grid.push(sgn * (ya + f * (yb - ya)));
    }
    grid
}

/// The harmonics `1..=max_order` below Nyquist from the spectrum `spec` of `m` grid points
/// spanning `p` electrical periods of a motor of `nr` pole pairs, whose grid starts at `th0`
/// rad: bin `k·P` is order `k`, `A_k = 2|X|/M`, `φ_k = arg X + π/2 − k·Nr·θ_first`.
fn harmonics_of(spec: &[Complex<f64>], m: usize, p: usize, nr: f64, max_order: u16, th0: f64) -> Vec<StaticHarmonic> {
    let mf = m as f64;
    let mut harmonics = Vec::new();
    for k in 1..=max_order {
        let bin = usize::from(k) * p;
        if bin >= m / 2 {
            break;
        }
        let x = spec[bin];
        let amp = 2.0 * x.norm() / mf;
        let phase = wrap_pi(x.im.atan2(x.re) + FRAC_PI_2 - f64::from(k) * nr * th0);
        harmonics.push(StaticHarmonic { order: k, amplitude_nm: amp, phase_rad: phase });
    }
    harmonics
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(n: usize, periods: f64, sign: f64, jitter: bool, inclusive: bool) -> Vec<(f64, f64)> {
        let nr = 50.0;
        let truth = [(4.0, 0.02, 0.3), (2.0, 0.012, 0.7), (1.0, 0.008, -1.1)];
        let th0 = 0.37;
        let span = periods * TAU / nr;
        let last = if inclusive { n } else { n - 1 };
        (0..=last)
            .filter(|&i| inclusive || i < n)
            .map(|i| {
                let mut x = i as f64 / n as f64;
                if jitter && i > 0 && i < n {
                    x += 0.3 * ((i as f64 * 12.9898).sin() * 43_758.547).fract() / n as f64;
                }
                let th = th0 + span * x;
                let tq: f64 = truth.iter().map(|&(k, a, ph)| a * (k * nr * th + ph).sin()).sum();
                (th, sign * tq + 0.001)
            })
            .collect()
    }

    fn check(c: &StaticCurve, tol_a: f64, tol_p: f64) {
        for (k, a, ph) in [(4u16, 0.02, 0.3), (2, 0.012, 0.7), (1, 0.008, -1.1)] {
            let h = c.select(&[k])[0];
            assert!((h.amplitude_nm - a).abs() < tol_a, "k={k}: {h:?}");
            assert!(wrap_pi(h.phase_rad - ph).abs() < tol_p, "k={k}: {h:?}");
        }
    }

    #[test]
    fn holding_torque_table_round_trips_through_the_fft() {
        let c = analyse(&table(512, 3.0, 1.0, false, false), 50, TorqueSign::Holding, 8, "t").unwrap();
        assert_eq!(c.electrical_periods, 3);
        check(&c, 1e-12, 1e-10);
        assert!((c.mean_nm - 0.001).abs() < 1e-12 && c.rest_rms_nm < 1e-9);
        assert!(c.select(&[3])[0].amplitude_nm < 1e-12);
    }

    #[test]
    fn torque_on_the_rotor_table_gives_the_same_harmonics() {
        // The detent itself: −Σ A sin(…). Declared as such, the same profile comes out …
        let t = table(400, 2.0, -1.0, false, true);
        let c = analyse(&t, 50, TorqueSign::OnRotor, 4, "t").unwrap();
        check(&c, 1e-12, 1e-10);
        // … and declared with the wrong sign, every phase is off by π.
        let wrong = analyse(&t, 50, TorqueSign::Holding, 4, "t").unwrap();
        for h in &wrong.harmonics {
            let right = c.select(&[h.order])[0];
            assert!((wrap_pi(h.phase_rad - right.phase_rad).abs() - std::f64::consts::PI).abs() < 1e-9);
        }
    }

    #[test]
    fn non_uniform_tables_are_resampled() {
        let c = analyse(&table(1000, 2.0, 1.0, true, false), 50, TorqueSign::Holding, 4, "t").unwrap();
        check(&c, 2e-4, 0.01);
    }

    #[test]
    fn a_table_that_is_not_whole_periods_is_rejected_with_its_span() {
        let mut t = table(300, 2.0, 1.0, false, false);
        t.truncate(200);
        let e = analyse(&t, 50, TorqueSign::Holding, 4, "curve.csv").unwrap_err().to_string();
        assert!(e.contains("curve.csv") && e.contains("1.327") && e.contains("whole number"), "{e}");
    }

    #[test]
    fn a_table_a_fraction_of_a_period_short_of_whole_is_rejected_even_over_many_periods() {
        // 50.4 periods at 200 points per period: 0.4 periods is 80 steps, not a rounding error.
        let t = table(10_080, 50.4, 1.0, false, false);
        let e = analyse(&t, 50, TorqueSign::Holding, 4, "long.csv").unwrap_err().to_string();
        assert!(e.contains("long.csv") && e.contains("50.395") && e.contains("whole number"), "{e}");
        // The same length ending on a whole number of periods is accepted.
        let c = analyse(&table(10_000, 50.0, 1.0, false, false), 50, TorqueSign::Holding, 4, "t").unwrap();
        assert_eq!(c.electrical_periods, 50);
        check(&c, 1e-12, 1e-10);
    }

    #[test]
    fn orders_above_the_tables_nyquist_limit_are_not_reported() {
        // 4 points per electrical period over 2 periods: bins k·P < 4 only, so order 1 alone.
        let c = analyse(&table(8, 2.0, 1.0, false, false), 50, TorqueSign::Holding, 4, "t").unwrap();
        let orders: Vec<u16> = c.harmonics.iter().map(|h| h.order).collect();
        assert_eq!(orders, vec![1]);
        assert!(c.select(&[1, 2, 4]).len() == 1);
    }

    #[test]
    fn degrees_or_absurd_angles_are_rejected_without_allocating_a_grid_for_them() {
        // A table in degrees: 360 "rad" over one mechanical turn is ≈ 2865 periods with 3.4 points per ten of them.
        let deg: Vec<(f64, f64)> = (0..=100).map(|i| (3.6 * f64::from(i), 0.01)).collect();
        let e = analyse(&deg, 50, TorqueSign::Holding, 4, "deg.csv").unwrap_err().to_string();
        assert!(e.contains("deg.csv") && e.contains("radians"), "{e}");
        // Angles up to 7e12 rad: far more periods than are ever analysed.
        let huge: Vec<(f64, f64)> = (0..=10).map(|i| (7e11 * f64::from(i), 0.01)).collect();
        let e = analyse(&huge, 50, TorqueSign::Holding, 4, "huge.csv").unwrap_err().to_string();
        assert!(e.contains("huge.csv") && e.contains("at most"), "{e}");
    }

    proptest::proptest! {
        #[test]
        fn any_harmonic_set_round_trips_in_both_sign_conventions(
            amps in proptest::collection::vec(0.0f64..0.05, 6),
            phases in proptest::collection::vec(-3.1f64..3.1, 6),
            th0 in -10.0f64..10.0,
            periods in 1u32..4,
            on_rotor: bool,
        ) {
            let nr = 50.0;
            let n = 96 * periods as usize;
            let span = f64::from(periods) * TAU / nr;
            let sign = if on_rotor { -1.0 } else { 1.0 };
            let pts: Vec<(f64, f64)> = (0..n)
                .map(|i| {
                    let th = th0 + span * i as f64 / n as f64;
                    let tq: f64 = (0..6).map(|k| amps[k] * ((k + 1) as f64 * nr * th + phases[k]).sin()).sum();
                    (th, sign * tq)
                })
                .collect();
            let which = if on_rotor { TorqueSign::OnRotor } else { TorqueSign::Holding };
            let c = analyse(&pts, 50, which, 6, "p").unwrap();
            for k in 0..6 {
                let h = c.harmonics[k];
                proptest::prop_assert!((h.amplitude_nm - amps[k]).abs() < 1e-9);
                if amps[k] > 1e-6 {
                    proptest::prop_assert!(wrap_pi(h.phase_rad - phases[k]).abs() < 1e-6);
                }
            }
        }
    }

    #[test]
    fn table_errors_name_the_file_line_and_column() {
        let e = parse_table("theta_rad,torque_nm\n0.0,1\n0.1,x\n".as_bytes(), "c.csv").unwrap_err().to_string();
        assert!(e.contains("c.csv") && e.contains("line 3") && e.contains("torque_nm"), "{e}");
        let e = parse_table("theta_rad,torque_nm\n0.1,1\n0.1,2\n".as_bytes(), "c.csv").unwrap_err().to_string();
        assert!(e.contains("c.csv") && e.contains("line 3") && e.contains("increase"), "{e}");
        let e = parse_table("angle,torque_nm\n0.1,1\n".as_bytes(), "c.csv").unwrap_err().to_string();
        assert!(e.contains("c.csv") && e.contains("theta_rad"), "{e}");
        // A short row names the column it lacks, not a parser's field count.
        let e = parse_table("theta_rad,torque_nm\n0.0,1\n0.1\n".as_bytes(), "c.csv").unwrap_err().to_string();
        assert!(e.contains("c.csv") && e.contains("line 3") && e.contains("torque_nm"), "{e}");
    }

    #[test]
    fn an_endless_or_binary_table_is_refused_without_echoing_it() {
        let e = read_table(Path::new("/dev/zero")).unwrap_err().to_string();
        assert!(e.contains("/dev/zero: line 1") && e.contains("longer than 65536 bytes"), "{e}");
        let e = parse_table(&b"theta_rad,torque_nm\n0,\x1b[31m\n"[..], "t.csv").unwrap_err().to_string();
        assert!(!e.contains('\x1b') && e.contains("line 2") && e.contains("torque_nm"), "{e}");
        let wide: Vec<String> = (0..5000).map(|i| format!("c{i}")).collect();
        let e = parse_table(format!("{}\n", wide.join(",")).as_bytes(), "t.csv").unwrap_err().to_string();
        assert!(e.contains("t.csv: line 1") && e.contains("5000 columns"), "{e}");
    }

    #[test]
    fn a_torque_beyond_any_motor_is_refused_instead_of_giving_infinite_harmonics() {
        // Found by fuzzing: one point of 1e308 N·m made the FFT's amplitudes infinite.
        let mut pts = table(64, 1.0, 1.0, false, false);
        pts[0].1 = 1e308;
        let e = analyse(&pts, 50, TorqueSign::OnRotor, 4, "t.csv").unwrap_err().to_string();
        assert!(e.contains("t.csv") && e.contains("point 1") && e.contains("1e6 N·m"), "{e}");
    }
}
