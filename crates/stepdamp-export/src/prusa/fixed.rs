//! The phase-shift arithmetic of Prusa-Firmware-Buddy ≥ 6.3.1, in fixed point, written from
//! its description (read at tag v6.3.1: `lib/Marlin/Marlin/src/feature/phase_stepping/lut.cpp`
//! and `common.hpp`, constants in `include/buddy/phase_stepping_opts.h`; the same at v6.3.2).
//!
//! - `mag_fixed = lround(mag · 4096 · 2⁸ / 2π)` (f32), `pha_fixed = lround(pha · 4096 / 2π)`;
//! - a quarter sine of `2¹⁵` full scale, `lround(2¹⁵ · sin(π/2 · i/1024))`, mirrored over the
//!   4096-unit period;
//! - per tick `i` of 1024: `raw = Σ_n SIN_FRACTION · mag_fixed_n · sin_lut(n·4i + pha_fixed_n)`
//!   in a 32-bit `int`, then `shift = round_fixed(raw, 15 + 8)` (rounding half away from zero)
//!   stored as `int8_t` in units of 2π/4096 of an electrical period;
//! - coil currents `sin_lut(4i + shift, 248)`, `cos_lut(…)`, where a range `r` rescales the
//!   2¹⁵ value as `round_fixed(v·r, 15)`.
//!
//! So an item `(mag, pha)` turns the current vector by `SIN_FRACTION · mag · sin(nθ + pha)`
//! rad: four times what the 6.2 releases' float code (and the master branch at 818d812)
//! does with the same numbers.

use super::SIN_PERIOD;

/// `SIN_FRACTION`: sine-table units per motor tick, and the factor on every magnitude.
pub const SIN_FRACTION: i64 = 4;
/// `SIN_LUT_FRACTIONAL`: fractional bits of the sine table.
pub const SIN_LUT_FRACTIONAL: u32 = 15;
/// `MAG_FRACTIONAL`: fractional bits of a magnitude.
pub const MAG_FRACTIONAL: u32 = 8;

/// `mag_to_fixed`: `lround(mag · 4096 · 256 / 2π)`, the product in f32 as the firmware does.
pub fn mag_to_fixed(mag: f32) -> i64 {
    (mag * SIN_PERIOD as f32 * (1u32 << MAG_FRACTIONAL) as f32 / (2.0 * std::f32::consts::PI)).round() as i64
}

/// `pha_to_fixed`: `lround(pha · 4096 / 2π)` in f32.
pub fn pha_to_fixed(pha: f32) -> i64 {
    (pha * SIN_PERIOD as f32 / (2.0 * std::f32::consts::PI)).round() as i64
}

/// `round_fixed`: `value / 2^bits` rounded half away from zero (symmetric for negatives).
pub fn round_fixed(value: i64, bits: u32) -> i64 {
    let half = 1i64 << (bits - 1);
    if value < 0 { -((-value + half) >> bits) } else { (value + half) >> bits }
}

/// The quarter table entry `i` (0…1024) of the 2¹⁵ sine.
fn quarter(i: i64) -> i64 {
    let x = std::f32::consts::PI / 2.0 * i as f32 / (SIN_PERIOD / 4) as f32;
    (f64::from(1u32 << SIN_LUT_FRACTIONAL) * f64::from(x).sin()).round() as i64
}

/// `sin_lut(x, range)`: the sine of `x` (period 4096) scaled to `range`.
pub fn sin_lut(x: i64, range: i64) -> i64 {
    let p = i64::from(SIN_PERIOD);
    let x = x.rem_euclid(p);
    let rescale = |v: i64| round_fixed(v * range, SIN_LUT_FRACTIONAL);
    if x <= p / 4 {
        rescale(quarter(x))
    } else if x <= p / 2 {
        rescale(quarter(p / 2 - x))
    } else if x <= 3 * p / 4 {
        -rescale(quarter(x - p / 2))
    } else {
        -rescale(quarter(p - x))
    }
}

/// The shift of every tick before the `int8_t` store, in 2π/4096 units; `None` when the
/// firmware's 32-bit sum would overflow (undefined behaviour on the chip).
pub fn shifts(mag: &[f32], pha: &[f32]) -> Option<Vec<i64>> {
    let fixed: Vec<(i64, i64)> = mag.iter().zip(pha).map(|(&m, &p)| (mag_to_fixed(m), pha_to_fixed(p))).collect();
    let full = 1i64 << SIN_LUT_FRACTIONAL;
    let fits = |v: i64| i64::from(i32::MIN) <= v && v <= i64::from(i32::MAX);
    // `lround` into the chip's 32-bit `long`: beyond it the firmware's result is undefined.
    if !fixed.iter().all(|&(m, p)| SIN_FRACTION.checked_mul(m).is_some_and(fits) && fits(p)) {
        return None;
    }
    let mut out = Vec::with_capacity(1024);
    for i in 0..1024i64 {
        let item_phase = i * SIN_FRACTION;
        let mut raw = 0i64;
        for (n, &(m, p)) in fixed.iter().enumerate() {
            let term = SIN_FRACTION * m * sin_lut(n as i64 * item_phase + p, full);
            raw += term;
            if !(fits(term) && fits(raw)) {
                return None;
            }
        }
        out.push(round_fixed(raw, SIN_LUT_FRACTIONAL + MAG_FRACTIONAL));
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_fixed_rounds_half_away_from_zero() {
        assert_eq!(round_fixed(3 << 7, 8), 2); // 1.5
        assert_eq!(round_fixed(-(3 << 7), 8), -2);
        assert_eq!(round_fixed(127, 8), 0);
        assert_eq!(round_fixed(-129, 8), -1);
    }

    #[test]
    fn sine_table_has_full_scale_at_a_quarter_and_is_odd() {
        assert_eq!(sin_lut(1024, 1 << 15), 1 << 15);
        assert_eq!(sin_lut(0, 248), 0);
        assert_eq!(sin_lut(1024, 248), 248);
        assert_eq!(sin_lut(3072, 248), -248);
        for x in [1, 100, 777, 2000] {
            assert_eq!(sin_lut(-x, 248), -sin_lut(x, 248));
        }
    }

    #[test]
    fn an_item_turns_the_vector_by_four_times_its_magnitude() {
        // mag 0.01 rad at order 0 with pha = π/2: a constant 4·0.01 rad = 26.08 units.
        let mut mag = [0f32; 17];
        let mut pha = [0f32; 17];
        mag[0] = 0.01;
        pha[0] = std::f32::consts::FRAC_PI_2;
        let s = shifts(&mag, &pha).unwrap();
        let want = 4.0 * 0.01 * 4096.0 / std::f64::consts::TAU;
        assert!(s.iter().all(|&v| (v as f64 - want).abs() <= 0.5), "{} vs {want}", s[0]);
        mag[0] = 1e3;
        mag[1] = 1e3;
        assert!(shifts(&mag, &pha).is_none(), "a 32-bit overflow is reported");
        // Found by the fuzzer: values beyond the 32-bit `long` of `lround` (any f32 a
        // 168-byte file can hold) are reported too, not computed with an overflow.
        for (m, p) in [(f32::MAX, 0.0), (0.0, f32::MAX), (-f32::MAX, -f32::MAX)] {
            mag[3] = m;
            pha[3] = p;
            assert!(shifts(&mag, &pha).is_none());
        }
    }
}
