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
//!   stages rotate it by their small angle steps (`angles::StageAngles`: one short series for
//!   the half step, two shorter ones for the acceleration's share);
//! - the detent series `Σ A_k sin(kθe + φ_k)` takes `sin kθe, cos kθe` by angle addition
//!   along a ladder of squarings and single steps that skips the orders not present
//!   (orders 1, 2, 4: two complex squarings), in registers;
//! - `1/L` and `1/J` are multiplied, not divided.

// Lane loops index several arrays in step: the index form is the clearest, and vectorises.
#![allow(clippy::needless_range_loop)]

use crate::friction::FrictionLaw;
use crate::plant::{PlantParams, PlantState, friction_substeps};
use stepdamp_profile::flux::FluxShape;

mod angles;
pub use angles::{NUDGE_LIMIT, ROTATION_LIMIT, SIN_COS_POLY_LIMIT, sin_cos};
use angles::{SinCosLanes, StageAngles, sin_cos_lanes};

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
    /// The flux linkage's shape beyond the pure sine, `None` for the patent's motor.
    flux: Option<FluxKernel>,
}

/// `(S_a, S_b)` per lane.
type ShapeSums<const N: usize> = ([f64; N], [f64; N]);

/// The flux shape sums `S_a`, `S_b` of [`stepdamp_profile::flux`] prepared for the lanes: the
/// harmonics dense by odd order from 3 (`(ca, sa, cb, sb)`, zeros where absent) and `1 + g`.
#[derive(Clone, Debug, PartialEq)]
struct FluxKernel {
    odd: Vec<[f64; 4]>,
    b_gain: f64,
}

impl FluxKernel {
    fn new(f: &FluxShape) -> Self {
        let highest = f.terms().iter().map(|t| usize::from(t.0)).max().unwrap_or(1);
        let mut odd = vec![[0.0; 4]; highest.saturating_sub(1) / 2];
        for &(n, [ca, sa], [cb, sb]) in f.terms().iter().filter(|t| t.0 >= 3 && t.0 % 2 == 1) {
            let e = &mut odd[usize::from(n - 3) / 2];
            *e = [e[0] + ca, e[1] + sa, e[2] + cb, e[3] + sb];
        }
        FluxKernel { odd, b_gain: f.b_gain() }
    }

