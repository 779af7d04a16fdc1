//! Prusa-Firmware-Buddy phase stepping, for the firmware users run (verified against its
//! source at the release tags; see `docs/exporters.md#prusa-phase-stepping` for the files).
//!
//! The firmware keeps, per axis and direction, a spectrum of 17 items `{mag, pha}` (f32,
//! n = 0…16) and turns it into a phase shift per tick of its 1024-tick electrical period,
//! `shift[i] ≈ 4096/(2π) · k_fw · Σ_n mag_n sin(n·2πi/1024 + pha_n)`, stored as `int8_t` in
//! units of 2π/4096 rad; the coil currents of tick `i` are then `a = sin_lut(4i + shift[i])`,
//! `b = cos_lut(4i + shift[i])` on a 4096-per-period sine of amplitude 248. The factor
//! `k_fw` is [`Firmware::scale`]: 4 since 6.3.1 (fixed point, [`fixed`]), 1 in 6.2.
//! So the rotation `Δ = k_fw · Σ mag sin(nθ + pha)` turns the current vector in the direction
//! of increasing phase at constant magnitude. With stepdamp's winding a on Prusa's `b`
//! (cosine) coil and winding b on `a` (sine), `θe = 2π·phase/1024` and the patent's
//! injection is `mag_k = A_k/(Km·I·k_fw)`, `pha_k = φ_k` (first order in `Δ`), `I` the peak
//! run current.
//!
//! The forward table is used while the physical speed is > 0 (phase increasing).

pub mod fixed;
pub mod gcode;
pub mod headroom;
pub mod measured;
pub mod read;
pub mod refine;

pub use read::{parse_bytes, parse_m971, parse_m972, parse_m973, parse_text};

use crate::{Correction, ExportError};
use stepdamp_core::{CorrectionTable, TABLE_TICKS};
use stepdamp_sim::Profile;
use stepdamp_sim::profile::DetentTerm;

/// Items in a Prusa spectrum (`CORRECTION_HARMONICS + 1`).
pub const ITEMS: usize = 17;
/// Bytes of a correction file: 32 zero bytes, then 17 × {f32 mag, f32 pha} little-endian.
pub const FILE_BYTES: usize = 32 + ITEMS * 8;
/// Amplitude of the firmware's sine table (`CURRENT_AMPLITUDE`).
pub const CURRENT_AMPLITUDE: i16 = 248;
/// Phase units per electrical period (`SIN_PERIOD`): the shift's resolution is 2π/4096.
pub const SIN_PERIOD: i32 = 4096;
/// The largest shift the `int8_t` table holds without wrapping, in 2π/4096 units (±0.195 rad).
pub const SHIFT_LIMIT: i64 = 127;

/// The firmware generation a correction is written for: the G-code and the magnitude scale
/// differ, the file format does not.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Firmware {
    /// 6.2.x: `M973 XF…` sets a direction's 17 items in one line, `M972` prints them;
    /// float arithmetic, an item turns the vector by `mag` rad.
    V6_2,
    /// 6.3.1 and later (v6.3.1, v6.3.2): `M971 X F I<n> M<mag> P<pha>` per item while phase
    /// stepping is off (`M970 X0`), read back with `M971 X F`; fixed point, an item turns
    /// the vector by `4·mag` rad.
    V6_3_1,
}

impl Firmware {
    /// Radians of rotation per unit of `mag`: `SIN_FRACTION` = 4 since 6.3.1, 1 in 6.2.
    pub fn scale(self) -> f64 {
        match self {
            Firmware::V6_2 => 1.0,
            Firmware::V6_3_1 => fixed::SIN_FRACTION as f64,
        }
    }

    /// `6.2` or `>= 6.3.1`, for comments and messages.
    pub fn label(self) -> &'static str {
        match self {
            Firmware::V6_2 => "6.2",
            Firmware::V6_3_1 => ">= 6.3.1",
        }
    }
}

