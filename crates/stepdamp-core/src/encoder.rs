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

use core::num::NonZeroU32;

use crate::angle::Position;
use crate::lowpass::LowPass;

/// Largest counts per revolution [`Encoder::new`] keeps (larger values are clamped): the
/// range [`crate::Config::new`] accepts, within which [`Encoder::position`]'s 32-bit long
/// division cannot overflow.
const MAX_COUNTS_PER_REV: u32 = crate::limits::COUNTS_PER_REV.max as u32;
/// Largest pole-pair count [`Encoder::new`] keeps (as [`crate::Config::new`] accepts).
const MAX_POLE_PAIRS: u16 = crate::limits::POLE_PAIRS.max as u16;
// The long division's bound (see `shl31_long_div`) holds for the range the limits allow.
const _: () = assert!(MAX_COUNTS_PER_REV <= 1 << 21 && MAX_POLE_PAIRS as u32 <= 1 << 10);

/// Encoder configuration, fixed at start-up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Encoder {
    counts_per_rev: NonZeroU32,
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
    /// [`crate::Config::new`]; values outside are clamped into those ranges).
    pub fn new(counts_per_rev: u32, pole_pairs: u16, period_s: f32, velocity_filter_hz: f32) -> Self {
        let cpr = NonZeroU32::new(counts_per_rev.clamp(1, MAX_COUNTS_PER_REV)).unwrap_or(NonZeroU32::MIN);
        Encoder {
            counts_per_rev: cpr,
            pole_pairs: pole_pairs.clamp(1, MAX_POLE_PAIRS),
            rad_s_per_count: core::f32::consts::TAU / (cpr.get() as f32 * period_s),
            velocity_filter: LowPass::new(velocity_filter_hz, period_s),
        }
    }

    /// Counts per mechanical revolution.
    pub fn counts_per_rev(&self) -> u32 {
        self.counts_per_rev.get()
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
        // delta = whole revolutions `turns` plus `extra` ∈ [0, cpr) counts, by one 32-bit
        // division (no 64-bit division on the chip): floor division of a signed count.
        let cpr = self.counts_per_rev;
        let mag = delta.unsigned_abs();
        // On 64-bit hosts (the simulator) skip the division in the usual case of less than
        // a revolution per period; the chip's code stays as it was (counted instructions).
        let (q, m) =
            if cfg!(target_pointer_width = "64") && mag < cpr.get() { (0, mag) } else { (mag / cpr, mag % cpr) };
        let (mut turns, extra) = if delta >= 0 {
            (i64::from(q), m)
        } else if m == 0 {
            (-i64::from(q), 0)
        } else {
            (-i64::from(q) - 1, cpr.get() - m)
        };
        // rem, extra < cpr ≤ 2²⁰: the sum cannot overflow and is below 2·cpr.
        let mut r = st.rem + extra;
        if r >= cpr.get() {
            r -= cpr.get();
            turns += 1;
        }
        st.rem = r;
        st.revs = st.revs.wrapping_add(turns);
        self.velocity_filter.update(&mut st.velocity_rad_s, delta as f32 * self.rad_s_per_count);
        self.position(st)
    }

    /// The position the state holds.
    #[inline]
    pub fn position(&self, st: &EncoderState) -> Position {
        let np = u64::from(self.pole_pairs);
        // The centre of the count's interval [n, n+1): the unbiased estimate whichever way
        // the rotor turns (rem + ½ counts, i.e. ⌊(2·rem + 1)·Nr·2³¹ / cpr⌋ units; (2·rem +
        // 1)·Nr < 2²¹·2¹⁰ fits a u32).
        let n = (2 * st.rem + 1) * u32::from(self.pole_pairs);
        let frac = shl31_div(n, self.counts_per_rev);
        Position(st.revs.wrapping_mul((np << 32) as i64).wrapping_add(frac as i64))
    }
}

