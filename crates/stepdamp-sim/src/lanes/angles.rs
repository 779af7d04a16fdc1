//! The sines and cosines of the plant's electrical angle for [`super`]'s RK4 over lanes:
//! a vectorisable `sin_cos` once per step, and the later stages' angles by rotation.

// Lane loops index several arrays in step: the index form is the clearest, and vectorises.
#![allow(clippy::needless_range_loop)]

/// `|x|` up to which [`sin_cos`] uses its polynomial: the Cody–Waite reduction below is
/// exact while the quadrant count `q = round(2x/π)` has at most 20 bits. Beyond (an
/// electrical angle of 10⁶ rad is 3,200 revolutions of a 50-pole-pair rotor), and for
/// non-finite `x`, it calls `f64::sin_cos`.
pub const SIN_COS_POLY_LIMIT: f64 = 1.0e6;

/// `(sin x, cos x)`, with an absolute error within 1.2e-16 of `f64::sin_cos` for
/// `|x| ≤` [`SIN_COS_POLY_LIMIT`] (test `sin_cos_matches_the_library_within_its_bound`).
///
/// Reduction: `q = round(2x/π)` by the `1.5·2⁵²` rounding trick (its low bits are the
/// quadrant), `r = x − q·π/2` with π/2 split in fdlibm's 33 + 33 + 53-bit parts
/// (`pio2_1`, `pio2_2`, `pio2_2t`); then fdlibm's `__kernel_sin`/`__kernel_cos` minimax
/// polynomials on `|r| ≤ π/4` (error < 1 ulp), and the quadrant picks and signs them by
/// bit operations. No branch: it vectorises.
#[inline(always)]
pub fn sin_cos(x: f64) -> (f64, f64) {
    const ROUND: f64 = 6_755_399_441_055_744.0; // 1.5·2^52
    // fdlibm's constants (e_rem_pio2.c, k_sin.c, k_cos.c), by their bits.
    const PIO2_1: f64 = f64::from_bits(0x3FF9_21FB_5440_0000); // first 33 bits of π/2
    const PIO2_2: f64 = f64::from_bits(0x3DD0_B461_1A60_0000); // next 33 bits
    const PIO2_2T: f64 = f64::from_bits(0x3BA3_198A_2E03_7073); // π/2 − PIO2_1 − PIO2_2
    const S: [f64; 6] = [
        f64::from_bits(0xBFC5_5555_5555_5549), // −1/3!
        f64::from_bits(0x3F81_1111_1110_F8A6),
        f64::from_bits(0xBF2A_01A0_19C1_61D5),
        f64::from_bits(0x3EC7_1DE3_57B1_FE7D),
        f64::from_bits(0xBE5A_E5E6_8A2B_9CEB),
        f64::from_bits(0x3DE5_D93A_5ACF_D57C),
    ];
    const C: [f64; 6] = [
        f64::from_bits(0x3FA5_5555_5555_554C), // 1/4!
        f64::from_bits(0xBF56_C16C_16C1_5177),
        f64::from_bits(0x3EFA_01A0_19CB_1590),
        f64::from_bits(0xBE92_7E4F_809C_52AD),
        f64::from_bits(0x3E21_EE9E_BDB4_B1C4),
        f64::from_bits(0xBDA8_FAE9_BE88_38D4),
    ];
    let t = x * core::f64::consts::FRAC_2_PI + ROUND;
    let q = t - ROUND;
    // t = 1.5·2^52 + q: the mantissa's low bits are q's (two's complement, mod 4).
    let n = t.to_bits();
    let r = ((x - q * PIO2_1) - q * PIO2_2) - q * PIO2_2T;
    let z = r * r;
    let v = z * r;
    let sp = S[1] + z * (S[2] + z * (S[3] + z * (S[4] + z * S[5])));
    let sin_r = r + v * (S[0] + z * sp);
    let cp = z * (C[0] + z * (C[1] + z * (C[2] + z * (C[3] + z * (C[4] + z * C[5])))));
    let hz = 0.5 * z;
    let w = 1.0 - hz;
    let cos_r = w + (((1.0 - w) - hz) + z * cp);
    // Quadrant n mod 4: (sin, cos) = (s, c), (c, −s), (−s, −c), (−c, s).
    let swap = (n & 1).wrapping_neg();
    let (sb, cb) = (sin_r.to_bits(), cos_r.to_bits());
    let sin_bits = (sb & !swap) | (cb & swap);
    let cos_bits = (cb & !swap) | (sb & swap);
    (f64::from_bits(sin_bits ^ ((n & 2) << 62)), f64::from_bits(cos_bits ^ ((n.wrapping_add(1) & 2) << 62)))
}

