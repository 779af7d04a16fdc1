//! Sine and cosine for the controller's step: `f32` only, no `f64`, no library call.
//!
//! The electrical angle is already a 32-bit fraction of a turn (the low 32 bits of a
//! [`Position`]), so range reduction is exact integer arithmetic: round to the nearest
//! quarter turn (the top two bits after adding an eighth of a turn), keep the remainder
//! `r ∈ [−2²⁹, 2²⁹)` units, i.e. `x = 2π·r/2³² ∈ [−π/4, π/4)`; evaluate a minimax
//! polynomial for `sin x` and `cos x` there; swap and negate by quadrant (exact).
//!
//! Polynomials (Cephes `sinf.c`/`cosf.c`, S. L. Moshier, minimax on `[0, π/4]` for
//! single precision, odd/even so valid on `[−π/4, π/4]`), with `z = x²`:
//!
//! ```text
//! sin x ≈ x + x·z·(S1 + z·(S2 + z·S3))
//! cos x ≈ 1 − z/2 + z²·(C1 + z·(C2 + z·C3))
//! ```
//!
//! **Error bound** ([`SIN_COS_MAX_ERROR`]): `|sin_cos_turn(a) − (sin θ, cos θ)| ≤ 1.25·10⁻⁷`
//! (absolute, each component, `θ = 2π·a/2³²` exactly) for every one of the 2³² angles.
//! The test `trig::tests::kernel_error_is_within_the_bound_for_every_reduced_angle` proves
//! it exhaustively: it evaluates the kernel at all 2³⁰ remainders `r` (every input the
//! polynomial can see; it runs over `r ≥ 0`, the kernel being exactly odd/even in `r`) against an `f64` Taylor reference accurate to 10⁻¹⁵, and the
//! quadrant step only swaps and negates results, so the bound holds for all 2³² angles;
//! a second test checks the full function on a stride through all four quadrants against
//! `f64` `sin`/`cos`. The bound is about one `f32` ulp of 1 (the rounding of `r` to 24
//! bits and of the products dominate; the polynomials' own error is below 10⁻⁸).
//! For comparison, turning the angle into `f32` radians first (as `sincosf` needs) already
//! rounds `θ` by up to 1.2·10⁻⁷ rad near ±π.
//!
//! Cost on a Cortex-M4F: a few dozen FPU and integer instructions inline, no call, no
//! table, no `f64` (a `libm::sincosf` call was about 2,400 instructions of software
//! double precision there).
//!
//! [`Position`]: crate::Position

use core::f32::consts::TAU;

/// Largest absolute error of [`sin_cos_turn`] in either component, over all 2³² angles
/// (proven exhaustively by this module's tests, see the module doc).
pub const SIN_COS_MAX_ERROR: f32 = 1.25e-7;

/// Largest absolute error of [`sin_cos_rad`] for `|x| ≤ 16π`, in either component,
/// against `sin`/`cos` of the `f32` argument: the kernel's bound plus the rounding of the
/// reduced angle to `f32` and of its conversion to turn units (2⁻²⁴ relative of up to π).
/// Checked by a sweep of 400 001 arguments over `[−16π, 16π]` in this module's tests.
pub const SIN_COS_RAD_MAX_ERROR: f32 = 4.0e-7;

/// rad per unit of 2⁻³² turn.
const RAD_PER_UNIT: f32 = TAU / 4_294_967_296.0;

// Cephes sinf.c: minimax for sin x = x + x³·P(x²) on [0, π/4].
#[allow(clippy::excessive_precision)] // the digits as published
const S1: f32 = -1.666_665_461_1e-1;
#[allow(clippy::excessive_precision)] // the digits as published
const S2: f32 = 8.332_160_873_6e-3;
#[allow(clippy::excessive_precision)] // the digits as published
const S3: f32 = -1.951_529_589_1e-4;
// Cephes cosf.c: minimax for cos x = 1 − x²/2 + x⁴·Q(x²) on [0, π/4].
#[allow(clippy::excessive_precision)] // the digits as published
const C1: f32 = 4.166_664_568_298_827e-2;
#[allow(clippy::excessive_precision)] // the digits as published
const C2: f32 = -1.388_731_625_493_765e-3;
#[allow(clippy::excessive_precision)] // the digits as published
const C3: f32 = 2.443_315_711_809_948e-5;

/// `(sin x, cos x)` for `x = 2π·r/2³²`, `r ∈ [−2²⁹, 2²⁹]` (|x| ≤ π/4).
#[inline(always)]
fn kernel(r: i32) -> (f32, f32) {
    let x = r as f32 * RAD_PER_UNIT;
    let z = x * x;
    let s = x + x * z * (S1 + z * (S2 + z * S3));
    let c = 1.0 - 0.5 * z + z * z * (C1 + z * (C2 + z * C3));
    (s, c)
}