/// `⌊n·2³¹ / d⌋` exactly, for `d ≤ 2²¹`: on 64-bit targets (the simulator's hosts) one
/// 64-bit division, a single instruction there; elsewhere [`shl31_long_div`]. The same
/// result either way (test `long_division_matches_64_bit_division`).
#[cfg(target_pointer_width = "64")]
#[inline]
fn shl31_div(n: u32, d: NonZeroU32) -> u64 {
    (u64::from(n) << 31) / core::num::NonZeroU64::from(d)
}

/// See the 64-bit variant.
#[cfg(not(target_pointer_width = "64"))]
#[inline]
fn shl31_div(n: u32, d: NonZeroU32) -> u64 {
    shl31_long_div(n, d)
}

/// `⌊n·2³¹ / d⌋` exactly, for `d ≤ 2²¹`, by long division in 32-bit steps (11, 10 and 10
/// bits; each shifted remainder is below `d·2¹¹ ≤ 2³²`): the Cortex-M4 divides 32-bit
/// integers in hardware but 64-bit ones in a ~70-instruction library routine.
#[cfg_attr(target_pointer_width = "64", allow(dead_code))] // tested on every target
#[inline]
fn shl31_long_div(n: u32, d: NonZeroU32) -> u64 {
    let (q0, r) = (n / d, n % d);
    let (q1, r) = ((r << 11) / d, (r << 11) % d);
    let (q2, r) = ((r << 10) / d, (r << 10) % d);
    let q3 = (r << 10) / d;
    (u64::from(q0) << 31) + (u64::from(q1) << 20) + (u64::from(q2) << 10) + u64::from(q3)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn long_division_matches_64_bit_division(n in any::<u32>(), d in 1u32..=(1 << 21)) {
            let d = NonZeroU32::new(d).unwrap();
            let want = (u64::from(n) << 31) / u64::from(d.get());
            prop_assert_eq!(shl31_long_div(n, d), want);
            prop_assert_eq!(shl31_div(n, d), want);
        }

        #[test]
        fn position_matches_the_exact_count_arithmetic(
            counts in proptest::collection::vec(any::<i32>(), 1..50), cpr in 1u32..=(1 << 20), np in 1u16..=1024
        ) {
            let enc = Encoder::new(cpr, np, 5e-5, 100.0);
            let mut st = EncoderState::default();
            let (mut raw, mut total) = (0u32, 0i128);
            for c in counts {
                raw = raw.wrapping_add(c as u32);
                total += i128::from(c);
                let p = enc.update(&mut st, raw);
                // Centre of count `total`: (total + ½)/cpr revolutions, floor in units,
                // modulo 2⁶⁴ (a Position wraps like the counter: few counts per turn and
                // many pole pairs overflow i64 units within an i32 of counts).
                let units = (2 * total + 1) * i128::from(np) * (1i128 << 31);
                let want = units.div_euclid(i128::from(cpr));
                prop_assert_eq!(p.0, want as i64);
                prop_assert!(st.rem < cpr);
            }
        }
    }

    proptest! {
        #[test]
        fn position_is_exact_for_small_moves_too(
            counts in proptest::collection::vec(-5000i32..5000, 1..200), cpr in 1u32..=20_000, np in 1u16..=1024
        ) {
            // Moves below a revolution per period (the usual case, which 64-bit hosts take
            // without a division) and beyond, against the exact arithmetic.
            let enc = Encoder::new(cpr, np, 5e-5, 100.0);
            let mut st = EncoderState::default();
            let (mut raw, mut total) = (0u32, 0i128);
            for c in counts {
                raw = raw.wrapping_add(c as u32);
                total += i128::from(c);
                let p = enc.update(&mut st, raw);
                let units = (2 * total + 1) * i128::from(np) * (1i128 << 31);
                prop_assert_eq!(p.0, units.div_euclid(i128::from(cpr)) as i64);
                prop_assert!(st.rem < cpr);
            }
        }
    }

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
