//! The run log: one CSV row per control period, written by the simulator (and by a real
//! drive) and read by identification. The column names are the field names, in this order.

use serde::{Deserialize, Serialize};

/// The columns of a run log, in the order [`write_csv`] writes a [`LogRow`] (its field names).
pub const LOG_COLUMNS: [&str; 11] = [
    "t_s",
    "theta_cmd_rad",
    "theta_fb_rad",
    "omega_fb_rad_s",
    "i_a_a",
    "i_b_a",
    "i_d_a",
    "i_q_a",
    "iq_cmd_a",
    "v_a_v",
    "v_b_v",
];

/// One row of a run log. Column names are the field names ([`LOG_COLUMNS`]).
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
    /// Mean voltage across winding A over `[t_s, t_s + Ts)` in V, after the modulator's
    /// limiting (with a computation delay: the voltage actually applied in that interval).
    pub v_a_v: f64,
    /// Mean voltage across winding B over `[t_s, t_s + Ts)` in V (as `v_a_v`).
    pub v_b_v: f64,
}

/// One row of a sensorless run log: what a drive without an encoder knows (the
/// sensorless route of identification). Column names are the field names.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SensorlessRow {
    /// Time in s.
    pub t_s: f64,
    /// Commanded mechanical angle in rad.
    pub theta_cmd_rad: f64,
    /// Sampled phase A current in A.
    pub i_a_a: f64,
    /// Sampled phase B current in A.
    pub i_b_a: f64,
    /// Mean voltage across winding A over `[t_s, t_s + Ts)` in V, as applied.
    pub v_a_v: f64,
    /// Mean voltage across winding B over `[t_s, t_s + Ts)` in V, as applied.
    pub v_b_v: f64,
}

impl From<&LogRow> for SensorlessRow {
    fn from(r: &LogRow) -> Self {
        SensorlessRow {
            t_s: r.t_s,
            theta_cmd_rad: r.theta_cmd_rad,
            i_a_a: r.i_a_a,
            i_b_a: r.i_b_a,
            v_a_v: r.v_a_v,
            v_b_v: r.v_b_v,
        }
    }
}

/// Writes rows (a [`LogRow`] or a [`SensorlessRow`]) as CSV, the header from the field names.
pub fn write_csv<W: std::io::Write, R: Serialize>(w: W, rows: &[R]) -> Result<(), csv::Error> {
    let mut wr = csv::Writer::from_writer(w);
    for r in rows {
        wr.serialize(r)?;
    }
    wr.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_columns_are_the_header_the_writer_writes() {
        let mut out = Vec::new();
        write_csv(&mut out, &[LogRow::default()]).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert_eq!(text.lines().next().unwrap(), LOG_COLUMNS.join(","));
    }
}
