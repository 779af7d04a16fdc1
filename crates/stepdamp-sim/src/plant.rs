//! The two-phase hybrid stepper, its friction and its load, in `f64` (docs/design.md#the-plant).
//!
//! ```text
//! L di_a/dt = v_a − R i_a + Km ω sin θe        θe = Nr θ
//! L di_b/dt = v_b − R i_b − Km ω cos θe        (the patent's eq. 2 prints sin: a typo)
//! τ_m       = Km (−i_a sin θe + i_b cos θe)
//! τ_detent  = −Σ_k A_k sin(k θe + φ_k)
//! J dω/dt   = τ_m + τ_detent − D ω + τ_load + τ_coulomb,   dθ/dt = ω
//! ```
//!
//! With a `[motor.flux]` section the back-EMF and `τ_m` come from the flux linkage's shape
//! instead ([`stepdamp_profile::flux`]): `e_a = −Km ω S_a`, `e_b = −(1+g) Km ω S_b`,
//! `τ_m = −Km (i_a S_a + (1+g) i_b S_b)`; without it the equations above hold bit for bit.
//!
//! Coulomb friction follows Karnopp's stick/slip rule: inside a velocity band `|ω| < ω_s`
//! the rotor sticks while the other torques stay within `Fs`, and breaks away with `Fs`
//! opposing them otherwise; outside the band it is `−Fs·sgn(ω)`. Sticking is exact: a
//! stuck rotor has `ω = 0` (set before and after every RK4 step),
//! not just `dω/dt = 0`, so it does not creep at its small in-band speed. The band is the
//! speed change that `Fs` alone makes in one integration step, so the model is never
//! stiff. Integration is classical RK4 with the voltages held over the step.

use crate::friction::FrictionLaw;
use crate::lanes::{Integrator, StateLanes};
use crate::profile::ProfileData;
use stepdamp_profile::data::FrictionLawName;
use stepdamp_profile::flux::FluxShape;

/// Plant parameters in SI units.
#[derive(Clone, Debug, PartialEq)]
pub struct PlantParams {
    /// Torque constant `Km` in N·m/A.
    pub km: f64,
    /// Pole pairs `Nr`.
    pub nr: f64,
    /// Phase resistance in Ω.
    pub r: f64,
    /// Phase inductance in H.
    pub l: f64,
    /// Inertia in kg·m².
    pub j: f64,
    /// Viscous friction in N·m·s/rad.
    pub d: f64,
    /// Coulomb friction in N·m.
    pub fs: f64,
    /// The law the Coulomb friction follows ([`FrictionLaw::Karnopp`]: the module doc).
    pub friction: FrictionLaw,
    /// Detent harmonics, dense by order: `(A cos φ, A sin φ)` at index `k − 1`.
    pub detent: Vec<(f64, f64)>,
    /// Constant external load torque on the rotor in N·m (signed).
    pub load_torque_nm: f64,
    /// The magnet flux linkage's shape, `None` for a pure sine and equal phases (then the
    /// plant is the patent's, bit for bit).
    pub flux: Option<FluxShape>,
}

/// Plant state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlantState {
    /// Phase A current in A.
    pub i_a: f64,
    /// Phase B current in A.
    pub i_b: f64,
    /// Rotor angle in rad (mechanical).
    pub theta: f64,
    /// Rotor speed in rad/s.
    pub omega: f64,
}

impl PlantParams {
    /// The plant a profile describes, with no load torque. A [`crate::Profile`] is valid by its
    /// type; unchecked data never panics here either, but a detent term of order 0
    /// (meaningless) is ignored and a repeated order adds up.
    pub fn from_profile(p: &ProfileData) -> Self {
        let max = p.motor.detent.iter().map(|h| usize::from(h.order)).max().unwrap_or(0);
        let mut detent = vec![(0.0, 0.0); max];
        for h in p.motor.detent.iter().filter(|h| h.order > 0) {
            let d: &mut (f64, f64) = &mut detent[usize::from(h.order) - 1];
            d.0 += h.amplitude_nm * h.phase_rad.cos();
            d.1 += h.amplitude_nm * h.phase_rad.sin();
        }
        PlantParams {
            km: p.motor.km_nm_per_a,
            nr: f64::from(p.motor.pole_pairs),
            r: p.motor.resistance_ohm,
            l: p.motor.inductance_h,
            j: p.motor.inertia_kg_m2,
            d: p.motor.viscous_nm_s_per_rad,
            fs: p.motor.coulomb_friction_nm,
            friction: friction_law(p),
            detent,
            load_torque_nm: 0.0,
            flux: (!p.motor.flux.is_default()).then(|| FluxShape::new(&p.motor.flux)),
        }
    }

