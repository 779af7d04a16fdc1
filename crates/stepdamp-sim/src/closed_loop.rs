//! The closed loop: the plant, the drive's sensors and power stage, and the
//! `stepdamp-core` controller, one control period at a time.
//!
//! Per period: sample the plant (currents through the profile's sensor offsets and gain
//! errors, then optional ADC quantisation and seeded Gaussian noise; encoder count by
//! `floor` of the angle through the disc's eccentricity, [`crate::sensors`]); run the core's [`step`]; apply the duties
//! (one period later when the profile's `drive.computation_delay_periods` is 1, the
//! default, as a real drive that loads the PWM compare registers for the next period) as average winding voltages
//! `Vdc·(d_α − d_γ)`, `Vdc·(d_β − d_γ)` held over the period (zero-order hold); integrate
//! the plant with `substeps` RK4 steps.

use crate::lanes::{Integrator, StateLanes};
use crate::plant::{PlantParams, PlantState};
use crate::profile::{Profile, ProfileError};
use crate::sensors::{CurrentSensors, Eccentricity};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use stepdamp_core::{
    Config, ConfigError, DriveSettings, Harmonic, LegDuties, Measurement, Mode, MotorModel, Params, ServoGains,
    Signals, State, Topology, step,
};

pub use stepdamp_core::Compensation;

/// Name of a compensation in tables and on the command line ([`Compensation::name`]).
pub fn compensation_name(c: Compensation) -> &'static str {
    c.name()
}

/// Name of a control mode in tables and on the command line ([`Mode::name`]).
pub fn mode_name(m: Mode) -> &'static str {
    m.name()
}

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
            mode: mode_name(mode),
            comp: compensation_name(comp),
            reason: ESTIMATED_IS_OPEN_LOOP_ONLY,
        });
    }
    if mode == Mode::Servo && matches!(comp, Compensation::Angle | Compensation::Table) {
        return Err(SimError::Unsupported {
            mode: mode_name(mode),
            comp: compensation_name(comp),
            reason: "angle and table are the open-loop laws of microstepping drives",
        });
    }
    Ok(())
}

/// Builds the core controller's configuration from a profile.
pub fn controller_config(p: &Profile, mode: Mode, comp: Compensation) -> Result<Config, ConfigError> {
    with_params(p, mode, comp, Config::new)
}

/// [`controller_config`] with [`Compensation::Table`] replaying `table`.
pub fn controller_config_with_table(
    p: &Profile,
    mode: Mode,
    table: &stepdamp_core::CorrectionTable,
) -> Result<Config, ConfigError> {
    with_params(p, mode, Compensation::Table, |params| Config::with_table(params, table))
}

