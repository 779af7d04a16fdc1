//! The lock-in on short blocks along a capture whose speed changes (an `M974` speed sweep), or
//! not (an `M973`): per block of whole electrical periods, the same least squares as
//! [`crate::influence::harmonic_response`] (`y = c + a·sin nθ + b·cos nθ`, `Y_b = a + i·b`), dated
//! and placed at the block's mean commanded speed (`docs/accelerometer.md#identifying-the-ripple-from-captures`).
//! A block is short enough that the speed is nearly constant within it: on Prusa's sweeps
//! (constant acceleration of about 1 rev/s² or less) a few periods change it by well under 1 %.

use crate::Reconstruction;
use crate::capture::{AccelCapture, CaptureError};
use crate::influence::{Complex, accumulate, check_lockin, solve_block};
use std::f64::consts::TAU;

/// One block's estimate of a harmonic's response.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockResponse {
    /// The harmonic `n` of the electrical angle.
    pub harmonic: u32,
    /// `Y_b` (m/s²): the component `Im(Y_b·e^{inθ})` against the commanded electrical angle
    /// `θ`, the convention of [`crate::Response`].
    pub value: Complex,
    /// The block's mean commanded speed (rev/s, signed like the electrical angle).
    pub speed_rev_s: f64,
    /// The samples in the block (the weight of its estimate: its noise variance goes as
    /// `1/samples`).
    pub samples: usize,
    /// The block's mean planned time (s).
    pub t_s: f64,
}

/// The response of harmonic `n` in every block of `periods_per_block` whole electrical
/// periods of the capture's analysed window (the planned `[signal_start, signal_end]`:
/// `M973`'s constant-speed part, `M974`'s two sweeps), counted by the commanded angle from the
/// window's first sample; the last, incomplete block is dropped, as is a block whose normal
/// equations are singular. Refuses a capture the firmware rejects or whose samples do not
/// cover the window.
pub fn block_responses(
    c: &AccelCapture,
    r: &Reconstruction,
    harmonic: u32,
    periods_per_block: u32,
) -> Result<Vec<BlockResponse>, CaptureError> {
    check_lockin(c, harmonic, periods_per_block)?;
    let window = c.require_gcode()?.planned_times()?;
    let states = c.commanded(r)?;
    let (t0, t1) = (window.signal_start, window.signal_end);
    let covered = states.first().is_some_and(|s| s.t_s <= t0) && states.last().is_some_and(|s| s.t_s >= t1);
    if !covered {
        return Err(c.unusable(format!(
            "the samples do not cover the analysed window {t0:.3}…{t1:.3} s: a cut capture or a wrong first_sample_s"
        )));
    }
    Ok(window_blocks(&states, &c.samples, (t0, t1), harmonic, periods_per_block))
}

/// The blocks of [`block_responses`] from the commanded motion and the sample at each of a
/// recording's samples (`states[i]` is sample `samples[i]`'s), inside the window
/// `[t0, t1]` (s): the part shared by Prusa's captures and Klipper's logs
/// ([`crate::klipper`]), which date and angle their samples themselves.
pub(crate) fn window_blocks(
    states: &[crate::capture::Commanded],
    samples: &[f64],
    (t0, t1): (f64, f64),
    harmonic: u32,
    periods_per_block: u32,
) -> Vec<BlockResponse> {
    let inside = || states.iter().zip(samples).filter(|(s, _)| s.t_s >= t0 && s.t_s <= t1);
    let Some((first, _)) = inside().next() else { return Vec::new() };
    let theta0 = first.electrical_rad;
    let n = f64::from(harmonic);
    let span = TAU * f64::from(periods_per_block);
    // Per block: the normal equations, then the sums of speed and time and the count.
    let mut blocks: Vec<([f64; 9], f64, f64, usize)> = Vec::new();
    for (st, &y) in inside() {
        let b = ((st.electrical_rad - theta0).abs() / span).floor() as usize;
        if b >= blocks.len() {
            blocks.resize(b + 1, ([0.0; 9], 0.0, 0.0, 0));
        }
        let e = &mut blocks[b];
        accumulate(&mut e.0, n * st.electrical_rad, y);
        e.1 += st.speed_rev_s;
        e.2 += st.t_s;
        e.3 += 1;
    }
    blocks.pop(); // the last block is incomplete (or ends exactly at the window's end)
    blocks
        .iter()
        .filter_map(|(sums, v, t, count)| {
            let value = solve_block(sums)?;
            let k = *count as f64;
            Some(BlockResponse { harmonic, value, speed_rev_s: v / k, samples: *count, t_s: t / k })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::{Annotations, Axis, Gcode};

    #[test]
    fn on_a_synthetic_sweep_each_block_finds_the_harmonic_at_its_speed() {
        // A response whose phasor turns with the speed: Y(v) = (0.5 + 0.2·v)·e^{i·0.3·v}.
        let g = Gcode::SpeedSweep { axis: Axis::X, start_speed: 1.0, end_speed: 2.0, revs: -6.0 };
        let times = g.planned_times().unwrap();
        let fs = 1344.0;
        let r = Reconstruction { periods_per_rev: 50, start_angle_rad: 0.2, first_sample_s: 0.0, mm_per_rev: 32.0 };
        let n_samples = ((times.end_marker + 0.3) * fs) as usize;
        let grid = AccelCapture {
            source: "synthetic".into(),
            line: 1,
            gcode: Some(g),
            samples: vec![0.0; n_samples],
            annotations: Annotations { sampling_freq_hz: fs, movement_ok: true, accel_error: 0, times },
        };
        let y = |v: f64| Complex::from_polar(0.5 + 0.2 * v, 0.3 * v);
        let samples = grid
            .commanded(&r)
            .unwrap()
            .iter()
            .map(|s| {
                let z = y(s.speed_rev_s) * Complex::from_polar(1.0, 2.0 * s.electrical_rad);
                0.7 + z.im + 0.4 * (3.0 * s.electrical_rad).sin()
            })
            .collect();
        let c = AccelCapture { samples, ..grid };
        let blocks = block_responses(&c, &r, 2, 3).unwrap();
        assert_eq!(blocks.len(), 6 * 50 / 3 - 1, "6 revolutions of 50 periods, the last block dropped");
        let worst = blocks.iter().map(|b| (b.value - y(b.speed_rev_s)).abs()).fold(0.0, f64::max);
        assert!(worst < 0.01, "{worst}");
        let (lo, hi) =
            blocks.iter().fold((f64::MAX, 0.0_f64), |(a, b), x| (a.min(x.speed_rev_s), b.max(x.speed_rev_s)));
        assert!(lo < 1.05 && hi > 1.95, "{lo} {hi}");
    }
}
