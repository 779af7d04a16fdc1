//! The open-loop compensations that microstepping drives actually apply, next to the
//! patent's q-current injection: [`Compensation::Angle`] (rotate the current vector by
//! `Δ(θ_cmd)` at constant magnitude, what Prusa's phase stepping and a Trinamic microstep
//! table do) and [`Compensation::Table`] (replay an exported integer table of reference
//! coil currents exactly as the drive would).
//!
//! **Angle law.** With the detent series `S(θe) = (1/Km) Σ A_k sin(k θe + φ_k)` (A) the
//! drive rotates the holding-current vector by `Δ = S(θ_cmd)/I_hold` (rad):
//! `i_d = I_hold cos Δ`, `i_q = I_hold sin Δ` in the frame of `θ_cmd`. To first order
//! `i_q ≈ S`, the patent's injection; the difference is second order in `Δ`
//! (`i_d` drops by `I·Δ²/2`, `i_q` by `I·Δ³/6`). `Δ` is bounded to `±π/2`.
//!
//! **Table law.** A [`CorrectionTable`] holds, for each of [`TABLE_TICKS`] ticks of one
//! electrical period and each direction of travel, the reference currents of stepdamp's
//! windings a and b as integers, `full_scale` counts being `I_hold`. The tick is
//! `floor(1024·θe_cmd/2π)` (the drive holds its reference over a tick, as a step/dir drive
//! at 256 microsteps per full step or Prusa's 1024-tick phase does); the reference is
//! Park-transformed at `θ_cmd` into the d/q commands the current loop follows. The
//! forward table is used while the commanded speed is ≥ 0, the backward one below 0.
//! Exporters (crate `stepdamp-export`) build these tables from Prusa's and Trinamic's
//! formats, with each project's coil and angle conventions mapped onto ours.
//!
//! [`Compensation::Angle`]: crate::Compensation::Angle
//! [`Compensation::Table`]: crate::Compensation::Table

use crate::config::{ConfigError, Reason};
use crate::park::{Ab, Dq};

/// Ticks of a [`CorrectionTable`] per electrical period (Prusa's `MOTOR_PERIOD`, the
/// Trinamic `MSCNT` range).
pub const TABLE_TICKS: usize = 1024;

/// Reference coil currents per tick of one electrical period, for both directions.
///
/// Entry `[tick][0]` is winding a, `[tick][1]` winding b (stepdamp's windings,
/// docs/design.md#the-plant: `i_d = i_a cos θe + i_b sin θe`), in counts of which
/// `full_scale` is `I_hold`.
/// Tick `n` covers `θe ∈ [2π·n/1024, 2π·(n+1)/1024)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CorrectionTable {
    /// Table used while the commanded speed is ≥ 0.
    pub forward: [[i16; 2]; TABLE_TICKS],
    /// Table used while the commanded speed is < 0.
    pub backward: [[i16; 2]; TABLE_TICKS],
    /// Counts that stand for the holding current (> 0); 248 for Prusa and the Trinamic
    /// default table's amplitude.
    pub full_scale: i16,
}

impl Default for CorrectionTable {
    fn default() -> Self {
        CorrectionTable { forward: [[0; 2]; TABLE_TICKS], backward: [[0; 2]; TABLE_TICKS], full_scale: 1 }
    }
}

impl CorrectionTable {
    /// Largest entry magnitude over both directions and windings, in counts.
    pub fn max_abs(&self) -> i32 {
        self.forward.iter().chain(self.backward.iter()).flatten().map(|&v| i32::from(v).abs()).max().unwrap_or(0)
    }
}

/// Checks a table for [`crate::Config::with_table`]: `full_scale > 0`, and the largest
/// entry, scaled to `holding_current_a`, within `current_limit_a`.
pub fn check_table(table: &CorrectionTable, holding_current_a: f32, current_limit_a: f32) -> Result<(), ConfigError> {
    if table.full_scale <= 0 {
        return Err(ConfigError::Invalid {
            field: "table.full_scale",
            value: f32::from(table.full_scale),
            reason: Reason::Other("must be > 0"),
        });
    }
    let peak = table.max_abs() as f32 / f32::from(table.full_scale) * holding_current_a;
    if peak > current_limit_a {
        return Err(ConfigError::Invalid {
            field: "table",
            value: peak,
            reason: Reason::Other("the largest reference current (A) exceeds drive.current_limit_a"),
        });
    }
    Ok(())
}

/// The tick of a position: the top 10 bits of its fraction of an electrical turn.
#[inline]
pub fn tick_of(position: crate::Position) -> usize {
    ((position.0 as u32) >> 22) as usize
}

/// Angle law: the holding-current vector rotated by `Δ = series_a / I_hold` (bounded to
/// ±π/2), at constant magnitude, in the frame of `θ_cmd`. With zero holding current there
/// is nothing to rotate: zero.
#[inline]
pub fn angle_law(holding_current_a: f32, series_a: f32) -> Dq {
    if holding_current_a <= 0.0 {
        return Dq::default();
    }
    let delta = crate::bound(series_a / holding_current_a, -core::f32::consts::FRAC_PI_2, core::f32::consts::FRAC_PI_2);
    let (s, c) = crate::trig::sin_cos_rad(delta);
    Dq { d: holding_current_a * c, q: holding_current_a * s }
}

