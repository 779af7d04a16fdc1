//! The magnet flux linkage's shape from the back-EMF of a fast servo run
//! (docs/identification.md#the-flux-linkage-from-the-back-emf).
//!
//! # Why
//!
//! The ripple that grows with the current comes from the flux linkage's odd harmonics and
//! the phases' gain imbalance (docs/design.md#real-motors-flux-harmonics). The patent's
//! servo runs hold `i_d = 0` and a small `i_q`, so in their torque that part is 20–60×
//! smaller than in open loop at the holding current: a torque fit on them cannot see it.
//! The same flux linkage makes the back-EMF, `e = −Km·ω·S(θe)`, whose harmonics are those
//! of `S` at any current. A servo run fast enough for the back-EMF to stand well above the
//! resistive and inductive drops measures them directly, each phase on its own.
//!
//! # Model
//!
//! Over control period `k` (from `t_k` to `t_{k+1}`), with the logged mean applied voltage
//! `v̄_k` and the sampled currents `i_k`, `i_{k+1}`:
//!
//! ```text
//! v̄_k − R·(i_k + i_{k+1})/2 − L·(i_{k+1} − i_k)/Ts = ω·Σ_n [p_n·sin(nθ) + q_n·cos(nθ)] + c
//! ```
//!
//! with `θ`, `ω` the electrical angle and mechanical speed at the middle of the period (the
//! encoder angle smoothed as in [`crate::kinematics`]), orders `n` = 1 and the fitted odd
//! harmonics, and `c` a constant (a voltage offset of the drive). Linear in `p, q, c`: one
//! least-squares solve per phase ([`crate::lsq`], blocks of one electrical period). With
//! `S_a = Σ n·h_n·sin(nθ + a_n)` and `S_b = (1 + g)·Σ n·h_n·sin(nθ + a_n − nπ/2)`
//! ([`stepdamp_profile::flux`]):
//!
//! * phase a: `p_n + j·q_n = −Km·n·h_n·e^{j·a_n}`, so `Km = |p_1 + j·q_1|`;
//! * phase b: `p_n + j·q_n = −(1 + g)·Km·n·h_n·e^{j(a_n − nπ/2)}`, so `(1 + g)·Km = |p_1 + j·q_1|`.
//!
//! Each phase gives `h_n·e^{j·a_n}`; the result is their mean (the profile's model has one
//! shape for both), and a disagreement beyond the intervals is warned about. `R` and `L`
//! are the base profile's, not fitted: at constant speed and `i_q` the phase current is a
//! sinusoid at the fundamental, so `R·i` is collinear with the back-EMF's fundamental and
//! the two cannot be told apart; an error `ΔR` moves `Km` by `ΔR·i_q/(Km·ω)` (below 0.1 %
//! for the plan's run) and the harmonics not at all. The phase of phase a's fundamental,
//! `arg(−p_1 − j·q_1)`, is the offset between the drive's electrical angle and the flux
//! (a commutation offset); the harmonics' phases are given in the drive's angle, as the
//! detent's are.
//!
//! # Error bounds
//!
//! Intervals (95 %) from the covariance of [`crate::lsq`], by the delta method; they cover
//! noise, not bias. Bias not modelled: a drive's dead time distorts the applied voltage at
//! odd harmonics of the current (log the voltage measured at the terminals, or the
//! command corrected for dead time); iron losses.

use crate::fit::{Estimate, polar_with_ci};
use crate::kinematics;
use crate::log::{PhaseSignals, RunLog};
use crate::lsq::{self, Design};
use std::f64::consts::{FRAC_PI_2, TAU};
use std::fmt;
use stepdamp_profile::Profile;
use stepdamp_profile::flux::{FluxHarmonic, FluxSection};

/// A run whose electrical frequency (from its mean speed over the whole log) is at least
/// this many Hz is a back-EMF run. The plan's slow servo runs turn at 4–8 Hz electrical
/// (`patent-motor`), its back-EMF run at 175 Hz; at 40 Hz the back-EMF of a typical
/// hybrid stepper (Km 0.3 N·m/A, Nr 50) is 1.5 V, and its third harmonic at 1 % is 45 mV,
/// ten times the resistive drop of the current noise.
pub const EMF_MIN_ELECTRICAL_HZ: f64 = 40.0;

