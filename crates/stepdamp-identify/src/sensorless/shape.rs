//! The flux shape without a sensor: what the flux circle's radius says about the magnet
//! flux linkage's harmonics (docs/sensorless.md#the-flux-shape-without-a-sensor).
//!
//! With the shape of docs/design.md#real-motors-flux-harmonics, the linkage vector per unit
//! of `Km/Nr` is, to first order in the harmonics (`X_n = h_n·e^{j·a_n}`),
//!
//! ```text
//! ψ_a + j·ψ_b = e^{jθe}·[1 + X₃*·e^{−j4θe} + X₅·e^{j4θe} + (g/2)·(1 − e^{−j2θe})]
//! |ψ| = 1 + g/2 − (g/2)·cos 2θe + Re[(X₃ + X₅)·e^{j4θe}]
//! ```
//!
//! so the radius's 2nd harmonic gives `g` and its 4th the sum `X₃ + X₅`. The split of that
//! sum between the third and the fifth is not observable below resonance: the estimated angle
//! is the linkage's direction, which the harmonics turn by `Im[(X₅ − X₃)·e^{j4θe}]`,
//! and in open loop the rotor's load angle and that turn add up to `4·(X₃ + X₅)` — the same
//! sum. The plan's turn runs, far above resonance, split it ([`super::turn`]); without them
//! [`THIRD_SHARE`] splits it by what measured motors show.
//!
//! Each log's radius gives its own estimate (a least-squares fit on `θe`); the estimates'
//! spread over the logs gives the 95 % intervals (Student's t), so a drift of the flux
//! integral shared by a log's samples is not mistaken for precision.

use crate::emf::{AMPLITUDE_TEST, stands_out};
use crate::fit::{Estimate, polar_with_ci};
use nalgebra::{SMatrix, SVector};
use stepdamp_profile::flux::{FluxHarmonic, FluxSection};

/// The share of the measured `X₃ + X₅` given to the third, `σ₃²/(σ₃² + σ₅²)`: the mean of
/// the two given the sum, for independent harmonics of typical size `σ₃ = 0.95 %` and
/// `σ₅ = 0.35 %`, the middles of the ranges measured on hybrid steppers (thirds 0.4–1.5 %,
/// fifths 0.1–0.6 %: `stepdamp_profile::flux::flux_limits`).
pub const THIRD_SHARE: f64 = 0.88;

/// Regressors of the radius fit: a constant, then `cos kθe`, `sin kθe` for these orders (1
/// and 8 are nuisances: the centre's interpolation error, the seventh).
const ORDERS: [f64; 4] = [1.0, 2.0, 4.0, 8.0];
/// Number of regressors.
const P: usize = 1 + 2 * ORDERS.len();

/// The least-squares coefficients of `y` on the regressors above (a constant, then
/// `cos kθe`, `sin kθe` for `k` in [`ORDERS`]) at the angles `theta_e_rad` (electrical rad,
/// the same length); `None` when the samples do not determine them (fewer than a few per
/// regressor, or a singular design).
pub(super) fn fit_orders(theta_e_rad: &[f64], y: &[f64]) -> Option<SVector<f64, P>> {
    if y.len() != theta_e_rad.len() || y.len() < 10 * P {
        return None;
    }
    let mut a = SMatrix::<f64, P, P>::zeros();
    let mut b = SVector::<f64, P>::zeros();
    for (&th, &r) in theta_e_rad.iter().zip(y) {
        let mut x = SVector::<f64, P>::zeros();
        x[0] = 1.0;
        for (i, k) in ORDERS.iter().enumerate() {
            let (s, c) = (k * th).sin_cos();
            x[1 + 2 * i] = c;
            x[2 + 2 * i] = s;
        }
        a += x * x.transpose();
        b += x * r;
    }
    a.lu().solve(&b)
}

/// One log's radius harmonics per unit of its mean radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RadiusHarmonics {
    /// Samples fitted.
    pub samples: usize,
    /// `(cos 2θe, sin 2θe)` coefficients.
    pub order2: (f64, f64),
    /// `(cos 4θe, sin 4θe)` coefficients.
    pub order4: (f64, f64),
}