    /// `(S_a, S_b)` per lane from `sin θe`, `cos θe`: the fundamental `(sin θe, −cos θe)`
    /// plus the odd harmonics, `e^{j(n+2)θe} = e^{jnθe}·e^{j2θe}`.
    #[inline(always)]
    fn shape_sums<const N: usize>(&self, s: &[f64; N], c: &[f64; N]) -> ([f64; N], [f64; N]) {
        let mut sa = *s;
        let mut sb = c.map(|c| -c);
        let (mut s2, mut c2) = ([0.0; N], [0.0; N]);
        for l in 0..N {
            s2[l] = 2.0 * (s[l] * c[l]);
            c2[l] = c[l] * c[l] - s[l] * s[l];
        }
        let (mut sn, mut cn) = (*s, *c);
        for &[ca, sa_, cb, sb_] in &self.odd {
            for l in 0..N {
                let next = sn[l] * c2[l] + cn[l] * s2[l];
                cn[l] = cn[l] * c2[l] - sn[l] * s2[l];
                sn[l] = next;
                sa[l] += ca * sn[l] + sa_ * cn[l];
                sb[l] += cb * sn[l] + sb_ * cn[l];
            }
        }
        (sa, sb)
    }
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
            flux: p.flux.as_ref().map(FluxKernel::new),
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
            match step {
                // `s·c + c·s` is `2·(s·c)` exactly: one product fewer, the same bits.
                Step::Square => {
                    for l in 0..N {
                        let sn = 2.0 * (sk[l] * ck[l]);
                        ck[l] = ck[l] * ck[l] - sk[l] * sk[l];
                        sk[l] = sn;
                    }
                }
                Step::TimesZ => {
                    for l in 0..N {
                        let sn = sk[l] * c[l] + ck[l] * s[l];
                        ck[l] = ck[l] * c[l] - sk[l] * s[l];
                        sk[l] = sn;
                    }
                }
            }
            if term {
                for l in 0..N {
                    sum[l] += a * sk[l] + b * ck[l];
                }
            }
        }
        sum
    }

    /// Every torque on the rotor but Coulomb friction, per lane; `sums` are the flux shape's
    /// `(S_a, S_b)` when the motor has one (computed once per stage by the caller).
    #[inline(always)]
    fn non_friction_torque(
        &mut self,
        x: &StateLanes<N>,
        s: &[f64; N],
        c: &[f64; N],
        load: &[f64; N],
        sums: Option<&ShapeSums<N>>,
    ) -> [f64; N] {
        let det = self.detent_series(s, c);
        let k = &self.k;
        let mut out = [0.0; N];
        if let (Some(f), Some((sa, sb))) = (&k.flux, sums) {
            for l in 0..N {
                let tau_m = -k.km * (x.i_a[l] * sa[l] + f.b_gain * x.i_b[l] * sb[l]);
                out[l] = tau_m - det[l] - k.d * x.omega[l] + load[l];
            }
            return out;
        }
        for l in 0..N {
            let tau_m = k.km * (-x.i_a[l] * s[l] + x.i_b[l] * c[l]);
            out[l] = tau_m - det[l] - k.d * x.omega[l] + load[l];
        }
        out
    }

    /// The windings' back-EMF terms `(Km·ω·S_a, (1+g)·Km·ω·S_b)` per lane (the winding
    /// equations are `L·di/dt = v − R·i + these`), for a flux shape.
    #[inline(always)]
    fn flux_emf(f: &FluxKernel, km: f64, x: &StateLanes<N>, (sa, sb): &ShapeSums<N>) -> ([f64; N], [f64; N]) {
        let (mut ea, mut eb) = ([0.0; N], [0.0; N]);
        for l in 0..N {
            ea[l] = km * x.omega[l] * sa[l];
            eb[l] = f.b_gain * km * x.omega[l] * sb[l];
        }
        (ea, eb)
    }

    /// Every torque on the rotor but Coulomb friction at the lanes' states, with no load
    /// (the static torque a test compares with the closed forms).
    #[cfg(test)]
    pub(crate) fn static_torque(&mut self, x: &StateLanes<N>) -> [f64; N] {
        let (s, c) = sin_cos_lanes(&x.theta.map(|t| self.k.nr * t));
        let sums = self.k.flux.as_ref().map(|f| f.shape_sums(&s, &c));
        self.non_friction_torque(x, &s, &c, &[0.0; N], sums.as_ref())
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
        let sums = self.k.flux.as_ref().map(|f| f.shape_sums(s, c));
        let others = self.non_friction_torque(x, s, c, load, sums.as_ref());
        let k = &self.k;
        let mut d = StateLanes { i_a: [0.0; N], i_b: [0.0; N], theta: x.omega, omega: [0.0; N] };
        // The windings' back-EMF terms: `v − R·i + e` with `e = (Km·ω·sin θe, −Km·ω·cos θe)`
        // for the pure sine (`a + (−b)` is `a − b` exactly: the same bits as before).
        let (ea, eb) = match (&k.flux, &sums) {
            (Some(f), Some(sums)) => Self::flux_emf(f, k.km, x, sums),
            _ => {
                let (mut ea, mut eb) = ([0.0; N], [0.0; N]);
                for l in 0..N {
                    ea[l] = k.km * x.omega[l] * s[l];
                    eb[l] = -(k.km * x.omega[l] * c[l]);
                }
                (ea, eb)
            }
        };
        for l in 0..N {
            d.i_a[l] = (va[l] - k.r * x.i_a[l] + ea[l]) * k.inv_l;
            d.i_b[l] = (vb[l] - k.r * x.i_b[l] + eb[l]) * k.inv_l;
        }
        if k.law != FrictionLaw::Karnopp {
            // A smooth law: a plain function of the speed, no stick state.
            for l in 0..N {
                d.omega[l] = (others[l] - k.law.friction_nm(k.fs, x.omega[l])) * k.inv_j;
            }
            return d;
        }
        for l in 0..N {
            let (w, o) = (x.omega[l], others[l]);
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
        let sums = self.k.flux.as_ref().map(|f| f.shape_sums(&s, &c));
        let others = self.non_friction_torque(x, &s, &c, load, sums.as_ref());
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
        // The stages' angles are the first one's advanced by Nr·a·ω: rotations.
        let x2 = axpy(&x1, 0.5 * h, &k1);
        let mut stages = StageAngles::new(nr);
        let sc2 = stages.second(&sc1, &k1.theta.map(|w| nr * (0.5 * h * w)), &x2.theta);
        let k2 = self.derivative(&x2, &sc2.0, &sc2.1, va, vb, load, band);
        let x3 = axpy(&x1, 0.5 * h, &k2);
        let sc3 = stages.third(&k2.theta.map(|w| nr * (0.5 * h * w)), &x3.theta);
        let k3 = self.derivative(&x3, &sc3.0, &sc3.1, va, vb, load, band);
        let x4 = axpy(&x1, h, &k3);
        let sc4 = stages.fourth(&k3.theta.map(|w| nr * (h * w)), &x4.theta);
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