/// One direction's spectrum: `Δ(θ) = k_fw · Σ_n mag[n] sin(n θ + pha[n])`, rad.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Spectrum {
    /// Magnitudes in the firmware's unit (rad / [`Firmware::scale`]).
    pub mag: [f32; ITEMS],
    /// Phases, rad.
    pub pha: [f32; ITEMS],
}

/// Both directions of one axis, and the firmware they are meant for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrusaCorrection {
    /// Used while the phase increases.
    pub forward: Spectrum,
    /// Used while the phase decreases.
    pub backward: Spectrum,
    /// Which arithmetic turns the items into a table.
    pub firmware: Firmware,
}

impl Spectrum {
    /// The firmware's shift per tick before its `int8_t` store, in 2π/4096 rad; `None` when
    /// the 6.3.1 fixed-point sum overflows its 32 bits.
    pub fn shifts_exact(&self, fw: Firmware) -> Option<Vec<i64>> {
        match fw {
            Firmware::V6_3_1 => fixed::shifts(&self.mag, &self.pha),
            Firmware::V6_2 => Some(
                (0..TABLE_TICKS)
                    .map(|i| {
                        let th = i as f32 * std::f32::consts::TAU / TABLE_TICKS as f32;
                        let d: f32 = (0..ITEMS).map(|n| self.mag[n] * (n as f32 * th + self.pha[n]).sin()).sum();
                        (SIN_PERIOD as f32 / std::f32::consts::TAU * d).round() as i64
                    })
                    .collect(),
            ),
        }
    }

    /// The largest |shift| of [`Self::shifts_exact`]; `None` on overflow.
    pub fn peak_shift(&self, fw: Firmware) -> Option<i64> {
        self.shifts_exact(fw).map(|v| v.iter().map(|x| x.saturating_abs()).max().unwrap_or(0))
    }

    /// The firmware's phase shift per tick as stored (`int8_t`, wrapping as on the chip;
    /// an overflowing 6.3.1 sum gives all zeros here — the exporter never writes one).
    pub fn shifts(&self, fw: Firmware) -> Vec<i8> {
        self.shifts_exact(fw).map(|v| v.into_iter().map(|x| x as i8).collect()).unwrap_or_else(|| vec![0; TABLE_TICKS])
    }

    /// The coil currents the firmware sets per tick, as stepdamp windings `[a, b]`:
    /// `[cos_lut(4i + shift), sin_lut(4i + shift)]`, full scale 248.
    pub fn currents(&self, fw: Firmware) -> Vec<[i16; 2]> {
        self.shifts(fw)
            .iter()
            .enumerate()
            .map(|(i, &s)| {
                let pha = 4 * i as i32 + i32::from(s);
                match fw {
                    Firmware::V6_2 => [sin_lut_6_2(pha + SIN_PERIOD / 4), sin_lut_6_2(pha)],
                    Firmware::V6_3_1 => {
                        let r = i64::from(CURRENT_AMPLITUDE);
                        [
                            fixed::sin_lut(i64::from(pha + SIN_PERIOD / 4), r) as i16,
                            fixed::sin_lut(i64::from(pha), r) as i16,
                        ]
                    }
                }
            })
            .collect()
    }
}

/// The 6.2 firmware's sine table: a quarter of `(u8)(248·sin(π/2·i/1024) + 0.5)`, mirrored.
pub fn sin_lut_6_2(x: i32) -> i16 {
    let q = SIN_PERIOD / 4;
    let quarter = |i: i32| {
        (f32::from(CURRENT_AMPLITUDE) * (std::f32::consts::FRAC_PI_2 * i as f32 / q as f32).sin() + 0.5) as i16
    };
    let x = x.rem_euclid(SIN_PERIOD);
    if x <= q {
        quarter(x)
    } else if x <= 2 * q {
        quarter(2 * q - x)
    } else if x <= 3 * q {
        -quarter(x - 2 * q)
    } else {
        -quarter(SIN_PERIOD - x)
    }
}

