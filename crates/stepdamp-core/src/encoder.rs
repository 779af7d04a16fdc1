//! Incremental encoder: raw wrapping counter → exact [`Position`] and a filtered velocity.
//!
//! The counter is a free-running `u32` (a 16-bit hardware timer is widened by the firmware),
//! zero at power-on where the rotor is at `θ = 0`, and counting *up* when the rotor turns
//! in the positive direction (positive `θ`, the direction a positive speed command and a
//! positive `i_q` turn it): if the hardware counts the other way, negate the counter. Each period the wrapping difference of
//! the counter (±2³¹ counts at most between two samples) moves an exact count of whole
//! revolutions and a remainder in `[0, cpr)`, so the position never drifts. Velocity is the
//! count difference divided by `Ts`, low-pass filtered: its quantum before the filter is
//! `2π/(cpr·Ts)` (31.4 rad/s for 4000 counts at 20 kHz, the patent's 300 rpm).

use crate::angle::Position;
use crate::lowpass::LowPass;

/// Encoder configuration, fixed at start-up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Encoder {
    counts_per_rev: u32,
    pole_pairs: u16,
    rad_s_per_count: f32,
    velocity_filter: LowPass,
}

/// Encoder state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EncoderState {
    last_raw: u32,
    revs: i64,
    rem: u32,
    /// Filtered velocity in rad/s (mechanical).
    pub velocity_rad_s: f32,
}

impl Encoder {
    /// `counts_per_rev` in `1..=2²⁰` and `pole_pairs` in `1..=1024` (checked by
    /// [`crate::Config::new`]).
    pub fn new(counts_per_rev: u32, pole_pairs: u16, period_s: f32, velocity_filter_hz: f32) -> Self {
        Encoder {
            counts_per_rev: counts_per_rev.max(1),
            pole_pairs: pole_pairs.max(1),
            rad_s_per_count: core::f32::consts::TAU / (counts_per_rev.max(1) as f32 * period_s),
            velocity_filter: LowPass::new(velocity_filter_hz, period_s),
        }
    }

    /// Counts per mechanical revolution.
    pub fn counts_per_rev(&self) -> u32 {
        self.counts_per_rev
    }

    /// Velocity of one count per period, rad/s (`2π/(cpr·Ts)`).
    pub fn rad_s_per_count(&self) -> f32 {
        self.rad_s_per_count
    }

    /// Takes this period's raw counter value; returns the rotor position.
    #[inline]
    pub fn update(&self, st: &mut EncoderState, raw: u32) -> Position {
        let delta = raw.wrapping_sub(st.last_raw) as i32;
        st.last_raw = raw;
        let cpr = i64::from(self.counts_per_rev);
        let r = i64::from(st.rem) + i64::from(delta);
        if (0..cpr).contains(&r) {
            st.rem = r as u32;
        } else {
            st.revs = st.revs.wrapping_add(r.div_euclid(cpr));
            st.rem = r.rem_euclid(cpr) as u32;
        }
        self.velocity_filter.update(&mut st.velocity_rad_s, delta as f32 * self.rad_s_per_count);
        self.position(st)
    }

    /// The position the state holds.
    #[inline]
    pub fn position(&self, st: &EncoderState) -> Position {
        let np = u64::from(self.pole_pairs);
        // The centre of the count's interval [n, n+1): the unbiased estimate whichever way
        // the rotor turns (rem + ½ counts; (2·rem + 1)·Nr < 2²¹·2¹⁰, so the shift by 31 stays
        // below 2⁶² and cannot overflow).
        let frac = (((2 * u64::from(st.rem) + 1) * np) << 31) / u64::from(self.counts_per_rev);
        Position(st.revs.wrapping_mul((np << 32) as i64).wrapping_add(frac as i64))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_map_to_exact_angles_across_wraps() {
        let enc = Encoder::new(4000, 50, 5e-5, 0.0);
        let mut st = EncoderState::default();
        // One count back from zero: the centre of count −1 is −½/4000 rev = −π/4000 rad.
        let p = enc.update(&mut st, u32::MAX);
        assert!((p.mechanical_rad_f64(50) + core::f64::consts::PI / 4000.0).abs() < 1e-9);
        // 2.5 revolutions forward in steps of 997 counts, wrapping the u32 counter.
        let mut raw = u32::MAX;
        for _ in 0..10 {
            raw = raw.wrapping_add(1001);
            enc.update(&mut st, raw);
        }
        let want = (10.0 * 1001.0 - 0.5) / 4000.0 * core::f64::consts::TAU;
        assert!((enc.position(&st).mechanical_rad_f64(50) - want).abs() < 1e-9);
    }

    #[test]
    fn velocity_is_count_rate_through_the_filter() {
        let ts = 5e-5;
        let enc = Encoder::new(4000, 50, ts, 0.0);
        let mut st = EncoderState::default();
        enc.update(&mut st, 2);
        // Two counts per period at 20 kHz = 10 rev/s = 62.83 rad/s.
        assert!((st.velocity_rad_s - 62.831_85).abs() < 1e-3);
    }

    #[test]
    fn electrical_angle_of_a_count_is_exact() {
        let enc = Encoder::new(4000, 50, 5e-5, 0.0);
        let mut st = EncoderState::default();
        // Count 20 spans [20, 21) of the 80 counts per electrical rev: centre 20.5/80 turn.
        let p = enc.update(&mut st, 20);
        assert!((p.electrical_angle_rad() - 20.5 / 80.0 * core::f32::consts::TAU).abs() < 1e-6);
    }
}