/// The odd harmonics fitted by default: the 3rd and 5th make the 4th-order ripple, the 7th
/// is fitted so that it does not leak into them.
pub const DEFAULT_FLUX_ORDERS: [u16; 3] = [3, 5, 7];

/// A steady sample's speed is within this fraction of the run's mean speed.
const STEADY_FRACTION: f64 = 0.2;

/// The angle's smoothing corner over the electrical frequency (see [`push_run`]).
const CORNER_PER_ELECTRICAL_HZ: f64 = 8.0;

/// Whether `log` turns fast enough for the back-EMF fit ([`EMF_MIN_ELECTRICAL_HZ`]) with a
/// rotor of `pole_pairs` pole pairs.
pub fn is_emf_run(log: &RunLog, pole_pairs: u16) -> bool {
    let d = log.duration_s();
    d > 0.0 && log.electrical_periods(pole_pairs) / d >= EMF_MIN_ELECTRICAL_HZ
}

/// Samples per period of the highest fitted harmonic a back-EMF run must have: fewer alias
/// it ([`fit_flux`] refuses such a run, naming its rate).
pub const MIN_SAMPLES_PER_HARMONIC: f64 = 4.0;

/// What the back-EMF fit needs from the base profile.
#[derive(Clone, Debug, PartialEq)]
pub struct EmfOptions {
    /// Rotor pole pairs `Nr`.
    pub pole_pairs: u16,
    /// Winding resistance, Ω (per phase, both alike).
    pub resistance_ohm: f64,
    /// Winding inductance, H.
    pub inductance_h: f64,
    /// The base's `Km`, N·m/A (compared with the back-EMF's).
    pub km_nm_per_a: f64,
    /// Odd flux harmonic orders to fit (3..=[`stepdamp_profile::flux::MAX_FLUX_ORDER`]).
    pub orders: Vec<u16>,
}

impl EmfOptions {
    /// The base profile's winding and [`DEFAULT_FLUX_ORDERS`].
    pub fn for_profile(base: &Profile) -> Self {
        EmfOptions {
            pole_pairs: base.motor.pole_pairs,
            resistance_ohm: base.motor.resistance_ohm,
            inductance_h: base.motor.inductance_h,
            km_nm_per_a: base.motor.km_nm_per_a,
            orders: DEFAULT_FLUX_ORDERS.to_vec(),
        }
    }
}

/// An amplitude (the magnitude of two noisy components) stands out of the noise at 95 % when
/// it exceeds `√χ²₂(0.95) = 2.448` standard deviations, i.e. 1.249 × the 95 % half-width of
/// [`polar_with_ci`] (1.96 σ); 1.96 σ alone would pass 15 % of pure noise.
pub(crate) const AMPLITUDE_TEST: f64 = 2.448 / 1.96;

/// Whether `e` stands out of the noise: `|value| > factor × ci95` (a NaN does not).
pub(crate) fn stands_out(e: &Estimate, factor: f64) -> bool {
    e.value.abs() > factor * e.ci95
}

/// One identified flux harmonic: `h_n·cos(n·θe + a_n)` in phase a's flux per unit of the
/// fundamental.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FluxHarmonicEstimate {
    /// Order `n` (odd).
    pub order: u16,
    /// `h_n`, relative to the fundamental (0.01 is 1 %).
    pub ratio: Estimate,
    /// `a_n`, rad.
    pub phase_rad: Estimate,
    /// `|h_a − h_b|` of the two phases' own estimates over the 95 % half-width of their
    /// difference (> 1: the phases' shapes differ beyond the noise).
    pub phase_disagreement: f64,
}

