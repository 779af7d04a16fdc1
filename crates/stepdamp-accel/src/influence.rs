//! One harmonic's complex response in a capture, the influence coefficient of a known trial
//! correction, the correction that cancels the response, and the next step of an iteration.
//! Equations: `docs/accelerometer.md#accelerometer-captures`.
//!
//! **Conventions.** `θ` is the commanded electrical angle ([`crate::capture::Commanded`]),
//! `n` the harmonic. A response `Y` (m/s²) stands for the acceleration component
//! `Im(Y·e^{inθ}) = |Y|·sin(nθ + arg Y)`, the form of a table item. A correction is the
//! phasor `U` (rad) of the angle shift `Im(U·e^{inθ}) = |U|·sin(nθ + arg U)` it adds to the
//! current vector: a table item `(mag, pha)` is `U = s·mag·e^{i·pha}` with `s` the firmware's
//! scale (4 for ≥ 6.3.1: `stepdamp_export::prusa::Firmware::scale`,
//! `docs/exporters.md#the-table-and-its-scale`). The model is linear near the operating
//! point: `Y(U) = Y₀ + C·U`, `C` the influence coefficient (m/s² per rad).

pub use crate::complex::Complex;

use crate::capture::{AccelCapture, CaptureError, Gcode, Reconstruction};
use std::f64::consts::TAU;

/// One harmonic's response in a capture's constant-speed window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Response {
    /// The harmonic `n` of the electrical angle.
    pub harmonic: u32,
    /// `Y` (m/s²): the mean of the blocks' estimates.
    pub value: Complex,
    /// Radius (m/s²) of the 95 % confidence disc around `value`, from the spread of the
    /// blocks: `r² = F₂,₂₍B−1₎(0.95)·Σ|Y_b − Ȳ|² / (B(B−1))` (isotropic, independent blocks).
    pub radius95: f64,
    /// The number of blocks `B`.
    pub blocks: usize,
    /// Whole electrical periods per block.
    pub periods_per_block: u32,
    /// The commanded speed in the window (rev/s, signed like the electrical angle).
    pub speed_rev_s: f64,
}

/// Why an influence or iteration step cannot be computed; one line each.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InfluenceError {
    /// A capture could not be analysed.
    #[error(transparent)]
    Capture(#[from] CaptureError),
    /// The inputs do not belong together or cannot give an answer.
    #[error("{0}")]
    Indeterminate(String),
}

/// The 0.95 quantile of the F distribution with 2 and `m` degrees of freedom, in closed
/// form: `F = (m/2)·(0.05^(−2/m) − 1)` (from its CDF `1 − (1 + 2x/m)^(−m/2)`).
pub fn f2_quantile_95(m: f64) -> f64 {
    m / 2.0 * (0.05_f64.powf(-2.0 / m) - 1.0)
}