impl RadiusHarmonics {
    /// The least-squares fit of `radius` (after the standstill) on the regressors above at
    /// the angles `theta_e_rad` (the same length); `None` when the samples do not
    /// determine it (fewer than a few per regressor, or a singular design).
    pub fn of(theta_e_rad: &[f64], radius: &[f64]) -> Option<Self> {
        let sol = fit_orders(theta_e_rad, radius)?;
        let mean = sol[0];
        (mean.is_finite() && mean > 0.0 && sol.iter().all(|v| v.is_finite())).then(|| RadiusHarmonics {
            samples: radius.len(),
            order2: (sol[3] / mean, sol[4] / mean),
            order4: (sol[5] / mean, sol[6] / mean),
        })
    }
}

/// The shape's error measured from the radius, over the logs (module documentation).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ShapeFit {
    /// `g` (phase b's flux over phase a's, minus 1) missing from the shape the angles were
    /// estimated with.
    pub phase_b_gain: Estimate,
    /// `|X₃ + X₅|` missing from that shape, per unit of the fundamental.
    pub sum_ratio: Estimate,
    /// `arg(X₃ + X₅)`, rad.
    pub sum_phase_rad: Estimate,
    /// The radius's `sin 2θe` coefficient per unit. A flux gain `g` makes only `cos 2θe`, so a
    /// term that stands out here is not the magnet's: a phase's current or voltage channel
    /// off in gain or timing, or `R` or `L` off (docs/sensorless.md#the-flux-shape-without-a-sensor).
    pub radius_sin2: Estimate,
    /// Logs the intervals come from.
    pub logs: usize,
}

impl ShapeFit {
    /// The estimate from each log's [`RadiusHarmonics`]; `None` with fewer than two logs
    /// (no spread to give an interval).
    pub fn of(per_log: &[RadiusHarmonics]) -> Option<ShapeFit> {
        let n = per_log.len();
        if n < 2 {
            return None;
        }
        let nf = n as f64;
        let t = student_t95(n - 1);
        let g: Vec<f64> = per_log.iter().map(|h| -2.0 * h.order2.0).collect();
        let (gm, gv) = mean_var(&g);
        let q: Vec<f64> = per_log.iter().map(|h| h.order2.1).collect();
        let (qm, qv) = mean_var(&q);
        // The phasor of `cos(4θe + a)` is `e^{ja}`: `c·cos − s·sin` has `(c, −s)`.
        let re: Vec<f64> = per_log.iter().map(|h| h.order4.0).collect();
        let im: Vec<f64> = per_log.iter().map(|h| -h.order4.1).collect();
        let (sum_ratio, sum_phase_rad) = mean_phasor(&re, &im);
        Some(ShapeFit {
            phase_b_gain: Estimate { value: gm, ci95: t * (gv / nf).sqrt() },
            sum_ratio,
            sum_phase_rad,
            radius_sin2: Estimate { value: qm, ci95: t * (qv / nf).sqrt() },
            logs: n,
        })
    }

    /// Whether anything stands out of the noise at 95 % (`g` outside its interval, the sum's
    /// amplitude above the χ²₂ test of `crate::emf`).
    pub fn significant(&self) -> (bool, bool) {
        (stands_out(&self.phase_b_gain, 1.0), stands_out(&self.sum_ratio, AMPLITUDE_TEST))
    }

    /// `section` with what stands out added: `g` to its gain, the sum split [`THIRD_SHARE`] :
    /// `1 − THIRD_SHARE` onto its third and fifth. Unchanged (bit for bit) when nothing does.
    pub fn corrected(&self, section: &FluxSection) -> FluxSection {
        let (g_out, sum_out) = self.significant();
        let mut out = section.clone();
        if g_out {
            out.phase_b_gain += self.phase_b_gain.value;
        }
        if sum_out {
            let (s, c) = self.sum_phase_rad.value.sin_cos();
            let (re, im) = (self.sum_ratio.value * c, self.sum_ratio.value * s);
            add_harmonic(&mut out, 3, THIRD_SHARE * re, THIRD_SHARE * im);
            add_harmonic(&mut out, 5, (1.0 - THIRD_SHARE) * re, (1.0 - THIRD_SHARE) * im);
        }
        out
    }

