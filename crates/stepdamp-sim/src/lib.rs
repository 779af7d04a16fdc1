//! # stepdamp-sim
//!
//! A fast, physically honest simulator of a two-phase hybrid stepper motor, its drive and
//! its load (docs/design.md#the-plant, docs/design.md#the-drive-and-its-control-laws),
//! closed around the very controller that runs on the chip (`stepdamp-core`). `f64` plant,
//! RK4 with zero-order-hold voltages, Karnopp stick/slip Coulomb friction, any list of
//! detent harmonics, ADC and encoder quantisation, current noise, a one-period computation
//! delay, finite bus voltage through the patent's three-leg stage.
//!
//! ```
//! use stepdamp_sim::{ClosedLoop, Compensation, Profile, RunSpec, SimOptions, run};
//! use stepdamp_core::Mode;
//!
//! let motor = Profile::preset("patent-motor").unwrap();
//! let spec = RunSpec { duration_s: 0.4, window_s: 0.2, ..RunSpec::at(8.4) };
//! let mut lp = ClosedLoop::new(&motor, &motor, Mode::OpenLoop, Compensation::Patent, &SimOptions::default())?;
//! let m = run(&mut lp, &spec, motor.drive.pwm_hz, |_, _| {})?;
//! assert!(!m.lost_sync);
//! # Ok::<(), stepdamp_sim::SimError>(())
//! ```

pub mod closed_loop;
pub mod friction;
pub mod lanes;
pub mod lockstep;
pub mod metrics;
pub mod options;
pub mod plant;
/// Motor profiles: [`stepdamp_profile`], re-exported where the simulator's users found them.
pub mod profile {
    pub use stepdamp_profile::*;
}
pub mod runlog;
pub mod scenario;
pub mod sensors;
pub mod summary;
pub mod sweep;

pub use closed_loop::{ClosedLoop, PeriodRecord};
pub use lockstep::{run_lockstep, run_lockstep_while};
pub use metrics::RunMetrics;
pub use options::{
    ESTIMATED_IS_OPEN_LOOP_ONLY, SimError, SimOptions, check_mode_compensation, check_same_hardware, check_substeps,
};
pub use plant::{PlantParams, PlantState};
pub use profile::{PRESETS, Profile, ProfileError};
pub use scenario::{RunSpec, SETTLE_S, check_speed, max_speed_rad_s, run, run_while};
pub use stepdamp_core::{Compensation, CorrectionTable, Mode};
pub use summary::SweepSummary;
pub use sweep::{
    CheckedSweep, MAX_POINTS, SweepRow, SweepSpec, check_points, derived_seed, linear_grid, sweep, sweep_until,
};

#[cfg(test)]
mod flux_tests;
#[cfg(test)]
mod tests;