/// The complex response `Y` of harmonic `n` in the constant-speed window of an `M973`
/// capture (the planned `[signal_start, signal_end]`), by lock-in against the reconstructed
/// electrical angle over whole periods: the window, counted in electrical periods from its
/// start, is cut into `B` blocks of `periods_per_block` whole periods (the rest is
/// dropped); in each, least squares of `y = c + a·sin nθ + b·cos nθ` give `Y_b = a + i·b`
/// (exact for a DC offset and any sampling that is not locked to the period); `Y` is their
/// mean, with [`Response::radius95`] from their spread.
///
/// Refuses: a capture the firmware itself would reject ([`crate::Annotations::is_valid`]),
/// `M974` (no constant speed), a harmonic at or above the accelerometer's Nyquist frequency
/// (`n·P·|v| ≥ f_s/2`), samples that do not cover the window, fewer than 3 blocks.
pub fn harmonic_response(
    c: &AccelCapture,
    r: &Reconstruction,
    harmonic: u32,
    periods_per_block: u32,
) -> Result<Response, CaptureError> {
    check_lockin(c, harmonic, periods_per_block)?;
    let g = c.require_gcode()?;
    let Gcode::ParamSweep { speed, .. } = g else {
        return Err(c.unusable(format!("`{g}` sweeps the speed: no constant-speed window")));
    };
    let fs = c.annotations.sampling_freq_hz;
    let f = f64::from(harmonic) * f64::from(r.periods_per_rev) * speed;
    if f >= fs / 2.0 {
        return Err(c.unusable(format!(
            "harmonic {harmonic} at {speed} rev/s is {f:.1} Hz, at or above the accelerometer's Nyquist {:.1} Hz",
            fs / 2.0
        )));
    }
    let window = g.planned_times()?;
    let states = c.commanded(r)?;
    let (t_first, t_last) = (states.first().map_or(f64::NAN, |s| s.t_s), states.last().map_or(f64::NAN, |s| s.t_s));
    if !(t_first <= window.signal_start && t_last >= window.signal_end) {
        return Err(c.unusable(format!(
            "the samples ({t_first:.3}…{t_last:.3} s) do not cover the constant-speed window {:.3}…{:.3} s: a cut capture or a wrong first_sample_s",
            window.signal_start, window.signal_end
        )));
    }
    // Whole blocks the window holds (1e-9: an exact count survives rounding). Bounded by
    // the samples: the window is sampled and n·P·v < f_s/2, so periods < samples/2.
    let periods = f64::from(r.periods_per_rev) * speed * (window.signal_end - window.signal_start);
    let complete = (periods / f64::from(periods_per_block) + 1e-9).floor() as usize;
    let sums = block_sums(c, &states, &window, r, harmonic, periods_per_block, complete);
    let estimates: Vec<Complex> = sums.iter().filter_map(solve_block).collect();
    let blocks = estimates.len();
    if blocks < 3 {
        return Err(c.unusable(format!(
            "{blocks} block(s) of {periods_per_block} electrical periods in the window: at least 3 are needed (a longer R or shorter blocks)"
        )));
    }
    let b = blocks as f64;
    let mean = estimates.iter().fold(Complex::default(), |s, &y| s + y).scale(1.0 / b);
    let spread: f64 = estimates.iter().map(|&y| (y - mean).norm_sqr()).sum();
    let radius95 = (f2_quantile_95(2.0 * (b - 1.0)) * spread / (b * (b - 1.0))).sqrt();
    Ok(Response {
        harmonic,
        value: mean,
        radius95,
        blocks,
        periods_per_block,
        speed_rev_s: g.phase_direction() * speed,
    })
}

/// Refuses a harmonic or block length of 0 and a capture the firmware itself discards
/// ([`crate::Annotations::is_valid`]): what every lock-in checks first.
pub(crate) fn check_lockin(c: &AccelCapture, harmonic: u32, periods_per_block: u32) -> Result<(), CaptureError> {
    if harmonic == 0 || periods_per_block == 0 {
        let value = format!("{harmonic}, {periods_per_block}");
        return Err(CaptureError::Parameter {
            what: "harmonic, periods_per_block", value, allowed: "both ≥ 1".into()
        });
    }
    if !c.annotations.is_valid() {
        let a = c.annotations;
        return Err(c.unusable(format!(
            "not a valid capture (movement_ok {}, accel_error {}, sampling_freq {}): the firmware discards it too",
            a.movement_ok, a.accel_error, a.sampling_freq_hz
        )));
    }
    Ok(())
}

/// The normal equations of `[1, sin nθ, cos nθ]` (upper triangle, then the right-hand side)
/// of each of the `complete` blocks of `per_block` whole periods from the window's start
/// (where the angle is extrapolated from the first sample inside, at constant speed).
fn block_sums(
    c: &AccelCapture,
    states: &[crate::capture::Commanded],
    window: &crate::capture::PlannedTimes,
    r: &Reconstruction,
    harmonic: u32,
    per_block: u32,
    complete: usize,
) -> Vec<[f64; 9]> {
    let mut sums = vec![[0.0; 9]; complete];
    let (t0, t1) = (window.signal_start, window.signal_end);
    let inside = || states.iter().zip(&c.samples).filter(|(s, _)| s.t_s >= t0 && s.t_s <= t1);
    let Some((first, _)) = inside().next() else { return sums };
    let rate = TAU * f64::from(r.periods_per_rev) * first.speed_rev_s;
    let theta0 = first.electrical_rad - rate * (first.t_s - t0);
    let n = f64::from(harmonic);
    for (st, &y) in inside() {
        let th = st.electrical_rad;
        let b = ((th - theta0).abs() / TAU / f64::from(per_block)).floor() as usize;
        let Some(a) = sums.get_mut(b) else { continue };
        accumulate(a, n * th, y);
    }
    sums
}

/// Adds the sample `y` at the harmonic's angle `n·θ` (rad) to a block's normal equations of
/// `[1, sin nθ, cos nθ]` (upper triangle, then the right-hand side), as [`solve_block`] reads them.
pub(crate) fn accumulate(a: &mut [f64; 9], n_theta: f64, y: f64) {
    let (s, co) = n_theta.sin_cos();
    for (slot, v) in a.iter_mut().zip([1.0, s, co, s * s, s * co, co * co, y, y * s, y * co]) {
        *slot += v;
    }
}

