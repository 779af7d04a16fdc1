//! Stick–slip: an angle from encoder edge timing, and the samples where the rotor is stuck or
//! nearly so, with a margin around each stick/slip edge.
//!
//! # Edge-timed angle
//!
//! A quantised encoder angle is a staircase. At low count rates (tens of samples per count)
//! its error is up to half a count for many samples in a row, and smoothing it cannot tell a
//! rotor that stopped inside a count from one that kept moving. The instant the count changes
//! is known much better: the rotor crossed the boundary between the two counts within the
//! sample period before. [`edge_timed_angle`] places each crossing at the boundary (the
//! midpoint of the two logged values, so it works for the centre and the floor conventions
//! alike, up to the constant half-count offset the floor convention has anyway) at the
//! middle of the sample period in which it happened (timing error ≤ half a period, uniform),
//! and interpolates linearly between crossings. Between two crossings the rotor's speed is
//! known only as their mean: the edge-timed speed of that gap.
//!
//! # Stuck samples
//!
//! Friction near zero speed is not the model's `Fs·sgn(ω)`: stuck, static friction holds
//! whatever torque is needed; creeping or just broken away, it is below or above `Fs`
//! (smooth Coulomb `tanh`, Stribeck). A sample is *stuck* when the gap it lies in is slower
//! than [`StickOptions::min_speed_fraction`] of the run's mean speed in the direction of
//! travel, or goes backwards, or when no count changed for longer than that speed allows
//! before the first or after the last crossing. The smoothed acceleration the fit uses is
//! smeared by the low-pass filter over about one period of its corner around every stick and
//! slip, so each stuck stretch is widened by [`StickOptions::margin_periods`] periods of
//! the corner on each side.
//!
//! Cost: two passes over the samples.

/// Options of the stuck-sample detection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StickOptions {
    /// A gap slower than this fraction of the run's mean speed is stuck (or nearly so).
    pub min_speed_fraction: f64,
    /// Margin around each stuck stretch, in periods of the speed filter's corner.
    pub margin_periods: f64,
}

impl Default for StickOptions {
    /// 30 % of the mean speed (measured: the Stribeck excess and the creep deficit are
    /// below 1 % of `Fs` there for Stribeck and creep speeds up to a tenth of the run's
    /// speed), one period of the corner (the zero-phase Butterworth's impulse response has
    /// decayed to a few % of its peak one period from the centre).
    fn default() -> Self {
        StickOptions { min_speed_fraction: 0.3, margin_periods: 1.0 }
    }
}

/// The edge-timed angle of a log and its gaps.
#[derive(Clone, Debug, PartialEq)]
pub struct EdgeTimed {
    /// Angle in rad at each sample: linear between count crossings, the logged value
    /// before the first and after the last.
    pub theta_rad: Vec<f64>,
    /// Signed edge-timed speed of the gap each sample lies in, rad/s (`NaN` before the
    /// first and after the last crossing).
    pub gap_speed_rad_s: Vec<f64>,
    /// Count crossings found.
    pub crossings: usize,
    /// Index of the first sample after each crossing, increasing.
    pub edge_index: Vec<usize>,
    /// Median angle step of a crossing, rad (one count, when the log is one count per step);
    /// 0 without crossings.
    pub step_rad: f64,
}

