//! An estimate of [`Reconstruction::first_sample_s`] from the capture's two marker moves
//! (0 → +2 → 0 → −2 → 0 rev/s at 1000 rev/s², 8 ms each, at `start_marker` and
//! `end_marker`), which the firmware plans so that they can be found in the samples.
//!
//! Our method, not the firmware's (which takes the first sample whose local energy exceeds
//! the mean near the planned marker, calibration.cpp:293–318 at `v6.3.1`): the normalised
//! correlation of the samples with the **commanded** acceleration over both marker windows,
//! maximised over the offset on a grid of `1/(8·f_s)` and refined by a parabola through the
//! best three points. Its sign is ignored (the projection's sign depends on the printer).
//! Each sample is compared with the commanded acceleration **averaged over the sample
//! period before it** (`(v(t) − v(t − 1/f_s))·f_s`), which makes the match a smooth function
//! of the offset; a sensor that filters otherwise shifts the estimate by a constant.
//!
//! What it measures is when the **head** moved, as the sensor saw it: the frame's and belt's
//! response and the sensor's own filter delay it against the command. That delay belongs to
//! the marker move, which is the same in every capture, so between captures of one printer
//! it cancels like a shared start angle does — to the extent the mechanics repeat.

use crate::capture::{AccelCapture, CaptureError, MARKER_ACCEL_REV_S2, MARKER_SPEED_REV_S, Reconstruction};

/// The time (s) each marker window extends before and after the 8 ms move.
pub const MARKER_MARGIN_S: f64 = 0.01;
/// The least normalised correlation at which the markers count as found: noise alone,
/// correlated with the ~22 samples the two markers span, reaches 0.5 over a search.
pub const MIN_SCORE: f64 = 0.8;
/// The most grid points searched (2²⁰ points: 0.78 s at 1344 Hz).
pub const MAX_GRID: usize = 1 << 20;
/// The most sample comparisons of one search (2²⁸, well under a second): the grid times
/// the samples in the marker windows (about 75 at 1344 Hz).
pub const MAX_WORK: f64 = (1u64 << 28) as f64;

/// An estimate of the planned time of sample 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimingEstimate {
    /// The estimate (s), for [`Reconstruction::first_sample_s`].
    pub first_sample_s: f64,
    /// `|Σ (y − ȳ)·a| / √(Σ (y − ȳ)² · Σ a²)` over the marker windows at the estimate, 0…1.
    pub score: f64,
}