    /// The smooth laws' step limit: the number of RK4 sub-steps a step of `h` s needs so
    /// that each is within `J / max_slope` (the friction's time constant at rest, where
    /// its slope is steepest), i.e. `h·λ ≤ 1` well inside RK4's real-axis stability bound
    /// 2.78; 1 for Karnopp.
    pub fn friction_substeps(&self, h: f64) -> u32 {
        friction_substeps(self.friction, self.fs, 1.0 / self.j, h)
    }

    /// `Σ A_k sin(k θe + φ_k)` given `(sin θe, cos θe)` (detent torque is minus this), by
    /// the plain recurrence over every order: the reference the integrator's chain over the
    /// orders present ([`crate::lanes`]) is tested against.
    pub fn detent_series(&self, s1: f64, c1: f64) -> f64 {
        let (mut sk, mut ck) = (s1, c1);
        let mut sum = 0.0;
        for &(a, b) in &self.detent {
            sum += a * sk + b * ck;
            let ns = sk * c1 + ck * s1;
            ck = ck * c1 - sk * s1;
            sk = ns;
        }
        sum
    }

    /// Detent potential energy `U(θ)` in J with `τ_detent = −dU/dθ`:
    /// `U = −Σ A_k cos(k θe + φ_k) / (k Nr)`.
    pub fn detent_energy(&self, theta: f64) -> f64 {
        let te = self.nr * theta;
        self.detent
            .iter()
            .enumerate()
            .map(|(i, &(a, b))| {
                let k = (i + 1) as f64;
                // A cos(kθe + φ) = a cos kθe − b sin kθe.
                -(a * (k * te).cos() - b * (k * te).sin()) / (k * self.nr)
            })
            .sum()
    }

    /// Motor torque `Km(−i_a sin θe + i_b cos θe)` in N·m (with a flux shape, its
    /// [`FluxShape::torque_nm`]).
    #[inline]
    pub fn motor_torque(&self, x: &PlantState) -> f64 {
        if let Some(f) = &self.flux {
            return f.torque_nm(self.km, self.nr * x.theta, x.i_a, x.i_b);
        }
        let (s, c) = (self.nr * x.theta).sin_cos();
        self.km * (-x.i_a * s + x.i_b * c)
    }

    /// Back-EMF `(e_a, e_b) = (−Km ω sin θe, Km ω cos θe)` in V (the winding equation is
    /// `L di/dt = v − R i − e`; with a flux shape, its [`FluxShape::back_emf_v`]).
    #[inline]
    pub fn back_emf(&self, x: &PlantState) -> (f64, f64) {
        if let Some(f) = &self.flux {
            return f.back_emf_v(self.km, self.nr * x.theta, x.omega);
        }
        let (s, c) = (self.nr * x.theta).sin_cos();
        (-self.km * x.omega * s, self.km * x.omega * c)
    }

    /// Karnopp band for an integration step of `h` s: the speed `Fs` alone changes in `h`.
    pub fn stick_band(&self, h: f64) -> f64 {
        (self.fs / self.j * h).max(1e-9)
    }

    /// One RK4 step of `h` s with the voltages held; a stuck rotor (module doc) is at
    /// rest before and after the step. A convenience for one-off steps: it prepares
    /// a [`crate::lanes::Integrator`] on every call, which is what the closed loop keeps.
    pub fn rk4(&self, x: &PlantState, va: f64, vb: f64, h: f64, band: f64) -> PlantState {
        let mut it = Integrator::<1>::new(self);
        let mut lanes = StateLanes::from_states(&[*x]);
        it.rk4(&mut lanes, &[va], &[vb], &[self.load_torque_nm], h, band);
        lanes.lane(0)
    }
}

/// [`PlantParams::friction_substeps`] from the law, `Fs` (N·m), `1/J` (1/(kg·m²)) and `h` (s).
pub(crate) fn friction_substeps(law: FrictionLaw, fs: f64, inv_j: f64, h: f64) -> u32 {
    match law.max_slope(fs) {
        Some(slope) if slope > 0.0 && inv_j > 0.0 => {
            let n = (h * slope * inv_j).ceil();
            // NaN (a non-finite h) and absurd counts: one step (the run then diverges
            // visibly rather than hanging).
            if (1.0..=1e6).contains(&n) { n as u32 } else { 1 }
        }
        _ => 1,
    }
}