/// The angle from the timing of the count changes of `theta_fb` (see the module
/// documentation). `t` increasing, same length as `theta_fb`.
pub fn edge_timed_angle(t: &[f64], theta_fb: &[f64]) -> EdgeTimed {
    let n = t.len().min(theta_fb.len());
    let mut theta_rad = theta_fb[..n].to_vec();
    let mut gap_speed_rad_s = vec![f64::NAN; n];
    // Crossings: (time, angle, index of the first sample after it).
    let mut edges: Vec<(f64, f64, usize)> = Vec::new();
    for i in 1..n {
        if theta_fb[i] != theta_fb[i - 1] {
            edges.push((0.5 * (t[i - 1] + t[i]), 0.5 * (theta_fb[i - 1] + theta_fb[i]), i));
        }
    }
    let mut steps: Vec<f64> = edges.windows(2).map(|w| (w[1].1 - w[0].1).abs()).collect();
    let step_rad = if steps.is_empty() {
        0.0
    } else {
        let mid = steps.len() / 2;
        *steps.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    for w in edges.windows(2) {
        let ((t0, a0, i0), (t1, a1, i1)) = (w[0], w[1]);
        let v = (a1 - a0) / (t1 - t0);
        for i in i0..i1 {
            theta_rad[i] = a0 + v * (t[i] - t0);
            gap_speed_rad_s[i] = v;
        }
    }
    let edge_index = edges.iter().map(|e| e.2).collect();
    EdgeTimed { theta_rad, gap_speed_rad_s, crossings: edges.len(), edge_index, step_rad }
}

/// Which samples to keep: `false` where the rotor is stuck or nearly so, or within the margin
/// of such a stretch (see the module documentation). `mean_speed_rad_s` is the run's mean
/// speed (its sign is the direction of travel), `corner_hz` the speed filter's corner,
/// `sample_hz` the sample rate.
pub fn moving_mask(
    et: &EdgeTimed,
    mean_speed_rad_s: f64,
    corner_hz: f64,
    sample_hz: f64,
    o: &StickOptions,
) -> Vec<bool> {
    let n = et.gap_speed_rad_s.len();
    let vmin = o.min_speed_fraction * mean_speed_rad_s.abs();
    let dir = mean_speed_rad_s.signum();
    let mut keep: Vec<bool> = et.gap_speed_rad_s.iter().map(|&v| v * dir >= vmin).collect();
    // Before the first and after the last crossing: stuck if that stretch is longer than a
    // gap at `vmin` would be (otherwise simply unknown: keep the staircase's samples).
    let first = et.gap_speed_rad_s.iter().position(|v| !v.is_nan()).unwrap_or(n);
    let last = et.gap_speed_rad_s.iter().rposition(|v| !v.is_nan()).map_or(0, |i| i + 1);
    if first < n {
        let allowed = if vmin > 0.0 { (et.step_rad / vmin * sample_hz).ceil() as usize } else { n };
        let head_ok = first <= allowed;
        let tail_ok = n - last <= allowed;
        keep[..first].fill(head_ok);
        keep[last..].fill(tail_ok);
    }
    let margin = (o.margin_periods * sample_hz / corner_hz.max(1e-9)).ceil() as usize;
    dilate_false(&keep, margin)
}

/// The mean rise of `effort` across one encoder count, in the direction of travel `dir`
/// (`±1`), over the gaps between crossings inside `[lo, hi)` that span at least 8 samples:
/// the mean of the gap's last quarter minus that of its first quarter. Near 0 when the rotor
/// moves smoothly through the counts (the detent changes little over a count and its slope
/// averages out); about the servo's stiffness times a count when the drive reacts to every
/// count faster than the rotor crosses it, so that the rotor stops and starts inside each
/// count (see [`crate::conditions`]). `None` with fewer than 10 such gaps.
pub fn count_rise(et: &EdgeTimed, effort: &[f64], lo: usize, hi: usize, dir: f64) -> Option<f64> {
    let (mut sum, mut gaps) = (0.0, 0usize);
    for w in et.edge_index.windows(2) {
        let (a, b) = (w[0], w[1]);
        if a < lo || b > hi || b - a < 8 {
            continue;
        }
        let quarter = (b - a) / 4;
        let mean = |r: std::ops::Range<usize>| effort[r.clone()].iter().sum::<f64>() / r.len() as f64;
        sum += dir * (mean(b - quarter..b) - mean(a..a + quarter));
        gaps += 1;
    }
    (gaps >= 10).then(|| sum / gaps as f64)
}

/// `keep` with every `false` widened by `margin` samples on each side.
fn dilate_false(keep: &[bool], margin: usize) -> Vec<bool> {
    let n = keep.len();
    let mut out = keep.to_vec();
    // Distance to the nearest `false` before and after each sample.
    let mut last_false: Option<usize> = None;
    for i in 0..n {
        if !keep[i] {
            last_false = Some(i);
        }
        if let Some(j) = last_false
            && i - j <= margin
        {
            out[i] = false;
        }
    }
    let mut next_false: Option<usize> = None;
    for i in (0..n).rev() {
        if !keep[i] {
            next_false = Some(i);
        }
        if let Some(j) = next_false
            && j - i <= margin
        {
            out[i] = false;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn staircase(theta: &[f64], q: f64) -> Vec<f64> {
        theta.iter().map(|th| ((th / q).floor() + 0.5) * q).collect()
    }

    #[test]
    fn the_edge_timed_angle_of_a_slow_ramp_is_within_a_sample_of_travel_not_half_a_count() {
        let q = TAU / 4000.0;
        let fs = 20_000.0;
        let w = 0.3;
        let t: Vec<f64> = (0..20_000).map(|i| f64::from(i) / fs).collect();
        let truth: Vec<f64> = t.iter().map(|&t| 0.0123 + w * t).collect();
        let fb = staircase(&truth, q);
        let et = edge_timed_angle(&t, &fb);
        let worst_stair = fb.iter().zip(&truth).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        let (first, last) = (
            et.gap_speed_rad_s.iter().position(|v| !v.is_nan()).unwrap(),
            et.gap_speed_rad_s.iter().rposition(|v| !v.is_nan()).unwrap(),
        );
        let worst_edge = (first..=last).map(|i| (et.theta_rad[i] - truth[i]).abs()).fold(0.0, f64::max);
        assert!(worst_stair > 0.45 * q, "{worst_stair}");
        assert!(worst_edge <= 0.5 * w / fs + 1e-12, "edge-timed error {worst_edge} rad");
        assert!((et.gap_speed_rad_s[first] - w).abs() < 0.05 * w);
    }

    #[test]
    fn a_stop_inside_a_count_is_marked_stuck_with_its_margin_and_steady_motion_is_kept() {
        let q = TAU / 4000.0;
        let fs = 20_000.0;
        let w = 0.5;
        // Moves at w, stops for 40 ms at t = 0.5 s, then moves on at w.
        let t: Vec<f64> = (0..20_000).map(|i| f64::from(i) / fs).collect();
        let truth: Vec<f64> = t
            .iter()
            .map(|&t| {
                if t < 0.5 {
                    w * t
                } else if t < 0.54 {
                    w * 0.5
                } else {
                    w * (t - 0.04)
                }
            })
            .collect();
        let et = edge_timed_angle(&t, &staircase(&truth, q));
        let keep = moving_mask(&et, w, 100.0, fs, &StickOptions::default());
        // The stop (0.50–0.54 s) and 10 ms (one period of 100 Hz) around it are left out.
        for (i, &k) in keep.iter().enumerate() {
            let ti = t[i];
            if (0.5..0.54).contains(&ti) {
                assert!(!k, "stuck sample at {ti} kept");
            }
            if (0.1..0.48).contains(&ti) || (0.56..0.9).contains(&ti) {
                assert!(k, "moving sample at {ti} dropped");
            }
        }
        let dropped = keep.iter().filter(|k| !**k).count() as f64 / fs;
        assert!(dropped < 0.04 + 2.0 * 0.01 + 2.0 * q / w + 0.005, "dropped {dropped} s");
    }

    #[test]
    fn backward_steps_are_stuck() {
        let t: Vec<f64> = (0..100).map(f64::from).collect();
        // Forward one count per sample, back for ten samples, forward again.
        let fb: Vec<f64> = (0..100)
            .map(|i| {
                if i < 40 {
                    f64::from(i)
                } else if i < 50 {
                    f64::from(80 - i)
                } else {
                    f64::from(i - 20)
                }
            })
            .collect();
        let et = edge_timed_angle(&t, &fb);
        let keep = moving_mask(&et, 1.0, 0.5, 1.0, &StickOptions { min_speed_fraction: 0.3, margin_periods: 0.0 });
        assert!(!keep[40] && !keep[45] && keep[20] && keep[70]);
    }
}
