//! The run current at which a correction fits Prusa's `int8_t` table whole.
//!
//! The table turns the current vector by `Δ(θe) = i_q(θe)/I` (the correction's
//! [`Correction::delta_rad`]), and it holds ±[`SHIFT_LIMIT`]·2π/4096 rad (±0.195 rad) before it
//! wraps. The detent's part of `Δ` falls as `1/I`; the part that grows with the current
//! (docs/design.md#real-motors-flux-harmonics) does not, so a higher run current helps only
//! as far as the detent dominates. [`super::fit`] scales a correction that does not fit down
//! (every order alike); this module says at which run current it would not have to.

use super::{Firmware, SHIFT_LIMIT, SIN_PERIOD};
use crate::{Correction, ExportError, RunCurrent};
use stepdamp_core::TABLE_TICKS;
use stepdamp_sim::Profile;

/// The largest rotation the table holds, rad: `SHIFT_LIMIT·2π/SIN_PERIOD` (0.1948).
pub fn limit_rad() -> f64 {
    SHIFT_LIMIT as f64 * std::f64::consts::TAU / f64::from(SIN_PERIOD)
}

/// The largest `|Δ(θe)|` the correction asks for over the table's ticks, rad.
pub fn wanted_peak_rad(c: &Correction) -> f64 {
    (0..TABLE_TICKS)
        .map(|i| c.delta_rad(std::f64::consts::TAU * i as f64 / TABLE_TICKS as f64).abs())
        .fold(0.0, f64::max)
}

/// Steps of [`scan_currents`]' grid: the currents are `from·(up_to/from)^(n/STEPS)`,
/// so the answer is at most `(up_to/from)^(1/STEPS)` above the exact one (0.35 % for a 2:1
/// range).
const STEPS: u32 = 200;

/// Whether [`super::fit`] writes `p`'s correction at run current `peak_a` (A) unscaled: the
/// same criterion, quantisation and all, as the export itself.
fn fits_whole(p: &Profile, peak_a: f64, fw: Firmware) -> Result<bool, ExportError> {
    Ok(super::fit(&Correction::from_profile(p, Some(peak_a))?, fw)?.kept == 1.0)
}

/// The lowest run current (peak, A) in `[from_a, up_to_a]` at which `p`'s correction
/// ([`Correction::from_profile`] at that current) is written whole for `fw`, found on
/// [`scan_currents`]'s grid; `None` when no grid point does. Errors as
/// [`Correction::from_profile`] and [`super::fit`], and for a range that is not
/// `0 < from_a ≤ up_to_a`.
pub fn lowest_fitting_current_a(
    p: &Profile,
    from_a: f64,
    up_to_a: f64,
    fw: Firmware,
) -> Result<Option<f64>, ExportError> {
    scan_currents(from_a, up_to_a, |i| fits_whole(p, i, fw))
}

/// The first current of the geometric grid `from_a·(up_to_a/from_a)^(n/`[`STEPS`]`)`,
/// `n = 0…STEPS`, whose last point is `up_to_a` itself, at which `fits` holds (the answer is
/// at most one step above the exact one, if `fits` is monotonic); `None` when none does.
/// Refuses a range that is not finite with `0 < from_a ≤ up_to_a`.
pub(super) fn scan_currents(
    from_a: f64,
    up_to_a: f64,
    mut fits: impl FnMut(f64) -> Result<bool, ExportError>,
) -> Result<Option<f64>, ExportError> {
    if !(from_a.is_finite() && up_to_a.is_finite() && from_a > 0.0 && from_a <= up_to_a) {
        return Err(ExportError::Invalid(format!(
            "run current range {from_a}..{up_to_a} A: must be finite with 0 < from ≤ up to"
        )));
    }
    for n in 0..=STEPS {
        // The last point is the limit itself: `powf(1)` may land an ulp above it, which the
        // ripple's current limit refuses.
        let i = if n == STEPS {
            up_to_a
        } else {
            (from_a * (up_to_a / from_a).powf(f64::from(n) / f64::from(STEPS))).min(up_to_a)
        };
        if fits(i)? {
            return Ok(Some(i));
        }
    }
    Ok(None)
}

/// Where a correction that had to be scaled would be written whole ([`headroom`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Headroom {
    /// A run current at which it is, as a user would type it (a whole mA of RMS whose peak
    /// and RMS, as displayed, both fit), if one up to [`Headroom::searched_up_to`] does.
    pub fits_at: Option<RunCurrent>,
    /// The lowest peak current (A) of the scan's grid at which it fits, if any
    /// ([`lowest_fitting_current_a`]); `fits_at` is at or above it.
    pub fits_from_a: Option<f64>,
    /// The highest run current searched: the profile's current limit, or the exported
    /// current where that is higher.
    pub searched_up_to: RunCurrent,
}

