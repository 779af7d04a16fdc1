//! What the logs can decide, and what the fit does when they cannot.
//!
//! # Runs that hardly move
//!
//! Each run adds a friction level (`Fs·sgn(ω̄) + D·ω̄`) that only its own samples determine:
//! what is left of them once the harmonics, shared by every run, are taken out. The samples
//! where the rotor is (nearly) stopped are not used ([`crate::stick`]), so a run whose rotor
//! moves in only a few of them contributes a level set by a sliver of the electrical period,
//! at the moments it broke free, and not by the run at `ω̄`. Such a run must not count as a
//! speed level: with the others it would decide `D` (and `J`) alone. So the speed levels are
//! taken from the samples the fit really uses, not from the speeds logged:
//! [`runs_without_motion`] leaves out every run whose used samples cover less than
//! [`MIN_MOVING_PERIODS`] electrical period (the window's periods times the share of it
//! used), with a warning naming the runs; `D` and `J` are then decided from the runs left,
//! and held at the base profile's when those no longer give two speeds. This comes after
//! the count-rate rule below, which names the cause when it finds it (a slow level short of
//! friction, both directions): leaving out one direction of such a level first would hide
//! it from that rule (found on the stress family's held-out set, where the order was
//! first the other way: three motors whose slow runs moved 0.9–2 periods each kept one slow
//! run and missed `Fs` by 21–36 %). Measured: on an independent smooth-creep motor driven at 0.5 rad/s with
//! a 78 Hz drive (stress motor 1026), the rotor moved in 0.3–0.5 % of the slow runs'
//! samples (0.03–0.06 period); kept as a speed level, they gave `D` 5.2× and `Fs` 0.2× the
//! truth; left out, `Fs` came within 0.4 % with `D` held.
//!
//! # Runs too slow for the encoder
//!
//! A drive that reacts to each encoder count faster than the rotor crosses it (count rate
//! below its loop bandwidth in rad/s) kicks the rotor at every count: it stops and starts
//! *inside* counts, where no edge timing can see it, and spends a share of the time at
//! speeds where friction is below `Fs` (creep, stiction). Such runs show less friction than
//! faster ones — measured on an independent simulation of the stress family (tests/independent), 5–21 % less at
//! 0.5 than at 1 rad/s with 40–80 Hz drives and 4000 counts, while the 1 rad/s runs gave `Fs`
//! within 0.5 % — and bias the harmonics by up to 6 %. The friction law `Fs + D·|ω|` cannot
//! make the slower level *lower* by more than `ΔD·Δω` (with `D` held at the base profile's),
//! so [`slow_levels_to_leave_out`] compares `Fs` fitted on each speed level alone (both
//! directions, `D` and `J` held at the base's): a level whose runs show the drive reacting to
//! every count (the effort ramps up across each count, [`reacts_to_counts`]) and whose `Fs`
//! is more than [`MAX_FRICTION_DEFICIT`] below the fastest level's is left out, with a
//! warning naming its runs and what to record instead.
//! A motor whose true `D` exceeds the base's by more than `0.04·Fs/Δω` would be misread this
//! way (then the base's `D` is wrong, and the warning says to check it).
//!
//! # Inertia
//!
//! [`InertiaMode::Auto`] (the default) fits `J` only when the runs kept can separate it from
//! the harmonics — two speed levels ([`SPEED_RATIO`](crate::fit::SPEED_RATIO) apart) and
//! both directions: the servo turns the detent into acceleration with a different gain and
//! phase at each speed, and the phase flips with the direction — and its 95 % interval is
//! within [`MAX_INERTIA_INTERVAL`] of the value; otherwise it holds the base profile's `J`.
//! Either way [`Decision`] says which and why. On one log `J` is not separable at all (its
//! instrument is a combination of the harmonic regressors), so a single log always holds it.

use crate::fit::SPEED_RATIO;