/// The flux section identified from the back-EMF, with its intervals.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FluxFit {
    /// Back-EMF constant of phase a, N·m/A (= V·s/rad).
    pub km_nm_per_a: Estimate,
    /// `g`: phase b's flux over phase a's, minus 1.
    pub phase_b_gain: Estimate,
    /// The drive's electrical angle minus the flux's (phase a's fundamental), rad.
    pub commutation_offset_rad: Estimate,
    /// The odd harmonics, in the options' order.
    pub harmonics: Vec<FluxHarmonicEstimate>,
    /// The runs used.
    pub runs: Vec<String>,
    /// Samples used per phase.
    pub samples: usize,
    /// RMS of the residual voltage, V (phase a, phase b).
    pub residual_rms_v: (f64, f64),
    /// The base profile's `Km`, N·m/A.
    pub base_km_nm_per_a: f64,
}

impl FluxFit {
    /// The `[motor.flux]` section: `g` and the harmonics that stand out of the noise at 95 %
    /// (`g` outside its interval; an amplitude above [`AMPLITUDE_TEST`] × its half-width); the
    /// others are left out (0). Writing a harmonic that is
    /// noise makes the controller feed forward that noise's ripple at the holding current:
    /// measured on `patent-motor` (a pure sine), 91.5× against 84.6× at the 4th-order
    /// resonance with the identified profile (docs/identification.md#the-flux-linkage-from-the-back-emf).
    pub fn section(&self) -> FluxSection {
        FluxSection {
            phase_b_gain: if stands_out(&self.phase_b_gain, 1.0) { self.phase_b_gain.value } else { 0.0 },
            harmonics: self
                .harmonics
                .iter()
                .filter(|h| stands_out(&h.ratio, AMPLITUDE_TEST))
                .map(|h| FluxHarmonic { order: h.order, ratio: h.ratio.value, phase_rad: h.phase_rad.value })
                .collect(),
        }
    }

    /// The fitted terms [`FluxFit::section`] leaves out (within the noise), by name.
    pub fn left_out(&self) -> Vec<String> {
        let g = (!stands_out(&self.phase_b_gain, 1.0)).then(|| "phase_b_gain".to_string());
        let mut out: Vec<String> = g.into_iter().collect();
        out.extend(
            self.harmonics
                .iter()
                .filter(|h| !stands_out(&h.ratio, AMPLITUDE_TEST))
                .map(|h| format!("harmonic {}", h.order)),
        );
        out
    }

    /// Cautions about the result: a `Km` or commutation offset off the base, phases whose
    /// harmonics disagree.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        let km = self.km_nm_per_a.value;
        if (km / self.base_km_nm_per_a - 1.0).abs() > 0.05 {
            w.push(format!(
                "the back-EMF gives Km = {km:.4} N·m/A, {:+.1} % off the base's {:.4}: the torques of the fit use the base's; check motor.km_nm_per_a",
                100.0 * (km / self.base_km_nm_per_a - 1.0),
                self.base_km_nm_per_a
            ));
        }
        if self.commutation_offset_rad.value.abs() > 0.05 {
            w.push(format!(
                "the drive's electrical angle is {:.3} rad off the flux's (a commutation offset): the harmonics' phases are in the drive's angle",
                self.commutation_offset_rad.value
            ));
        }
        for h in self.harmonics.iter().filter(|h| h.phase_disagreement > 1.0) {
            w.push(format!(
                "flux harmonic {}: the two phases disagree ({:.1} × the 95 % interval of their difference); the model has one shape for both, their mean is used",
                h.order, h.phase_disagreement
            ));
        }
        w
    }
}

impl fmt::Display for FluxFit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "flux linkage from the back-EMF ({} runs, {} samples per phase; residual {:.3} / {:.3} V):",
            self.runs.len(),
            self.samples,
            self.residual_rms_v.0,
            self.residual_rms_v.1
        )?;
        let (km, g, off) = (self.km_nm_per_a, self.phase_b_gain, self.commutation_offset_rad);
        writeln!(f, "  Km (phase a)          {:.4} ± {:.4} N·m/A", km.value, km.ci95)?;
        writeln!(f, "  phase_b_gain          {:+.4} ± {:.4}", g.value, g.ci95)?;
        writeln!(f, "  commutation offset    {:+.4} ± {:.4} rad", off.value, off.ci95)?;
        for h in &self.harmonics {
            writeln!(
                f,
                "  harmonic {:>2}           {:.5} ± {:.5} at {:+.3} ± {:.3} rad",
                h.order, h.ratio.value, h.ratio.ci95, h.phase_rad.value, h.phase_rad.ci95
            )?;
        }
        let left_out = self.left_out();
        if !left_out.is_empty() {
            writeln!(f, "  not written to the profile (within the noise at 95 %): {}", left_out.join(", "))?;
        }
        for w in self.warnings() {
            writeln!(f, "  warning: {w}")?;
        }
        Ok(())
    }
}

