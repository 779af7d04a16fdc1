//! The plant's RK4 integrator over `N` plants side by side ("lanes"), the one
//! implementation of the plant equations of [`crate::plant`] used by every simulation.
//!
//! A lane is one plant state; all lanes share one set of [`PlantParams`] (except the load
//! torque, which is per lane) and one step size. Every operation is element-wise over
//! fixed-size `[f64; N]` arrays with no branch that depends on another lane, so the
//! compiler maps the lanes to SIMD registers (safe code, no intrinsics) and **each lane's
//! result is bit-identical to integrating it alone** (`N = 1`): a sweep runs
//! [`LANES`] speeds per lane group, a single run uses `N = 1`, and they agree exactly
//! (tested).
//!
//! Costs that this layout removes compared with a scalar RK4 over `f64::sin_cos`:
//! - `sin`/`cos` of the electrical angle come from [`sin_cos`], a branch-free polynomial
//!   (fdlibm's kernels after a Cody–Waite reduction) that vectorises over the lanes,
//!   instead of the C library's scalar `sincos`, once per RK4 step: the other three
//!   stages rotate it by their small angle step (`rotated`);
//! - the detent series `Σ A_k sin(kθe + φ_k)` takes `sin kθe, cos kθe` by angle addition
//!   along a ladder of squarings and single steps that skips the orders not present
//!   (orders 1, 2, 4: two complex squarings), in registers;
//! - `1/L` and `1/J` are multiplied, not divided.

// Lane loops index several arrays in step: the index form is the clearest, and vectorises.
#![allow(clippy::needless_range_loop)]

use crate::friction::FrictionLaw;
use crate::plant::{PlantParams, PlantState, friction_substeps};

/// Plants integrated side by side in a sweep: eight `f64` lanes, four SSE2 (two AVX)
/// registers per quantity, and eight independent dependency chains for the out-of-order
/// core (measured 10 % faster than four on the README sweep).
pub const LANES: usize = 8;

/// `N` plant states, one per lane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StateLanes<const N: usize> {
    /// Phase A currents in A.
    pub i_a: [f64; N],
    /// Phase B currents in A.
    pub i_b: [f64; N],
    /// Rotor angles in rad (mechanical).
    pub theta: [f64; N],
    /// Rotor speeds in rad/s.
    pub omega: [f64; N],
}

impl<const N: usize> StateLanes<N> {
    /// The lanes holding `x`.
    pub fn from_states(x: &[PlantState; N]) -> Self {
        StateLanes {
            i_a: x.map(|s| s.i_a),
            i_b: x.map(|s| s.i_b),
            theta: x.map(|s| s.theta),
            omega: x.map(|s| s.omega),
        }
    }

    /// Lane `i`'s state.
    pub fn lane(&self, i: usize) -> PlantState {
        PlantState { i_a: self.i_a[i], i_b: self.i_b[i], theta: self.theta[i], omega: self.omega[i] }
    }
}

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
fn sin_cos_lanes<const N: usize>(x: &[f64; N]) -> ([f64; N], [f64; N]) {
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

/// Largest rotation in rad [`rotated`] takes by its short series (the README sweep's
/// largest stage step is 0.1 rad at 40 rad/s and 20 kHz).
pub const ROTATION_LIMIT: f64 = 0.25;

/// `(sin, cos)` of the electrical angle `θe + δ` per lane, from `sc` = `(sin θe, cos θe)`:
/// rotated by `δ` with `sin δ`, `cos δ` by their Taylor series to δ¹³ and δ¹² (truncation
/// below 1e-19 for `|δ| ≤` [`ROTATION_LIMIT`]). A lane with a larger (or non-finite) `δ`
/// takes [`sin_cos`] of `Nr·θ` from `theta` instead, decided by its own values only.
#[inline(always)]
fn rotated<const N: usize>(sc: &SinCosLanes<N>, delta: &[f64; N], theta: &[f64; N], nr: f64) -> SinCosLanes<N> {
    let mut out = ([0.0; N], [0.0; N]);
    for l in 0..N {
        let d = delta[l];
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
                    + z * (-1.0 / 720.0
                        + z * (1.0 / 40_320.0 + z * (-1.0 / 3_628_800.0 + z * (1.0 / 479_001_600.0))))));
        out.0[l] = sc.0[l] * cd + sc.1[l] * sd;
        out.1[l] = sc.1[l] * cd - sc.0[l] * sd;
    }
    let in_range = delta.iter().fold(true, |ok, d| ok & (d.abs() <= ROTATION_LIMIT));
    if !in_range {
        for l in 0..N {
            if delta[l].is_nan() || delta[l].abs() > ROTATION_LIMIT {
                let x = nr * theta[l];
                (out.0[l], out.1[l]) = if x.abs() <= SIN_COS_POLY_LIMIT { sin_cos(x) } else { x.sin_cos() };
            }
        }
    }
    out
}

