//! Spectrum of a torque against electrical angle: amplitude per harmonic order, for the
//! report's "effort ripple before/after" plot.
//!
//! Samples `(θe, value)` are averaged in `bins` equal bins over one electrical period
//! (`θe` taken modulo 2π), empty bins filled by periodic linear interpolation, and the
//! bin means transformed with a real FFT (`realfft`). Order `k` has amplitude
//! `2|X_k|/bins` (order 0: the mean). Binning attenuates order `k` by
//! `sinc(π·k/bins)`: under 0.3 % for `k ≤ bins/20`.

use realfft::RealFftPlanner;
use std::f64::consts::TAU;

/// Amplitudes of orders `0..=max_order` (index = order) of `values` against the
/// electrical angles `theta_e_rad`, binned in `bins` bins (≥ 2·max_order + 2, even).
/// Returns an empty vector when there are no samples.
pub fn order_spectrum(theta_e_rad: &[f64], values: &[f64], max_order: usize, bins: usize) -> Vec<f64> {
    let bins = (bins.max(2 * max_order + 2) + 1) & !1;
    if theta_e_rad.is_empty() || values.is_empty() {
        return Vec::new();
    }
    let mut sum = vec![0.0; bins];
    let mut count = vec![0usize; bins];
    for (&th, &v) in theta_e_rad.iter().zip(values) {
        let b = ((th.rem_euclid(TAU) / TAU * bins as f64) as usize).min(bins - 1);
        sum[b] += v;
        count[b] += 1;
    }
    let filled: Vec<usize> = (0..bins).filter(|&b| count[b] > 0).collect();
    let mut mean: Vec<f64> = (0..bins).map(|b| if count[b] > 0 { sum[b] / count[b] as f64 } else { 0.0 }).collect();
    if filled.len() < bins && !filled.is_empty() {
        for b in 0..bins {
            if count[b] > 0 {
                continue;
            }
            // Nearest filled bins on each side, periodically.
            let next = filled.iter().copied().find(|&f| f > b).unwrap_or(filled[0] + bins);
            let prev = filled
                .iter()
                .rev()
                .copied()
                .find(|&f| f < b)
                .map_or(filled[filled.len() - 1] as isize - bins as isize, |f| f as isize);
            let (vp, vn) = (mean[prev.rem_euclid(bins as isize) as usize], mean[next % bins]);
            let f = (b as isize - prev) as f64 / (next as isize - prev) as f64;
            mean[b] = vp + f * (vn - vp);
        }
    }
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(bins);
    let mut out = fft.make_output_vec();
    if fft.process(&mut mean, &mut out).is_err() {
        return Vec::new();
    }
    (0..=max_order.min(bins / 2))
        .map(|k| if k == 0 { out[0].re / bins as f64 } else { 2.0 * out[k].norm() / bins as f64 })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pure_harmonic_shows_at_its_order() {
        let th: Vec<f64> = (0..10_000).map(|i| i as f64 * 0.0123).collect();
        let v: Vec<f64> = th.iter().map(|t| 0.5 + 0.02 * (4.0 * t + 0.3).sin()).collect();
        let s = order_spectrum(&th, &v, 8, 256);
        assert!((s[0] - 0.5).abs() < 1e-3);
        assert!((s[4] - 0.02).abs() < 1e-4, "{s:?}");
        assert!(s[1] < 1e-4 && s[2] < 1e-4 && s[8] < 1e-4);
    }
}