/// A correction fitted into the firmware's range, as it will be written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fitted {
    /// The items, quantized to the decimals the G-code carries.
    pub correction: PrusaCorrection,
    /// Share of the wanted correction kept, 0 < kept ≤ 1: every order is scaled by it when
    /// the wanted table would exceed ±[`SHIFT_LIMIT`] (and wrap on the chip).
    pub kept: f64,
    /// The largest |shift| of the written table, 2π/4096 units (≤ [`SHIFT_LIMIT`]).
    pub peak_shift: i64,
    /// The largest |shift| the unscaled correction asks for, 2π/4096 units.
    pub wanted_peak_shift: f64,
}

impl std::fmt::Display for Fitted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let unit = std::f64::consts::TAU / f64::from(SIN_PERIOD);
        if self.kept < 1.0 {
            writeln!(
                f,
                "the correction needs up to {:.3} rad, beyond the ±{:.3} rad ({SHIFT_LIMIT}/4096 of a period) of Prusa's \
                 int8 table: scaled to {:.1} % of it (every order alike), peak {:.3} rad",
                self.wanted_peak_shift * unit,
                SHIFT_LIMIT as f64 * unit,
                100.0 * self.kept,
                self.peak_shift as f64 * unit
            )
        } else {
            writeln!(
                f,
                "correction kept: 100 % (peak shift {:.3} rad of the ±{:.3} rad Prusa's int8 table holds)",
                self.peak_shift as f64 * unit,
                SHIFT_LIMIT as f64 * unit
            )
        }
    }
}

/// The firmware's spectrum of a correction: `mag_k = c_k/(I·k_fw)`, `pha_k = φ_k` (a negative
/// amplitude turned by π, phases in (−π, π]), scaled down alike when the table would pass
/// ±[`SHIFT_LIMIT`] or the firmware's 32-bit sum would overflow. Orders above 16 are refused.
pub fn fit(c: &Correction, fw: Firmware) -> Result<Fitted, ExportError> {
    let (mut x, mut y) = ([0f64; ITEMS], [0f64; ITEMS]);
    for &(k, amp, ph) in &c.terms {
        let n = usize::from(k);
        if n >= ITEMS {
            return Err(ExportError::Invalid(format!("detent order {k}: Prusa's correction holds orders 0..=16 only")));
        }
        let m = amp / c.holding_current_a / fw.scale();
        x[n] += m * ph.cos();
        y[n] += m * ph.sin();
    }
    let build = |s: f64| {
        let mut sp = Spectrum::default();
        for n in 0..ITEMS {
            let m = s * x[n].hypot(y[n]);
            if gcode::quantize(m, gcode::MAG_DECIMALS) != 0.0 {
                sp.mag[n] = gcode::quantize(m, gcode::MAG_DECIMALS);
                sp.pha[n] = gcode::quantize(y[n].atan2(x[n]), gcode::PHA_DECIMALS);
            }
        }
        sp
    };
    let unit = f64::from(SIN_PERIOD) / std::f64::consts::TAU;
    let wanted_peak_shift = unit * headroom::wanted_peak_rad(c);
    let mut s = 1.0;
    for _ in 0..1000 {
        let sp = build(s);
        if let Some(peak) = sp.peak_shift(fw).filter(|&p| p <= SHIFT_LIMIT) {
            return Ok(Fitted {
                correction: PrusaCorrection { forward: sp, backward: sp, firmware: fw },
                kept: s,
                peak_shift: peak,
                wanted_peak_shift,
            });
        }
        s = if s == 1.0 && wanted_peak_shift > 0.0 {
            (SHIFT_LIMIT as f64 / wanted_peak_shift).min(0.999)
        } else {
            s * 0.995
        };
    }
    Err(ExportError::Invalid(format!(
        "the correction (up to {:.3} rad) cannot be scaled into Prusa's int8 table",
        wanted_peak_shift / unit
    )))
}

impl PrusaCorrection {
    /// Refuses items whose table the firmware cannot compute (its 32-bit fixed-point sum
    /// overflows: undefined on the chip), which [`Self::table`] would replay as no correction.
    pub fn check_replay(&self, what: &str) -> Result<(), ExportError> {
        for (name, s) in [("forward", &self.forward), ("backward", &self.backward)] {
            if s.shifts_exact(self.firmware).is_none() {
                return Err(ExportError::Parse {
                    what: what.to_string(),
                    reason: format!("the {name} items overflow the firmware's 32-bit table arithmetic"),
                });
            }
        }
        Ok(())
    }

