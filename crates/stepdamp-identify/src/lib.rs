//! # stepdamp-identify
//!
//! Identification of the detent harmonics and the friction of a hybrid stepper motor
//! (docs/design.md#identification; US 7,733,051 part A, claim 1), from servo-mode run logs of the simulator or
//! of a real drive, and the motor profile that results.
//!
//! | module | what |
//! |---|---|
//! | [`from_logs`] | the one entry from logs: read each once, take the route, fit, report, profile |
//! | [`log`] | read a run-log CSV (docs/files.md); errors name the file, line and column |
//! | [`kinematics`] | speed and acceleration from a quantised encoder angle |
//! | [`lsq`] | least squares (QR + SVD) with a block-robust covariance |
//! | [`emf`] | the flux linkage's harmonics and phase imbalance from a fast run's back-EMF |
//! | [`fit`] | the torque balance fit: harmonics, `Fs`, `D`, intervals, warnings |
//! | [`conditions`] | what the logs can decide: slow runs short of friction, `J` fitted or held |
//! | [`model`] | the identified model and the profile made from it |
//! | [`plan`] | which runs to record and why |
//! | `simulate` | simulate the plan's runs, write their logs (feature `simulate`) |
//! | `refine` | the patent's criterion: feed-forward on, remove the remaining ripple (feature `simulate`) |
//! | [`static_curve`] | torque-versus-angle table → FFT → harmonics |
//! | [`spectrum`] | amplitude per harmonic order of a torque against angle (reports) |
//! | [`stick`] | stick–slip: edge-timed angle, stuck samples with a margin |
//! | [`validation`] | share of the periodic effort ripple explained, residual by order, verdict |
//!
//! Reading logs and fitting need only `stepdamp-profile`; what simulates (the `simulate`
//! and `refine` modules) needs the default feature `simulate` (the simulator and rayon).
//!
//! Sign conventions are the profile's: the detent torque on the rotor is
//! `−Σ A_k sin(k·Nr·θ + φ_k)`, friction `−Fs·sgn(ω) − D·ω`; phases are in `(−π, π]`.
//!
//! ```
//! use stepdamp_identify::{fit::{fit, FitOptions}, model::Model, plan::{plan, simulate_plan, PlanOptions}};
//! use stepdamp_sim::{Compensation, Profile};
//! # #[cfg(feature = "simulate")] {
//!
//! let motor = Profile::preset("patent-motor").unwrap();
//! // The runs to record (short ones here), simulated with current noise.
//! let opts = PlanOptions { electrical_periods: 8.0, min_steady_s: 0.5, ..PlanOptions::default() };
//! let p = plan(&motor, &opts)?;
//! let logs = simulate_plan(&motor, &p.profile, Compensation::Off, &p, opts.current_noise_a, 1, &|| {})?;
//! // Fit orders 1, 2, 4 and write the result into a profile.
//! let f = fit(&logs, &FitOptions::for_profile(&p.profile, &[1, 2, 4]))?;
//! let identified = Model::from_fit(&f).apply_to(&motor, Some("identified"), "identified.toml")?;
//! let a4 = identified.motor.detent.iter().find(|h| h.order == 4).unwrap().amplitude_nm;
//! assert!((a4 - 0.02).abs() < 0.001);
//! # }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod conditions;
pub mod emf;
pub mod fit;
pub mod from_logs;
pub mod kinematics;
pub mod log;
pub mod lsq;
pub mod model;
pub mod plan;
#[cfg(feature = "simulate")]
pub mod refine;
pub mod sensorless;
#[cfg(feature = "simulate")]
pub mod simulate;
pub mod spectrum;
pub mod static_curve;
pub mod stick;
pub mod validation;

#[cfg(all(test, feature = "simulate"))]
mod tests;

#[cfg(all(test, feature = "simulate"))]
mod flux_tests;
