//! What a sweep shows, as numbers: the resonance speeds, per mode and compensation the
//! median RMS and the worst peak-to-peak velocity error with their ratios to compensation
//! off, and the peak-to-peak error near each resonance. `Display` is the text the command
//! line prints; `Serialize` gives the same numbers to scripts (`--format json`).

use crate::profile::Profile;
use crate::sweep::SweepRow;
use serde::Serialize;
use std::fmt;
use stepdamp_core::{Compensation, Mode};

/// Half-width of the window around a resonance speed in which its peak is looked for, as a
/// fraction of the speed (±10 %: the grid of the README's sweep has a point within it).
pub const PEAK_WINDOW: f64 = 0.1;

/// The summary of a sweep.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepSummary {
    /// The simulated motor's name.
    pub motor: String,
    /// Its natural frequency `ω_n` in rad/s.
    pub natural_frequency_rad_s: f64,
    /// Its open-loop damping ratio.
    pub damping_ratio: f64,
    /// Resonance speeds `ω_n/(k·Nr)`, highest order first ([`Profile::resonance_orders`]).
    pub resonances: Vec<Resonance>,
    /// Lowest commanded speed of the sweep, rad/s.
    pub from_rad_s: f64,
    /// Highest commanded speed of the sweep, rad/s.
    pub to_rad_s: f64,
    /// Per mode, in table order.
    pub modes: Vec<ModeSummary>,
}

/// A resonance speed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Resonance {
    /// Harmonic order `k`.
    pub order: u16,
    /// `ω_n/(k·Nr)` in rad/s.
    pub speed_rad_s: f64,
}

/// One mode of the sweep.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ModeSummary {
    /// The mode.
    pub mode: Mode,
    /// Per compensation, in table order.
    pub compensations: Vec<CompensationSummary>,
    /// Near each resonance, in the order of [`SweepSummary::resonances`].
    pub near_resonances: Vec<NearResonance>,
}

/// The runs of one compensation in one mode, over the sweep's speeds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CompensationSummary {
    /// The compensation.
    pub compensation: Compensation,
    /// Median of the RMS velocity errors, rad/s (a diverged run counts as the highest).
    pub median_rms_rad_s: f64,
    /// Worst peak-to-peak velocity error, rad/s (infinite when a run diverged).
    pub worst_pp_rad_s: f64,
    /// Speed of the worst, rad/s.
    pub worst_at_rad_s: f64,
    /// Runs that lost synchronism.
    pub lost_sync: usize,
    /// Runs of this compensation in this mode.
    pub runs: usize,
    /// Compensation off over this one (how many times less), when both were run.
    pub vs_off: Option<Ratios>,
}

/// How many times less error than without compensation (`off / this`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Ratios {
    /// Of the median RMS.
    pub median_rms: f64,
    /// Of the worst peak-to-peak.
    pub worst_pp: f64,
}

/// The peaks near one resonance.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NearResonance {
    /// The resonance.
    pub resonance: Resonance,
    /// Per compensation with a point in the window.
    pub peaks: Vec<Peak>,
}

/// The highest peak-to-peak error of one compensation near a resonance.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Peak {
    /// The compensation.
    pub compensation: Compensation,
    /// Peak-to-peak velocity error, rad/s.
    pub pp_rad_s: f64,
    /// Compensation off over this one, when both have a point here.
    pub vs_off: Option<f64>,
}

/// Infinity for NaN (a diverged run is the worst).
fn nan_high(v: f64) -> f64 {
    if v.is_nan() { f64::INFINITY } else { v }
}

/// The modes and the compensations of `rows`, each in order of first appearance.
pub fn modes_and_compensations(rows: &[SweepRow]) -> (Vec<Mode>, Vec<Compensation>) {
    let (mut modes, mut comps) = (Vec::new(), Vec::new());
    for r in rows {
        if !modes.contains(&r.mode) {
            modes.push(r.mode);
        }
        if !comps.contains(&r.compensation) {
            comps.push(r.compensation);
        }
    }
    (modes, comps)
}

/// The rows of `comp` in `mode`.
pub(crate) fn runs_of(rows: &[SweepRow], mode: Mode, comp: Compensation) -> Vec<&SweepRow> {
    rows.iter().filter(|r| r.mode == mode && r.compensation == comp).collect()
}