    /// The replay table the core runs in `table` mode.
    pub fn table(&self) -> CorrectionTable {
        let mut t = CorrectionTable { full_scale: CURRENT_AMPLITUDE, ..Default::default() };
        for (i, e) in self.forward.currents(self.firmware).into_iter().enumerate() {
            t.forward[i] = e;
        }
        for (i, e) in self.backward.currents(self.firmware).into_iter().enumerate() {
            t.backward[i] = e;
        }
        t
    }
}

/// A correction file (`/internal/phase_step_<axis>_fwd|bck`): 32 zero bytes, then 17 ×
/// {f32 mag, f32 pha} little-endian (the firmware's `CorrectionSaveFormat` on a
/// little-endian Cortex-M).
pub fn encode_file(s: &Spectrum) -> Vec<u8> {
    let mut out = vec![0u8; 32];
    for n in 0..ITEMS {
        out.extend_from_slice(&s.mag[n].to_le_bytes());
        out.extend_from_slice(&s.pha[n].to_le_bytes());
    }
    out
}

/// Reads a correction file. The firmware loads only a file of at least 168 bytes (it reads
/// exactly 168); the 32 reserved bytes must be zero, and every value finite.
pub fn decode_file(bytes: &[u8], what: &str) -> Result<Spectrum, ExportError> {
    let bad = |reason: String| ExportError::Parse { what: what.to_string(), reason };
    if bytes.len() != FILE_BYTES {
        return Err(bad(format!("{} bytes: a Prusa correction file has exactly {FILE_BYTES}", bytes.len())));
    }
    if bytes[..32].iter().any(|&b| b != 0) {
        return Err(bad("the 32-byte header is not all zero (an unknown version)".into()));
    }
    let mut s = Spectrum::default();
    for n in 0..ITEMS {
        let at = 32 + 8 * n;
        let f = |o: usize| f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
        s.mag[n] = f(at);
        s.pha[n] = f(at + 4);
        if !(s.mag[n].is_finite() && s.pha[n].is_finite()) {
            return Err(bad(format!("item {n} is not finite")));
        }
    }
    Ok(s)
}