/// Per-lane `(sin, cos)` of one multiple of the electrical angle.
type SinCosLanes<const N: usize> = ([f64; N], [f64; N]);

/// The plant equations prepared for integration (one per motor, shared by all lanes).
#[derive(Clone, Debug, PartialEq)]
struct Kernel {
    km: f64,
    nr: f64,
    r: f64,
    inv_l: f64,
    inv_j: f64,
    d: f64,
    fs: f64,
    law: FrictionLaw,
    /// The detent term of order 1 `(A cos φ, A sin φ)` (zeros when absent).
    first: (f64, f64),
    /// Angle-addition ladder from `e^{jθe}` to the highest order: each step squares the
    /// running power `e^{jmθe}` or multiplies it by `e^{jθe}`, then adds the term of the
    /// order reached if there is one `(present, A cos φ, A sin φ)`.
    steps: Vec<(Step, bool, f64, f64)>,
}

/// One step of the detent ladder.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Step {
    /// `m → 2m`.
    Square,
    /// `m → m + 1`.
    TimesZ,
}

impl Kernel {
    fn new(p: &PlantParams) -> Self {
        // PlantParams keeps the terms dense by order: index k − 1.
        let present: Vec<usize> = (1..=p.detent.len()).filter(|&k| p.detent[k - 1] != (0.0, 0.0)).collect();
        let first = if present.first() == Some(&1) { p.detent[0] } else { (0.0, 0.0) };
        let mut steps = Vec::new();
        let mut m = 1;
        for &k in present.iter().filter(|&&k| k > 1) {
            for step in ladder(m, k) {
                steps.push((step, false, 0.0, 0.0));
            }
            if let Some(last) = steps.last_mut() {
                (last.1, last.2, last.3) = (true, p.detent[k - 1].0, p.detent[k - 1].1);
            }
            m = k;
        }
        Kernel {
            km: p.km,
            nr: p.nr,
            r: p.r,
            inv_l: 1.0 / p.l,
            inv_j: 1.0 / p.j,
            d: p.d,
            fs: p.fs,
            law: p.friction,
            first,
            steps,
        }
    }
}

/// The steps from order `m` to order `k > m`: backwards from `k`, halve while the half is
/// still ≥ `m`, else step down by one; never more steps than `k − m` (the plain
/// recurrence), and `log2(k/m)` squarings for powers of two (orders 1, 2, 4: two).
fn ladder(m: usize, k: usize) -> Vec<Step> {
    let mut back = Vec::new();
    let mut at = k;
    while at > m {
        if at % 2 == 0 && at / 2 >= m {
            back.push(Step::Square);
            at /= 2;
        } else {
            back.push(Step::TimesZ);
            at -= 1;
        }
    }
    back.reverse();
    back
}

/// RK4 over `N` lanes of one motor (see the module doc). Holds the prepared equations.
#[derive(Clone, Debug)]
pub struct Integrator<const N: usize> {
    k: Kernel,
}

impl<const N: usize> Integrator<N> {
    /// The integrator of `p`'s plant (its `load_torque_nm` is not used: loads are per lane).
    pub fn new(p: &PlantParams) -> Self {
        Integrator { k: Kernel::new(p) }
    }

    /// Whether `p` describes the same plant (load torque aside) as this integrator's.
    pub fn is_for(&self, p: &PlantParams) -> bool {
        Kernel::new(p) == self.k
    }