/// [`sin_cos`] of every lane; lanes beyond [`SIN_COS_POLY_LIMIT`] (or not finite) are
/// redone with `f64::sin_cos`, each by its own value, so a lane's result never depends on
/// the others.
#[inline(always)]
pub(super) fn sin_cos_lanes<const N: usize>(x: &[f64; N]) -> ([f64; N], [f64; N]) {
    let mut s = [0.0; N];
    let mut c = [0.0; N];
    for i in 0..N {
        (s[i], c[i]) = sin_cos(x[i]);
    }
    // Non-short-circuit `&`: one test for all lanes, not a branch per lane.
    let in_range = x.iter().fold(true, |ok, v| ok & (v.abs() <= SIN_COS_POLY_LIMIT));
    if !in_range {
        for i in 0..N {
            if x[i].is_nan() || x[i].abs() > SIN_COS_POLY_LIMIT {
                (s[i], c[i]) = x[i].sin_cos();
            }
        }
    }
    (s, c)
}

/// Largest half-step angle `δ₂` in rad that `sin_cos_small` takes by its series (the
/// README sweep's largest is 0.05 rad, at 40 rad/s and 20 kHz).
pub const ROTATION_LIMIT: f64 = 0.25;

/// Largest stage correction `ε` in rad that `sin_cos_tiny` takes by its series: `ε` is
/// the angle the rotor's acceleration adds to a later RK4 stage, `Nr·h²·dω/dt/4` or `/2`,
/// 3·10⁻⁴ rad for the patent motor's 1.4·10⁴ rad/s² at 20 kHz; the limit allows 60 times
/// that.
pub const NUDGE_LIMIT: f64 = 0.02;

/// `(sin δ, cos δ)` by their Taylor series to δ¹³ and δ¹² (truncation below 1e-19 for
/// `|δ| ≤` [`ROTATION_LIMIT`]). No check: the caller tests the range.
#[inline(always)]
fn sin_cos_small(d: f64) -> (f64, f64) {
    let z = d * d;
    let sd = d
        * (1.0
            + z * (-1.0 / 6.0
                + z * (1.0 / 120.0
                    + z * (-1.0 / 5040.0
                        + z * (1.0 / 362_880.0 + z * (-1.0 / 39_916_800.0 + z * (1.0 / 6_227_020_800.0)))))));
    let cd = 1.0
        + z * (-0.5
            + z * (1.0 / 24.0
                + z * (-1.0 / 720.0 + z * (1.0 / 40_320.0 + z * (-1.0 / 3_628_800.0 + z * (1.0 / 479_001_600.0))))));
    (sd, cd)
}

/// `(sin ε, cos ε)` by their Taylor series to ε⁷ and ε⁶ (truncation below 1e-18 for
/// `|ε| ≤` [`NUDGE_LIMIT`]: the next terms are ε⁹/9! and ε⁸/8!). No check: the caller
/// tests the range.
#[inline(always)]
fn sin_cos_tiny(e: f64) -> (f64, f64) {
    let z = e * e;
    let se = e * (1.0 + z * (-1.0 / 6.0 + z * (1.0 / 120.0 + z * (-1.0 / 5040.0))));
    let ce = 1.0 + z * (-0.5 + z * (1.0 / 24.0 + z * (-1.0 / 720.0)));
    (se, ce)
}

/// `|x| > limit` or `x` is NaN: out of a series' range.
#[inline(always)]
fn beyond(x: f64, limit: f64) -> bool {
    x.is_nan() || x.abs() > limit
}

/// `sc` rotated by the angles whose sines and cosines are `s`, `c`, per lane.
#[inline(always)]
fn rotate<const N: usize>(sc: &SinCosLanes<N>, s: &[f64; N], c: &[f64; N]) -> SinCosLanes<N> {
    let mut out = ([0.0; N], [0.0; N]);
    for l in 0..N {
        out.0[l] = sc.0[l] * c[l] + sc.1[l] * s[l];
        out.1[l] = sc.1[l] * c[l] - sc.0[l] * s[l];
    }
    out
}

/// `sc` rotated by the small angles `e` per lane ([`sin_cos_tiny`]).
#[inline(always)]
fn nudge<const N: usize>(sc: &SinCosLanes<N>, e: &[f64; N]) -> SinCosLanes<N> {
    let mut s = [0.0; N];
    let mut c = [0.0; N];
    for l in 0..N {
        (s[l], c[l]) = sin_cos_tiny(e[l]);
    }
    rotate(sc, &s, &c)
}