/// Median of the RMS velocity errors (NaN counts as the highest).
fn median_rms(rows: &[&SweepRow]) -> f64 {
    let mut x: Vec<f64> = rows.iter().map(|r| nan_high(r.vel_err_rms_rad_s)).collect();
    if x.is_empty() {
        return f64::NAN;
    }
    x.sort_by(f64::total_cmp);
    0.5 * (x[x.len() / 2] + x[(x.len() - 1) / 2])
}

/// Worst peak-to-peak velocity error and its speed (NaN counts as infinite).
fn worst_pp(rows: &[&SweepRow]) -> (f64, f64) {
    rows.iter()
        .map(|r| (nan_high(r.vel_err_pp_rad_s), r.speed_cmd_rad_s))
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap_or((f64::NAN, f64::NAN))
}

/// Highest peak-to-peak error within [`PEAK_WINDOW`] of `speed`.
fn peak_near(rows: &[&SweepRow], speed: f64) -> Option<f64> {
    rows.iter()
        .filter(|r| (r.speed_cmd_rad_s - speed).abs() <= PEAK_WINDOW * speed)
        .map(|r| r.vel_err_pp_rad_s)
        .max_by(|a, b| nan_high(*a).total_cmp(&nan_high(*b)))
}

impl SweepSummary {
    /// The summary of `rows`, a sweep of `motor`.
    pub fn new(motor: &Profile, rows: &[SweepRow]) -> SweepSummary {
        let resonances: Vec<Resonance> = motor
            .resonance_orders()
            .into_iter()
            .map(|order| Resonance { order, speed_rad_s: motor.resonance_speed_rad_s(order) })
            .collect();
        let (modes, comps) = modes_and_compensations(rows);
        let modes = modes
            .into_iter()
            .map(|mode| {
                let off = runs_of(rows, mode, Compensation::Off);
                let compensations = comps
                    .iter()
                    .filter_map(|&comp| {
                        let this = runs_of(rows, mode, comp);
                        if this.is_empty() {
                            return None;
                        }
                        let (med, (worst, at)) = (median_rms(&this), worst_pp(&this));
                        let vs_off = (comp != Compensation::Off && !off.is_empty())
                            .then(|| Ratios { median_rms: median_rms(&off) / med, worst_pp: worst_pp(&off).0 / worst });
                        Some(CompensationSummary {
                            compensation: comp,
                            median_rms_rad_s: med,
                            worst_pp_rad_s: worst,
                            worst_at_rad_s: at,
                            lost_sync: this.iter().filter(|r| r.lost_sync).count(),
                            runs: this.len(),
                            vs_off,
                        })
                    })
                    .collect();
                let near_resonances = resonances
                    .iter()
                    .map(|&resonance| {
                        let off_pp = peak_near(&off, resonance.speed_rad_s);
                        let peaks = comps
                            .iter()
                            .filter_map(|&comp| {
                                let pp = peak_near(&runs_of(rows, mode, comp), resonance.speed_rad_s)?;
                                let vs_off = if comp == Compensation::Off { None } else { off_pp.map(|o| o / pp) };
                                Some(Peak { compensation: comp, pp_rad_s: pp, vs_off })
                            })
                            .collect();
                        NearResonance { resonance, peaks }
                    })
                    .collect();
                ModeSummary { mode, compensations, near_resonances }
            })
            .collect();
        SweepSummary {
            motor: motor.name.clone(),
            natural_frequency_rad_s: motor.natural_frequency_rad_s(),
            damping_ratio: motor.damping_ratio(),
            resonances,
            from_rad_s: rows.iter().map(|r| r.speed_cmd_rad_s).fold(f64::INFINITY, f64::min),
            to_rad_s: rows.iter().map(|r| r.speed_cmd_rad_s).fold(f64::NEG_INFINITY, f64::max),
            modes,
        }
    }
}

/// `off / on` as "12.3x less" (or "more").
struct Ratio(f64);

impl fmt::Display for Ratio {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = self.0;
        if !r.is_finite() || r <= 0.0 {
            f.write_str("ratio n/a")
        } else if r >= 1.0 {
            write!(f, "{r:.1}x less")
        } else {
            write!(f, "{:.1}x more", 1.0 / r)
        }
    }
}