/// `a + i·b` of one block's least squares `y = c + a·sin + b·cos` (Cramer's rule on the 3×3
/// normal equations); `None` if they are singular (too few samples).
pub(crate) fn solve_block(m: &[f64; 9]) -> Option<Complex> {
    let [n, s, co, ss, sc, cc, y, ys, yc] = *m;
    let det3 = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let a = [[n, s, co], [s, ss, sc], [co, sc, cc]];
    let d = det3(a);
    if d.is_nan() || d.abs() <= 1e-9 * n * n * n {
        return None;
    }
    let rhs = [y, ys, yc];
    let col = |j: usize| {
        let mut m = a;
        for (row, &v) in m.iter_mut().zip(&rhs) {
            row[j] = v;
        }
        det3(m) / d
    };
    Some(Complex::new(col(1), col(2)))
}

/// The shift phasor `U = scale·mag·e^{i·pha}` (rad) of a table item `(mag, pha)`.
pub fn table_shift(mag: f64, pha: f64, scale: f64) -> Complex {
    Complex::from_polar(scale * mag, pha)
}

/// The table item `(mag ≥ 0, pha in (−π, π])` of a shift phasor `U`.
pub fn table_item(u: Complex, scale: f64) -> (f64, f64) {
    (u.abs() / scale, u.arg())
}

/// An influence coefficient and the correction that cancels the baseline response.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Influence {
    /// `C = (Y₁ − Y₀)/U_t` (m/s² per rad).
    pub coefficient: Complex,
    /// 95 % radius of `C`: `√(r₀² + r₁²)/|U_t|`.
    pub coefficient_radius95: f64,
    /// `U* = −Y₀/C` (rad): the shift phasor that cancels `Y₀`.
    pub cancelling: Complex,
    /// 95 % radius of `U*`, to first order: `δU* = −δY₀·(1/C + Y₀/(C²U_t)) + δY₁·Y₀/(C²U_t)`,
    /// the two radii added in quadrature.
    pub cancelling_radius95: f64,
}

/// [`Influence`] from a baseline response `y0` (no trial) and a response `y1` with the trial
/// shift `trial` added (a constant `M973` trial: [`crate::TrialSweep::constant`] through
/// [`table_shift`]). Both must be of the same harmonic, speed and direction, and share the
/// reconstruction's start angle (see [`Reconstruction::start_angle_rad`]). Refuses a trial
/// whose effect is within the noise (`|C| ≤` its radius).
pub fn influence(y0: &Response, y1: &Response, trial: Complex) -> Result<Influence, InfluenceError> {
    let bad = |s: String| Err(InfluenceError::Indeterminate(s));
    if y0.harmonic != y1.harmonic {
        return bad(format!("harmonics {} and {}: one harmonic per influence coefficient", y0.harmonic, y1.harmonic));
    }
    if y0.speed_rev_s != y1.speed_rev_s {
        return bad(format!(
            "speeds {} and {} rev/s: responses at different speeds or directions are not comparable",
            y0.speed_rev_s, y1.speed_rev_s
        ));
    }
    if !(trial.is_finite() && trial.abs() > 0.0) {
        return bad(format!("trial shift {trial:?}: must be finite and non-zero"));
    }
    let c = (y1.value - y0.value) / trial;
    let c_r = y0.radius95.hypot(y1.radius95) / trial.abs();
    if c.abs() <= c_r {
        return bad(format!(
            "the trial changed harmonic {} by {:.3e} m/s², within the noise ({:.3e}): a larger trial or longer captures",
            y0.harmonic,
            (y1.value - y0.value).abs(),
            y0.radius95.hypot(y1.radius95)
        ));
    }
    let u = -y0.value / c;
    let k1 = y0.value / (c * c * trial);
    let k0 = Complex::new(1.0, 0.0) / c + k1;
    let u_r = (k0.abs() * y0.radius95).hypot(k1.abs() * y1.radius95);
    Ok(Influence { coefficient: c, coefficient_radius95: c_r, cancelling: u, cancelling_radius95: u_r })
}

