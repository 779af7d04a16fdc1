//! The run current at which a table **measured** on the printer would fit Prusa's `int8_t`
//! table: the accelerometer route's counterpart of [`super::headroom`], which works from a
//! profile (docs/accelerometer.md#when-the-table-is-too-small).
//!
//! The influence steps give the table that cancels the vibration at the run current `I` they
//! were recorded at: per direction and harmonic `n`, a shift phasor `U_n` (rad,
//! [`table_shift`]). The table turns the current vector by `Δ = i_q/I`; the detent needs a
//! fixed `i_q = T/Km`, so its share of `U_n` falls as `1/I`, while the ripple of the flux
//! harmonics grows with `I` (docs/design.md#real-motors-flux-harmonics) and its share stays.
//! The model per item and direction is therefore
//!
//! ```text
//! U_n(I) = a_n/I + b_n        (rad; a_n in rad·A, b_n in rad; complex)
//! ```
//!
//! One measured table fixes `a_n = I₀·U_n(I₀)` with `b_n = 0`: exact for a detent alone, an
//! **estimate** otherwise (a part that grows with the current in phase with the detent's
//! asks for more current, one against it for less). Two, at different currents, fix both.
//! The model leaves out what else changes with the current (the rotor's load angle, the
//! magnetic stiffness's effect on the response): a current it gives is where to record again,
//! not a promise.

use super::headroom::scan_currents;
use super::{Firmware, ITEMS, PrusaCorrection, SHIFT_LIMIT, Spectrum};
use crate::ExportError;
use stepdamp_accel::Complex;
use stepdamp_accel::influence::{table_item, table_shift};

/// A table that cancels the vibration as measured at one run current.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeasuredTable {
    /// The run current the captures were recorded at, A peak.
    pub peak_a: f64,
    /// The wanted table, unscaled (its peak may pass ±[`SHIFT_LIMIT`]).
    pub table: PrusaCorrection,
}

/// The module's model `U_n(I) = a_n/I + b_n`, fitted to one or two [`MeasuredTable`]s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TableVsCurrent {
    /// `a_n` per direction (forward, backward) and item, rad·A.
    a: [[Complex; ITEMS]; 2],
    /// `b_n` per direction and item, rad.
    b: [[Complex; ITEMS]; 2],
    /// The firmware of the tables.
    firmware: Firmware,
    /// The highest current measured, A peak: where a search starts.
    measured_up_to_a: f64,
}

/// The shift phasors of a spectrum's items, rad.
fn phasors(s: &Spectrum, fw: Firmware) -> [Complex; ITEMS] {
    std::array::from_fn(|n| table_shift(f64::from(s.mag[n]), f64::from(s.pha[n]), fw.scale()))
}

impl TableVsCurrent {
    /// The model through `tables`: one (`b = 0`) or two at currents at least 2 % apart, of
    /// one firmware, every current finite and positive.
    pub fn fit(tables: &[MeasuredTable]) -> Result<Self, ExportError> {
        let bad = |why: String| Err(ExportError::Invalid(why));
        let Some(first) = tables.first() else { return bad("no measured table".into()) };
        let fw = first.table.firmware;
        if tables.len() > 2 {
            return bad(format!("{} measured tables: the model takes one or two", tables.len()));
        }
        for t in tables {
            if !(t.peak_a.is_finite() && t.peak_a > 0.0) {
                return bad(format!(
                    "a measured table at {} A peak: the current must be finite and positive",
                    t.peak_a
                ));
            }
            if t.table.firmware != fw {
                return bad("measured tables of different firmware".into());
            }
        }
        let dirs = |t: &MeasuredTable| [phasors(&t.table.forward, fw), phasors(&t.table.backward, fw)];
        let (u0, i0) = (dirs(first), first.peak_a);
        let zero = [[Complex::default(); ITEMS]; 2];
        let (a, b) = match tables.get(1) {
            None => (u0.map(|d| d.map(|u| u.scale(i0))), zero),
            Some(second) => {
                let (u1, i1) = (dirs(second), second.peak_a);
                if (i1 - i0).abs() < 0.02 * i0.max(i1) {
                    return bad(format!(
                        "measured tables at {i0} and {i1} A peak: the currents must be at least 2 % apart"
                    ));
                }
                // U0 = a/I0 + b, U1 = a/I1 + b ⇒ a = (U0 − U1)/(1/I0 − 1/I1), b = U0 − a/I0.
                let k = 1.0 / (1.0 / i0 - 1.0 / i1);
                let a: [[Complex; ITEMS]; 2] =
                    std::array::from_fn(|d| std::array::from_fn(|n| (u0[d][n] - u1[d][n]).scale(k)));
                let b = std::array::from_fn(|d| std::array::from_fn(|n| u0[d][n] - a[d][n].scale(1.0 / i0)));
                (a, b)
            }
        };
        let measured_up_to_a = tables.iter().map(|t| t.peak_a).fold(0.0, f64::max);
        Ok(Self { a, b, firmware: fw, measured_up_to_a })
    }

    /// The table the model predicts at `peak_a` (A peak; finite and > 0, else its items are
    /// not numbers: [`Self::fits_at`] checks).
    pub fn table_at(&self, peak_a: f64) -> PrusaCorrection {
        let scale = self.firmware.scale();
        let spectrum = |d: usize| {
            let mut s = Spectrum::default();
            for n in 0..ITEMS {
                let (mag, pha) = table_item(self.a[d][n].scale(1.0 / peak_a) + self.b[d][n], scale);
                s.mag[n] = mag as f32;
                s.pha[n] = pha as f32;
            }
            s
        };
        PrusaCorrection { forward: spectrum(0), backward: spectrum(1), firmware: self.firmware }
    }