/// The offset in `[from_s, to_s]` (planned time of sample 0, s) at which the samples best
/// match the commanded acceleration of both markers. `r` gives the belt (`mm_per_rev`) for
/// the plan; its `first_sample_s` is not used. Refuses a search wider than [`MAX_GRID`]
/// points or [`MAX_WORK`] comparisons, and a best match below [`MIN_SCORE`].
pub fn estimate_first_sample(
    c: &AccelCapture,
    r: &Reconstruction,
    from_s: f64,
    to_s: f64,
) -> Result<TimingEstimate, CaptureError> {
    let g = c.require_gcode()?;
    let fs = c.annotations.sampling_freq_hz;
    if !(fs.is_finite() && fs > 0.0) {
        return Err(c.unusable(format!("sampling_freq {fs}: no sample times (the accelerometer failed)")));
    }
    let step = 1.0 / (8.0 * fs);
    let points = ((to_s - from_s) / step).floor();
    if !(from_s.is_finite() && points >= 2.0 && points < MAX_GRID as f64) {
        return Err(CaptureError::Parameter {
            what: "from_s, to_s",
            value: format!("{from_s}, {to_s}"),
            allowed: format!("finite, from < to, at most {MAX_GRID} steps of 1/(8·f_s) apart"),
        });
    }
    let dur = 4.0 * MARKER_SPEED_REV_S / MARKER_ACCEL_REV_S2;
    let per_point = (2.0 * ((dur + 2.0 * MARKER_MARGIN_S) * fs + 1.0)).min(c.samples.len() as f64);
    if points * per_point > MAX_WORK {
        return Err(c.unusable(format!(
            "a search of {points} offsets × {per_point} samples at {fs} Hz: more than {MAX_WORK} comparisons"
        )));
    }
    c.check_annotations()?;
    let plan = g.plan(r.mm_per_rev)?;
    let windows =
        [plan.times.start_marker, plan.times.end_marker].map(|t| (t - MARKER_MARGIN_S, t + dur + MARKER_MARGIN_S));
    let score = |tau: f64| {
        let mut cursor = plan.cursor();
        let (mut ya, mut yy, mut aa) = (0.0, 0.0, 0.0);
        for (w0, w1) in windows {
            let k0 = ((w0 - tau) * fs).ceil().max(0.0) as usize;
            let k1 = (((w1 - tau) * fs).floor().max(-1.0) + 1.0) as usize;
            let ks = k0..k1.min(c.samples.len());
            if ks.is_empty() {
                continue;
            }
            let mean = c.samples[ks.clone()].iter().sum::<f64>() / ks.len() as f64;
            for k in ks {
                let t = tau + k as f64 / fs;
                let a = (cursor.at(t).1 - cursor.at(t - 1.0 / fs).1) * fs;
                let y = c.samples[k] - mean;
                (ya, yy, aa) = (ya + y * a, yy + y * y, aa + a * a);
            }
        }
        if yy > 0.0 && aa > 0.0 { (ya / (yy * aa).sqrt()).abs() } else { 0.0 }
    };
    let n = points as usize + 1;
    let scores: Vec<f64> = (0..n).map(|i| score(from_s + i as f64 * step)).collect();
    let best = (0..n).max_by(|&a, &b| scores[a].total_cmp(&scores[b])).expect("n ≥ 3");
    if scores[best] < MIN_SCORE {
        return Err(c.unusable(format!(
            "no marker found between {from_s} and {to_s} s: best correlation {:.2} < {MIN_SCORE}",
            scores[best]
        )));
    }
    // A parabola through the best point and its neighbours (inside the grid).
    let shift = if best > 0 && best + 1 < n {
        let (l, m, h) = (scores[best - 1], scores[best], scores[best + 1]);
        let den = l - 2.0 * m + h;
        if den < 0.0 { (0.5 * (l - h) / den).clamp(-0.5, 0.5) } else { 0.0 }
    } else {
        0.0
    };
    Ok(TimingEstimate { first_sample_s: from_s + (best as f64 + shift) * step, score: scores[best] })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::{Annotations, Axis, Gcode, TrialSweep};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    const FS: f64 = 1344.37;

    /// An `M973` capture whose samples are the commanded acceleration of the head (belt
    /// 40 mm/rev) averaged over each sample period, clipped at the sensor's ±2 g, times
    /// `sign`, plus an offset and noise; sample 0 at planned time `t0`.
    fn capture(t0: f64, sign: f64, signal: f64) -> (AccelCapture, Reconstruction) {
        let trial = TrialSweep { harmonic: 2, pha_start: 0.0, pha_end: 0.0, mag_start: 0.0, mag_end: 0.0 };
        let g = Gcode::ParamSweep { axis: Axis::Y, speed: 2.0, revs: 4.0, trial };
        let times = g.planned_times().unwrap();
        let annotations = Annotations { sampling_freq_hz: FS, movement_ok: true, accel_error: 0, times };
        let mut c = AccelCapture { source: "t".into(), line: 1, gcode: Some(g), samples: vec![0.0; 5000], annotations };
        let r = Reconstruction { periods_per_rev: 50, start_angle_rad: 0.0, first_sample_s: t0, mm_per_rev: 40.0 };
        let states = c.commanded(&r).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let noise = Normal::new(0.0, 0.3).unwrap();
        let mut before = 0.0;
        for (y, s) in c.samples.iter_mut().zip(&states) {
            // The mean acceleration over the sample period before it, in m/s² at the head.
            let mean = (s.speed_rev_s - before) * FS;
            before = s.speed_rev_s;
            let head = (signal * mean * 40.0 / 1000.0).clamp(-19.6, 19.6);
            *y = 0.4 + sign * head + noise.sample(&mut rng);
        }
        (c, r)
    }

    #[test]
    fn the_markers_give_the_time_of_the_first_sample() {
        for (t0, sign) in [(0.0417, 1.0), (0.1234, -1.0), (-0.02, 1.0)] {
            let (c, r) = capture(t0, sign, 1.0);
            let e = estimate_first_sample(&c, &r, -0.1, 0.3).unwrap();
            assert!((e.first_sample_s - t0).abs() < 0.1 / FS, "{t0}: {e:?}");
            assert!(e.score > 0.8, "{e:?}");
        }
    }

    #[test]
    fn no_marker_in_the_samples_is_refused() {
        let (c, r) = capture(0.05, 1.0, 0.0);
        let e = estimate_first_sample(&c, &r, -0.1, 0.3).unwrap_err().to_string();
        assert!(e.contains("no marker found between -0.1 and 0.3 s"), "{e}");
        let e = estimate_first_sample(&c, &r, 0.3, -0.1).unwrap_err().to_string();
        assert!(e.contains("from_s, to_s = 0.3, -0.1"), "{e}");
    }
}