/// `(sin θ, cos θ)` of the angle `θ = 2π·angle/2³²` (a fraction of a turn, wrapping;
/// pass the low 32 bits of a [`crate::Position`]). Error ≤ [`SIN_COS_MAX_ERROR`].
#[inline]
pub fn sin_cos_turn(angle: u32) -> (f32, f32) {
    // The nearest quarter turn and the remainder from it, both exact.
    let shifted = angle.wrapping_add(1 << 29);
    let quadrant = shifted >> 30;
    let r = (shifted & ((1 << 30) - 1)) as i32 - (1 << 29);
    let (s, c) = kernel(r);
    // sin(qπ/2 + x), cos(qπ/2 + x): swap for odd q, negate sin for q ∈ {2, 3} and cos for
    // q ∈ {1, 2}; by bits, so there are no branches and no rounding.
    let (a, b) = if quadrant & 1 == 0 { (s, c) } else { (c, s) };
    let sin = f32::from_bits(a.to_bits() ^ ((quadrant & 2) << 30));
    let cos = f32::from_bits(b.to_bits() ^ ((quadrant.wrapping_add(1) & 2) << 30));
    (sin, cos)
}

/// `(sin x, cos x)` for `x` in rad, through [`sin_cos_turn`]: `x` is reduced by the
/// nearest whole turn `n` (Cody–Waite: `x − n·2π_hi − n·2π_lo`, with `n·2π_hi` exact for
/// `|n| < 2¹⁵`) and the remainder in `[−π, π]` converted to 2⁻³² turn units. Error
/// ≤ [`SIN_COS_RAD_MAX_ERROR`] for `|x| ≤ 16π` against `sin`/`cos` of the `f32` argument
/// (the controller passes load angles, `|x| < 3π`). Non-finite `x` gives finite values
/// (the conversions saturate and map NaN to the angle 0), never NaN.
#[inline]
pub fn sin_cos_rad(x: f32) -> (f32, f32) {
    let t = x * (1.0 / TAU);
    // Nearest integer without a library call: truncate (`as` saturates, NaN → 0), adjust.
    let mut n = (t as i32) as f32;
    let f = t - n;
    if f > 0.5 {
        n += 1.0;
    } else if f < -0.5 {
        n -= 1.0;
    }
    let r = (x - n * TAU_HI) - n * TAU_LO;
    // |r| ≤ π plus rounding: r·2³²/2π fits `i32` but for the last few units at ±π, where
    // `as` saturates (an error of those few units, 10⁻⁹ rad).
    let units = (r * (4_294_967_296.0 / TAU)) as i32;
    sin_cos_turn(units as u32)
}

/// 2π split for exact range reduction: `TAU_HI` = 201/32 has 8 significant bits, so
/// `n·TAU_HI` is exact in `f32` for `|n| < 2¹⁶`; `TAU_LO` = 2π − `TAU_HI`.
const TAU_HI: f32 = 6.281_25;
#[allow(clippy::excessive_precision)] // rounded to f32 by the compiler
const TAU_LO: f32 = 1.935_307_179_586_5e-3;

#[cfg(test)]
mod tests {
    use super::*;

    /// Taylor coefficients of `sin x / x` and `cos x` in `z = x²` up to x¹⁸: for |x| ≤ π/4
    /// the truncation is below x²⁰/20! < 2·10⁻²¹, far below the `f32` error measured.
    fn coefficients() -> ([f64; 10], [f64; 10]) {
        let (mut cs, mut cc) = ([0.0; 10], [0.0; 10]);
        let mut fact = 1.0f64; // (2k)!
        for k in 0..10 {
            if k > 0 {
                fact *= (2 * k - 1) as f64 * (2 * k) as f64;
            }
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            cc[k] = sign / fact;
            cs[k] = sign / (fact * (2 * k + 1) as f64);
        }
        (cs, cc)
    }

    /// `(sin x / x, cos x)` from the coefficients at `z = x²` (Horner, f64).
    #[inline(always)]
    fn taylor(cs: &[f64; 10], cc: &[f64; 10], z: f64) -> (f64, f64) {
        let (mut ps, mut pc) = (0.0, 0.0);
        for k in (0..10).rev() {
            ps = ps * z + cs[k];
            pc = pc * z + cc[k];
        }
        (ps, pc)
    }

