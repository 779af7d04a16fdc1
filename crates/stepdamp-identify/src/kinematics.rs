//! Speed and acceleration of the rotor from a quantised encoder angle.
//!
//! The encoder angle `θ_fb` is a staircase: the true angle plus a quantisation error of at
//! most half a count that repeats once per count. Differentiating it directly gives spikes
//! at every count edge. This module removes the straight line through the log (the mean
//! speed, found by least squares), low-passes the rest with a second-order Butterworth run
//! forwards and backwards (zero phase, fourth-order roll-off), adds the line back, and
//! takes central differences: `ω = dθ/dt`, `α = d²θ/dt²`.
//!
//! The corner is chosen per log ([`corner_hz`]): a quarter of the count rate (so the
//! staircase is attenuated about 250-fold in angle), but never below five times the
//! frequency of the highest detent harmonic of interest (so that harmonic keeps
//! `1/(1 + (1/5)⁴) > 99.8 %` of its amplitude, with no phase shift). Ends of the log within
//! three time constants of the filter are marked unreliable ([`Kinematics::edge`]).
//!
//! Cost: two passes of a biquad and one of differences, ~10 ns per sample.

use std::f64::consts::{PI, TAU};

/// Speed and acceleration estimates of one log.
#[derive(Clone, Debug, PartialEq)]
pub struct Kinematics {
    /// Smoothed speed `ω` in rad/s (mechanical).
    pub omega_rad_s: Vec<f64>,
    /// Smoothed acceleration `dω/dt` in rad/s².
    pub alpha_rad_s2: Vec<f64>,
    /// Mean speed of the log in rad/s: slope of the least-squares line through `θ_fb(t)`.
    pub mean_speed_rad_s: f64,
    /// Samples at each end affected by the filter's start-up (exclude them from fits).
    pub edge: usize,
    /// The low-pass corner used, in Hz.
    pub corner_hz: f64,
}

/// The corner of the smoothing filter for a log at `mean_speed_rad_s` with an encoder of
/// `counts_per_rev` counts (`None`: unknown) and highest harmonic `max_order` of `Nr`
/// pole pairs, sampled at `sample_hz`: `max(count rate / 4, 5 × highest harmonic
/// frequency)`, at most `0.2 × sample_hz`.
pub fn corner_hz(
    mean_speed_rad_s: f64,
    counts_per_rev: Option<u32>,
    max_order: u16,
    pole_pairs: u16,
    sample_hz: f64,
) -> f64 {
    let w = mean_speed_rad_s.abs();
    let harmonic_hz = f64::from(max_order.max(1)) * f64::from(pole_pairs) * w / TAU;
    let count_hz = counts_per_rev.map_or(0.0, |c| f64::from(c) * w / TAU);
    (0.25 * count_hz).max(5.0 * harmonic_hz).max(1.0).min(0.2 * sample_hz)
}