fn with_params<R>(p: &Profile, mode: Mode, comp: Compensation, f: impl FnOnce(&Params<'_>) -> R) -> R {
    let detent: Vec<Harmonic> = p
        .motor
        .detent
        .iter()
        .map(|h| Harmonic { order: h.order, amplitude_nm: h.amplitude_nm as f32, phase_rad: h.phase_rad as f32 })
        .collect();
    f(&Params {
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

/// What one period shows: the plant as sampled, what the sensors read, and the
/// controller's signals.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PeriodRecord {
    /// Plant state at the sampling instant (the truth).
    pub plant: PlantState,
    /// What the controller was given: the sampled phase currents (with the options' noise
    /// and quantisation) and the encoder count.
    pub measurement: Measurement,
    /// Controller signals of this period.
    pub signals: Signals,
    /// Mean voltage across winding A over this period `[t_k, t_k + Ts)` in V: the
    /// modulator's (limited) duties applied in this period, which with a computation
    /// delay are the ones computed in the period before. What a sensorless identification
    /// integrates (`∫(v − R i) dt`).
    pub v_a_v: f64,
    /// Mean voltage across winding B over this period in V (as [`PeriodRecord::v_a_v`]).
    pub v_b_v: f64,
}

/// Plant + sensors + controller.
#[derive(Clone, Debug)]
pub struct ClosedLoop {
    plant: PlantParams,
    /// The plant's integrator, one lane ([`crate::lanes`]; a sweep runs the same code over
    /// four lanes).
    integrator: Integrator<1>,
    pub(crate) x: PlantState,
    /// Boxed: with the drive-replay table a `Config` is about 8 kB, most of it never read
    /// in a sweep; out of line, the loop's hot fields (plant state, controller state, the
    /// sensors) stay within a few cache lines, and the lanes of a lock-step group sit
    /// close together instead of 8 kB apart.
    cfg: Box<Config>,
    st: State,
    topology: Topology,
    vdc: f64,
    pub(crate) h: f64,
    pub(crate) band: f64,
    pub(crate) substeps: u32,
    delay: bool,
    pending: LegDuties,
    noise: f64,
    lsb: f64,
    rng: ChaCha8Rng,
    counts_per_rad: f64,
    /// The profile's current-sensor errors (`None`: ideal).
    current_sensors: Option<CurrentSensors>,
    /// The profile's encoder eccentricity (`None`: a centred disc).
    eccentricity: Option<Eccentricity>,
    pole_pairs: u16,
    load_torque_nm: f64,
    /// The speed command of the last period (NaN before the first): the controller's
    /// command and the load torque's sign are set again only when it changes.
    last_speed_cmd: f64,
}

impl ClosedLoop {
    /// A loop simulating `motor` driven by a controller configured from `controller`
    /// (normally the same profile; another one models a mis-identified motor, and must
    /// describe the same hardware: [`check_same_hardware`]). Estimated-angle compensation
    /// exists in open loop only ([`check_mode_compensation`]).
    pub fn new(
        motor: &Profile,
        controller: &Profile,
        mode: Mode,
        comp: Compensation,
        opts: &SimOptions,
    ) -> Result<Self, SimError> {
        check_same_hardware(motor, &motor.name, controller, &controller.name)?;
        check_mode_compensation(mode, comp)?;
        let cfg = controller_config(controller, mode, comp)?;
        Self::with_config(motor, cfg, opts)
    }

    /// A loop around an already built controller configuration. The configuration must be
    /// for the motor's pole pairs, PWM frequency, bus voltage and power stage (the profile
    /// is valid by its type).
    pub fn with_config(motor: &Profile, cfg: Config, opts: &SimOptions) -> Result<Self, SimError> {
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
            let cfg_topology = crate::profile::TopologyName::from(cfg.topology()).as_str().to_string();
            return Err(mismatch("drive.topology", motor.drive.topology.as_str().to_string(), cfg_topology));
        }
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
            cfg: Box::new(cfg),
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
            current_sensors: CurrentSensors::from_profile(motor),
            eccentricity: Eccentricity::from_profile(motor),
            pole_pairs: motor.motor.pole_pairs,
            load_torque_nm: opts.load_torque_nm,
            last_speed_cmd: f64::NAN,
            integrator: Integrator::new(&plant),
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

    #[inline]
    fn sample_current(&mut self, i: f64) -> f32 {
        if self.noise > 0.0 || self.lsb > 0.0 { self.sample_current_noisy(i) } else { i as f32 }
    }

    #[inline(never)]
    fn sample_current_noisy(&mut self, i: f64) -> f32 {
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
        let (rec, va, vb) = self.control(speed_cmd_rad_s);
        let mut x = StateLanes::from_states(&[self.x]);
        for _ in 0..self.substeps {
            self.integrator.rk4(&mut x, &[va], &[vb], &[self.plant.load_torque_nm], self.h, self.band);
        }
        self.x = x.lane(0);
        rec
    }

    /// The load torque on the plant now in N·m (signed against the command).
    pub(crate) fn load_torque_now(&self) -> f64 {
        self.plant.load_torque_nm
    }

    /// The sensor-and-controller half of a period: samples the plant, steps the controller
    /// and returns the period's record and the winding voltages `(v_a, v_b)` to hold over
    /// it. The plant half is [`ClosedLoop::period`]'s integration, or the lock-step one of
    /// [`crate::lockstep`].
    #[inline]
    pub(crate) fn control(&mut self, speed_cmd_rad_s: f64) -> (PeriodRecord, f64, f64) {
        let sampled = self.x;
        // The profile's sensor errors, before noise and quantisation.
        let (i_a, i_b) = match self.current_sensors {
            Some(s) => s.read(sampled.i_a, sampled.i_b),
            None => (sampled.i_a, sampled.i_b),
        };
        let theta_read = match self.eccentricity {
            Some(e) => e.read(sampled.theta),
            None => sampled.theta,
        };
        let m = Measurement {
            i_a_a: self.sample_current(i_a),
            i_b_a: self.sample_current(i_b),
            encoder_count: (crate::sensors::floor_i64(theta_read * self.counts_per_rad)) as u32,
        };
        // `!=` is also true while the last command is NaN, so the first period sets it.
        if speed_cmd_rad_s != self.last_speed_cmd {
            self.last_speed_cmd = speed_cmd_rad_s;
            self.st.command_speed(&self.cfg, speed_cmd_rad_s as f32);
            self.plant.load_torque_nm = if speed_cmd_rad_s > 0.0 {
                -self.load_torque_nm
            } else if speed_cmd_rad_s < 0.0 {
                self.load_torque_nm
            } else {
                0.0
            };
        }
        let out = step(&self.cfg, &mut self.st, &m);
        let duties = if self.delay { core::mem::replace(&mut self.pending, out.duties) } else { out.duties };
        let (a, b) = self.topology.winding_voltages_per_vdc(&duties);
        let (va, vb) = (f64::from(a) * self.vdc, f64::from(b) * self.vdc);
        (PeriodRecord { plant: sampled, measurement: m, signals: out.signals, v_a_v: va, v_b_v: vb }, va, vb)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::ProfileData;
    use crate::runlog::{FromRecord, LogRow};

    fn patent() -> Profile {
        Profile::preset("patent-motor").unwrap()
    }

    #[test]
    fn a_controller_profile_for_other_hardware_is_rejected_by_key() {
        let m = patent();
        type Edit = fn(&mut ProfileData);
        let edits: [(&str, Edit); 6] = [
            ("drive.pwm_hz", |p| p.drive.pwm_hz = 25_000.0),
            ("drive.bus_voltage_v", |p| p.drive.bus_voltage_v *= 2.0),
            ("drive.topology", |p| p.drive.topology = crate::profile::TopologyName::TwoHBridge),
            ("drive.computation_delay_periods", |p| p.drive.computation_delay_periods = 0),
            ("encoder.counts_per_rev", |p| p.encoder.counts_per_rev = 1000),
            ("motor.pole_pairs", |p| p.motor.pole_pairs = 100),
        ];
        for (key, edit) in edits {
            let mut c = m.to_data();
            c.name = "ctl".into();
            edit(&mut c);
            let c = c.validate("ctl").unwrap();
            let e = ClosedLoop::new(&m, &c, Mode::OpenLoop, Compensation::Patent, &SimOptions::default()).unwrap_err();
            assert!(matches!(&e, SimError::HardwareMismatch { key: k, .. } if *k == key), "{key}: {e:?}");
            let msg = e.to_string();
            assert!(msg.contains("patent-motor") && msg.contains("ctl") && msg.contains(key), "{msg}");
        }
        // The motor model and the controller's own settings may differ.
        let mut c = m.to_data();
        c.motor.resistance_ohm *= 1.2;
        c.motor.km_nm_per_a *= 0.8;
        c.motor.detent.pop();
        c.motor.coulomb_friction_nm = 0.0;
        c.drive.current_loop_bandwidth_hz = 800.0;
        c.servo.bandwidth_hz = 20.0;
        let c = c.validate("ctl").unwrap();
        ClosedLoop::new(&m, &c, Mode::Servo, Compensation::Patent, &SimOptions::default()).unwrap();
    }

    #[test]
    fn with_config_takes_only_a_valid_profile_and_matches_the_configuration() {
        let good = patent();
        let cfg = controller_config(&good, Mode::OpenLoop, Compensation::Patent).unwrap();
        // A bad profile cannot be built, so it cannot reach the loop.
        let e = good.edited("bad", |d| d.motor.detent[0].order = 0).unwrap_err().to_string();
        assert!(e.contains("motor.detent[0].order"), "{e}");
        let e = good.edited("bad", |d| d.motor.inductance_h = -1.0).unwrap_err().to_string();
        assert!(e.contains("motor.inductance_h"), "{e}");
        let other = good
            .edited("other", |d| {
                d.drive.pwm_hz = 10_000.0;
                d.drive.current_loop_bandwidth_hz = 1000.0;
            })
            .unwrap();
        let e = ClosedLoop::with_config(&other, cfg, &SimOptions::default()).unwrap_err().to_string();
        assert!(e.contains("drive.pwm_hz"), "{e}");
    }

    #[test]
    fn estimated_compensation_is_open_loop_only() {
        let m = patent();
        let e = ClosedLoop::new(&m, &m, Mode::Servo, Compensation::Estimated, &SimOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains(ESTIMATED_IS_OPEN_LOOP_ONLY), "{e}");
        ClosedLoop::new(&m, &m, Mode::OpenLoop, Compensation::Estimated, &SimOptions::default()).unwrap();
    }

    #[test]
    fn the_run_log_holds_the_sampled_currents() {
        let m = patent();
        let opts = SimOptions { current_noise_a: 0.05, current_lsb_a: 0.01, ..SimOptions::default() };
        let mut lp = ClosedLoop::new(&m, &m, Mode::OpenLoop, Compensation::Off, &opts).unwrap();
        let mut differ = 0;
        for k in 0..200 {
            let rec = lp.period(5.0);
            let row = LogRow::from_record(k, m.drive.pwm_hz, m.motor.pole_pairs, &rec);
            assert_eq!((row.i_a_a, row.i_b_a), (f64::from(rec.measurement.i_a_a), f64::from(rec.measurement.i_b_a)));
            // Quantised to the LSB.
            for i in [row.i_a_a, row.i_b_a] {
                assert!(((i / 0.01) - (i / 0.01).round()).abs() < 1e-3, "{i}");
            }
            differ += usize::from(row.i_a_a != rec.plant.i_a);
        }
        assert!(differ > 150, "only {differ} of 200 samples differ from the true current");
    }

    #[test]
    fn a_constant_command_gives_the_same_run_as_setting_it_every_period() {
        // The command is set only when it changes: a run that changes it every period (by
        // going through another value and back) must match one that does not.
        let m = patent();
        let opts = SimOptions { load_torque_nm: 0.05, ..SimOptions::default() };
        let mut a = ClosedLoop::new(&m, &m, Mode::OpenLoop, Compensation::Patent, &opts).unwrap();
        let mut b = a.clone();
        for k in 0..2000 {
            let w = if k < 500 { 0.0 } else { 6.0 };
            let ra = a.period(w);
            b.last_speed_cmd = f64::NAN;
            let rb = b.period(w);
            assert_eq!(ra, rb, "period {k}");
        }
    }
}