/// Why the back-EMF fit failed.
#[derive(Debug, thiserror::Error)]
pub enum EmfError {
    /// A fitted order that is not an odd harmonic the profile can hold.
    #[error("flux harmonic order {0}: must be odd, 3 to {max}", max = stepdamp_profile::flux::MAX_FLUX_ORDER)]
    Order(u16),
    /// The least-squares problem of a phase could not be solved.
    #[error("the back-EMF fit of phase {phase} over {runs}: {source}")]
    Solve {
        /// `a` or `b`.
        phase: char,
        /// The runs.
        runs: String,
        /// Why.
        source: lsq::LsqError,
    },
    /// A back-EMF run sampled too slowly for its highest fitted harmonic.
    #[error(
        "{run}: sampled at {rate_hz:.0} Hz, a back-EMF run needs at least {need_hz:.0} Hz ({MIN_SAMPLES_PER_HARMONIC} samples per period of its highest fitted flux harmonic); log every control period"
    )]
    SampleRate {
        /// The run.
        run: String,
        /// Its sample rate, Hz.
        rate_hz: f64,
        /// The rate it needs, Hz.
        need_hz: f64,
    },
    /// The fundamental came out too small to normalise by.
    #[error("the back-EMF fit over {0}: no back-EMF fundamental (is the motor turning, are the voltages logged?)")]
    NoFundamental(String),
}

/// Fits the flux section to the back-EMF runs among `logs` (those with phase signals that
/// are [`is_emf_run`]); `Ok(None)` when there are none.
pub fn fit_flux(logs: &[RunLog], o: &EmfOptions) -> Result<Option<FluxFit>, EmfError> {
    if let Some(&n) = o.orders.iter().find(|&&n| n < 3 || n % 2 == 0 || n > stepdamp_profile::flux::MAX_FLUX_ORDER) {
        return Err(EmfError::Order(n));
    }
    let runs: Vec<&RunLog> = logs.iter().filter(|l| l.phases.is_some() && is_emf_run(l, o.pole_pairs)).collect();
    if runs.is_empty() {
        return Ok(None);
    }
    let names = runs.iter().map(|l| l.source.as_str()).collect::<Vec<_>>().join(", ");
    let mut orders = vec![1u16];
    orders.extend(&o.orders);
    let nmax = f64::from(*orders.iter().max().unwrap_or(&1));
    for log in &runs {
        let (rate, f_e) =
            (1.0 / crate::kinematics::median_step(&log.t_s), log.electrical_periods(o.pole_pairs) / log.duration_s());
        let need = MIN_SAMPLES_PER_HARMONIC * nmax * f_e;
        if rate.partial_cmp(&need) == Some(std::cmp::Ordering::Less) || rate.is_nan() || need.is_nan() {
            return Err(EmfError::SampleRate { run: log.source.clone(), rate_hz: rate, need_hz: need });
        }
    }
    let p = 2 * orders.len() + 1;
    let (mut da, mut db) = (Design::new(p), Design::new(p));
    let mut block_base = 0u32;
    for log in &runs {
        block_base = push_run(log, o, &orders, &mut da, &mut db, block_base);
    }
    let solve = |d: &Design, phase: char| {
        lsq::solve(d).map_err(|source| EmfError::Solve { phase, runs: names.clone(), source })
    };
    let (sa, sb) = (solve(&da, 'a')?, solve(&db, 'b')?);
    combine(&sa, &sb, o, &orders, &runs, da.rows()).map(Some).ok_or(EmfError::NoFundamental(names))
}