/// The sines and cosines of the electrical angles of RK4's stages 2–4 from stage 1's by
/// rotation, without a `sin`/`cos` of their own (module doc). With `δ₂ = Nr·(h/2)·ω₁`
/// the half step stage 2 takes, the stages' angles are
///
/// ```text
/// θe₂ = θe₁ + δ₂          rotate stage 1 by δ₂            (sin_cos_small)
/// θe₃ = θe₂ + ε₃          ε₃ = Nr·(h/2)·ω₂ − δ₂             (sin_cos_tiny)
/// θe₄ = θe₂ + δ₂ + ε₄     ε₄ = Nr·h·ω₃ − 2δ₂, reusing sin δ₂, cos δ₂
/// ```
///
/// where `ε₃ = Nr·h²·ω̇₁/4` and `ε₄ = Nr·h²·ω̇₂/2` are the acceleration's small share
/// ([`NUDGE_LIMIT`]). A lane whose `δ₂` or `ε` is beyond its series' range or not finite
/// takes [`sin_cos`] of its own angle `Nr·θ` from that stage on, decided by its own values
/// only (so lanes stay bit-identical to runs alone). Rotation errors add up over the
/// three stages to a few ulp (test `stage_angles_match_their_sine_and_cosine`).
pub(super) struct StageAngles<const N: usize> {
    nr: f64,
    /// `Nr·(h/2)·ω₁` per lane.
    d2: [f64; N],
    sd2: [f64; N],
    cd2: [f64; N],
    sc2: SinCosLanes<N>,
    /// Lanes that take their own angle's `sin_cos` (out of the series' range).
    direct: [bool; N],
}

impl<const N: usize> StageAngles<N> {
    /// No stage yet (for `Nr` = `nr`).
    #[inline(always)]
    pub(super) fn new(nr: f64) -> Self {
        StageAngles { nr, d2: [0.0; N], sd2: [0.0; N], cd2: [0.0; N], sc2: ([0.0; N], [0.0; N]), direct: [false; N] }
    }

    /// Stage 2: `sc1` rotated by `d2 = Nr·(h/2)·ω₁`; `theta2` are the stage's rotor angles
    /// (for the fallback).
    #[inline(always)]
    pub(super) fn second(&mut self, sc1: &SinCosLanes<N>, d2: &[f64; N], theta2: &[f64; N]) -> SinCosLanes<N> {
        for l in 0..N {
            self.d2[l] = d2[l];
            (self.sd2[l], self.cd2[l]) = sin_cos_small(d2[l]);
            self.direct[l] = beyond(d2[l], ROTATION_LIMIT);
        }
        let mut sc2 = rotate(sc1, &self.sd2, &self.cd2);
        self.fall_back(&mut sc2, theta2);
        self.sc2 = sc2;
        sc2
    }

    /// Stage 3 from its half-step angles `d3 = Nr·(h/2)·ω₂`.
    #[inline(always)]
    pub(super) fn third(&mut self, d3: &[f64; N], theta3: &[f64; N]) -> SinCosLanes<N> {
        let mut e = [0.0; N];
        for l in 0..N {
            e[l] = d3[l] - self.d2[l];
            self.direct[l] |= beyond(e[l], NUDGE_LIMIT);
        }
        let mut sc3 = nudge(&self.sc2, &e);
        self.fall_back(&mut sc3, theta3);
        sc3
    }

    /// Stage 4 from its full-step angles `d4 = Nr·h·ω₃`.
    #[inline(always)]
    pub(super) fn fourth(&mut self, d4: &[f64; N], theta4: &[f64; N]) -> SinCosLanes<N> {
        let mut e = [0.0; N];
        for l in 0..N {
            e[l] = d4[l] - 2.0 * self.d2[l];
            self.direct[l] |= beyond(e[l], NUDGE_LIMIT);
        }
        let mut sc4 = nudge(&rotate(&self.sc2, &self.sd2, &self.cd2), &e);
        self.fall_back(&mut sc4, theta4);
        sc4
    }

    /// The lanes marked `direct` take `sin_cos(Nr·θ)` of their own angle.
    #[inline(always)]
    fn fall_back(&self, sc: &mut SinCosLanes<N>, theta: &[f64; N]) {
        if self.direct.iter().fold(false, |any, &d| any | d) {
            for l in 0..N {
                if self.direct[l] {
                    let x = self.nr * theta[l];
                    (sc.0[l], sc.1[l]) = if x.abs() <= SIN_COS_POLY_LIMIT { sin_cos(x) } else { x.sin_cos() };
                }
            }
        }
    }
}

