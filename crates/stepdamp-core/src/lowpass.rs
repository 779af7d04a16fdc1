//! First-order low-pass filter `y ← y + α (x − y)`, `α = 1 − exp(−2π fc Ts)`.
//!
//! Exact discretisation of `τ dy/dt = x − y` for a piecewise-constant input: the −3 dB
//! corner is at `fc` for `fc ≪ 1/Ts`. Cost: 1 multiply, 2 adds.

/// Filter coefficient, computed once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LowPass {
    alpha: f32,
}

impl LowPass {
    /// A filter with corner `corner_hz` sampled every `period_s`. `corner_hz ≤ 0` or
    /// non-finite gives a pass-through filter (α = 1).
    pub fn new(corner_hz: f32, period_s: f32) -> Self {
        let alpha = if corner_hz.is_finite() && corner_hz > 0.0 {
            1.0 - libm::expf(-core::f32::consts::TAU * corner_hz * period_s)
        } else {
            1.0
        };
        LowPass { alpha }
    }

    /// The coefficient α in (0, 1].
    pub fn alpha(&self) -> f32 {
        self.alpha
    }

    /// Feeds `x` into the filter state `y` and returns the new output.
    #[inline]
    pub fn update(&self, y: &mut f32, x: f32) -> f32 {
        *y += self.alpha * (x - *y);
        *y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_response_reaches_63_percent_after_one_time_constant() {
        let fc = 100.0;
        let ts = 1.0 / 20_000.0;
        let lp = LowPass::new(fc, ts);
        let tau = 1.0 / (core::f32::consts::TAU * fc);
        let n = libm::roundf(tau / ts) as usize;
        let mut y = 0.0;
        for _ in 0..n {
            lp.update(&mut y, 1.0);
        }
        assert!((y - (1.0 - libm::expf(-1.0))).abs() < 0.01, "{y}");
    }

    #[test]
    fn zero_corner_passes_through() {
        let lp = LowPass::new(0.0, 1e-4);
        let mut y = 0.0;
        assert_eq!(lp.update(&mut y, 3.5), 3.5);
    }
}