impl fmt::Display for SweepSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let wn = self.natural_frequency_rad_s;
        writeln!(
            f,
            "{}: ω_n = {wn:.1} rad/s ({:.1} Hz), damping ratio {:.4}",
            self.motor,
            wn / std::f64::consts::TAU,
            self.damping_ratio
        )?;
        let res: Vec<String> =
            self.resonances.iter().map(|r| format!("k={} {:.2} rad/s", r.order, r.speed_rad_s)).collect();
        writeln!(f, "resonance speeds ω_n/(k·Nr): {}", res.join(", "))?;
        for m in &self.modes {
            writeln!(f, "{}: velocity error over {:.2}..{:.2} rad/s", m.mode, self.from_rad_s, self.to_rad_s)?;
            for l in &m.compensations {
                write!(
                    f,
                    "  {:>9}: median rms {:.4} rad/s, worst pp {:.4} rad/s at {:.2} rad/s, lost sync {}/{}",
                    l.compensation.name(),
                    l.median_rms_rad_s,
                    l.worst_pp_rad_s,
                    l.worst_at_rad_s,
                    l.lost_sync,
                    l.runs
                )?;
                if let Some(r) = l.vs_off {
                    write!(f, "; vs off: median rms {}, worst pp {}", Ratio(r.median_rms), Ratio(r.worst_pp))?;
                }
                writeln!(f)?;
            }
            for n in m.near_resonances.iter().filter(|n| !n.peaks.is_empty()) {
                let parts: Vec<String> = n
                    .peaks
                    .iter()
                    .map(|p| match p.vs_off {
                        Some(r) => format!("{} {:.4} ({})", p.compensation, p.pp_rad_s, Ratio(r)),
                        None => format!("{} {:.4}", p.compensation, p.pp_rad_s),
                    })
                    .collect();
                writeln!(
                    f,
                    "  pp near k={} {:.2} rad/s ±10 %, rad/s: {}",
                    n.resonance.order,
                    n.resonance.speed_rad_s,
                    parts.join(", ")
                )?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(mode: Mode, compensation: Compensation, w: f64, rms: f64, pp: f64) -> SweepRow {
        SweepRow {
            mode,
            compensation,
            speed_cmd_rad_s: w,
            vel_err_rms_rad_s: rms,
            vel_err_pp_rad_s: pp,
            lost_sync: pp.is_nan(),
        }
    }

    #[test]
    fn the_summary_gives_median_rms_and_worst_pp_ratios_and_the_peaks_near_each_resonance() {
        let p = Profile::preset("patent-motor").unwrap();
        let w4 = p.resonance_speed_rad_s(4);
        let mut rows = Vec::new();
        for (i, w) in [w4, 6.0, 10.0].into_iter().enumerate() {
            rows.push(row(Mode::Servo, Compensation::Off, w, [1.0, 2.0, 3.0][i], [10.0, 4.0, 6.0][i]));
            rows.push(row(Mode::Servo, Compensation::Patent, w, [0.1, 0.2, 0.3][i], [1.0, 2.0, 0.5][i]));
        }
        let sum = SweepSummary::new(&p, &rows);
        let patent = sum.modes[0].compensations[1];
        assert_eq!(patent.vs_off, Some(Ratios { median_rms: 2.0 / 0.2, worst_pp: 10.0 / 2.0 }));
        let s = sum.to_string();
        // Median rms 2.0 vs 0.2, worst pp 10 vs 2.
        assert!(s.contains("median rms 2.0000 rad/s, worst pp 10.0000 rad/s at 4.22 rad/s, lost sync 0/3"), "{s}");
        assert!(s.contains("vs off: median rms 10.0x less, worst pp 5.0x less"), "{s}");
        assert!(s.contains("pp near k=4 4.22 rad/s ±10 %, rad/s: off 10.0000, patent 1.0000 (10.0x less)"), "{s}");
        // A diverged run is the worst and counts as lost.
        rows.push(row(Mode::Servo, Compensation::Patent, 12.0, f64::NAN, f64::NAN));
        let s = SweepSummary::new(&p, &rows).to_string();
        assert!(s.contains("worst pp inf rad/s at 12.00 rad/s, lost sync 1/4"), "{s}");
        assert!(!s.contains("-inf"), "{s}");
    }
}
