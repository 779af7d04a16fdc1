//! What a simulation is set up with and what can go wrong: the run options
//! ([`SimOptions`]), the errors ([`SimError`]), and the checks every entry point (the
//! closed loop, the sweep, the command line, the Python binding) shares: the options'
//! ranges, the same drive and encoder hardware in the motor's and the controller's
//! profiles, and which compensations exist in which mode. Each check is defined here once.

use crate::profile::{Profile, ProfileError, TopologyName};
use stepdamp_core::{Compensation, Config, ConfigError, Mode, Topology};

/// Largest [`SimOptions::substeps`].
pub const MAX_SUBSTEPS: u32 = 1000;

/// Simulation options (the physics of the drive that a profile does not describe).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimOptions {
    /// RK4 steps per control period (≥ 1). One is the default: against two, it changes
    /// the sweep's velocity-error metrics by well under the 1 % step-convergence tolerance
    /// (test `halving_the_integration_step_changes_the_sweep_metric_by_under_one_percent`).
    pub substeps: u32,
    /// Standard deviation of the current-sensor noise in A.
    pub current_noise_a: f64,
    /// ADC quantisation step of the current samples in A (0 = none).
    pub current_lsb_a: f64,
    /// Seed of the noise generator.
    pub seed: u64,
    /// Constant load torque in N·m opposing the commanded direction of travel (≥ 0).
    pub load_torque_nm: f64,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions { substeps: 1, current_noise_a: 0.0, current_lsb_a: 0.0, seed: 1, load_torque_nm: 0.0 }
    }
}

impl SimOptions {
    /// Checks the options: [`check_substeps`], and the current noise, current LSB and load
    /// torque finite and ≥ 0. The error's `what` is `substeps`, `current noise`,
    /// `current LSB` or `load torque`.
    pub fn check(&self) -> Result<(), SimError> {
        check_substeps(i64::from(self.substeps))?;
        for (what, v, unit) in [
            ("current noise", self.current_noise_a, "A"),
            ("current LSB", self.current_lsb_a, "A"),
            ("load torque", self.load_torque_nm, "N·m"),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(SimError::Option { what, reason: format!("{v} must be a finite number ≥ 0 {unit}") });
            }
        }
        Ok(())
    }
}

/// Checks a number of RK4 steps per control period as written (the command line reads a
/// signed number): in `1..=`[`MAX_SUBSTEPS`]. Returns it as [`SimOptions::substeps`] takes it.
pub fn check_substeps(n: i64) -> Result<u32, SimError> {
    match u32::try_from(n) {
        Ok(s) if (1..=MAX_SUBSTEPS).contains(&s) => Ok(s),
        _ => Err(SimError::Option { what: "substeps", reason: format!("{n} is not in 1..={MAX_SUBSTEPS}") }),
    }
}

/// Why a simulation could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The controller rejected its configuration.
    #[error("controller configuration: {0}")]
    Config(#[from] ConfigError),
    /// An option is out of range.
    #[error("{what}: {reason}")]
    Option {
        /// The option.
        what: &'static str,
        /// Why.
        reason: String,
    },
    /// The simulated motor's profile is invalid.
    #[error("{0}")]
    Profile(#[from] ProfileError),
    /// The controller's profile describes other drive or encoder hardware than the
    /// simulated motor's ([`check_same_hardware`]).
    #[error(
        "{motor} and {controller} differ in {key} ({motor_value} vs {controller_value}): the controller's profile may \
         differ in the motor model (R, L, Km, detent, friction) and controller settings, not in the drive or encoder"
    )]
    HardwareMismatch {
        /// The simulated motor's profile (file or preset name).
        motor: String,
        /// The controller's profile (file or preset name).
        controller: String,
        /// The key, e.g. `drive.pwm_hz`.
        key: &'static str,
        /// Its value in the motor's profile.
        motor_value: String,
        /// Its value in the controller's profile.
        controller_value: String,
    },
    /// The simulation diverged: a plant state became infinite or NaN (a profile or an
    /// option far outside what a real motor and drive can be). The run is stopped there.
    #[error("the simulation diverged at t = {t_s} s ({what})")]
    Diverged {
        /// Simulated time of the first non-finite sample in s.
        t_s: f64,
        /// What diverged, e.g. `rotor speed ω = NaN rad/s`, after the run's name if any.
        what: String,
    },
    /// The caller asked the run or sweep to stop before its end (its `stop` check returned
    /// true, e.g. on Ctrl-C in the Python binding; [`crate::scenario::run_while`],
    /// [`crate::sweep::sweep_until`]). No result is returned.
    #[error("stopped at t = {t_s} s before the end of the run, as the caller asked")]
    Stopped {
        /// Simulated time in s of the period where the run stopped.
        t_s: f64,
    },
    /// A combination of control mode and compensation that does not exist.
    #[error("compensation {comp} in {mode} mode: {reason}")]
    Unsupported {
        /// The mode.
        mode: &'static str,
        /// The compensation.
        comp: &'static str,
        /// Why.
        reason: &'static str,
    },
}