    /// The whole shape error against `base`, after the passes that gave `written`, with
    /// `self` the last pass's (what is left): values `written − base` plus what is left,
    /// intervals the last pass's (the noise is the same in every pass; the first pass alone
    /// is biased by the terms of second order: about −g² in `g`, 10⁻⁴ in the sum).
    pub fn total_since(&self, base: &FluxSection, written: &FluxSection) -> ShapeFit {
        let sum = |f: &FluxSection| {
            f.harmonics
                .iter()
                .filter(|h| h.order == 3 || h.order == 5)
                .fold((0.0, 0.0), |a, h| (a.0 + h.ratio * h.phase_rad.cos(), a.1 + h.ratio * h.phase_rad.sin()))
        };
        let (w, b) = (sum(written), sum(base));
        let (s, c) = self.sum_phase_rad.value.sin_cos();
        let (re, im) = (w.0 - b.0 + self.sum_ratio.value * c, w.1 - b.1 + self.sum_ratio.value * s);
        let ratio = re.hypot(im);
        ShapeFit {
            phase_b_gain: Estimate {
                value: written.phase_b_gain - base.phase_b_gain + self.phase_b_gain.value,
                ci95: self.phase_b_gain.ci95,
            },
            sum_ratio: Estimate { value: ratio, ci95: self.sum_ratio.ci95 },
            sum_phase_rad: Estimate {
                value: im.atan2(re),
                ci95: if ratio > 0.0 {
                    (self.sum_ratio.ci95 / ratio).min(std::f64::consts::PI)
                } else {
                    std::f64::consts::PI
                },
            },
            radius_sin2: self.radius_sin2,
            logs: self.logs,
        }
    }

    /// Whether the radius's `sin 2θe` term stands out of the noise at 95 % (see
    /// [`ShapeFit::radius_sin2`]).
    pub fn sin2_stands_out(&self) -> bool {
        stands_out(&self.radius_sin2, 1.0)
    }

    /// The measured terms [`ShapeFit::corrected`] leaves out (within the noise), by name.
    pub fn left_out(&self) -> Vec<&'static str> {
        let (g, sum) = self.significant();
        [(!g).then_some("phase_b_gain"), (!sum).then_some("harmonics 3 + 5")].into_iter().flatten().collect()
    }
}

/// Adds `re + j·im` to the phasor `h_n·e^{j·a_n}` of harmonic `order` (created if absent).
pub(super) fn add_harmonic(f: &mut FluxSection, order: u16, re: f64, im: f64) {
    let i = match f.harmonics.iter().position(|h| h.order == order) {
        Some(i) => i,
        None => {
            f.harmonics.push(FluxHarmonic { order, ratio: 0.0, phase_rad: 0.0 });
            f.harmonics.len() - 1
        }
    };
    let h = &mut f.harmonics[i];
    let (s, c) = h.phase_rad.sin_cos();
    let (x, y) = (h.ratio * c + re, h.ratio * s + im);
    h.ratio = x.hypot(y);
    h.phase_rad = y.atan2(x);
}

/// The mean of per-log phasors `re + j·im` (at least two) as amplitude and phase, with 95 %
/// intervals from their spread (Student's t with `n − 1` degrees of freedom).
pub(super) fn mean_phasor(re: &[f64], im: &[f64]) -> (Estimate, Estimate) {
    let nf = re.len() as f64;
    // Student's t over the 1.96 of `polar_with_ci`, squared onto the variances.
    let t = student_t95(re.len() - 1);
    let scale = (t / crate::fit::thresholds::Z_95).powi(2) / nf;
    let ((rm, rv), (im_m, iv)) = (mean_var(re), mean_var(im));
    let cov = re.iter().zip(im).map(|(a, b)| (a - rm) * (b - im_m)).sum::<f64>() / (nf - 1.0);
    polar_with_ci(rm, im_m, rv * scale, cov * scale, iv * scale)
}

/// Mean and sample variance (`n − 1`).
fn mean_var(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    (m, v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0))
}