    #[test]
    fn kernel_error_is_within_the_bound_for_every_reduced_angle() {
        // Every remainder the quadrant reduction can produce, r ∈ [−2²⁹, 2²⁹), through
        // r ∈ [0, 2²⁹]: the kernel is exactly odd (sin) and even (cos) in r (negating r
        // negates x exactly and leaves z unchanged; checked below), like the reference.
        // Together with the exact swap/negate by quadrant this covers all 2³² angles.
        let (cs, cc) = coefficients();
        let unit = core::f64::consts::TAU / 4_294_967_296.0;
        let (mut worst_s, mut worst_c) = (0.0f64, 0.0f64);
        let mut r = 0i32;
        while r <= (1 << 29) {
            let (s, c) = kernel(r);
            let x = f64::from(r) * unit;
            let z = x * x;
            let (ps, pc) = taylor(&cs, &cc, z);
            worst_s = worst_s.max((f64::from(s) - x * ps).abs());
            worst_c = worst_c.max((f64::from(c) - pc).abs());
            r += 1;
        }
        let bound = f64::from(SIN_COS_MAX_ERROR);
        assert!(worst_s <= bound && worst_c <= bound, "sin {worst_s:.3e}, cos {worst_c:.3e} > {bound:.1e}");
        // The bound is not loose: the measured error is at least half of it.
        assert!(worst_s.max(worst_c) > 0.5 * bound, "sin {worst_s:.3e}, cos {worst_c:.3e}");
    }

    #[test]
    fn kernel_is_exactly_odd_and_even_in_the_remainder() {
        let mut r = 1i32;
        while r <= (1 << 29) {
            let (s, c) = kernel(r);
            let (sn, cn) = kernel(-r);
            assert!(sn.to_bits() == (-s).to_bits() && cn.to_bits() == c.to_bits(), "{r}");
            r = r.wrapping_mul(3) / 2 + 7;
        }
    }

    #[test]
    fn taylor_reference_matches_f64_sin_cos() {
        let (cs, cc) = coefficients();
        for i in -100..=100 {
            let x = f64::from(i) * core::f64::consts::FRAC_PI_4 / 100.0;
            let (ps, pc) = taylor(&cs, &cc, x * x);
            assert!((x * ps - libm::sin(x)).abs() < 1e-15 && (pc - libm::cos(x)).abs() < 1e-15, "{x}");
        }
    }

    #[test]
    fn all_quadrants_match_f64_sin_cos_on_a_dense_stride() {
        // 2²⁴ + 1 angles: every 256th unit plus the quadrant and octant edges.
        let mut worst = 0.0f64;
        let mut check = |a: u32| {
            let (s, c) = sin_cos_turn(a);
            let th = f64::from(a) * core::f64::consts::TAU / 4_294_967_296.0;
            let err = (f64::from(s) - libm::sin(th)).abs().max((f64::from(c) - libm::cos(th)).abs());
            worst = worst.max(err);
        };
        for k in 0..(1u32 << 24) {
            check(k << 8 | (k & 0xff));
        }
        for q in 0..8u32 {
            for d in [0u32, 1, 2, u32::MAX, u32::MAX - 1] {
                check((q << 29).wrapping_add(d));
            }
        }
        assert!(worst <= f64::from(SIN_COS_MAX_ERROR), "{worst:.3e}");
    }

    #[test]
    fn exact_values_at_the_quarter_turns() {
        assert_eq!(sin_cos_turn(0), (0.0, 1.0));
        assert_eq!(sin_cos_turn(1 << 30), (1.0, 0.0));
        assert_eq!(sin_cos_turn(1 << 31), (0.0, -1.0));
        assert_eq!(sin_cos_turn(3 << 30), (-1.0, 0.0));
    }

    #[test]
    fn radians_match_f64_sin_cos_and_never_give_nan() {
        let mut worst = 0.0f64;
        for i in -200_000..=200_000 {
            let x = i as f32 * (16.0 * core::f32::consts::PI / 200_000.0);
            let (s, c) = sin_cos_rad(x);
            let err =
                (f64::from(s) - libm::sin(f64::from(x))).abs().max((f64::from(c) - libm::cos(f64::from(x))).abs());
            worst = worst.max(err);
        }
        assert!(worst <= f64::from(SIN_COS_RAD_MAX_ERROR), "{worst:.3e}");
        for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, -f32::MAX] {
            let (s, c) = sin_cos_rad(x);
            assert!(s.is_finite() && c.is_finite(), "{x}: {s} {c}");
        }
    }

    #[test]
    fn radians_wrap_at_half_turns_without_a_jump() {
        use core::f32::consts::PI;
        for x in [PI, -PI, 3.0 * PI, -3.0 * PI] {
            for dx in [-1e-6f32, 0.0, 1e-6] {
                let (s, c) = sin_cos_rad(x + dx);
                let y = f64::from(x + dx);
                assert!((f64::from(s) - libm::sin(y)).abs() < 1e-6 && (f64::from(c) - libm::cos(y)).abs() < 1e-6);
            }
        }
    }
}