/// The friction law of `[motor.friction]`. Missing parameters (a profile that did not go
/// through validation) fall back to Karnopp rather than panic.
fn friction_law(p: &ProfileData) -> FrictionLaw {
    let f = &p.motor.friction;
    match (f.law, f.creep_speed_rad_s, f.static_nm, f.stribeck_speed_rad_s) {
        (FrictionLawName::Smooth, Some(creep), _, _) => FrictionLaw::SmoothCoulomb { creep_speed_rad_s: creep },
        (FrictionLawName::Stribeck, Some(creep), Some(st), Some(ws)) => {
            FrictionLaw::Stribeck { static_nm: st, stribeck_speed_rad_s: ws, creep_speed_rad_s: creep }
        }
        _ => FrictionLaw::Karnopp,
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::profile::Profile;
    use proptest::prelude::*;

    fn patent() -> PlantParams {
        PlantParams::from_profile(&Profile::preset("patent-motor").unwrap())
    }

    proptest! {
        #[test]
        fn back_emf_power_equals_mechanical_power(
            ia in -5.0f64..5.0, ib in -5.0f64..5.0, th in -10.0f64..10.0, w in -100.0f64..100.0
        ) {
            let p = patent();
            let x = PlantState { i_a: ia, i_b: ib, theta: th, omega: w };
            let (ea, eb) = p.back_emf(&x);
            let pe = ea * ia + eb * ib;
            let pm = p.motor_torque(&x) * w;
            prop_assert!((pe - pm).abs() <= 1e-9 * (1.0 + pm.abs()));
        }

        #[test]
        fn detent_torque_is_minus_the_gradient_of_its_energy(th in -1.0f64..1.0) {
            let p = patent();
            let h = 1e-7;
            let grad = (p.detent_energy(th + h) - p.detent_energy(th - h)) / (2.0 * h);
            let (s, c) = (p.nr * th).sin_cos();
            prop_assert!((-p.detent_series(s, c) + grad).abs() < 1e-6);
        }
    }

    /// Energy balance over a run: what the voltages put in equals the magnetic, kinetic
    /// and detent energy gained plus the copper and viscous losses (no Coulomb friction,
    /// whose stick phases are not smooth). Returns (imbalance, input) in J.
    pub(crate) fn energy_imbalance_of_a_driven_run(mut p: PlantParams) -> (f64, f64) {
        p.fs = 0.0;
        let h = 5e-6;
        let band = p.stick_band(h);
        let mut x = PlantState::default();
        let energy = |x: &PlantState| {
            0.5 * p.l * (x.i_a * x.i_a + x.i_b * x.i_b) + 0.5 * p.j * x.omega * x.omega + p.detent_energy(x.theta)
        };
        let e0 = energy(&x);
        let (mut e_in, mut e_loss) = (0.0, 0.0);
        for n in 0..40_000 {
            // A rotating voltage vector drags the rotor along through its resonances.
            let t = n as f64 * h;
            let ph = 2.0 * t * 50.0 * 10.0 * t.min(0.1);
            let (va, vb) = (3.0 * ph.cos(), 3.0 * ph.sin());
            let pin = |x: &PlantState| va * x.i_a + vb * x.i_b;
            let ploss = |x: &PlantState| p.r * (x.i_a * x.i_a + x.i_b * x.i_b) + p.d * x.omega * x.omega;
            let xn = p.rk4(&x, va, vb, h, band);
            // Simpson over the step with the midpoint from an RK4 half step.
            let xm = p.rk4(&x, va, vb, 0.5 * h, band);
            e_in += h / 6.0 * (pin(&x) + 4.0 * pin(&xm) + pin(&xn));
            e_loss += h / 6.0 * (ploss(&x) + 4.0 * ploss(&xm) + ploss(&xn));
            x = xn;
        }
        assert!(x.omega.abs() > 1.0, "the rotor moved: {x:?}");
        (e_in - e_loss - (energy(&x) - e0), e_in)
    }

    #[test]
    fn energy_is_conserved_over_a_driven_run() {
        let (err, e_in) = energy_imbalance_of_a_driven_run(patent());
        assert!(err.abs() < 1e-6 * e_in.abs(), "in {e_in} err {err}");
    }

    #[test]
    fn coulomb_friction_holds_a_rotor_below_breakaway() {
        let mut p = patent();
        p.detent.clear();
        // Windings decoupled: at zero volts they would be shorted and brake at Km²/R·ω.
        p.km = 0.0;
        // Coulomb friction alone.
        p.d = 0.0;
        let h = 2.5e-5;
        let band = p.stick_band(h);
        // A load torque of 0.9 Fs: the rotor never moves.
        p.load_torque_nm = 0.9 * p.fs;
        let mut x = PlantState::default();
        for _ in 0..10_000 {
            x = p.rk4(&x, 0.0, 0.0, h, band);
        }
        assert!(x.theta.abs() < 1e-9 && x.omega.abs() < 1e-9, "{x:?}");
        // 1.1 Fs: it accelerates at 0.1 Fs / J.
        p.load_torque_nm = 1.1 * p.fs;
        let mut x = PlantState::default();
        for _ in 0..4_000 {
            x = p.rk4(&x, 0.0, 0.0, h, band);
        }
        let t = 4_000.0 * h;
        let want = 0.1 * p.fs / p.j * t;
        assert!((x.omega - want).abs() < 0.02 * want + band, "{} vs {want}", x.omega);
    }

    #[test]
    fn a_stuck_rotor_does_not_creep() {
        let mut p = patent();
        p.detent.clear();
        p.km = 0.0;
        p.load_torque_nm = 0.0;
        let h = 2.5e-5;
        let band = p.stick_band(h);
        // A small speed inside the stick band, not exactly 0, and nothing driving the rotor:
        // friction holds it, so it must neither move nor keep its speed.
        let theta0 = 0.3;
        let mut x = PlantState { theta: theta0, omega: 0.5 * band, ..Default::default() };
        for _ in 0..100_000 {
            x = p.rk4(&x, 0.0, 0.0, h, band);
        }
        assert_eq!(x.omega, 0.0, "{x:?}");
        assert_eq!(x.theta, theta0, "crept by {}", x.theta - theta0);
        // The same with the speed just below the band on the other side, and a load torque
        // within Fs.
        p.load_torque_nm = 0.5 * p.fs;
        let mut x = PlantState { theta: theta0, omega: -0.99 * band, ..Default::default() };
        for _ in 0..10_000 {
            x = p.rk4(&x, 0.0, 0.0, h, band);
        }
        assert_eq!((x.theta, x.omega), (theta0, 0.0), "{x:?}");
        // Above the band it slides and slows down instead.
        let mut x = PlantState { theta: theta0, omega: 3.0 * band, ..Default::default() };
        x = p.rk4(&x, 0.0, 0.0, h, band);
        assert!(x.theta > theta0, "{x:?}");
    }

    #[test]
    fn a_profile_with_a_bad_detent_order_does_not_panic() {
        let mut m = Profile::preset("patent-motor").unwrap().to_data();
        m.motor.detent[0].order = 0;
        let p = PlantParams::from_profile(&m);
        assert!(p.detent.len() <= usize::from(m.motor.detent.iter().map(|h| h.order).max().unwrap()));
    }

    #[test]
    fn rk4_converges_at_fourth_order() {
        // Smooth dynamics only: Coulomb friction's kink would cap the order.
        let mut p = patent();
        p.fs = 0.0;
        let run = |h: f64| {
            let band = p.stick_band(1e-9);
            let mut x = PlantState { i_a: 1.9, ..Default::default() };
            let n = (0.01 / h).round() as usize;
            for _ in 0..n {
                x = p.rk4(&x, 1.0, 2.0, h, band);
            }
            x.theta
        };
        let (a, b, c) = (run(1e-4), run(5e-5), run(2.5e-5));
        let ratio = (a - b) / (b - c);
        assert!(ratio > 12.0 && ratio < 20.0, "order ratio {ratio}");
    }

    /// The patent motor as a bare rotor under a load torque and the law `law`: windings
    /// decoupled (`Km = 0`), no detent, no viscous friction.
    fn bare_rotor(law: FrictionLaw, load: f64) -> PlantParams {
        let mut p = patent();
        p.detent.clear();
        p.km = 0.0;
        p.d = 0.0;
        p.friction = law;
        p.load_torque_nm = load;
        p
    }

    fn run_for(p: &PlantParams, x0: PlantState, h: f64, t: f64) -> PlantState {
        let band = p.stick_band(h);
        let mut x = x0;
        for _ in 0..(t / h).round() as usize {
            x = p.rk4(&x, 0.0, 0.0, h, band);
        }
        x
    }

    #[test]
    fn smooth_coulomb_creeps_at_the_speed_where_tanh_balances_the_torque() {
        // Below Fs the rotor does not stick but creeps at ω = ω_ε·atanh(τ/Fs), the speed
        // where friction balances the load. ω_ε = 1 mrad/s makes the law stiff at 20 kHz
        // (13 sub-steps per period).
        let law = FrictionLaw::SmoothCoulomb { creep_speed_rad_s: 1e-3 };
        for frac in [0.3, 0.9, -0.6] {
            let p = bare_rotor(law, frac * 0.01);
            assert_eq!(p.friction_substeps(5e-5), 13);
            let x = run_for(&p, PlantState::default(), 5e-5, 0.2);
            let want = 1e-3 * f64::atanh(frac);
            assert!((x.omega - want).abs() < 1e-9 * want.abs().max(1e-3), "τ = {frac} Fs: {} vs {want}", x.omega);
        }
    }

    #[test]
    fn stribeck_holds_below_its_break_away_torque_and_slips_above() {
        let (fs, fst) = (0.01, 0.015);
        let law = FrictionLaw::Stribeck { static_nm: fst, stribeck_speed_rad_s: 0.05, creep_speed_rad_s: 1e-3 };
        // 2 % below Fs_static: it creeps below the Stribeck speed (on the rising tanh).
        let p = bare_rotor(law, 0.98 * fst);
        let x = run_for(&p, PlantState::default(), 5e-5, 0.3);
        assert!(x.omega > 0.0 && x.omega < 0.01, "held: {x:?}");
        assert!((law.friction_nm(fs, x.omega) - 0.98 * fst).abs() < 1e-9, "friction balances the load: {x:?}");
        // 1 % above: it breaks away, friction falls to Fs and the rotor accelerates at
        // least at (1.01 Fs_static − Fs)/J once past the Stribeck speed.
        let p = bare_rotor(law, 1.01 * fst);
        let x = run_for(&p, PlantState::default(), 5e-5, 0.3);
        let at_least = (1.01 * fst - fs - (fst - fs) * (-1.0f64).exp()) / p.j * 0.1;
        assert!(x.omega > at_least, "broke away: {x:?}, want > {at_least}");
    }

    #[test]
    fn smooth_friction_converges_at_fourth_order() {
        // A creep speed large enough for one sub-step at every h below: plain RK4, whose
        // order the smooth law must keep (Karnopp's kink caps it).
        let law = FrictionLaw::SmoothCoulomb { creep_speed_rad_s: 0.5 };
        let mut p = patent();
        p.friction = law;
        let run = |h: f64| {
            assert_eq!(p.friction_substeps(h), 1);
            let band = p.stick_band(h);
            let mut x = PlantState { i_a: 1.9, omega: -0.3, ..Default::default() };
            for _ in 0..(0.01 / h).round() as usize {
                x = p.rk4(&x, 1.0, 2.0, h, band);
            }
            x.theta
        };
        let (a, b, c) = (run(1e-4), run(5e-5), run(2.5e-5));
        let ratio = (a - b) / (b - c);
        assert!(ratio > 12.0 && ratio < 20.0, "order ratio {ratio}");
    }

    #[test]
    fn sub_stepping_keeps_a_stiff_smooth_law_stable_and_converged() {
        // ω_ε = 0.1 mrad/s: the law's time constant J/(Fs/ω_ε) = 0.4 µs, 125 times shorter
        // than a 20 kHz period. Sub-stepped, the period step agrees with one four times
        // finer, through a ring-down across ω = 0 with the windings driven.
        let law = FrictionLaw::SmoothCoulomb { creep_speed_rad_s: 1e-4 };
        let mut p = patent();
        p.friction = law;
        assert_eq!(p.friction_substeps(5e-5), 125);
        let run = |h: f64| {
            let band = p.stick_band(h);
            let mut x = PlantState { omega: 2.0, ..Default::default() };
            for _ in 0..(0.02 / h).round() as usize {
                x = p.rk4(&x, 0.5, -0.3, h, band);
            }
            x
        };
        let (coarse, fine) = (run(5e-5), run(1.25e-5));
        assert!(coarse.omega.is_finite() && coarse.omega.abs() < 10.0, "{coarse:?}");
        assert!((coarse.theta - fine.theta).abs() < 1e-9, "{coarse:?} vs {fine:?}");
        assert!((coarse.omega - fine.omega).abs() < 1e-6, "{coarse:?} vs {fine:?}");
    }

    #[test]
    fn the_default_profile_has_karnopp_friction() {
        assert_eq!(patent().friction, FrictionLaw::Karnopp);
        assert_eq!(patent().friction_substeps(5e-5), 1);
    }
}
