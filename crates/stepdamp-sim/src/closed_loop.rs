//! The closed loop: the plant, the drive's sensors and power stage, and the
//! `stepdamp-core` controller, one control period at a time.
//!
//! Per period: sample the plant (currents with optional ADC quantisation and seeded
//! Gaussian noise, encoder count by `floor`); run the core's [`step`]; apply the duties
//! (one period later when the profile's `drive.computation_delay_periods` is 1, the
//! default, as a real drive that loads the PWM compare registers for the next period) as average winding voltages
//! `Vdc·(d_α − d_γ)`, `Vdc·(d_β − d_γ)` held over the period (zero-order hold); integrate
//! the plant with `substeps` RK4 steps.

use crate::plant::{PlantParams, PlantState};
use crate::profile::Profile;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use stepdamp_core::{
    Config, ConfigError, DriveSettings, Harmonic, LegDuties, Measurement, Mode, MotorModel, Params, ServoGains,
    Signals, State, Topology, step,
};

pub use stepdamp_core::Compensation;

/// Name of a compensation in tables and on the command line.
pub fn compensation_name(c: Compensation) -> &'static str {
    match c {
        Compensation::Off => "off",
        Compensation::Patent => "patent",
        Compensation::Estimated => "estimated",
    }
}

/// Name of a control mode in tables and on the command line.
pub fn mode_name(m: Mode) -> &'static str {
    match m {
        Mode::OpenLoop => "open-loop",
        Mode::Servo => "servo",
    }
}

/// Simulation options (the physics of the drive that a profile does not describe).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimOptions {
    /// RK4 steps per control period (≥ 1).
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
        SimOptions { substeps: 2, current_noise_a: 0.0, current_lsb_a: 0.0, seed: 1, load_torque_nm: 0.0 }
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
}

/// Builds the core controller's configuration from a profile.
pub fn controller_config(p: &Profile, mode: Mode, comp: Compensation) -> Result<Config, ConfigError> {
    let detent: Vec<Harmonic> = p
        .motor
        .detent
        .iter()
        .map(|h| Harmonic { order: h.order, amplitude_nm: h.amplitude_nm as f32, phase_rad: h.phase_rad as f32 })
        .collect();
    Config::new(&Params {
        motor: MotorModel {
            km_nm_per_a: p.motor.km_nm_per_a as f32,
            pole_pairs: p.motor.pole_pairs,
            resistance_ohm: p.motor.resistance_ohm as f32,
            inductance_h: p.motor.inductance_h as f32,
            coulomb_friction_nm: p.motor.coulomb_friction_nm as f32,
            detent: &detent,
        },
        drive: DriveSettings {
            bus_voltage_v: p.drive.bus_voltage_v as f32,
            pwm_hz: p.drive.pwm_hz as f32,
            holding_current_a: p.drive.holding_current_a as f32,
            current_limit_a: p.drive.current_limit_a as f32,
            current_loop_bandwidth_hz: p.drive.current_loop_bandwidth_hz as f32,
            topology: p.drive.topology.into(),
            computation_delay_periods: p.drive.computation_delay_periods,
        },
        encoder_counts_per_rev: p.encoder.counts_per_rev,
        servo: ServoGains::for_bandwidth(
            p.motor.inertia_kg_m2 as f32,
            p.servo.bandwidth_hz as f32,
            p.servo.velocity_filter_hz as f32,
        ),
        mode,
        compensation: comp,
    })
}

/// What one period shows: the plant as sampled, and the controller's signals.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PeriodRecord {
    /// Plant state at the sampling instant.
    pub plant: PlantState,
    /// Controller signals of this period.
    pub signals: Signals,
}

/// Plant + sensors + controller.
#[derive(Clone, Debug)]
pub struct ClosedLoop {
    plant: PlantParams,
    x: PlantState,
    cfg: Config,
    st: State,
    topology: Topology,
    vdc: f64,
    h: f64,
    band: f64,
    substeps: u32,
    delay: bool,
    pending: LegDuties,
    noise: f64,
    lsb: f64,
    rng: ChaCha8Rng,
    counts_per_rad: f64,
    pole_pairs: u16,
    load_torque_nm: f64,
}

