//! A log cut into the stretches the ripple fit can use: the motor turning one way at a
//! steady or slowly changing speed, with the settle time cut from each end
//! (`docs/accelerometer.md#klippers-motion-analysis-logs`).

use super::Log;
use crate::capture::{CaptureError, Reconstruction, SETTLE_S};
use crate::influence::Complex;
use crate::lockin::{BlockResponse, window_blocks};
use crate::ripple::{Direction, RippleCapture, RippleError};
use std::ops::Range;

/// The slowest commanded speed (rev/s, absolute) a stretch runs at.
pub const MIN_SPEED_REV_S: f64 = 0.05;
/// The largest commanded acceleration (rev/s², absolute) inside a stretch: a slow sweep
/// (Prusa's `M974` runs at about 1 rev/s²) is kept, a move's ramps (Klipper's default
/// `max_accel` of thousands of mm/s² is over 50 rev/s²) are not.
pub const MAX_ACCEL_REV_S2: f64 = 10.0;
/// The shortest stretch kept (s), after [`SETTLE_S`] is cut from each end (the belt's
/// transient after a ramp, as Prusa's firmware cuts it).
pub const MIN_SEGMENT_S: f64 = 0.5;

/// One stretch of a log: the samples `range` of [`Log::times_s`].
#[derive(Debug, Clone, PartialEq)]
pub struct Segment<'a> {
    /// The log.
    pub log: &'a Log,
    /// Its samples.
    pub range: Range<usize>,
    /// The direction of the electrical angle (forward: the MCU position counting up).
    pub direction: Direction,
}

impl Log {
    /// The stretches where the commanded speed keeps one sign and at least
    /// [`MIN_SPEED_REV_S`], and the commanded acceleration stays within
    /// [`MAX_ACCEL_REV_S2`], less [`SETTLE_S`] at each end, at least [`MIN_SEGMENT_S`] long
    /// and with two samples or more.
    pub fn segments(&self) -> Vec<Segment<'_>> {
        let c = &self.commanded;
        let ok = |i: usize| c[i].speed_rev_s.abs() >= MIN_SPEED_REV_S && c[i].accel_rev_s2.abs() <= MAX_ACCEL_REV_S2;
        let mut out = Vec::new();
        let mut i = 0;
        while i < c.len() {
            if !ok(i) {
                i += 1;
                continue;
            }
            let sign = c[i].speed_rev_s.signum();
            let start = i;
            while i < c.len() && ok(i) && c[i].speed_rev_s.signum() == sign {
                i += 1;
            }
            let (t0, t1) = (self.times_s[start] + SETTLE_S, self.times_s[i - 1] - SETTLE_S);
            if t1 - t0 < MIN_SEGMENT_S {
                continue;
            }
            let a = start + self.times_s[start..i].partition_point(|&t| t < t0);
            let b = start + self.times_s[start..i].partition_point(|&t| t <= t1);
            if b < a + 2 {
                continue; // the accelerometer left a gap: no rate, no blocks
            }
            let direction = if sign > 0.0 { Direction::Forward } else { Direction::Backward };
            out.push(Segment { log: self, range: a..b, direction });
        }
        out
    }
}

impl Segment<'_> {
    /// The first and last sample's times (s).
    pub fn span_s(&self) -> (f64, f64) {
        let t = &self.log.times_s[self.range.clone()];
        (t[0], t[t.len() - 1])
    }
}

impl RippleCapture for Segment<'_> {
    fn origin(&self) -> String {
        format!("{}: t = {:.3} s", self.log.source, self.span_s().0)
    }

    /// The mean rate over the stretch.
    fn sampling_freq_hz(&self) -> f64 {
        let (t0, t1) = self.span_s();
        (self.range.len() - 1) as f64 / (t1 - t0)
    }

    /// The log's trial ([`super::KlipperOptions::trial`]), already in rad: `trial_scale`
    /// (Prusa's table units) does not apply.
    fn direction_and_trial(&self, _: f64) -> Result<(Direction, Option<(u32, Complex)>), RippleError> {
        let trial = self.log.trial.filter(|t| t.amplitude_rad != 0.0);
        Ok((self.direction, trial.map(|t| (t.harmonic, Complex::from_polar(t.amplitude_rad, t.phase_rad)))))
    }

    /// The blocks over the whole stretch; the reconstruction is not used (the log dates and
    /// angles its samples).
    fn blocks(&self, _: &Reconstruction, harmonic: u32, per_block: u32) -> Result<Vec<BlockResponse>, CaptureError> {
        if harmonic == 0 || per_block == 0 {
            let value = format!("{harmonic}, {per_block}");
            return Err(CaptureError::Parameter {
                what: "harmonic, periods_per_block",
                value,
                allowed: "both ≥ 1".into(),
            });
        }
        let r = self.range.clone();
        Ok(window_blocks(&self.log.commanded[r.clone()], &self.log.accel_m_s2[r], self.span_s(), harmonic, per_block))
    }
}