/// Table law: the reference of `tick` for the direction of `speed_rad_s`, scaled so that
/// `full_scale` counts are `holding_current_a`, Park-transformed at `θ_cmd` given
/// `(sin θe, cos θe)`.
#[inline]
pub fn table_law(
    table: &CorrectionTable,
    tick: usize,
    speed_rad_s: f32,
    holding_current_a: f32,
    sin: f32,
    cos: f32,
) -> Dq {
    let rows = if speed_rad_s < 0.0 { &table.backward } else { &table.forward };
    let [a, b] = rows[tick % TABLE_TICKS];
    let scale = holding_current_a / f32::from(table.full_scale.max(1));
    crate::park::park(Ab { a: f32::from(a) * scale, b: f32::from(b) * scale }, sin, cos)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Position;

    #[test]
    fn angle_law_keeps_the_magnitude_and_matches_the_injection_to_first_order() {
        for &s in &[-0.3f32, -0.01, 0.0, 0.02, 0.2] {
            let dq = angle_law(1.9, s);
            assert!((libm::hypotf(dq.d, dq.q) - 1.9).abs() < 1e-5);
            // i_q = I sin(S/I): within I·Δ³/6 of S.
            let delta = s / 1.9;
            assert!((dq.q - s).abs() <= 1.9 * delta.abs().powi(3) / 6.0 + 1e-6, "{s}");
        }
        assert_eq!(angle_law(0.0, 1.0), Dq::default());
        let big = angle_law(1.0, 100.0);
        assert!((big.q - 1.0).abs() < 1e-6 && big.d.abs() < 1e-6);
    }

    #[test]
    fn tick_is_the_floor_of_1024_per_electrical_turn() {
        assert_eq!(tick_of(Position(0)), 0);
        assert_eq!(tick_of(Position((1 << 22) - 1)), 0);
        assert_eq!(tick_of(Position(1 << 22)), 1);
        assert_eq!(tick_of(Position(-1)), 1023);
        assert_eq!(tick_of(Position((5i64 << 32) + (7 << 22))), 7);
    }

    #[test]
    fn config_refuses_a_table_law_without_a_table_or_in_servo_mode() {
        use crate::{Compensation, Config, ConfigError, Mode, Params};
        let p = Params::patent_motor(Mode::OpenLoop, Compensation::Table);
        assert!(matches!(Config::new(&p), Err(ConfigError::Invalid { field: "compensation", .. })));
        let t = CorrectionTable { full_scale: 248, ..Default::default() };
        assert!(Config::with_table(&p, &t).is_ok());
        for c in [Compensation::Angle, Compensation::Table] {
            let servo = Params::patent_motor(Mode::Servo, c);
            assert!(matches!(Config::with_table(&servo, &t), Err(ConfigError::Invalid { field: "compensation", .. })));
        }
        // 248 counts are I_hold = 1.9 A; 500 counts are 3.8 A, beyond the 3 A limit.
        let mut big = t;
        big.forward[3] = [500, 0];
        assert!(matches!(Config::with_table(&p, &big), Err(ConfigError::Invalid { field: "table", .. })));
        let zero = CorrectionTable { full_scale: 0, ..Default::default() };
        assert!(Config::with_table(&p, &zero).is_err());
    }

    #[test]
    fn step_in_table_mode_commands_the_tables_reference() {
        use crate::{Compensation, Config, Measurement, Mode, Params, State, step};
        let p = Params::patent_motor(Mode::OpenLoop, Compensation::Table);
        let mut t = CorrectionTable { full_scale: 248, ..Default::default() };
        // Tick 0 only: the reference is half the holding current on winding b (q at θe = 0).
        t.forward[0] = [0, 124];
        let cfg = Config::with_table(&p, &t).unwrap();
        let mut st = State::default();
        let out = step(&cfg, &mut st, &Measurement::default());
        assert!(
            (out.signals.i_dq_cmd.q - 0.95).abs() < 1e-6 && out.signals.i_dq_cmd.d.abs() < 1e-6,
            "{:?}",
            out.signals
        );
    }

    #[test]
    fn a_plain_sine_table_gives_the_holding_current_on_d() {
        let mut t = CorrectionTable { full_scale: 248, ..Default::default() };
        for n in 0..TABLE_TICKS {
            let th = core::f32::consts::TAU * n as f32 / TABLE_TICKS as f32;
            let e = [libm::roundf(248.0 * libm::cosf(th)) as i16, libm::roundf(248.0 * libm::sinf(th)) as i16];
            t.forward[n] = e;
            t.backward[n] = [-e[0], -e[1]];
        }
        let th = core::f32::consts::TAU * 100.0 / 1024.0;
        let dq = table_law(&t, 100, 1.0, 1.9, libm::sinf(th), libm::cosf(th));
        assert!((dq.d - 1.9).abs() < 0.01 && dq.q.abs() < 0.01, "{dq:?}");
        let back = table_law(&t, 100, -1.0, 1.9, libm::sinf(th), libm::cosf(th));
        assert!((back.d + 1.9).abs() < 0.01, "the backward table is used below zero speed");
    }
}
