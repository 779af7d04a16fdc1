//! The print head between the rotor and the accelerometer: [`HeadModel`] lives in
//! [`stepdamp_accel::head`] (the one home of its transfer function, re-exported here); this
//! module runs its belt mode in the time domain for the simulated printer
//! (`docs/accelerometer.md#simulated-printer`).
//!
//! **Approximations** (as [`stepdamp_accel::head`] states them): the carriage is coupled
//! **rigidly** to the rotor for the motor's dynamics (`m·r²` added to `J` in the motor
//! simulation); the head's acceleration is the rotor's angular acceleration times `r` through
//! the belt mode, a second-order low-pass at `ω_b = √(k/m)` with damping ratio `ζ`
//! ([`HeadModel::transfer`]). The belt's reaction on the rotor is left out.

pub use stepdamp_accel::head::{HeadError, HeadModel};

/// The belt mode in the time domain: `y'' + 2ζω_b·y' + ω_b²·y = ω_b²·u` with `u = r·α`
/// held over each step, integrated with one RK4 step per control period. `y` is the head
/// acceleration (m/s²). Held at its mean over the step (centred on the step's middle), the
/// input stands for the continuous one without delay: the output is the head's acceleration
/// at the step's end.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BeltFilter {
    wb: f64,
    zeta: f64,
    r: f64,
    y: f64,
    dy: f64,
}

impl BeltFilter {
    pub(crate) fn new(h: &HeadModel) -> Self {
        BeltFilter { wb: h.belt_omega_rad_s(), zeta: h.belt_damping_ratio, r: h.pulley_radius_m, y: 0.0, dy: 0.0 }
    }

    /// Advances by `dt` (s) with the rotor's mean angular acceleration `alpha` (rad/s²)
    /// over the step; returns the head acceleration (m/s²) at its end.
    pub(crate) fn step(&mut self, alpha: f64, dt: f64) -> f64 {
        let u = self.r * alpha;
        let (wb, z) = (self.wb, self.zeta);
        let f = |y: f64, dy: f64| (dy, wb * wb * (u - y) - 2.0 * z * wb * dy);
        let k1 = f(self.y, self.dy);
        let k2 = f(self.y + 0.5 * dt * k1.0, self.dy + 0.5 * dt * k1.1);
        let k3 = f(self.y + 0.5 * dt * k2.0, self.dy + 0.5 * dt * k2.1);
        let k4 = f(self.y + dt * k3.0, self.dy + dt * k3.1);
        self.y += dt / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
        self.dy += dt / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
        self.y
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;
    use stepdamp_accel::Complex;

    #[test]
    fn the_belt_filter_follows_the_transfer_function_in_steady_state() {
        let h = HeadModel::default();
        let (dt, w) = (1.0 / 20_000.0, TAU * 400.0);
        let mut f = BeltFilter::new(&h);
        // Drive with sin(w t) held over each step (its mean over the step, dated at its middle).
        let (mut s, mut c) = (0.0, 0.0);
        let n = 20_000;
        for k in 0..n {
            let mid = (k as f64 + 0.5) * dt;
            let y = f.step((w * mid).sin(), dt);
            if k >= n / 2 {
                let end = (k + 1) as f64 * dt;
                s += y * (w * end).sin();
                c += y * (w * end).cos();
            }
        }
        let m = (n / 2) as f64;
        let got = Complex::new(2.0 * s / m, 2.0 * c / m);
        let want = h.transfer(w);
        assert!((got - want).abs() < 0.01 * want.abs(), "{got:?} vs {want:?}");
    }
}