/// A speed level whose `Fs` (fitted alone) is more than this fraction below the fastest
/// level's is left out (see the module documentation).
pub const MAX_FRICTION_DEFICIT: f64 = 0.04;

/// With [`InertiaMode::Auto`], the fitted `J` is used only when its 95 % half-width is
/// within this fraction of its value.
pub const MAX_INERTIA_INTERVAL: f64 = 0.1;

/// A run whose used samples cover less than this many electrical periods is left out and
/// does not count as a speed level (see the module documentation). One period: below it the
/// run's samples do not even span the detent's period once, so its friction level rests on
/// part of it.
pub const MIN_MOVING_PERIODS: f64 = 1.0;

/// The runs to leave out because the rotor hardly moves in them: `moving_periods[i]` is the
/// electrical periods' worth of run `i`'s samples the fit uses. Empty when every run moves
/// enough, and when none does (then nothing better is left: the fit keeps them all, and the
/// per-run warnings say how much was left out as stopped).
pub fn runs_without_motion(moving_periods: &[f64]) -> Vec<usize> {
    let short: Vec<usize> = (0..moving_periods.len())
        .filter(|&i| moving_periods[i].is_nan() || moving_periods[i] < MIN_MOVING_PERIODS)
        .collect();
    if short.len() == moving_periods.len() { Vec::new() } else { short }
}

/// How `J` is obtained.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InertiaMode {
    /// Always fitted.
    Fit,
    /// Always the base profile's.
    Base,
    /// Fitted when the logs decide it, else the base profile's (see the module docs).
    #[default]
    Auto,
}

stepdamp_core::named_choice!(InertiaMode, "inertia mode", "fit, base, auto", [
    Fit => "fit",
    Base => "base",
    Auto => "auto",
]);

/// The speed level of each run: runs sorted by `|ω̄|`, a new level starting where a speed
/// is at least [`SPEED_RATIO`] times the slowest of the current level. Level 0 is the
/// slowest.
pub fn speed_levels(speeds_rad_s: &[f64]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..speeds_rad_s.len()).collect();
    order.sort_by(|&a, &b| speeds_rad_s[a].abs().total_cmp(&speeds_rad_s[b].abs()));
    let mut level = vec![0; speeds_rad_s.len()];
    let (mut current, mut floor) = (0, f64::NAN);
    for (n, &i) in order.iter().enumerate() {
        let s = speeds_rad_s[i].abs();
        if n == 0 {
            floor = s;
        } else if s >= SPEED_RATIO * floor {
            current += 1;
            floor = s;
        }
        level[i] = current;
    }
    level
}

/// Slow levels whose friction is too low to be trusted.
#[derive(Clone, Debug, PartialEq)]
pub struct LeftOut {
    /// Indices of the runs left out.
    pub runs: Vec<usize>,
    /// `Fs` of the slowest level left out and of the fastest level, N·m.
    pub fs_slow_nm: f64,
    /// `Fs` of the fastest level, N·m.
    pub fs_fast_nm: f64,
    /// Mean `|ω̄|` of the slowest level left out and of the fastest level, rad/s.
    pub slow_rad_s: f64,
    /// Mean `|ω̄|` of the fastest level, rad/s.
    pub fast_rad_s: f64,
}

/// A run's effort rises across an encoder count by more than this fraction of its mean
/// effort: the drive reacts to each count ([`reacts_to_counts`]).
pub const MIN_COUNT_RISE: f64 = 0.5;

/// Whether the drive reacts to each encoder count within the run: the mean rise of the
/// effort across a count ([`crate::stick::count_rise`]) exceeds [`MIN_COUNT_RISE`] times the
/// run's mean effort in the direction of travel (both in the same unit). Measured: 2–12 on
/// the independent 40–80 Hz drives at 0.5 and 1 rad/s, 3.2 on the plan's slow runs, below
/// 0.1 on its fast runs, 0 on logs without a servo.
pub fn reacts_to_counts(rise: Option<f64>, mean_effort: f64) -> bool {
    rise.is_some_and(|r| r > MIN_COUNT_RISE * mean_effort.abs())
}