/// Least-squares line `θ ≈ θ0 + ω̄ (t − t̄)`: returns `(θ̄, t̄, ω̄)`.
pub fn line_fit(t: &[f64], theta: &[f64]) -> (f64, f64, f64) {
    let n = t.len().max(1) as f64;
    let tm = t.iter().sum::<f64>() / n;
    let thm = theta.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (&ti, &yi) in t.iter().zip(theta) {
        let dt = ti - tm;
        sxy += dt * (yi - thm);
        sxx += dt * dt;
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    (thm, tm, slope)
}

/// Estimates `ω` and `α` from `θ_fb(t)`; the low-pass corner is `corner_hz` (see
/// [`corner_hz`]). `t` must be increasing and roughly uniform (the filter runs on the
/// sample index at the median period; the differences use the actual times).
pub fn estimate(t: &[f64], theta: &[f64], corner: f64) -> Kinematics {
    let n = t.len();
    let (thm, tm, w) = line_fit(t, theta);
    if n < 3 {
        return Kinematics {
            omega_rad_s: vec![w; n],
            alpha_rad_s2: vec![0.0; n],
            mean_speed_rad_s: w,
            edge: n,
            corner_hz: corner,
        };
    }
    let mut r: Vec<f64> = t.iter().zip(theta).map(|(&ti, &yi)| yi - thm - w * (ti - tm)).collect();
    let (fs, fc) = smooth(t, &mut r, corner);
    let mut omega = vec![0.0; n];
    let mut alpha = vec![0.0; n];
    for i in 1..n - 1 {
        let (h0, h1) = (t[i] - t[i - 1], t[i + 1] - t[i]);
        let (d0, d1) = ((r[i] - r[i - 1]) / h0, (r[i + 1] - r[i]) / h1);
        omega[i] = w + (d0 * h1 + d1 * h0) / (h0 + h1);
        alpha[i] = 2.0 * (d1 - d0) / (h0 + h1);
    }
    omega[0] = omega[1];
    omega[n - 1] = omega[n - 2];
    alpha[0] = alpha[1];
    alpha[n - 1] = alpha[n - 2];
    // A Butterworth biquad settles to ~1 % in about 1.5 periods of its corner; take three.
    let edge = ((3.0 * fs / fc).ceil() as usize).min(n);
    Kinematics { omega_rad_s: omega, alpha_rad_s2: alpha, mean_speed_rad_s: w, edge, corner_hz: fc }
}

/// Low-passes `x` (sampled at times `t`) in place with the zero-phase filter of [`estimate`]
/// at `corner` Hz, so that a signal smoothed here lines up sample for sample with the `ω`
/// and `α` of [`estimate`]. Returns the sample rate used (1 / median step) and the corner
/// actually used, Hz.
pub fn smooth(t: &[f64], x: &mut [f64], corner: f64) -> (f64, f64) {
    let fs = 1.0 / median_step(t);
    let fc = corner.min(0.45 * fs).max(1e-6 * fs);
    let bq = Biquad::lowpass(fc / fs);
    bq.run_forward(x);
    x.reverse();
    bq.run_forward(x);
    x.reverse();
    (fs, fc)
}

/// Gain of the zero-phase filter of [`smooth`] (corner `fc`, sample rate `fs`, both Hz) at
/// `f` Hz: `|H|²` of the bilinear Butterworth biquad, `1 / (1 + (tan(πf/fs) / tan(πfc/fs))⁴)`.
pub fn smooth_gain(f: f64, fc: f64, fs: f64) -> f64 {
    let x = (PI * f / fs).tan() / (PI * fc / fs).tan();
    1.0 / (1.0 + x.powi(4))
}

/// Median of the time steps in s.
pub fn median_step(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return 1.0;
    }
    let mid = d.len() / 2;
    *d.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Second-order Butterworth low-pass (bilinear transform, pre-warped), direct form II
/// transposed.
#[derive(Clone, Copy, Debug)]
struct Biquad {
    b0: f64,
    b1: f64,
    b2: f64,
    a1: f64,
    a2: f64,
}

impl Biquad {
    /// `f` = corner / sample rate, in (0, 0.5).
    fn lowpass(f: f64) -> Self {
        let k = (PI * f).tan();
        let q = std::f64::consts::FRAC_1_SQRT_2;
        let norm = 1.0 / (1.0 + k / q + k * k);
        let b0 = k * k * norm;
        Biquad { b0, b1: 2.0 * b0, b2: b0, a1: 2.0 * (k * k - 1.0) * norm, a2: (1.0 - k / q + k * k) * norm }
    }

    /// Filters `x` in place, starting from the steady state of its first sample.
    fn run_forward(&self, x: &mut [f64]) {
        let Some(&x0) = x.first() else { return };
        // Steady state for a constant input x0 (DC gain 1): y = x0.
        let mut z1 = x0 * (1.0 - self.b0);
        let mut z2 = x0 * (self.b2 - self.a2);
        for v in x.iter_mut() {
            let xin = *v;
            let y = self.b0 * xin + z1;
            z1 = self.b1 * xin - self.a1 * y + z2;
            z2 = self.b2 * xin - self.a2 * y;
            *v = y;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quantised_ramp_with_ripple_gives_its_speed_and_acceleration() {
        // θ = ω̄ t + a sin(Ω t), quantised to 4000 counts/rev; 20 kHz.
        let (w, a, big_w) = (1.0, 2e-3, 2.0 * TAU * 8.0);
        let q = TAU / 4000.0;
        let t: Vec<f64> = (0..40_000).map(|i| i as f64 * 5e-5).collect();
        let th: Vec<f64> = t.iter().map(|&t| (((w * t + a * (big_w * t).sin()) / q).floor() + 0.5) * q).collect();
        let c = corner_hz(w, Some(4000), 4, 50, 20_000.0);
        let k = estimate(&t, &th, c);
        assert!((k.mean_speed_rad_s - w).abs() < 2e-3, "{}", k.mean_speed_rad_s);
        // Project the acceleration onto the ripple: −a Ω² sin(Ω t).
        let (mut s, mut n) = (0.0, 0.0);
        for (ti, a) in t.iter().zip(&k.alpha_rad_s2).take(t.len() - k.edge).skip(k.edge) {
            s += a * (big_w * ti).sin();
            n += 1.0;
        }
        let amp = -2.0 * s / n;
        let want = a * big_w * big_w;
        assert!((amp - want).abs() < 0.02 * want, "α ripple {amp}, want {want}");
    }

    #[test]
    fn smoothing_a_sine_scales_it_by_the_stated_gain() {
        let fs = 20_000.0;
        let t: Vec<f64> = (0..40_000).map(|i| f64::from(i) / fs).collect();
        for f in [10.0, 100.0, 300.0] {
            let mut x: Vec<f64> = t.iter().map(|&t| (TAU * f * t).sin()).collect();
            let (_, fc) = smooth(&t, &mut x, 200.0);
            let mid = 20_000;
            let amp = x[mid..mid + 2000].iter().zip(&t[mid..]).map(|(v, &t)| v * (TAU * f * t).sin()).sum::<f64>()
                * 2.0
                / 2000.0;
            let g = smooth_gain(f, fc, fs);
            assert!((amp - g).abs() < 2e-3, "{f} Hz: {amp} vs {g}");
        }
    }

    #[test]
    fn a_steady_biquad_passes_a_constant() {
        let bq = Biquad::lowpass(0.01);
        let mut x = vec![3.0; 100];
        bq.run_forward(&mut x);
        assert!(x.iter().all(|v| (v - 3.0).abs() < 1e-12));
    }
}