impl std::fmt::Display for Headroom {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let up_to = self.searched_up_to.peak_a();
        match (self.fits_at, self.fits_from_a) {
            (Some(i), _) => writeln!(
                f,
                "the whole correction fits the table at a run current of {i} (the lowest found up to {up_to:.3} A \
                 peak, the profile's current limit or the exported current above it); whether the motor and driver \
                 may run that hot is yours to check"
            ),
            (None, Some(from)) => writeln!(
                f,
                "the whole correction fits the table from about {from:.4} A peak, but no whole mA of RMS from there \
                 to {up_to:.3} A peak (the profile's current limit or the exported current above it) was found whose \
                 peak and RMS, as printed, both fit"
            ),
            (None, None) => writeln!(
                f,
                "no run current up to {up_to:.3} A peak (the profile's current limit or the exported current above \
                 it) fits the whole correction (with flux harmonics, the part of the ripple that grows with the \
                 current does not shrink with it)"
            ),
        }
    }
}

/// The first whole mA of RMS at or above `peak_a` (A peak): what `M906` takes (Marlin's
/// `rms_current`, mA).
fn first_whole_ma_rms(peak_a: f64) -> f64 {
    (1e3 * peak_a / std::f64::consts::SQRT_2).ceil()
}

/// The run current to advise for a table that fits from `peak_a` (A peak): the first whole
/// mA of RMS at or above it, if its peak is within `limit_a`; `None` when the answer lies
/// within a mA of RMS below the limit and the next whole mA passes it.
pub fn whole_ma_rms_at_or_above(peak_a: f64, limit_a: f64) -> Result<Option<RunCurrent>, ExportError> {
    let at = RunCurrent::from_rms(first_whole_ma_rms(peak_a) / 1e3)?;
    Ok((at.peak_a() <= limit_a).then_some(at))
}

/// Mill-amperes of RMS [`headroom`] tries above the scan's answer for one whose displayed
/// values fit too: a few are enough where the wanted shift falls with the current.
const COPYABLE_TRIES: u32 = 8;

/// `x` as `{:.3}` prints it (what a user copies), read back.
fn shown(x: f64) -> Result<f64, ExportError> {
    format!("{x:.3}").parse().map_err(|e| ExportError::Invalid(format!("{x:.3} A does not read back: {e}")))
}

