//! The run current at which a correction fits Prusa's `int8_t` table whole.
//!
//! The table turns the current vector by `Δ(θe) = i_q(θe)/I` (the correction's
//! [`Correction::delta_rad`]), and it holds ±[`SHIFT_LIMIT`]·2π/4096 rad (±0.195 rad) before it
//! wraps. The detent's part of `Δ` falls as `1/I`; the part that grows with the current
//! (docs/design.md#real-motors-flux-harmonics) does not, so a higher run current helps only
//! as far as the detent dominates. [`super::fit`] scales a correction that does not fit down
//! (every order alike); this module says at which run current it would not have to.

use super::{SHIFT_LIMIT, SIN_PERIOD};
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

/// Steps of [`lowest_fitting_current_a`]'s scan: the currents are `from·(up_to/from)^(n/STEPS)`,
/// so the answer is at most `(up_to/from)^(1/STEPS)` above the exact one (0.4 % for a 2:1 range).
const STEPS: u32 = 200;

/// The lowest run current (peak, A) in `[from_a, up_to_a]` at which `p`'s correction
/// ([`Correction::from_profile`] at that current) fits the table unscaled, found on a
/// geometric grid of [`STEPS`] steps (rounded up to it); `None` when none does. Errors as
/// [`Correction::from_profile`], and for a range that is not `0 < from_a ≤ up_to_a`.
pub fn lowest_fitting_current_a(p: &Profile, from_a: f64, up_to_a: f64) -> Result<Option<f64>, ExportError> {
    if !(from_a.is_finite() && up_to_a.is_finite() && from_a > 0.0 && from_a <= up_to_a) {
        return Err(ExportError::Invalid(format!(
            "run current range {from_a}..{up_to_a} A: must be finite with 0 < from ≤ up to"
        )));
    }
    let limit = limit_rad();
    for n in 0..=STEPS {
        let i = from_a * (up_to_a / from_a).powf(f64::from(n) / f64::from(STEPS));
        if wanted_peak_rad(&Correction::from_profile(p, Some(i))?) <= limit {
            return Ok(Some(i));
        }
    }
    Ok(None)
}

/// Where a correction that had to be scaled would fit whole ([`headroom`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Headroom {
    /// The lowest run current that fits, if any up to [`Headroom::searched_up_to`].
    pub fits_at: Option<RunCurrent>,
    /// The highest run current searched: the profile's current limit.
    pub searched_up_to: RunCurrent,
}

impl std::fmt::Display for Headroom {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.fits_at {
            Some(i) => writeln!(
                f,
                "the whole correction fits the table from a run current of {i} (searched up to the profile's \
                 current limit, {:.3} A peak); whether the motor and driver may run that hot is yours to check",
                self.searched_up_to.peak_a()
            ),
            None => writeln!(
                f,
                "no run current up to the profile's current limit ({:.3} A peak) fits the whole correction: \
                 the part of the ripple that grows with the current does not shrink with it",
                self.searched_up_to.peak_a()
            ),
        }
    }
}

/// [`lowest_fitting_current_a`] from the run current `c` was exported for up to `p`'s current
/// limit (`drive.current_limit_a`; at least `c`'s), rounded up so that both numbers a user may
/// copy from its three-decimal display, the peak for `--current` and the RMS for
/// `--current-rms`, are at or above it ([`copyable`]).
pub fn headroom(p: &Profile, c: &Correction) -> Result<Headroom, ExportError> {
    let up_to = p.drive.current_limit_a.max(c.holding_current_a);
    Ok(Headroom {
        fits_at: lowest_fitting_current_a(p, c.holding_current_a, up_to)?.map(copyable).transpose()?,
        searched_up_to: RunCurrent::from_peak(up_to)?,
    })
}

/// The run current at or above `peak_a` whose RMS is a whole mA and whose peak, rounded to
/// the mA as [`RunCurrent`]'s display prints it, is not below `peak_a` either.
fn copyable(peak_a: f64) -> Result<RunCurrent, ExportError> {
    let mut rms_ma = (1e3 * peak_a / std::f64::consts::SQRT_2).ceil();
    // Two steps at most: one mA of RMS is 1.41 mA of peak.
    while (rms_ma * std::f64::consts::SQRT_2).round() < (1e3 * peak_a).ceil() {
        rms_ma += 1.0;
    }
    RunCurrent::from_rms(rms_ma / 1e3)
}

#[cfg(test)]
mod tests {
    use super::*;
    use stepdamp_sim::profile::DetentTerm;

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
        // Δ = A/(Km·I) ≤ limit ⇔ I ≥ A/(Km·limit): 0.15 N·m, Km 0.3 → 2.567 A.
        let p = detent_only(0.15);
        let exact = 0.15 / (0.3 * limit_rad());
        let got = lowest_fitting_current_a(&p, 1.0, 3.0).unwrap().unwrap();
        assert!(got >= exact && got <= exact * 3f64.powf(1.0 / f64::from(STEPS)) * 1.0001, "{got} vs {exact}");
        assert!(wanted_peak_rad(&Correction::from_profile(&p, Some(got)).unwrap()) <= limit_rad());
    }

    #[test]
    fn no_current_in_range_is_none_and_a_fitting_start_is_the_start() {
        let p = detent_only(0.15);
        assert_eq!(lowest_fitting_current_a(&p, 1.0, 2.0).unwrap(), None);
        assert_eq!(lowest_fitting_current_a(&p, 2.8, 3.0).unwrap(), Some(2.8));
    }

    #[test]
    fn the_headroom_searches_from_the_exported_current_to_the_current_limit() {
        // patent-motor's current limit is 3 A.
        let p = detent_only(0.15);
        let h = headroom(&p, &Correction::from_profile(&p, Some(1.9)).unwrap()).unwrap();
        assert_eq!(h.searched_up_to.peak_a(), 3.0);
        let at = h.fits_at.unwrap();
        assert!((2.56..2.6).contains(&at.peak_a()), "{at}");
        // Both displayed values fit: the peak and the RMS, as printed to the mA.
        let shown = |x: f64| (1e3 * x).round() / 1e3;
        for peak in [shown(at.peak_a()), shown(at.rms_a()) * std::f64::consts::SQRT_2] {
            let w = wanted_peak_rad(&Correction::from_profile(&p, Some(peak)).unwrap());
            assert!(w <= limit_rad(), "{peak} A peak: {w} rad");
        }
        assert!(h.to_string().contains("fits the table from a run current of"), "{h}");
        let too_big = detent_only(0.3);
        let h = headroom(&too_big, &Correction::from_profile(&too_big, Some(1.9)).unwrap()).unwrap();
        assert_eq!(h.fits_at, None);
        assert!(h.to_string().starts_with("no run current up to"), "{h}");
    }

    #[test]
    fn a_bad_range_is_refused() {
        let p = detent_only(0.15);
        for (a, b) in [(0.0, 1.0), (2.0, 1.0), (f64::NAN, 1.0), (1.0, f64::INFINITY)] {
            assert!(lowest_fitting_current_a(&p, a, b).is_err(), "{a}..{b}");
        }
    }
}
