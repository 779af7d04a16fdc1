//! The independent generators' magnet flux shape and torque ripple: one home for the flux
//! linkage that both [`super::servo_real`] (servo) and [`super::open_loop`] (open loop) take
//! their torque and back-EMF from.
//!
//! Written without any code of `stepdamp-profile`'s flux and ripple code. Per unit of
//! `Km/Nr`, `θe = Nr·θ`:
//!
//! * `λ_a(θe) = cos θe + Σ_n h_n·cos(n·θe + a_n)`,
//! * `λ_b(θe) = (1 + g)·[sin θe + Σ_n h_n·cos(n·θe + a_n − n·π/2)]` (phase b is phase a a
//!   quarter electrical period later, times `1 + g`).
//!
//! With no harmonics and `g = 0` ([`FluxShape::sine`]) this is the sine motor,
//! `(λ_a', λ_b') = (−sin θe, cos θe)`, computed to the same bits as the sine formulas.
//!
//! **Energy**: with `ψ_x = (Km/Nr)·λ_x` the torque on the rotor is
//! `τ_m = Km·(i_a·λ_a' + i_b·λ_b')` (`'` = `d/dθe`) and the back-EMF `e_x = Km·ω·λ_x'`, so
//! `e_a·i_a + e_b·i_b = τ_m·ω`.

use std::f64::consts::{FRAC_PI_2, TAU};

/// A magnet's flux shape (module documentation).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FluxShape {
    /// Odd flux harmonics `(n, h_n, a_n)` of phase a, per unit of the fundamental (`a_n` in
    /// rad).
    pub harmonics: Vec<(u16, f64, f64)>,
    /// `g`: phase b's flux is `1 + g` times phase a's.
    pub g: f64,
}

impl FluxShape {
    /// The sine motor: no harmonics, equal phases.
    pub fn sine() -> Self {
        Self::default()
    }

    /// `(λ_a, λ_b)`: the per-unit flux linkages at `θe`.
    pub fn linkage(&self, te: f64) -> (f64, f64) {
        let (mut la, mut lb) = (te.cos(), te.sin());
        for &(n, h, a) in &self.harmonics {
            let nf = f64::from(n);
            la += h * (nf * te + a).cos();
            lb += h * (nf * te + a - nf * FRAC_PI_2).cos();
        }
        (la, (1.0 + self.g) * lb)
    }

    /// `(λ_a', λ_b')`: the derivatives of the per-unit flux linkages by `θe`.
    pub fn slopes(&self, te: f64) -> (f64, f64) {
        let (mut da, mut db) = (-te.sin(), te.cos());
        for &(n, h, a) in &self.harmonics {
            let nf = f64::from(n);
            da -= nf * h * (nf * te + a).sin();
            db -= nf * h * (nf * te + a - nf * FRAC_PI_2).sin();
        }
        (da, (1.0 + self.g) * db)
    }
}

/// The torque ripple of `torque(θe, i_a, i_b)` (N·m, motor and detent) at rotor-frame
/// currents `(i_d, i_q)` (`i_a = i_d cos θe − i_q sin θe`, `i_b = i_d sin θe + i_q cos θe`):
/// `(order, A, φ)` with the torque's periodic part `−Σ A sin(k·θe + φ)` (the detent's
/// convention), orders 1..=`max_order`, by a DFT over `points` angles of one electrical
/// period.
pub fn ripple(
    torque: impl Fn(f64, f64, f64) -> f64,
    i_d: f64,
    i_q: f64,
    max_order: u16,
    points: usize,
) -> Vec<(u16, f64, f64)> {
    let tau: Vec<(f64, f64)> = (0..points)
        .map(|j| {
            let te = TAU * j as f64 / points as f64;
            let (s, c) = te.sin_cos();
            (te, torque(te, i_d * c - i_q * s, i_d * s + i_q * c))
        })
        .collect();
    (1..=max_order)
        .map(|k| {
            let kf = f64::from(k);
            let (mut bs, mut bc) = (0.0, 0.0);
            for &(te, t) in &tau {
                bs += t * (kf * te).sin();
                bc += t * (kf * te).cos();
            }
            let (bs, bc) = (2.0 * bs / points as f64, 2.0 * bc / points as f64);
            // −A sin(kθ + φ) = −A cos φ · sin kθ − A sin φ · cos kθ.
            (k, bs.hypot(bc), (-bc).atan2(-bs))
        })
        .collect()
}
