//! The run log (the format is [`stepdamp_profile::runlog`]): one CSV row per control period,
//! made here from a simulated period.

use crate::closed_loop::PeriodRecord;
use crate::options::SimError;
pub use stepdamp_profile::runlog::{LOG_COLUMNS, LogRow, write_csv};

/// A log row from a simulated period.
pub trait FromRecord {
    /// The row for period `k` of a run at `pwm_hz`; the phase currents are the sampled ones
    /// the controller was given (with the simulation's sensor noise and quantisation), as a
    /// real drive logs them.
    fn from_record(k: usize, pwm_hz: f64, pole_pairs: u16, r: &PeriodRecord) -> Self;
}

impl FromRecord for LogRow {
    fn from_record(k: usize, pwm_hz: f64, pole_pairs: u16, r: &PeriodRecord) -> Self {
        let s = &r.signals;
        LogRow {
            t_s: k as f64 / pwm_hz,
            theta_cmd_rad: s.theta_cmd.mechanical_rad_f64(pole_pairs),
            theta_fb_rad: s.theta_fb.mechanical_rad_f64(pole_pairs),
            omega_fb_rad_s: f64::from(s.omega_fb_rad_s),
            i_a_a: f64::from(r.measurement.i_a_a),
            i_b_a: f64::from(r.measurement.i_b_a),
            i_d_a: f64::from(s.i_dq.d),
            i_q_a: f64::from(s.i_dq.q),
            iq_cmd_a: f64::from(s.i_dq_cmd.q),
            v_a_v: r.v_a_v,
            v_b_v: r.v_b_v,
        }
    }
}

/// Most rows of a run log held in memory (the Python binding's `simulate` returns the whole
/// log): 25 000 000 rows, 2.2 GB of [`LOG_COLUMNS`] `f64` columns, 1250 s at 20 kHz. The
/// CLI writes its log row by row and needs no such bound.
pub const MAX_LOG_ROWS: usize = 25_000_000;

/// Checks that a run of `duration_s` s at `pwm_hz` Hz logs at most [`MAX_LOG_ROWS`] rows
/// (one per control period, [`crate::RunSpec::periods`]), before they are allocated; returns
/// the number of rows.
pub fn check_log_rows(duration_s: f64, pwm_hz: f64) -> Result<usize, SimError> {
    let n = (duration_s * pwm_hz).round();
    if n.is_finite() && n >= 0.0 && n <= MAX_LOG_ROWS as f64 {
        return Ok(n as usize);
    }
    let max_s = MAX_LOG_ROWS as f64 / pwm_hz;
    Err(SimError::Option {
        what: "duration",
        reason: format!(
            "{duration_s} s must be in (0, {max_s}] s: at {pwm_hz} Hz it would log {n} rows, more than the \
             {MAX_LOG_ROWS} held in memory"
        ),
    })
}