    /// Whether the predicted table at `peak_a` fits both directions within ±[`SHIFT_LIMIT`];
    /// `false` for a current that is not finite and positive.
    pub fn fits_at(&self, peak_a: f64) -> bool {
        if !(peak_a.is_finite() && peak_a > 0.0) {
            return false;
        }
        let t = self.table_at(peak_a);
        [t.forward, t.backward].iter().all(|s| s.peak_shift(self.firmware).is_some_and(|p| p <= SHIFT_LIMIT))
    }

    /// The lowest current (A peak) from the highest measured one up to `up_to_a` at which the
    /// predicted table fits (on [`super::headroom`]'s grid); `None` when none does. Refuses
    /// an `up_to_a` below the measured current or not finite.
    pub fn lowest_fitting_current_a(&self, up_to_a: f64) -> Result<Option<f64>, ExportError> {
        scan_currents(self.measured_up_to_a, up_to_a, |i| Ok(self.fits_at(i)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FW: Firmware = Firmware::V6_3_1;

    /// A table with harmonic 4 of `u4` rad and harmonic 2 of `u2` rad in both directions.
    fn table(peak_a: f64, u4: Complex, u2: Complex) -> MeasuredTable {
        let mut s = Spectrum::default();
        for (n, u) in [(4, u4), (2, u2)] {
            let (mag, pha) = table_item(u, FW.scale());
            s.mag[n] = mag as f32;
            s.pha[n] = pha as f32;
        }
        MeasuredTable { peak_a, table: PrusaCorrection { forward: s, backward: s, firmware: FW } }
    }

    /// The limit in rad: 127 of 4096 of a period.
    fn limit_rad() -> f64 {
        super::super::headroom::limit_rad()
    }

    #[test]
    fn one_table_of_a_detent_falls_as_one_over_the_current() {
        // One harmonic of 1.5× the limit at 0.6 A: it fits from 0.9 A (one grid step at most).
        let m = TableVsCurrent::fit(&[table(0.6, Complex::from_polar(1.5 * limit_rad(), 0.4), Complex::default())])
            .unwrap();
        assert!(!m.fits_at(0.6));
        let got = m.lowest_fitting_current_a(3.0).unwrap().unwrap();
        let step = 5f64.powf(1.0 / 200.0);
        assert!((0.9 / step..=0.9 * step * step).contains(&got), "{got}");
        assert!(m.fits_at(got) && !m.fits_at(got / step));
    }

    #[test]
    fn two_tables_recover_a_part_that_does_not_fall_with_the_current() {
        // Truth: harmonic 4 = a/I + b with b a third of the limit; harmonic 2 pure detent.
        let (a4, b4) = (Complex::from_polar(0.12, 0.3), Complex::from_polar(limit_rad() / 3.0, -1.0));
        let a2 = Complex::from_polar(0.06, 2.0);
        let at = |i: f64| table(i, a4.scale(1.0 / i) + b4, a2.scale(1.0 / i));
        let m = TableVsCurrent::fit(&[at(0.6), at(0.8)]).unwrap();
        for i in [0.5, 1.0, 2.0] {
            let (want, got) = (at(i).table, m.table_at(i));
            for n in [2, 4] {
                let (w, g) = (phasors(&want.forward, FW)[n], phasors(&got.forward, FW)[n]);
                assert!((w - g).abs() < 1e-6, "{i} A, item {n}: {w:?} vs {g:?}");
            }
        }
        // One table alone, blind to b, promises a lower current than the truth needs.
        let one = TableVsCurrent::fit(&[at(0.6)]).unwrap().lowest_fitting_current_a(3.0).unwrap().unwrap();
        let two = m.lowest_fitting_current_a(3.0).unwrap().unwrap();
        assert!(one < two, "{one} vs {two}");
        assert!(TableVsCurrent::fit(&[at(two)]).unwrap().fits_at(two), "the truth fits where the model says");
    }

    #[test]
    fn a_table_that_no_current_fits_gives_none_and_bad_inputs_are_refused() {
        // b alone is past the limit: no current helps.
        let t = |i: f64| table(i, Complex::from_polar(0.01, 0.0), Complex::from_polar(1.2 * limit_rad(), 0.0));
        let m = TableVsCurrent::fit(&[t(0.6), t(0.9)]).unwrap();
        assert_eq!(m.lowest_fitting_current_a(3.0).unwrap(), None);
        let ok = table(0.6, Complex::default(), Complex::default());
        for bad in [
            vec![],
            vec![ok, ok],
            vec![ok, ok, ok],
            vec![MeasuredTable { peak_a: f64::NAN, ..ok }],
            vec![MeasuredTable { peak_a: 0.0, ..ok }],
        ] {
            assert!(TableVsCurrent::fit(&bad).is_err(), "{bad:?}");
        }
        let mut other = ok;
        other.peak_a = 0.9;
        other.table.firmware = Firmware::V6_2;
        assert!(TableVsCurrent::fit(&[ok, other]).is_err());
        assert!(m.lowest_fitting_current_a(0.5).is_err(), "below the measured current");
        assert!(!m.fits_at(0.0) && !m.fits_at(f64::NAN) && !m.fits_at(-1.0));
    }
}