/// The runs of the slow speed levels to leave out (see the module documentation):
/// `fs_of(runs)` fits `Fs` on those runs alone with `D` and `J` held (`None` if it cannot).
/// Only levels logged in both directions (so that a constant torque does not count as
/// friction) whose every run the drive drove count by count (`reacts`, see
/// [`reacts_to_counts`]) are candidates; a motor without that signature keeps its runs and
/// the difference goes into `D`. `None` when fewer than two levels, or none is short of
/// friction.
pub fn slow_levels_to_leave_out(
    speeds_rad_s: &[f64],
    reacts: &[bool],
    mut fs_of: impl FnMut(&[usize]) -> Option<f64>,
) -> Option<LeftOut> {
    let level = speed_levels(speeds_rad_s);
    let top = *level.iter().max()?;
    if top == 0 {
        return None;
    }
    let runs_of = |l: usize| (0..level.len()).filter(|&i| level[i] == l).collect::<Vec<_>>();
    let mean_speed = |r: &[usize]| r.iter().map(|&i| speeds_rad_s[i].abs()).sum::<f64>() / r.len() as f64;
    let both_ways = |r: &[usize]| r.iter().any(|&i| speeds_rad_s[i] > 0.0) && r.iter().any(|&i| speeds_rad_s[i] < 0.0);
    let fast = runs_of(top);
    if !both_ways(&fast) {
        return None;
    }
    let fs_fast = fs_of(&fast)?;
    if fs_fast.is_nan() || fs_fast <= 0.0 {
        return None;
    }
    // The fastest level below the top that is short of friction, and every level below it.
    for l in (0..top).rev() {
        let runs = runs_of(l);
        if !(both_ways(&runs) && runs.iter().all(|&i| reacts.get(i).copied().unwrap_or(false))) {
            continue;
        }
        let Some(fs) = fs_of(&runs) else { continue };
        if fs < (1.0 - MAX_FRICTION_DEFICIT) * fs_fast {
            return Some(LeftOut {
                runs: (0..level.len()).filter(|&i| level[i] <= l).collect(),
                fs_slow_nm: fs,
                fs_fast_nm: fs_fast,
                slow_rad_s: mean_speed(&runs),
                fast_rad_s: mean_speed(&fast),
            });
        }
    }
    None
}

/// Whether the runs' design can separate `J` from the harmonics: two speed levels and both
/// directions (see the module documentation). `Err` gives the reason it cannot.
pub fn inertia_separable(speeds_rad_s: &[f64]) -> Result<(), &'static str> {
    let forward = speeds_rad_s.iter().any(|&s| s > 0.0);
    let reverse = speeds_rad_s.iter().any(|&s| s < 0.0);
    let levels = speed_levels(speeds_rad_s).into_iter().max().map_or(0, |m| m + 1);
    match (speeds_rad_s.len(), forward && reverse, levels >= 2) {
        (0 | 1, _, _) => Err("one log: J cannot be told from the harmonics"),
        (_, false, _) => Err("one direction only: J is confounded with the harmonics"),
        (_, true, false) => Err("one speed only: J is confounded with the harmonics (log two speeds ≥ 1.3× apart)"),
        _ => Ok(()),
    }
}

/// Whether to fit `J`: `Ok(forced)` to fit it (`forced` when asked rather than decided),
/// `Err(reason)` to hold the base profile's. `fit_allowed` is
/// [`FitOptions::fit_inertia`](crate::fit::FitOptions::fit_inertia) (off for feed-forward-on
/// logs).
pub fn inertia_choice(fit_allowed: bool, mode: InertiaMode, speeds_rad_s: &[f64]) -> Result<bool, String> {
    match (fit_allowed, mode) {
        (false, _) => Err("held for these logs (feed-forward on, or asked)".into()),
        (true, InertiaMode::Base) => Err("as asked (--inertia base)".into()),
        (true, InertiaMode::Fit) => Ok(true),
        (true, InertiaMode::Auto) => inertia_separable(speeds_rad_s).map(|()| false).map_err(str::to_string),
    }
}

