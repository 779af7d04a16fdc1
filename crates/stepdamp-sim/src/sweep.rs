//! Parallel velocity-error sweeps over a speed grid (rayon). Deterministic: every lane has
//! its own noise seed derived from the sweep seed and its index, so the table is the same
//! on any number of threads.

use crate::closed_loop::{
    ClosedLoop, Compensation, SimError, SimOptions, compensation_name, controller_config, mode_name,
};
use crate::profile::Profile;
use crate::scenario::{RunSpec, run};
use rayon::prelude::*;
use serde::Serialize;
use stepdamp_core::Mode;

/// What to sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepSpec {
    /// Speeds in rad/s.
    pub speeds_rad_s: Vec<f64>,
    /// Control modes.
    pub modes: Vec<Mode>,
    /// Compensations.
    pub compensations: Vec<Compensation>,
    /// Run shape (its speed is replaced by each grid speed).
    pub run: RunSpec,
    /// Simulation options (its seed is the base of the lane seeds).
    pub options: SimOptions,
}

/// One row of the sweep table (design.md §6; column names are the field names).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepRow {
    /// `open-loop` or `servo`.
    pub mode: &'static str,
    /// Compensation name.
    pub compensation: &'static str,
    /// Commanded speed in rad/s.
    pub speed_cmd_rad_s: f64,
    /// RMS velocity error in rad/s.
    pub vel_err_rms_rad_s: f64,
    /// Peak-to-peak velocity error in rad/s.
    pub vel_err_pp_rad_s: f64,
    /// The rotor slipped.
    pub lost_sync: bool,
}

/// `points` speeds evenly spaced from `from` to `to` rad/s inclusive.
pub fn linear_grid(from: f64, to: f64, points: usize) -> Vec<f64> {
    match points {
        0 => vec![],
        1 => vec![from],
        _ => (0..points).map(|i| from + (to - from) * i as f64 / (points - 1) as f64).collect(),
    }
}

/// Runs the sweep; `tick` is called once per finished lane (from any thread).
/// Rows come ordered by mode, then compensation, then speed.
pub fn sweep(
    motor: &Profile,
    controller: &Profile,
    spec: &SweepSpec,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<SweepRow>, SimError> {
    let mut lanes = Vec::new();
    for &mode in &spec.modes {
        for &comp in &spec.compensations {
            let cfg = controller_config(controller, mode, comp)?;
            // Fail before the parallel part if options are bad.
            ClosedLoop::with_config(motor, cfg, &spec.options)?;
            for &w in &spec.speeds_rad_s {
                lanes.push((mode, comp, cfg, w));
            }
        }
    }
    let pwm = motor.drive.pwm_hz;
    let rows = lanes
        .par_iter()
        .enumerate()
        .map(|(i, &(mode, comp, cfg, w))| {
            let opts = SimOptions { seed: lane_seed(spec.options.seed, i as u64), ..spec.options };
            let mut lp = ClosedLoop::with_config(motor, cfg, &opts).expect("options checked above");
            let m = run(&mut lp, &RunSpec { speed_rad_s: w, ..spec.run }, pwm, |_, _| {});
            tick();
            SweepRow {
                mode: mode_name(mode),
                compensation: compensation_name(comp),
                speed_cmd_rad_s: w,
                vel_err_rms_rad_s: m.vel_err_rms_rad_s,
                vel_err_pp_rad_s: m.vel_err_pp_rad_s,
                lost_sync: m.lost_sync,
            }
        })
        .collect();
    Ok(rows)
}

/// SplitMix64 of the base seed and the lane index.
fn lane_seed(base: u64, lane: u64) -> u64 {
    let mut z = base.wrapping_add(lane.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}