/// [`lowest_fitting_current_a`] from the run current `c` was exported for up to `p`'s current
/// limit (`drive.current_limit_a`; at least `c`'s), then the first whole mA of RMS at or
/// above it (of [`COPYABLE_TRIES`]), within the limit, at which both numbers a user may copy
/// from [`RunCurrent`]'s three-decimal display (the peak for `--current`, the RMS for
/// `--current-rms`) are written whole too: a flux profile's wanted shift need not fall
/// monotonically with the current, so each is checked, not assumed. An error here is
/// advice lost, not an export failed: the CLI prints it as a warning.
pub fn headroom(p: &Profile, c: &Correction, fw: Firmware) -> Result<Headroom, ExportError> {
    let up_to = p.drive.current_limit_a.max(c.holding_current_a);
    let searched_up_to = RunCurrent::from_peak(up_to)?;
    let fits_from_a = lowest_fitting_current_a(p, c.holding_current_a, up_to, fw)?;
    let mut h = Headroom { fits_at: None, fits_from_a, searched_up_to };
    let Some(lowest) = fits_from_a else { return Ok(h) };
    let first_rms_ma = first_whole_ma_rms(lowest);
    for rms_ma in (0..COPYABLE_TRIES).map(|k| first_rms_ma + f64::from(k)) {
        let at = RunCurrent::from_rms(rms_ma / 1e3)?;
        let typed = [shown(at.peak_a())?, shown(at.rms_a())? * std::f64::consts::SQRT_2];
        if typed.iter().any(|&t| t > up_to) {
            break;
        }
        if typed.iter().try_fold(true, |ok, &t| Ok::<_, ExportError>(ok && fits_whole(p, t, fw)?))? {
            h.fits_at = Some(at);
            break;
        }
    }
    Ok(h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use stepdamp_sim::profile::{DetentTerm, FluxHarmonic};

    const FW: Firmware = Firmware::V6_3_1;

    /// patent-motor with a 4th-order detent of `a4` N·m only.
    fn detent_only(a4: f64) -> Profile {
        Profile::preset("patent-motor")
            .unwrap()
            .edited("big", |d| {
                d.motor.detent = vec![DetentTerm { order: 4, amplitude_nm: a4, phase_rad: 0.3 }];
            })
            .unwrap()
    }

    #[test]
    fn a_detent_only_correction_fits_at_the_current_the_closed_form_gives() {
        // Δ = A/(Km·I) ≤ limit ⇔ I ≥ A/(Km·limit): 0.15 N·m, Km 0.3 → 2.567 A; the firmware's
        // quantised magnitudes move it by well under a step.
        let p = detent_only(0.15);
        let exact = 0.15 / (0.3 * limit_rad());
        let step = 3f64.powf(1.0 / f64::from(STEPS));
        let got = lowest_fitting_current_a(&p, 1.0, 3.0, FW).unwrap().unwrap();
        assert!(got >= exact / step && got <= exact * step * step, "{got} vs {exact}");
        assert!(fits_whole(&p, got, FW).unwrap());
        assert!(!fits_whole(&p, got / step, FW).unwrap(), "{got} is not the lowest grid point");
    }

    #[test]
    fn no_current_in_range_is_none_and_a_fitting_start_is_the_start() {
        let p = detent_only(0.15);
        assert_eq!(lowest_fitting_current_a(&p, 1.0, 2.0, FW).unwrap(), None);
        assert_eq!(lowest_fitting_current_a(&p, 2.8, 3.0, FW).unwrap(), Some(2.8));
    }

    /// patent-motor with a flux third of `h3` (ratio of the fundamental): its current part
    /// asks the table for `3·h3` rad at any current.
    fn with_third(h3: f64, current_limit_a: f64) -> Profile {
        Profile::preset("patent-motor")
            .unwrap()
            .edited("third", |d| {
                d.motor.flux.harmonics = vec![FluxHarmonic { order: 3, ratio: h3, phase_rad: 0.4 }];
                d.drive.current_limit_a = current_limit_a;
            })
            .unwrap()
    }

    #[test]
    fn a_flux_profile_is_scanned_up_to_its_current_limit_without_passing_it() {
        // A range whose geometric grid lands an ulp above its end unless the end is taken as is.
        let (from, up_to) = (2.488, 3.041);
        assert!(from * (up_to / from) > up_to, "pick a pair that overshoots");
        let p = with_third(0.1, up_to);
        assert_eq!(lowest_fitting_current_a(&p, from, up_to, FW).unwrap(), None);
        let h = headroom(&p, &Correction::from_profile(&p, Some(from)).unwrap(), FW).unwrap();
        assert_eq!((h.fits_at, h.fits_from_a, h.searched_up_to.peak_a()), (None, None, up_to));
        assert!(h.to_string().starts_with("no run current up to 3.041 A peak"), "{h}");
    }

    #[test]
    fn the_headroom_searches_from_the_exported_current_to_the_current_limit() {
        // patent-motor's current limit is 3 A.
        let p = detent_only(0.15);
        let h = headroom(&p, &Correction::from_profile(&p, Some(1.9)).unwrap(), FW).unwrap();
        assert_eq!(h.searched_up_to.peak_a(), 3.0);
        let at = h.fits_at.unwrap();
        assert!((2.55..2.6).contains(&at.peak_a()), "{at}");
        // Both displayed values fit: the peak and the RMS, as printed to the mA.
        for peak in [shown(at.peak_a()).unwrap(), shown(at.rms_a()).unwrap() * std::f64::consts::SQRT_2] {
            assert!(fits_whole(&p, peak, FW).unwrap(), "{peak} A peak");
        }
        assert!(h.to_string().contains("fits the table at a run current of"), "{h}");
        let too_big = detent_only(0.3);
        let h = headroom(&too_big, &Correction::from_profile(&too_big, Some(1.9)).unwrap(), FW).unwrap();
        assert_eq!((h.fits_at, h.fits_from_a), (None, None));
        assert!(h.to_string().starts_with("no run current up to 3.000 A peak"), "{h}");
    }

    #[test]
    fn a_current_that_fits_only_at_the_limit_is_not_advised_above_it() {
        // The limit set where the correction just fits (2.557 A): the scan finds the limit
        // itself, and the first whole mA of RMS above it displays a peak above the limit,
        // which the advice must not offer.
        let lowest = lowest_fitting_current_a(&detent_only(0.15), 1.9, 3.0, FW).unwrap().unwrap();
        let limit = (1e3 * lowest).ceil() / 1e3;
        let p = detent_only(0.15).edited("tight", |d| d.drive.current_limit_a = limit).unwrap();
        assert_eq!(lowest_fitting_current_a(&p, 1.9, limit, FW).unwrap(), Some(limit));
        let next_peak = (1e3 * limit / std::f64::consts::SQRT_2).ceil() * std::f64::consts::SQRT_2 / 1e3;
        assert!((1e3 * next_peak).round() / 1e3 > limit, "{next_peak} vs {limit}: pick another limit");
        let h = headroom(&p, &Correction::from_profile(&p, Some(1.9)).unwrap(), FW).unwrap();
        assert_eq!((h.fits_at, h.fits_from_a), (None, Some(limit)));
        // It says that it fits there, not that nothing does.
        assert!(
            h.to_string().starts_with(&format!("the whole correction fits the table from about {limit:.4} A peak")),
            "{h}"
        );
    }

    #[test]
    fn a_bad_range_is_refused() {
        let p = detent_only(0.15);
        for (a, b) in [(0.0, 1.0), (2.0, 1.0), (f64::NAN, 1.0), (1.0, f64::INFINITY)] {
            assert!(lowest_fitting_current_a(&p, a, b, FW).is_err(), "{a}..{b}");
        }
    }
}