/// Appends the rows of one back-EMF run to the designs of phase a and b; returns the next
/// free block label.
fn push_run(log: &RunLog, o: &EmfOptions, orders: &[u16], da: &mut Design, db: &mut Design, block0: u32) -> u32 {
    let Some(ph) = &log.phases else { return block0 };
    let n = log.len();
    // Columns of another length (a log built by hand) are no run to fit.
    let lens = [log.theta_fb_rad.len(), ph.i_a_a.len(), ph.i_b_a.len(), ph.v_a_v.len(), ph.v_b_v.len()];
    if lens.iter().any(|&len| len != n) {
        return block0;
    }
    let nr = f64::from(o.pole_pairs);
    let (t, th) = (&log.t_s, &log.theta_fb_rad);
    // The speed and the angle come from the quantised encoder angle. Its staircase, sampled
    // at a count rate close to the sample rate, aliases to a few kHz; at such a speed the
    // rotor's own angle deviates from the straight line by microradians (its inertia), so the
    // corner is put low, at the electrical frequency: the quantisation error left in the
    // angle is what biases the back-EMF's fit (measured: Km 1–2 % off with the corner at
    // 4 kHz on a 4000-count encoder, 0.01 % with 2^20 counts).
    let (_, _, w_line) = kinematics::line_fit(t, th);
    let fs = 1.0 / kinematics::median_step(t);
    let corner = (CORNER_PER_ELECTRICAL_HZ * f64::from(o.pole_pairs) * w_line.abs() / TAU).min(0.2 * fs).max(1.0);
    let kin = kinematics::estimate(t, th, corner);
    let smooth_theta = smoothed_angle(t, th, &kin);
    let wbar = kin.mean_speed_rad_s;
    let mut row = vec![0.0; da.p];
    let mut max_block = 0;
    let lo = kin.edge.max(1);
    let hi = n.saturating_sub(kin.edge.max(1));
    let (r, l) = (o.resistance_ohm, o.inductance_h);
    for k in lo..hi {
        let dt = t[k + 1] - t[k];
        let w = 0.5 * (kin.omega_rad_s[k] + kin.omega_rad_s[k + 1]);
        if (w - wbar).abs() > STEADY_FRACTION * wbar.abs() || dt <= 0.0 {
            continue;
        }
        let theta_e = nr * 0.5 * (smooth_theta[k] + smooth_theta[k + 1]);
        for (j, &ord) in orders.iter().enumerate() {
            let (s, c) = (f64::from(ord) * theta_e).sin_cos();
            row[2 * j] = w * s;
            row[2 * j + 1] = w * c;
        }
        row[da.p - 1] = 1.0;
        let block = block0.saturating_add((theta_e - nr * smooth_theta[lo]).abs().div_euclid(TAU) as u32);
        max_block = max_block.max(block);
        let drop = |i: &[f64], v: &[f64]| v[k] - r * 0.5 * (i[k] + i[k + 1]) - l * (i[k + 1] - i[k]) / dt;
        let PhaseSignals { i_a_a, i_b_a, v_a_v, v_b_v } = ph;
        da.push(&row, drop(i_a_a, v_a_v), block);
        db.push(&row, drop(i_b_a, v_b_v), block);
    }
    max_block.saturating_add(1)
}

/// The encoder angle with its quantisation smoothed away: the least-squares line plus the
/// low-passed remainder at the corner of `kin` ([`kinematics::smooth`]).
fn smoothed_angle(t: &[f64], th: &[f64], kin: &kinematics::Kinematics) -> Vec<f64> {
    let (thm, tm, w) = kinematics::line_fit(t, th);
    let mut r: Vec<f64> = t.iter().zip(th).map(|(&ti, &y)| y - thm - w * (ti - tm)).collect();
    kinematics::smooth(t, &mut r, kin.corner_hz);
    t.iter().zip(&r).map(|(&ti, &ri)| thm + w * (ti - tm) + ri).collect()
}