    /// `Σ A_k sin(kθe + φ_k)` per lane, given `sin θe, cos θe`.
    #[inline(always)]
    fn detent_series(&self, s: &[f64; N], c: &[f64; N]) -> [f64; N] {
        let (a1, b1) = self.k.first;
        let mut sum = [0.0; N];
        for l in 0..N {
            sum[l] = a1 * s[l] + b1 * c[l];
        }
        let (mut sk, mut ck) = (*s, *c);
        for &(step, term, a, b) in &self.k.steps {
            let (sb, cb) = match step {
                Step::Square => (sk, ck),
                Step::TimesZ => (*s, *c),
            };
            for l in 0..N {
                let sn = sk[l] * cb[l] + ck[l] * sb[l];
                ck[l] = ck[l] * cb[l] - sk[l] * sb[l];
                sk[l] = sn;
            }
            if term {
                for l in 0..N {
                    sum[l] += a * sk[l] + b * ck[l];
                }
            }
        }
        sum
    }

    /// Every torque on the rotor but Coulomb friction, per lane.
    #[inline(always)]
    fn non_friction_torque(&mut self, x: &StateLanes<N>, s: &[f64; N], c: &[f64; N], load: &[f64; N]) -> [f64; N] {
        let det = self.detent_series(s, c);
        let k = &self.k;
        let mut out = [0.0; N];
        for l in 0..N {
            let tau_m = k.km * (-x.i_a[l] * s[l] + x.i_b[l] * c[l]);
            out[l] = tau_m - det[l] - k.d * x.omega[l] + load[l];
        }
        out
    }

