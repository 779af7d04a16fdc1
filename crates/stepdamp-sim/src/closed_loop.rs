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
use crate::options::{SimError, SimOptions, check_config_hardware, check_mode_compensation, check_same_hardware};
use crate::plant::{PlantParams, PlantState};
use crate::profile::Profile;
use crate::sensors::{CurrentSensors, Eccentricity};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use stepdamp_core::{Compensation, Config, LegDuties, Measurement, Mode, Signals, State, Topology, step};

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
    /// [`crate::lanes::LANES`] lanes).
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
        let cfg = controller.controller_config(mode, comp, None)?;
        Self::with_config(motor, cfg, opts)
    }

    /// A loop around an already built controller configuration. The configuration must be
    /// for the motor's pole pairs, PWM frequency, bus voltage and power stage
    /// ([`check_config_hardware`]) and the options in range ([`SimOptions::check`]); the
    /// profile is valid by its type.
    pub fn with_config(motor: &Profile, cfg: Config, opts: &SimOptions) -> Result<Self, SimError> {
        check_config_hardware(motor, &cfg)?;
        opts.check()?;
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
    use crate::options::ESTIMATED_IS_OPEN_LOOP_ONLY;
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
        let cfg = good.controller_config(Mode::OpenLoop, Compensation::Patent, None).unwrap();
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