/// The flux fit from the two phases' solutions (module documentation, *Model*); `None`
/// when a fundamental is zero.
fn combine(
    sa: &lsq::Solution,
    sb: &lsq::Solution,
    o: &EmfOptions,
    orders: &[u16],
    runs: &[&RunLog],
    samples: usize,
) -> Option<FluxFit> {
    let pq = |s: &lsq::Solution, j: usize| (s.beta[2 * j], s.beta[2 * j + 1]);
    let var =
        |s: &lsq::Solution, j: usize| (s.cov[(2 * j, 2 * j)], s.cov[(2 * j, 2 * j + 1)], s.cov[(2 * j + 1, 2 * j + 1)]);
    // Phase a: −(p1 + j q1) = Km·e^{jε}; phase b: −(p1 + j q1)·e^{jπ/2} = (1 + g)·Km·e^{jε}.
    let (p1a, q1a) = pq(sa, 0);
    let (p1b, q1b) = pq(sb, 0);
    let (va, vb) = (var(sa, 0), var(sb, 0));
    let (km_a, offset) = polar_with_ci(-p1a, -q1a, va.0, va.1, va.2);
    let (km_b, _) = polar_with_ci(q1b, -p1b, vb.2, -vb.1, vb.0);
    if !(km_a.value > 0.0 && km_b.value > 0.0) {
        return None;
    }
    let ratio = km_b.value / km_a.value;
    let g_ci = ratio * ((km_a.ci95 / km_a.value).powi(2) + (km_b.ci95 / km_b.value).powi(2)).sqrt();
    let harmonics = orders[1..]
        .iter()
        .enumerate()
        .map(|(i, &ord)| {
            let j = i + 1;
            let nf = f64::from(ord);
            // Phase a: h·e^{ja} = −(p + jq)/(n·Km_a).
            let (p, q) = pq(sa, j);
            let ka = -1.0 / (nf * km_a.value);
            let (xa, ya) = (ka * p, ka * q);
            let (vpa, vpqa, vqa) = var(sa, j);
            let (vxa, vxya, vya) = (ka * ka * vpa, ka * ka * vpqa, ka * ka * vqa);
            // Phase b: h·e^{ja} = −(p + jq)·e^{jnπ/2}/(n·Km_b).
            let (p, q) = pq(sb, j);
            let kb = -1.0 / (nf * km_b.value);
            let (sr, cr) = (nf * FRAC_PI_2).sin_cos();
            let (xb, yb) = (kb * (p * cr - q * sr), kb * (p * sr + q * cr));
            let (vp, vpq, vq) = var(sb, j);
            let (vxb, vxyb, vyb) = rotate_cov(vp, vpq, vq, cr, sr, kb);
            let (x, y) = (0.5 * (xa + xb), 0.5 * (ya + yb));
            let (r, ph) = polar_with_ci(x, y, 0.25 * (vxa + vxb), 0.25 * (vxya + vxyb), 0.25 * (vya + vyb));
            let diff = (xa - xb).hypot(ya - yb);
            let diff_ci = crate::fit::Z_95 * (vxa + vxb + vya + vyb).max(f64::MIN_POSITIVE).sqrt();
            FluxHarmonicEstimate { order: ord, ratio: r, phase_rad: ph, phase_disagreement: diff / diff_ci }
        })
        .collect();
    Some(FluxFit {
        km_nm_per_a: km_a,
        phase_b_gain: Estimate { value: ratio - 1.0, ci95: g_ci },
        commutation_offset_rad: offset,
        harmonics,
        runs: runs.iter().map(|l| l.source.clone()).collect(),
        samples,
        residual_rms_v: (sa.residual_rms, sb.residual_rms),
        base_km_nm_per_a: o.km_nm_per_a,
    })
}

/// The covariance of `k·R·(p, q)` with `R` the rotation by `(cos, sin) = (cr, sr)`, from
/// that of `(p, q)`: `(var x, cov xy, var y)`.
fn rotate_cov(vp: f64, vpq: f64, vq: f64, cr: f64, sr: f64, k: f64) -> (f64, f64, f64) {
    // x = k(cr·p − sr·q), y = k(sr·p + cr·q).
    let k2 = k * k;
    let vx = k2 * (cr * cr * vp - 2.0 * cr * sr * vpq + sr * sr * vq);
    let vy = k2 * (sr * sr * vp + 2.0 * sr * cr * vpq + cr * cr * vq);
    let cxy = k2 * (cr * sr * vp + (cr * cr - sr * sr) * vpq - sr * cr * vq);
    (vx, cxy, vy)
}

#[cfg(test)]
mod tests;