    /// Time derivative of the lanes for winding voltages `va`, `vb` with `s`, `c` the
    /// sine and cosine of their electrical angles; Karnopp friction with band `band`.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn derivative(
        &mut self,
        x: &StateLanes<N>,
        s: &[f64; N],
        c: &[f64; N],
        va: &[f64; N],
        vb: &[f64; N],
        load: &[f64; N],
        band: f64,
    ) -> StateLanes<N> {
        let others = self.non_friction_torque(x, s, c, load);
        let k = &self.k;
        let mut d = StateLanes { i_a: [0.0; N], i_b: [0.0; N], theta: x.omega, omega: [0.0; N] };
        if k.law != FrictionLaw::Karnopp {
            // A smooth law: a plain function of the speed, no stick state.
            for l in 0..N {
                let w = x.omega[l];
                d.i_a[l] = (va[l] - k.r * x.i_a[l] + k.km * w * s[l]) * k.inv_l;
                d.i_b[l] = (vb[l] - k.r * x.i_b[l] - k.km * w * c[l]) * k.inv_l;
                d.omega[l] = (others[l] - k.law.friction_nm(k.fs, w)) * k.inv_j;
            }
            return d;
        }
        for l in 0..N {
            let w = x.omega[l];
            d.i_a[l] = (va[l] - k.r * x.i_a[l] + k.km * w * s[l]) * k.inv_l;
            d.i_b[l] = (vb[l] - k.r * x.i_b[l] - k.km * w * c[l]) * k.inv_l;
            let o = others[l];
            let sliding = o - k.fs.copysign(w);
            let breaking = o - k.fs.copysign(o);
            // Stuck (inside the band, friction balances the rest): no acceleration.
            let tau = select(w.abs() >= band, sliding, select(o.abs() <= k.fs, 0.0, breaking));
            d.omega[l] = tau * k.inv_j;
        }
        d
    }

    /// Karnopp's stuck state made exact (see [`crate::plant`]): lanes inside the band
    /// whose other torques stay within `±Fs` are set to `ω = 0`. `sc` is `sin_cos` of the
    /// lanes' electrical angles if already known.
    #[inline(always)]
    fn stick(&mut self, x: &mut StateLanes<N>, sc: Option<&SinCosLanes<N>>, load: &[f64; N], band: f64) {
        if self.k.fs <= 0.0 || self.k.fs.is_nan() || self.k.law != FrictionLaw::Karnopp {
            return;
        }
        let mut inside = [false; N];
        for l in 0..N {
            inside[l] = x.omega[l] != 0.0 && x.omega[l].abs() < band;
        }
        if !inside.iter().fold(false, |any, &i| any | i) {
            return;
        }
        let (s, c) = match sc {
            Some(&sc) => sc,
            None => sin_cos_lanes(&x.theta.map(|t| self.k.nr * t)),
        };
        let others = self.non_friction_torque(x, &s, &c, load);
        for l in 0..N {
            if inside[l] && others[l].abs() <= self.k.fs {
                x.omega[l] = 0.0;
            }
        }
    }

    /// One RK4 step of `h` s with the voltages `va`, `vb` held and per-lane load torques
    /// `load` in N·m; Karnopp band `band` ([`PlantParams::stick_band`]). A stuck rotor is
    /// at rest before and after the step.
    ///
    /// A smooth friction law (stiff at rest: slope `Fs_static/ω_ε`) is integrated by
    /// explicit sub-stepping: `h` is split into [`PlantParams::friction_substeps`] equal RK4
    /// steps, each within the friction's time constant `J/max_slope`, so the step stays
    /// stable and fourth-order (test `smooth_friction_converges_at_fourth_order`). The
    /// count depends on the plant and `h` only, never on a lane's state, so lanes stay
    /// bit-identical to a run alone. Karnopp takes the single step as before.
    pub fn rk4(&mut self, x: &mut StateLanes<N>, va: &[f64; N], vb: &[f64; N], load: &[f64; N], h: f64, band: f64) {
        if self.k.law == FrictionLaw::Karnopp {
            self.rk4_once(x, va, vb, load, h, band);
        } else {
            let n = friction_substeps(self.k.law, self.k.fs, self.k.inv_j, h);
            let hs = h / f64::from(n);
            for _ in 0..n {
                self.rk4_once(x, va, vb, load, hs, band);
            }
        }
    }

    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn rk4_once(&mut self, x: &mut StateLanes<N>, va: &[f64; N], vb: &[f64; N], load: &[f64; N], h: f64, band: f64) {
        let nr = self.k.nr;
        let sc1 = sin_cos_lanes(&x.theta.map(|t| nr * t));
        self.stick(x, Some(&sc1), load, band);
        let x1 = *x;
        let k1 = self.derivative(&x1, &sc1.0, &sc1.1, va, vb, load, band);
        // The stages' angles are the first one's advanced by δ = Nr·a·ω: a rotation.
        let x2 = axpy(&x1, 0.5 * h, &k1);
        let sc2 = rotated(&sc1, &k1.theta.map(|w| nr * (0.5 * h * w)), &x2.theta, nr);
        let k2 = self.derivative(&x2, &sc2.0, &sc2.1, va, vb, load, band);
        let x3 = axpy(&x1, 0.5 * h, &k2);
        let sc3 = rotated(&sc1, &k2.theta.map(|w| nr * (0.5 * h * w)), &x3.theta, nr);
        let k3 = self.derivative(&x3, &sc3.0, &sc3.1, va, vb, load, band);
        let x4 = axpy(&x1, h, &k3);
        let sc4 = rotated(&sc1, &k3.theta.map(|w| nr * (h * w)), &x4.theta, nr);
        let k4 = self.derivative(&x4, &sc4.0, &sc4.1, va, vb, load, band);
        let w = h / 6.0;
        let comb = |x: &[f64; N], a: &[f64; N], b: &[f64; N], c: &[f64; N], d: &[f64; N]| {
            let mut o = [0.0; N];
            for l in 0..N {
                o[l] = x[l] + w * (a[l] + 2.0 * b[l] + 2.0 * c[l] + d[l]);
            }
            o
        };
        *x = StateLanes {
            i_a: comb(&x1.i_a, &k1.i_a, &k2.i_a, &k3.i_a, &k4.i_a),
            i_b: comb(&x1.i_b, &k1.i_b, &k2.i_b, &k3.i_b, &k4.i_b),
            theta: comb(&x1.theta, &k1.theta, &k2.theta, &k3.theta, &k4.theta),
            omega: comb(&x1.omega, &k1.omega, &k2.omega, &k3.omega, &k4.omega),
        };
        self.stick(x, None, load, band);
    }
}