impl ClosedLoop {
    /// A loop simulating `motor` driven by a controller configured from `controller`
    /// (normally the same profile; another one models a mis-identified motor).
    pub fn new(
        motor: &Profile,
        controller: &Profile,
        mode: Mode,
        comp: Compensation,
        opts: &SimOptions,
    ) -> Result<Self, SimError> {
        let cfg = controller_config(controller, mode, comp)?;
        Self::with_config(motor, cfg, opts)
    }

    /// A loop around an already built controller configuration.
    pub fn with_config(motor: &Profile, cfg: Config, opts: &SimOptions) -> Result<Self, SimError> {
        if opts.substeps == 0 || opts.substeps > 1000 {
            return Err(SimError::Option { what: "substeps", reason: format!("{} is not in 1..=1000", opts.substeps) });
        }
        for (what, v) in [
            ("current noise", opts.current_noise_a),
            ("current LSB", opts.current_lsb_a),
            ("load torque", opts.load_torque_nm),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(SimError::Option { what, reason: format!("{v} must be a finite number ≥ 0") });
            }
        }
        let plant = PlantParams::from_profile(motor);
        let h = 1.0 / motor.drive.pwm_hz / f64::from(opts.substeps);
        let band = plant.stick_band(h);
        Ok(ClosedLoop {
            topology: cfg.topology(),
            pending: cfg.topology().neutral(),
            cfg,
            st: State::default(),
            x: PlantState::default(),
            vdc: motor.drive.bus_voltage_v,
            h,
            band,
            substeps: opts.substeps,
            delay: motor.drive.computation_delay_periods == 1,
            noise: opts.current_noise_a,
            lsb: opts.current_lsb_a,
            rng: ChaCha8Rng::seed_from_u64(opts.seed),
            counts_per_rad: f64::from(motor.encoder.counts_per_rev) / std::f64::consts::TAU,
            pole_pairs: motor.motor.pole_pairs,
            load_torque_nm: opts.load_torque_nm,
            plant,
        })
    }

    /// The plant state now.
    pub fn plant_state(&self) -> &PlantState {
        &self.x
    }

    /// Moves the rotor to `theta_rad` at `omega_rad_s` (an impulse, for ring-down tests);
    /// currents and the controller are untouched.
    pub fn kick_rotor(&mut self, theta_rad: f64, omega_rad_s: f64) {
        self.x.theta = theta_rad;
        self.x.omega = omega_rad_s;
    }

    /// The plant parameters.
    pub fn plant(&self) -> &PlantParams {
        &self.plant
    }

    /// Rotor pole pairs.
    pub fn pole_pairs(&self) -> u16 {
        self.pole_pairs
    }

    /// The controller state (read-only).
    pub fn controller_state(&self) -> &State {
        &self.st
    }

    fn sample_current(&mut self, i: f64) -> f32 {
        let mut v = i;
        if self.noise > 0.0 {
            let n: f64 = StandardNormal.sample(&mut self.rng);
            v += self.noise * n;
        }
        if self.lsb > 0.0 {
            v = (v / self.lsb).round() * self.lsb;
        }
        v as f32
    }

    /// Runs one control period with speed command `speed_cmd_rad_s`.
    #[inline]
    pub fn period(&mut self, speed_cmd_rad_s: f64) -> PeriodRecord {
        let sampled = self.x;
        let m = Measurement {
            i_a_a: self.sample_current(sampled.i_a),
            i_b_a: self.sample_current(sampled.i_b),
            encoder_count: ((sampled.theta * self.counts_per_rad).floor() as i64) as u32,
        };
        self.st.command_speed(&self.cfg, speed_cmd_rad_s as f32);
        let out = step(&self.cfg, &mut self.st, &m);
        let duties = if self.delay { core::mem::replace(&mut self.pending, out.duties) } else { out.duties };
        let (a, b) = self.topology.winding_voltages_per_vdc(&duties);
        let (va, vb) = (f64::from(a) * self.vdc, f64::from(b) * self.vdc);
        self.plant.load_torque_nm = if speed_cmd_rad_s > 0.0 {
            -self.load_torque_nm
        } else if speed_cmd_rad_s < 0.0 {
            self.load_torque_nm
        } else {
            0.0
        };
        for _ in 0..self.substeps {
            self.x = self.plant.rk4(&self.x, va, vb, self.h, self.band);
        }
        PeriodRecord { plant: sampled, signals: out.signals }
    }
}