/// Which `J` was used and why.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub enum Decision {
    /// `J` fitted.
    InertiaFitted {
        /// Fitted `J`, kg·m².
        value: f64,
        /// Its 95 % half-width, kg·m².
        ci95: f64,
        /// Asked for (`--inertia fit`) rather than decided.
        forced: bool,
    },
    /// `J` held at the base profile's.
    InertiaHeld {
        /// The base profile's `J`, kg·m².
        base: f64,
        /// Why.
        reason: String,
    },
    /// Back-EMF runs (with phase signals and [`crate::emf::is_emf_run`]) left out of the torque fit: their
    /// harmonics are far beyond the servo, their torque all `J·dω/dt`; they are for the
    /// flux linkage ([`crate::emf`]).
    BackEmfRunsLeftOut {
        /// The runs' sources.
        runs: Vec<String>,
    },
}

impl std::fmt::Display for Decision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Decision::InertiaFitted { value, ci95, forced: true } => {
                write!(f, "J fitted ({value:.4e} ± {ci95:.1e} kg·m²) as asked (--inertia fit)")
            }
            Decision::InertiaFitted { value, ci95, forced: false } => write!(
                f,
                "J fitted ({value:.4e} ± {ci95:.1e} kg·m²): two speeds in both directions separate it and its interval is within {:.0} %",
                100.0 * MAX_INERTIA_INTERVAL
            ),
            Decision::InertiaHeld { base, reason } => {
                write!(f, "J held at the base profile's {base:.4e} kg·m²: {reason}")
            }
            Decision::BackEmfRunsLeftOut { runs } => write!(
                f,
                "{}: back-EMF runs (at least {} Hz electrical), used for the flux linkage, not for the torque fit",
                runs.join(", "),
                crate::emf::EMF_MIN_ELECTRICAL_HZ
            ),
        }
    }
}

/// A condition of the logs that weakens a term (a warning of the fit).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub enum Condition {
    /// Slow runs left out: their friction is short of the fastest runs'.
    SlowRunsLeftOut {
        /// The runs' sources.
        runs: Vec<String>,
        /// `Fs` fitted on the slowest of them alone, N·m.
        fs_slow_nm: f64,
        /// `Fs` fitted on the fastest runs alone, N·m.
        fs_fast_nm: f64,
        /// Their speed, rad/s.
        slow_rad_s: f64,
        /// The fastest runs' speed, rad/s.
        fast_rad_s: f64,
        /// The `D` held while comparing, N·m·s/rad.
        viscous_held: f64,
    },
    /// Runs left out because the rotor moves in too few of their samples
    /// ([`runs_without_motion`]).
    TooLittleMotion {
        /// The runs' sources.
        runs: Vec<String>,
        /// The electrical periods' worth of samples used, per run.
        moving_periods: Vec<f64>,
    },
}