/// `if c { a } else { b }` by bit masks, which vectorises where a branch would not.
#[inline(always)]
fn select(c: bool, a: f64, b: f64) -> f64 {
    let m = u64::from(c).wrapping_neg();
    f64::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}

#[inline(always)]
fn axpy<const N: usize>(x: &StateLanes<N>, a: f64, k: &StateLanes<N>) -> StateLanes<N> {
    let f = |x: &[f64; N], k: &[f64; N]| {
        let mut o = [0.0; N];
        for l in 0..N {
            o[l] = x[l] + a * k[l];
        }
        o
    };
    StateLanes {
        i_a: f(&x.i_a, &k.i_a),
        i_b: f(&x.i_b, &k.i_b),
        theta: f(&x.theta, &k.theta),
        omega: f(&x.omega, &k.omega),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::Profile;

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
    fn a_rotated_angle_matches_its_sine_and_cosine_and_falls_back_beyond_the_limit() {
        let nr = 50.0;
        for i in -2000..=2000 {
            let theta = f64::from(i) * 0.0317;
            let sc = sin_cos_lanes(&[nr * theta]);
            for j in -100..=100 {
                // Up to twice the limit: half of these take the fallback.
                let delta = f64::from(j) * (2.0 * ROTATION_LIMIT / 100.0);
                let th2 = theta + delta / nr;
                let (s, c) = rotated(&sc, &[delta], &[th2], nr);
                if delta.abs() <= ROTATION_LIMIT {
                    // The rotation by the library's sin δ, cos δ, to a few ulp.
                    let (sd, cd) = delta.sin_cos();
                    let (s0, c0) = (sc.0[0] * cd + sc.1[0] * sd, sc.1[0] * cd - sc.0[0] * sd);
                    assert!((s[0] - s0).abs() <= 1e-15 && (c[0] - c0).abs() <= 1e-15, "θ {theta} δ {delta}");
                } else {
                    assert_eq!((s[0], c[0]), sin_cos(nr * th2), "θ {theta} δ {delta}");
                }
            }
        }
        let (s, c) = rotated(&sin_cos_lanes(&[1.0]), &[f64::NAN], &[0.5], 2.0);
        assert_eq!((s[0], c[0]), sin_cos(1.0), "a NaN δ takes the angle itself");
    }

    #[test]
    fn sin_cos_lanes_fall_back_beyond_the_limit_and_pass_nan_through() {
        let x = [1e7, f64::NAN, f64::INFINITY, 2.0];
        let (s, c) = sin_cos_lanes(&x);
        assert_eq!((s[0], c[0]), 1e7f64.sin_cos());
        assert!(s[1].is_nan() && c[1].is_nan() && s[2].is_nan() && c[2].is_nan());
        assert_eq!((s[3], c[3]), sin_cos(2.0));
    }

    #[test]
    fn the_detent_chain_equals_the_dense_series_for_any_set_of_orders() {
        let mut p = PlantParams::from_profile(&Profile::preset("patent-motor").unwrap());
        for orders in [vec![1u16], vec![4], vec![1, 2, 4], vec![3, 5, 7], vec![32], (1..=32).collect::<Vec<_>>()] {
            let max = usize::from(*orders.iter().max().unwrap());
            p.detent = vec![(0.0, 0.0); max];
            for &k in &orders {
                let k = usize::from(k);
                p.detent[k - 1] = (0.01 / k as f64, -0.003 * k as f64);
            }
            let it = Integrator::<2>::new(&p);
            // Never more products than the plain recurrence; powers of two by squaring.
            assert!(it.k.steps.len() < max.max(2), "{orders:?}: {:?}", it.k.steps);
            if orders.iter().all(|k| k.is_power_of_two()) {
                assert_eq!(it.k.steps.len(), max.ilog2() as usize, "{orders:?}");
            }
            for th in [-3.0, -0.01, 0.4, 2.5, 100.0] {
                let (s, c) = (p.nr * th).sin_cos();
                let got = it.detent_series(&[s, s], &[c, c]);
                let want = p.detent_series(s, c);
                assert!((got[0] - want).abs() < 1e-12 && got[0] == got[1], "{orders:?} θ {th}: {got:?} vs {want}");
            }
        }
    }
}
