//! The run log of design.md §6: one CSV row per control period.

use crate::closed_loop::PeriodRecord;
use serde::{Deserialize, Serialize};

/// One row of a run log. Column names are the field names.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LogRow {
    /// Time in s.
    pub t_s: f64,
    /// Commanded mechanical angle in rad.
    pub theta_cmd_rad: f64,
    /// Encoder angle in rad (quantised).
    pub theta_fb_rad: f64,
    /// Filtered encoder velocity in rad/s.
    pub omega_fb_rad_s: f64,
    /// Sampled phase A current in A.
    pub i_a_a: f64,
    /// Sampled phase B current in A.
    pub i_b_a: f64,
    /// d current in the controller's frame in A.
    pub i_d_a: f64,
    /// q current in the controller's frame in A.
    pub i_q_a: f64,
    /// q current command in A.
    pub iq_cmd_a: f64,
}

impl LogRow {
    /// The row for period `k` of a run at `pwm_hz`; the phase currents are the sampled ones
    /// the controller was given (with the simulation's sensor noise and quantisation), as a
    /// real drive logs them.
    pub fn from_record(k: usize, pwm_hz: f64, pole_pairs: u16, r: &PeriodRecord) -> Self {
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
        }
    }
}

/// Writes rows as CSV with the header of design.md §6.
pub fn write_csv<W: std::io::Write>(w: W, rows: &[LogRow]) -> Result<(), csv::Error> {
    let mut wr = csv::Writer::from_writer(w);
    for r in rows {
        wr.serialize(r)?;
    }
    wr.flush()?;
    Ok(())
}