/// Per-lane `(sin, cos)` of one multiple of the electrical angle.
pub(super) type SinCosLanes<const N: usize> = ([f64; N], [f64; N]);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sin_cos_matches_the_library_within_its_bound() {
        // A dense sweep of small angles, a coarser one to the limit, and the awkward
        // points: multiples of π/4 (quadrant edges), ±0, the limit itself.
        let mut worst: f64 = 0.0;
        let mut check = |x: f64| {
            let (s, c) = sin_cos(x);
            let (s0, c0) = x.sin_cos();
            let e = (s - s0).abs().max((c - c0).abs());
            assert!(e <= 1.2e-16, "x = {x:e}: ({s:e}, {c:e}) vs ({s0:e}, {c0:e})");
            worst = worst.max(e);
        };
        for i in -2_000_000..=2_000_000 {
            check(f64::from(i) * 1e-5);
        }
        for i in -1_000_000..=1_000_000 {
            check(f64::from(i) * (SIN_COS_POLY_LIMIT / 1e6) + 0.123_456_789 * f64::from(i % 7));
        }
        for k in -4000..=4000 {
            let x = f64::from(k) * core::f64::consts::FRAC_PI_4;
            for d in [-1e-12, 0.0, 1e-12] {
                check(x + d);
            }
        }
        for x in [0.0, -0.0, SIN_COS_POLY_LIMIT, -SIN_COS_POLY_LIMIT, 1e-300, 3000.5] {
            check(x);
        }
        println!("largest |error| against f64::sin_cos: {worst:e}");
    }

    #[test]
    fn stage_angles_match_their_sine_and_cosine_and_fall_back_beyond_the_limits() {
        let nr = 50.0;
        // sc rotated by δ with the library's sin δ, cos δ.
        let exact = |sc: &SinCosLanes<1>, d: f64| {
            let (sd, cd) = d.sin_cos();
            (sc.0[0] * cd + sc.1[0] * sd, sc.1[0] * cd - sc.0[0] * sd)
        };
        let mut worst: f64 = 0.0;
        for i in -300..=300 {
            let theta = f64::from(i) * 0.0317;
            let sc1 = sin_cos_lanes(&[nr * theta]);
            for j in -40..=40 {
                // Up to twice the limits: some of these take the fallback.
                let d2 = f64::from(j) * (2.0 * ROTATION_LIMIT / 40.0);
                for m in -10..=10 {
                    let e3 = f64::from(m) * (2.0 * NUDGE_LIMIT / 10.0);
                    let e4 = -1.5 * e3;
                    let th = |d: f64| theta + d / nr;
                    let (d3, d4) = (d2 + e3, 2.0 * d2 + e4);
                    let mut st = StageAngles::new(nr);
                    let sc2 = st.second(&sc1, &[d2], &[th(d2)]);
                    let sc3 = st.third(&[d3], &[th(d3)]);
                    let sc4 = st.fourth(&[d4], &[th(d4)]);
                    let ok2 = d2.abs() <= ROTATION_LIMIT;
                    // The corrections as the stages see them (d3, d4 are rounded).
                    let ok3 = ok2 && (d3 - d2).abs() <= NUDGE_LIMIT;
                    let ok4 = ok3 && (d4 - 2.0 * d2).abs() <= NUDGE_LIMIT;
                    for (ok, d, sc) in [(ok2, d2, sc2), (ok3, d3, sc3), (ok4, d4, sc4)] {
                        if ok {
                            let (s0, c0) = exact(&sc1, d);
                            let e = (sc.0[0] - s0).abs().max((sc.1[0] - c0).abs());
                            assert!(e <= 1e-15, "θ {theta} δ {d}: error {e:e}");
                            worst = worst.max(e);
                        } else {
                            assert_eq!((sc.0[0], sc.1[0]), sin_cos(nr * th(d)), "θ {theta} δ {d}");
                        }
                    }
                }
            }
        }
        println!("largest |error| against the rotation by the library's sin, cos: {worst:e}");
        let mut st = StageAngles::new(2.0);
        let sc2 = st.second(&sin_cos_lanes(&[1.0]), &[f64::NAN], &[0.5]);
        assert_eq!((sc2.0[0], sc2.1[0]), sin_cos(1.0), "a NaN δ takes the angle itself");
        let sc3 = st.third(&[0.0], &[0.25]);
        assert_eq!((sc3.0[0], sc3.1[0]), sin_cos(0.5), "and so do its later stages");
        let mut st = StageAngles::new(2.0);
        st.second(&sin_cos_lanes(&[1.0]), &[0.0], &[0.5]);
        let sc3 = st.third(&[f64::NAN], &[0.25]);
        assert_eq!((sc3.0[0], sc3.1[0]), sin_cos(0.5), "a NaN ε takes the angle itself");
    }

    #[test]
    fn sin_cos_lanes_fall_back_beyond_the_limit_and_pass_nan_through() {
        let x = [1e7, f64::NAN, f64::INFINITY, 2.0];
        let (s, c) = sin_cos_lanes(&x);
        assert_eq!((s[0], c[0]), 1e7f64.sin_cos());
        assert!(s[1].is_nan() && c[1].is_nan() && s[2].is_nan() && c[2].is_nan());
        assert_eq!((s[3], c[3]), sin_cos(2.0));
    }
}