/// Why estimated-angle compensation is not run in servo mode.
pub const ESTIMATED_IS_OPEN_LOOP_ONLY: &str = "estimated applies to open loop; servo uses the encoder angle";

/// Checks that a controller profile describes the same drive and encoder hardware as the
/// simulated motor's: `drive.pwm_hz`, `drive.bus_voltage_v`, `drive.topology`,
/// `drive.computation_delay_periods`, `encoder.counts_per_rev` and `motor.pole_pairs` must
/// be equal (the simulation takes them from the motor, the controller from its own
/// profile). The controller may differ in the motor model (R, L, Km, J, detent,
/// friction) and in its own settings (holding current, current loop, `[servo]`): that is
/// what a mis-identified motor is. `motor_name` and `controller_name` name the two
/// profiles in the error (file paths or preset names).
pub fn check_same_hardware(
    motor: &Profile,
    motor_name: &str,
    controller: &Profile,
    controller_name: &str,
) -> Result<(), SimError> {
    let (m, c) = (motor, controller);
    let keys: [(&'static str, String, String); 6] = [
        ("drive.pwm_hz", m.drive.pwm_hz.to_string(), c.drive.pwm_hz.to_string()),
        ("drive.bus_voltage_v", m.drive.bus_voltage_v.to_string(), c.drive.bus_voltage_v.to_string()),
        ("drive.topology", m.drive.topology.as_str().to_string(), c.drive.topology.as_str().to_string()),
        (
            "drive.computation_delay_periods",
            m.drive.computation_delay_periods.to_string(),
            c.drive.computation_delay_periods.to_string(),
        ),
        ("encoder.counts_per_rev", m.encoder.counts_per_rev.to_string(), c.encoder.counts_per_rev.to_string()),
        ("motor.pole_pairs", m.motor.pole_pairs.to_string(), c.motor.pole_pairs.to_string()),
    ];
    for (key, motor_value, controller_value) in keys {
        if motor_value != controller_value {
            return Err(SimError::HardwareMismatch {
                motor: motor_name.to_string(),
                controller: controller_name.to_string(),
                key,
                motor_value,
                controller_value,
            });
        }
    }
    Ok(())
}

/// Checks that `comp` exists in `mode`: estimated-angle compensation is an open-loop law
/// (servo mode evaluates the compensation at the encoder angle), and so are the drives'
/// angle and table laws.
pub fn check_mode_compensation(mode: Mode, comp: Compensation) -> Result<(), SimError> {
    if mode == Mode::Servo && comp == Compensation::Estimated {
        return Err(SimError::Unsupported {
            mode: mode.name(),
            comp: comp.name(),
            reason: ESTIMATED_IS_OPEN_LOOP_ONLY,
        });
    }
    if mode == Mode::Servo && matches!(comp, Compensation::Angle | Compensation::Table) {
        return Err(SimError::Unsupported {
            mode: mode.name(),
            comp: comp.name(),
            reason: "angle and table are the open-loop laws of microstepping drives",
        });
    }
    Ok(())
}

/// Checks that a controller configuration is for `motor`'s pole pairs, PWM frequency, bus
/// voltage and power stage (what [`check_same_hardware`] checks of two profiles, for a
/// configuration built elsewhere).
pub fn check_config_hardware(motor: &Profile, cfg: &Config) -> Result<(), SimError> {
    let mismatch = |key: &'static str, m: String, c: String| SimError::HardwareMismatch {
        motor: motor.name.clone(),
        controller: "the controller configuration".to_string(),
        key,
        motor_value: m,
        controller_value: c,
    };
    if cfg.pole_pairs() != motor.motor.pole_pairs {
        return Err(mismatch("motor.pole_pairs", motor.motor.pole_pairs.to_string(), cfg.pole_pairs().to_string()));
    }
    let period = 1.0 / motor.drive.pwm_hz;
    if (f64::from(cfg.period_s()) - period).abs() > 1e-6 * period {
        return Err(mismatch("drive.pwm_hz", motor.drive.pwm_hz.to_string(), (1.0 / cfg.period_s()).to_string()));
    }
    let vdc = motor.drive.bus_voltage_v;
    if (f64::from(cfg.bus_voltage_v()) - vdc).abs() > 1e-6 * vdc {
        return Err(mismatch("drive.bus_voltage_v", vdc.to_string(), cfg.bus_voltage_v().to_string()));
    }
    if cfg.topology() != Topology::from(motor.drive.topology) {
        let cfg_topology = TopologyName::from(cfg.topology()).as_str().to_string();
        return Err(mismatch("drive.topology", motor.drive.topology.as_str().to_string(), cfg_topology));
    }
    Ok(())
}
