//! PI current controller with anti-windup.
//!
//! `u = Kp·e + I`, `I ← I + Ki·Ts·e`. Gains from the winding: `Kp = L·ωc`, `Ki = R·ωc`
//! cancel the winding pole `R/L`, so the closed current loop is first order with bandwidth
//! `ωc` (as long as `ωc ≪ 2π/Ts`).
//!
//! Anti-windup is conditional integration with a hard bound: while the output is limited
//! the integrator only moves when the error would pull the output back inside, and it never
//! leaves `[−bound, bound]` (callers pass the voltage the bus can always make). So after any
//! saturation, however long, the integrator holds at most `bound` and the loop recovers in
//! a few time constants. Cost: 3 multiplies, 3 adds, 2 compares.

/// PI gains, fixed at configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pi {
    /// Proportional gain (output units per error unit; V/A for a current loop).
    pub kp: f32,
    /// Integral gain times the sample period (output units per error unit per period).
    pub ki_ts: f32,
}

impl Pi {
    /// Current-loop gains for a winding of `resistance_ohm`, `inductance_h` and a closed
    /// loop bandwidth of `bandwidth_hz`, sampled every `period_s`.
    pub fn for_winding(resistance_ohm: f32, inductance_h: f32, bandwidth_hz: f32, period_s: f32) -> Self {
        let wc = core::f32::consts::TAU * bandwidth_hz;
        Pi { kp: inductance_h * wc, ki_ts: resistance_ohm * wc * period_s }
    }

    /// The output before limiting, for error `e` and integrator `integral`
    /// (the integral term includes this period's error).
    #[inline]
    pub fn output(&self, integral: f32, e: f32) -> f32 {
        self.kp * e + integral + self.ki_ts * e
    }

    /// Commits the integrator after the caller limited the output `unlimited` (from
    /// [`Pi::output`]): integrate unless limited and the error pushes further out; keep
    /// `|integral| ≤ bound`. An integration that gives a non-finite value (NaN or infinite
    /// error or integrator) restarts the integrator from zero, as does a non-finite
    /// integrator that is held.
    #[inline]
    pub fn commit(&self, integral: &mut f32, e: f32, unlimited: f32, limited: bool, bound: f32) {
        if !limited || e * unlimited < 0.0 {
            // Test finiteness before bounding: `f32::max` drops a NaN operand, so bounding
            // first would turn a NaN error into `−bound` instead of a restart from zero.
            let x = *integral + self.ki_ts * e;
            *integral = if x.is_finite() { crate::bound(x, -bound, bound) } else { 0.0 };
        } else if !integral.is_finite() {
            *integral = 0.0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A scalar loop around a first-order plant `L di/dt = u − R i`, output clamped to ±umax.
    fn run(pi: &Pi, integral: &mut f32, i: &mut f32, target: f32, umax: f32, n: usize) {
        let (r, l, ts) = (0.9f32, 2.5e-3f32, 5e-5f32);
        for _ in 0..n {
            let e = target - *i;
            let u0 = pi.output(*integral, e);
            let u = u0.max(-umax).min(umax);
            pi.commit(integral, e, u0, u != u0, umax);
            // Exact update of the plant over one period.
            let a = libm::expf(-r / l * ts);
            *i = *i * a + u / r * (1.0 - a);
        }
    }

    #[test]
    fn unsaturated_loop_tracks_a_step_in_a_few_time_constants() {
        let pi = Pi::for_winding(0.9, 2.5e-3, 1500.0, 5e-5);
        let (mut integ, mut i) = (0.0, 0.0);
        // 1 ms ≈ 9 time constants of a 1.5 kHz loop.
        run(&pi, &mut integ, &mut i, 1.9, 1e6, 20);
        assert!((i - 1.9).abs() < 0.01, "{i}");
    }

    #[test]
    fn integrator_does_not_wind_up_during_long_saturation() {
        let pi = Pi::for_winding(0.9, 2.5e-3, 1500.0, 5e-5);
        // Impossible target: 100 A with 10 V on 0.9 Ω. Run briefly and for a long time.
        let (mut a, mut ia) = (0.0, 0.0);
        run(&pi, &mut a, &mut ia, 100.0, 10.0, 100);
        let (mut b, mut ib) = (0.0, 0.0);
        run(&pi, &mut b, &mut ib, 100.0, 10.0, 100_000);
        assert!(b.abs() <= 10.0);
        // Then ask for 1 A: the long-saturated loop recovers like the brief one, within
        // 10 ms (3.5 winding time constants).
        run(&pi, &mut a, &mut ia, 1.0, 10.0, 200);
        run(&pi, &mut b, &mut ib, 1.0, 10.0, 200);
        assert!((ia - 1.0).abs() < 0.02 && (ib - 1.0).abs() < 0.02, "{ia} {ib}");
    }

    #[test]
    fn a_non_finite_error_restarts_the_integrator_from_zero() {
        let pi = Pi::for_winding(0.9, 2.5e-3, 1500.0, 5e-5);
        for e in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            // Not limited: the sum is non-finite, so the integrator restarts at 0 (not ±bound).
            let mut integ = 1.5f32;
            let u = pi.output(integ, e);
            pi.commit(&mut integ, e, u, false, 10.0);
            assert_eq!(integ, 0.0, "e = {e}");
        }
        // Limited, with an infinite error that would pull back inside: same.
        for e in [f32::INFINITY, f32::NEG_INFINITY] {
            let mut integ = 1.5f32;
            pi.commit(&mut integ, e, -e, true, 10.0);
            assert_eq!(integ, 0.0, "e = {e}, limited");
        }
        // Limited with a NaN error: no evidence it pulls back inside, so the (finite)
        // integrator is held.
        let mut integ = 1.5f32;
        pi.commit(&mut integ, f32::NAN, 20.0, true, 10.0);
        assert_eq!(integ, 1.5);
        // A NaN integrator held by a limited output restarts too.
        let mut integ = f32::NAN;
        pi.commit(&mut integ, 1.0, 50.0, true, 10.0);
        assert_eq!(integ, 0.0);
        // A finite step still saturates at the bound.
        let mut integ = 9.9f32;
        pi.commit(&mut integ, 1e6, 1.0, false, 10.0);
        assert_eq!(integ, 10.0);
    }

    proptest! {
        #[test]
        fn integrator_stays_bounded_for_any_error_sequence(
            errs in proptest::collection::vec(proptest::num::f32::ANY, 1..200),
            bound in 0.0f32..100.0
        ) {
            let pi = Pi::for_winding(0.9, 2.5e-3, 1500.0, 5e-5);
            let mut integ = 0.0f32;
            for e in errs {
                let u0 = pi.output(integ, e);
                let u = u0.max(-bound).min(bound);
                pi.commit(&mut integ, e, u0, u != u0, bound);
                prop_assert!(integ.is_finite() && integ.abs() <= bound);
            }
        }
    }
}