/// [`influence`] straight from two `M973` captures of the same `H`, speed and direction: the
/// baseline with no trial (`C = D = 0`) and one with a constant trial (`A = B`, `C = D`),
/// whose `(C, A)` is the table item `(mag, pha)` and `scale` the firmware's (4 for ≥ 6.3.1).
/// The harmonic is `H`; [`harmonic_response`] measures both with `periods_per_block`.
pub fn influence_of_captures(
    base: &AccelCapture,
    trial: &AccelCapture,
    r: &Reconstruction,
    periods_per_block: u32,
    scale: f64,
) -> Result<Influence, InfluenceError> {
    let sweep = |c: &AccelCapture| c.constant_trial("an influence step").map(|(h, _, _, mag, pha)| (h, (mag, pha)));
    let (h0, (mag0, _)) = sweep(base)?;
    let (h1, (mag, pha)) = sweep(trial)?;
    if mag0 != 0.0 || h0 != h1 {
        return Err(InfluenceError::Indeterminate(format!(
            "{}:{} and {}:{}: the baseline needs C = D = 0 and the same H as the trial (H{h0} C{mag0}, H{h1})",
            base.source, base.line, trial.source, trial.line
        )));
    }
    let y0 = harmonic_response(base, r, h0, periods_per_block)?;
    let y1 = harmonic_response(trial, r, h1, periods_per_block)?;
    influence(&y0, &y1, table_shift(mag, pha, scale))
}

/// One step of an iteration: the shift applied and the response measured with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// The shift phasor `U` (rad) applied (the baseline's is 0).
    pub shift: Complex,
    /// The response measured.
    pub response: Response,
}

/// Why an iteration stops.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    /// The last response is within its own 95 % radius of zero: nothing left to cancel.
    WithinNoise,
    /// The last response fell by less than the asked share below the best before it.
    NotFalling,
}

/// What to do next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Next {
    /// Measure with this shift phasor (rad).
    Try(Complex),
    /// Stop and keep the step at this index (the smallest response).
    Stop {
        /// The index of the best step.
        best: usize,
        /// Why.
        reason: StopReason,
    },
}

/// The next shift of an iteration from its steps (`steps[0]` the baseline, `steps[1]` the
/// trial, the rest earlier updates): least squares of `Y = Y₀ + C·U` over the last `window`
/// steps (`window = 2` is the secant step), `Ĉ = Σ conj(U−Ū)(Y−Ȳ) / Σ|U−Ū|²`,
/// `Ŷ₀ = Ȳ − Ĉ·Ū`, next `U = −Ŷ₀/Ĉ`. Stops when the last response is within its own radius of
/// zero ([`StopReason::WithinNoise`]) or, from the third step on, when it is not below
/// `(1 − min_fall)` × the smallest before it ([`StopReason::NotFalling`]).
pub fn next_shift(steps: &[Step], window: usize, min_fall: f64) -> Result<Next, InfluenceError> {
    let bad = |s: String| Err(InfluenceError::Indeterminate(s));
    if steps.len() < 2 || window < 2 || !(0.0..1.0).contains(&min_fall) {
        return bad(format!(
            "{} step(s), window {window}, min_fall {min_fall}: need ≥ 2 steps, window ≥ 2, min_fall in [0, 1)",
            steps.len()
        ));
    }
    let size = |s: &Step| s.response.value.abs();
    let best = (0..steps.len()).min_by(|&a, &b| size(&steps[a]).total_cmp(&size(&steps[b]))).expect("≥ 2 steps");
    let last = &steps[steps.len() - 1];
    if size(last) <= last.response.radius95 {
        return Ok(Next::Stop { best, reason: StopReason::WithinNoise });
    }
    let before = steps[..steps.len() - 1].iter().map(size).fold(f64::INFINITY, f64::min);
    if steps.len() >= 3 && size(last) > (1.0 - min_fall) * before {
        return Ok(Next::Stop { best, reason: StopReason::NotFalling });
    }
    let fit = &steps[steps.len().saturating_sub(window)..];
    let m = fit.len() as f64;
    let u_mean = fit.iter().fold(Complex::default(), |s, x| s + x.shift).scale(1.0 / m);
    let y_mean = fit.iter().fold(Complex::default(), |s, x| s + x.response.value).scale(1.0 / m);
    let den: f64 = fit.iter().map(|x| (x.shift - u_mean).norm_sqr()).sum();
    let num = fit.iter().fold(Complex::default(), |s, x| s + (x.shift - u_mean).conj() * (x.response.value - y_mean));
    if den.is_nan() || den <= 0.0 {
        return bad("every step in the window has the same shift: the influence coefficient is unknown".into());
    }
    let c = num.scale(1.0 / den);
    let y0 = y_mean - c * u_mean;
    let next = -y0 / c;
    if !next.is_finite() {
        return bad("the fitted influence coefficient is zero: the shifts had no effect".into());
    }
    Ok(Next::Try(next))
}

#[cfg(test)]
pub(crate) mod tests;