impl std::fmt::Display for Condition {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Condition::SlowRunsLeftOut { runs, fs_slow_nm, fs_fast_nm, slow_rad_s, fast_rad_s, viscous_held } => {
                write!(
                    f,
                    "{}: friction at {slow_rad_s:.3} rad/s ({:.2} mN·m) is {:.0} % below that at {fast_rad_s:.3} rad/s ({:.2} mN·m): the drive reacts to each encoder count faster than the rotor crosses it, so the rotor stops and starts inside counts; these runs are left out of the fit (record them faster, at a count rate above the servo bandwidth in rad/s, or with a softer servo; if the motor's D is far above the base profile's {viscous_held:.3e} N·m·s/rad, correct the base profile)",
                    runs.join(", "),
                    1e3 * fs_slow_nm,
                    100.0 * (1.0 - fs_slow_nm / fs_fast_nm),
                    1e3 * fs_fast_nm
                )
            }
            Condition::TooLittleMotion { runs, moving_periods } => {
                let each: Vec<String> =
                    runs.iter().zip(moving_periods).map(|(r, p)| format!("{r} ({p:.2} period)")).collect();
                write!(
                    f,
                    "{}: the rotor moves in too few samples (less than {MIN_MOVING_PERIODS:.0} electrical period's worth; the rest is stopped or creeping): these runs are left out and do not count as a speed level, so D and J are decided from the other runs (record them faster, or with a softer servo)",
                    each.join(", ")
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speeds_group_into_levels_at_the_speed_ratio() {
        assert_eq!(speed_levels(&[0.5, -0.5, 1.0, -1.0]), vec![0, 0, 1, 1]);
        assert_eq!(speed_levels(&[1.0, -1.2, 1.25]), vec![0, 0, 0]);
        assert_eq!(speed_levels(&[2.0, 1.0, 4.0]), vec![1, 0, 2]);
    }

    #[test]
    fn a_slow_level_short_of_friction_is_left_out_and_a_consistent_one_is_kept() {
        let speeds = [0.5, -0.5, 1.0, -1.0];
        let short = |r: &[usize]| Some(if r.contains(&0) { 0.009 } else { 0.010 });
        let reacts = [true; 4];
        let out = slow_levels_to_leave_out(&speeds, &reacts, short).unwrap();
        assert_eq!(out.runs, vec![0, 1]);
        assert!((out.slow_rad_s - 0.5).abs() < 1e-12 && (out.fast_rad_s - 1.0).abs() < 1e-12);
        let consistent = |r: &[usize]| Some(if r.contains(&0) { 0.0097 } else { 0.010 });
        assert_eq!(slow_levels_to_leave_out(&speeds, &reacts, consistent), None);
        assert_eq!(slow_levels_to_leave_out(&[1.0, -1.0], &reacts, short), None);
        // Without the drive's count-by-count signature, or in one direction only: kept.
        assert_eq!(slow_levels_to_leave_out(&speeds, &[false, true, true, true], short), None);
        assert_eq!(slow_levels_to_leave_out(&[0.5, 1.0, -1.0], &reacts, short), None);
    }

    #[test]
    fn a_run_moving_less_than_one_period_is_left_out_unless_no_run_moves_enough() {
        assert_eq!(runs_without_motion(&[0.04, 0.06, 16.0, 16.0]), vec![0, 1]);
        assert_eq!(runs_without_motion(&[1.0, 12.0]), Vec::<usize>::new());
        assert_eq!(runs_without_motion(&[f64::NAN, 12.0]), vec![0]);
        assert_eq!(runs_without_motion(&[0.2, 0.3]), Vec::<usize>::new());
    }

    #[test]
    fn a_count_rise_counts_only_above_half_the_mean_effort() {
        assert!(reacts_to_counts(Some(0.6), -1.0));
        assert!(!reacts_to_counts(Some(0.4), 1.0) && !reacts_to_counts(None, 1.0));
    }

    #[test]
    fn inertia_needs_two_speeds_and_both_directions() {
        assert!(inertia_separable(&[0.5, -0.5, 1.0, -1.0]).is_ok());
        assert!(inertia_separable(&[1.0]).unwrap_err().contains("one log"));
        assert!(inertia_separable(&[1.0, 2.0]).unwrap_err().contains("one direction"));
        assert!(inertia_separable(&[1.0, -1.0]).unwrap_err().contains("one speed"));
    }

    #[test]
    fn inertia_modes_parse_from_their_names_only() {
        for &m in InertiaMode::ALL {
            assert_eq!(m.name().parse::<InertiaMode>(), Ok(m));
        }
        assert!("Auto".parse::<InertiaMode>().unwrap_err().to_string().contains("fit, base, auto"));
    }
}