/// Two-sided 95 % quantile of Student's t with `dof` degrees of freedom (tables; 1.96 from
/// 30 on, where the table is within 4 % of it).
fn student_t95(dof: usize) -> f64 {
    const T: [f64; 29] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145, 2.131,
        2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045,
    ];
    T.get(dof.wrapping_sub(1)).copied().unwrap_or(crate::fit::thresholds::Z_95)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A radius with a known 2nd and 4th harmonic (and a 1st and 8th) reads back.
    #[test]
    fn the_radius_fit_reads_back_its_harmonics() {
        let th: Vec<f64> = (0..5000).map(|i| 0.01 * f64::from(i)).collect();
        let r: Vec<f64> = th
            .iter()
            .map(|t| {
                0.006
                    * (1.0 + 0.01 * (2.0 * t).cos() - 0.004 * (4.0 * t).sin()
                        + 0.002 * t.cos()
                        + 0.001 * (8.0 * t).sin())
            })
            .collect();
        let h = RadiusHarmonics::of(&th, &r).unwrap();
        assert!((h.order2.0 - 0.01).abs() < 1e-12 && h.order2.1.abs() < 1e-12, "{h:?}");
        assert!(h.order4.0.abs() < 1e-12 && (h.order4.1 + 0.004).abs() < 1e-12, "{h:?}");
    }

    /// The radius of the shape's own linkage gives back its `g` and `X₃ + X₅` to first order.
    #[test]
    fn the_radius_of_a_flux_shape_gives_its_gain_and_the_sum_of_third_and_fifth() {
        let f = FluxSection {
            phase_b_gain: 0.03,
            harmonics: vec![
                FluxHarmonic { order: 3, ratio: 0.012, phase_rad: 0.4 },
                FluxHarmonic { order: 5, ratio: 0.004, phase_rad: -0.8 },
            ],
        };
        let shape = stepdamp_profile::flux::FluxShape::new(&f);
        let per_log: Vec<RadiusHarmonics> = (0..4)
            .map(|k| {
                let th: Vec<f64> = (0..4000).map(|i| 0.0031 * f64::from(i) + 0.1 * f64::from(k)).collect();
                let r: Vec<f64> = th
                    .iter()
                    .map(|&t| {
                        let (a, b) = shape.linkage(t);
                        a.hypot(b)
                    })
                    .collect();
                RadiusHarmonics::of(&th, &r).unwrap()
            })
            .collect();
        let fit = ShapeFit::of(&per_log).unwrap();
        let (re, im) = (0.012 * 0.4f64.cos() + 0.004 * (-0.8f64).cos(), 0.012 * 0.4f64.sin() + 0.004 * (-0.8f64).sin());
        // Second-order terms (products of 1 % harmonics and g) are ~1e-4.
        assert!((fit.phase_b_gain.value - 0.03).abs() < 1e-3, "{fit:?}");
        assert!((fit.sum_ratio.value - re.hypot(im)).abs() < 3e-4, "{fit:?}");
        assert!((fit.sum_phase_rad.value - im.atan2(re)).abs() < 0.03, "{fit:?}");
        let c = fit.corrected(&FluxSection::default());
        let third = c.harmonics.iter().find(|h| h.order == 3).unwrap();
        assert!((third.ratio - THIRD_SHARE * fit.sum_ratio.value).abs() < 1e-12);
    }

    /// A `sin 2θe` term in the radius, which no flux gain makes, is flagged; `g` is not
    /// taken from it.
    #[test]
    fn a_sin_2_theta_radius_term_is_flagged_and_not_taken_for_a_gain() {
        let h = |s2: f64| RadiusHarmonics { samples: 1000, order2: (0.0, s2), order4: (0.0, 0.0) };
        let fit = ShapeFit::of(&[h(0.0100), h(0.0102), h(0.0098), h(0.0101)]).unwrap();
        assert!(fit.sin2_stands_out(), "{fit:?}");
        assert_eq!(fit.phase_b_gain.value, 0.0);
        let quiet = ShapeFit::of(&[h(1e-4), h(-1e-4), h(0.5e-4), h(-0.5e-4)]).unwrap();
        assert!(!quiet.sin2_stands_out(), "{quiet:?}");
    }

    /// Nothing that stands out: the section comes back bit for bit.
    #[test]
    fn a_shape_error_within_the_noise_leaves_the_section_unchanged() {
        let h = |c2: f64, c4: f64| RadiusHarmonics { samples: 1000, order2: (c2, 0.0), order4: (c4, -c4) };
        let fit = ShapeFit::of(&[h(1e-4, 1e-4), h(-1e-4, -1e-4), h(0.5e-4, -0.5e-4)]).unwrap();
        let f =
            FluxSection { phase_b_gain: 0.01, harmonics: vec![FluxHarmonic { order: 3, ratio: 0.01, phase_rad: 0.2 }] };
        assert_eq!(fit.corrected(&f), f);
        assert_eq!(fit.left_out(), vec!["phase_b_gain", "harmonics 3 + 5"]);
    }
}