/// A detent model equivalent to a spectrum (the inverse of [`Spectrum::from_correction`]):
/// `(order, A_k = k_fw·mag_k·Km·I in N·m, φ_k)` for n = 1..16 with a non-zero magnitude. A
/// negative magnitude becomes a positive amplitude with the phase turned by π. Item 0 (a
/// constant shift) is not a detent torque and is returned separately, rad. `current_a` is the
/// peak run current.
pub fn to_detent(s: &Spectrum, fw: Firmware, km_nm_per_a: f64, current_a: f64) -> (Vec<(u16, f64, f64)>, f64) {
    let mut terms = Vec::new();
    for n in 1..ITEMS {
        let (m, p) = (fw.scale() * f64::from(s.mag[n]), f64::from(s.pha[n]));
        if m == 0.0 {
            continue;
        }
        let (a, ph) = if m < 0.0 { (-m, p + std::f64::consts::PI) } else { (m, p) };
        let ph = (ph + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        terms.push((n as u16, a * km_nm_per_a * current_a, ph));
    }
    (terms, fw.scale() * f64::from(s.mag[0]) * f64::from(s.pha[0]).sin())
}

/// A profile equal to `base` with the detent model a Prusa correction stands for, at
/// peak holding current `current_a`: each order's phasor `mag·e^{i·pha}` averaged over the two
/// directions (a detent torque does not depend on the direction; what differs between
/// the directions is returned as the largest phasor difference in rotation, rad, for the user
/// to see).
pub fn import_profile(base: &Profile, c: &PrusaCorrection, current_a: f64) -> Result<(Profile, f64), ExportError> {
    if !(current_a.is_finite() && current_a > 0.0) {
        return Err(ExportError::Invalid(format!("--current {current_a:e} A: must be finite and > 0")));
    }
    let mut avg = Spectrum::default();
    let mut spread: f64 = 0.0;
    for n in 0..ITEMS {
        let (f, b) = (&c.forward, &c.backward);
        let (fx, fy) =
            (f64::from(f.mag[n]) * f64::from(f.pha[n]).cos(), f64::from(f.mag[n]) * f64::from(f.pha[n]).sin());
        let (bx, by) =
            (f64::from(b.mag[n]) * f64::from(b.pha[n]).cos(), f64::from(b.mag[n]) * f64::from(b.pha[n]).sin());
        spread = spread.max(c.firmware.scale() * (fx - bx).hypot(fy - by));
        let (x, y) = ((fx + bx) / 2.0, (fy + by) / 2.0);
        avg.mag[n] = x.hypot(y) as f32;
        avg.pha[n] = y.atan2(x) as f32;
    }
    let (terms, _) = to_detent(&avg, c.firmware, base.motor.km_nm_per_a, current_a);
    let name = stepdamp_sim::profile::name::derived_name(&base.name, " (Prusa correction)");
    let p = base
        .edited(&name, |d| {
            d.name = name.clone();
            d.motor.detent = terms
                .into_iter()
                .map(|(order, amplitude_nm, phase_rad)| DetentTerm { order, amplitude_nm, phase_rad })
                .collect();
            d.drive.holding_current_a = current_a.min(d.drive.current_limit_a);
        })
        .map_err(|e| ExportError::Invalid(e.to_string()))?;
    Ok((p, spread))
}

#[cfg(test)]
mod tests {
    use super::*;
    use stepdamp_sim::Profile;

    fn patent() -> Correction {
        Correction::from_profile(&Profile::preset("patent-motor").unwrap(), None).unwrap()
    }

    #[test]
    fn patent_spectrum_is_a_over_km_i_in_each_firmwares_scale() {
        let new = fit(&patent(), Firmware::V6_3_1).unwrap();
        let old = fit(&patent(), Firmware::V6_2).unwrap();
        let want = 0.02 / (0.3 * 1.9);
        assert!((f64::from(old.correction.forward.mag[4]) - want).abs() < 1e-6);
        assert!((f64::from(new.correction.forward.mag[4]) - want / 4.0).abs() < 1e-6);
        assert!((f64::from(new.correction.forward.pha[2]) - 0.7).abs() < 1e-6);
        assert_eq!(new.correction.forward.mag[0], 0.0);
        assert_eq!(new.correction.forward.mag[3], 0.0);
        assert_eq!(new.kept, 1.0);
        // The same rotation either way: the tables agree within a unit of rounding.
        let (a, b) = (new.correction.forward.shifts(Firmware::V6_3_1), old.correction.forward.shifts(Firmware::V6_2));
        assert!(a.iter().zip(&b).all(|(x, y)| (i32::from(*x) - i32::from(*y)).abs() <= 1));
    }

    #[test]
    fn files_round_trip_byte_for_byte() {
        let s = fit(&patent(), Firmware::V6_3_1).unwrap().correction.forward;
        let bytes = encode_file(&s);
        assert_eq!(bytes.len(), 168);
        assert!(bytes[..32].iter().all(|&b| b == 0));
        // Item 4's magnitude sits at 32 + 4·8, little-endian.
        assert_eq!(&bytes[64..68], &s.mag[4].to_le_bytes());
        let back = decode_file(&bytes, "t").unwrap();
        assert_eq!(back, s);
        assert_eq!(encode_file(&back), bytes);
        assert!(decode_file(&bytes[..167], "t").is_err());
        let mut v = bytes.clone();
        v[3] = 1;
        assert!(decode_file(&v, "t").is_err());
    }

    #[test]
    fn angle_origin_and_direction_a_zero_correction_is_plain_microstepping() {
        // Tick 0: stepdamp's winding a (Prusa's cosine coil) at full current, b at zero —
        // θe = 0, the d axis on winding a. Tick 256 (a quarter period): b at full.
        for fw in [Firmware::V6_2, Firmware::V6_3_1] {
            let t =
                PrusaCorrection { forward: Spectrum::default(), backward: Spectrum::default(), firmware: fw }.table();
            assert_eq!(t.forward[0], [248, 0]);
            assert_eq!(t.forward[256], [0, 248]);
            assert_eq!(t.forward[512], [-248, 0]);
        }
    }

    #[test]
    fn a_positive_shift_turns_the_current_vector_towards_positive_theta() {
        // mag_0 with pha_0 = π/2 is a constant Δ = k_fw·mag: the current vector leads θe by Δ,
        // so the q current (−i_a sin θe + i_b cos θe) is +I·sin Δ, the patent's +i_q.
        for fw in [Firmware::V6_2, Firmware::V6_3_1] {
            let mut s = Spectrum::default();
            s.mag[0] = (0.05 / fw.scale()) as f32;
            s.pha[0] = std::f32::consts::FRAC_PI_2;
            let cur = s.currents(fw);
            for &i in &[0usize, 100, 300, 700] {
                let th = std::f64::consts::TAU * i as f64 / 1024.0;
                let [a, b] = cur[i];
                let q = -f64::from(a) * th.sin() + f64::from(b) * th.cos();
                assert!((q / 248.0 - 0.05f64.sin()).abs() < 0.01, "{fw:?} {i}: {q}");
            }
        }
    }

    #[test]
    fn shifts_follow_the_intended_rotation_and_too_large_is_scaled_never_wrapped() {
        let c = patent();
        for fw in [Firmware::V6_2, Firmware::V6_3_1] {
            let sh = fit(&c, fw).unwrap().correction.forward.shifts(fw);
            for i in [0usize, 17, 500, 1000] {
                let th = std::f64::consts::TAU * i as f64 / 1024.0;
                let want = 4096.0 / std::f64::consts::TAU * c.delta_rad(th);
                assert!((f64::from(sh[i]) - want).abs() <= 0.6, "{fw:?} {i}");
            }
            let mut big = patent();
            big.holding_current_a = 0.1;
            let f = fit(&big, fw).unwrap();
            assert!(f.kept < 0.25 && f.kept > 0.1, "{fw:?} kept {}", f.kept);
            assert!(f.peak_shift <= SHIFT_LIMIT && f.peak_shift >= SHIFT_LIMIT - 2, "{}", f.peak_shift);
            // The stored int8 table is the unwrapped one: no entry changed sign or size.
            let exact = f.correction.forward.shifts_exact(fw).unwrap();
            let stored = f.correction.forward.shifts(fw);
            assert!(exact.iter().zip(&stored).all(|(e, s)| *e == i64::from(*s)));
            assert!(f.to_string().contains("scaled to"), "{f}");
        }
    }

    #[test]
    fn import_inverts_export() {
        let c = patent();
        for fw in [Firmware::V6_2, Firmware::V6_3_1] {
            let s = fit(&c, fw).unwrap().correction.forward;
            let (terms, offset) = to_detent(&s, fw, 0.3, 1.9);
            assert_eq!(offset, 0.0);
            assert_eq!(terms.len(), 3);
            for (k, a, ph) in terms {
                let h = Profile::preset("patent-motor").unwrap().motor.detent.iter().copied().find(|h| h.order == k);
                let h = h.unwrap();
                assert!((a - h.amplitude_nm).abs() < 4.0 * 1e-6 * 0.3 * 1.9 && (ph - h.phase_rad).abs() < 1e-5, "{k}");
            }
        }
    }

    proptest::proptest! {
        #[test]
        fn any_finite_spectrum_round_trips_through_a_file(
            mag in proptest::collection::vec(-1.0f32..1.0, ITEMS),
            pha in proptest::collection::vec(-4.0f32..4.0, ITEMS),
        ) {
            let mut s = Spectrum::default();
            s.mag.copy_from_slice(&mag);
            s.pha.copy_from_slice(&pha);
            let bytes = encode_file(&s);
            proptest::prop_assert_eq!(encode_file(&decode_file(&bytes, "t").unwrap()), bytes);
        }
    }
}
