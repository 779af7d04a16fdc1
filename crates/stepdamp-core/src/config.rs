//! Controller parameters (what a user sets) and the validated [`Config`] built from them
//! once at start-up (what the 20 kHz step reads).

use crate::correction::CorrectionTable;
use crate::detent::{Harmonic, HarmonicSeries};
use crate::encoder::Encoder;
use crate::limits::{self, Limit};
use crate::modulator::Topology;
use crate::observer::{LoadAngleObserver, ObserverSettings};
use crate::pi::Pi;
use crate::ripple::{CurrentRipple, RippleModel};

mod error;
pub use error::{ConfigError, Reason};

/// What the controller knows of the motor (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorModel<'a> {
    /// Torque constant `Km` in N·m/A (> 0).
    pub km_nm_per_a: f32,
    /// Rotor teeth / pole pairs `Nr` (1..=1024; 50 for a 1.8° motor).
    pub pole_pairs: u16,
    /// Phase resistance `R` in Ω (> 0).
    pub resistance_ohm: f32,
    /// Phase inductance `L` in H (> 0).
    pub inductance_h: f32,
    /// Coulomb friction `Fs` in N·m (≥ 0), fed forward in servo mode.
    pub coulomb_friction_nm: f32,
    /// Detent harmonics, torque on the rotor `−Σ A sin(k Nr θ + φ)`.
    pub detent: &'a [Harmonic],
    /// The ripple that grows with the current ([`CurrentRipple::NONE`] for a pure-sine
    /// motor with equal phases): fed forward at the operating point of the law
    /// ([`crate::ripple`]).
    pub current_ripple: CurrentRipple<'a>,
}

/// Power stage and current loop settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveSettings {
    /// DC bus voltage in V (> 0).
    pub bus_voltage_v: f32,
    /// Control and PWM frequency in Hz (> 0; 20 kHz typical).
    pub pwm_hz: f32,
    /// Open-loop d-axis holding current `I_hold` in A (≥ 0, ≤ current limit).
    pub holding_current_a: f32,
    /// Limit of the current vector magnitude in A (> 0).
    pub current_limit_a: f32,
    /// Closed current-loop bandwidth in Hz (> 0, below a quarter of `pwm_hz`).
    pub current_loop_bandwidth_hz: f32,
    /// Power stage.
    pub topology: Topology,
    /// Periods between sampling and the duties taking effect: 0 (computed and applied
    /// within the period) or 1 (loaded for the next period, as most drives do).
    pub computation_delay_periods: u8,
}

/// Servo-mode gains (patent eq. 15), in torque units: the law divides by `Km`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoGains {
    /// `Kp_vel` in N·m·s/rad (≥ 0).
    pub velocity_nm_s_per_rad: f32,
    /// `Kp_pos` in N·m/rad (≥ 0).
    pub position_nm_per_rad: f32,
    /// `Ki_pos` in N·m/(rad·s) (≥ 0).
    pub position_integral_nm_per_rad_s: f32,
    /// Corner of the encoder velocity low-pass filter in Hz (> 0).
    pub velocity_filter_hz: f32,
}

impl ServoGains {
    /// Gains that place the position loop of a rigid inertia `inertia_kg_m2` at natural
    /// frequency `bandwidth_hz` with damping 0.7, an integral corner a tenth of that, and
    /// the velocity filter at `velocity_filter_hz`.
    pub fn for_bandwidth(inertia_kg_m2: f32, bandwidth_hz: f32, velocity_filter_hz: f32) -> Self {
        let w = core::f32::consts::TAU * bandwidth_hz;
        ServoGains {
            velocity_nm_s_per_rad: 2.0 * 0.7 * inertia_kg_m2 * w,
            position_nm_per_rad: inertia_kg_m2 * w * w,
            position_integral_nm_per_rad_s: inertia_kg_m2 * w * w * w / 10.0,
            velocity_filter_hz,
        }
    }
}

/// Control mode. Named `open-loop` and `servo` in tables, profiles and on the command line
/// ([`Mode::name`], `FromStr`, serde with the `serde` feature).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize), serde(rename_all = "kebab-case"))]
pub enum Mode {
    /// Microstepping without an encoder: Park at `θ_cmd`, `i_d = I_hold` (eqs. 7–8).
    #[default]
    OpenLoop,
    /// Position servo on the encoder: Park at `θ_fb`, `i_d = 0` (eqs. 14–15).
    Servo,
}

/// Everything the controller is configured with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params<'a> {
    /// Motor model.
    pub motor: MotorModel<'a>,
    /// Drive settings.
    pub drive: DriveSettings,
    /// Encoder counts per mechanical revolution (1..=2²⁰; used in servo mode).
    pub encoder_counts_per_rev: u32,
    /// Servo gains (used in servo mode).
    pub servo: ServoGains,
    /// Control mode.
    pub mode: Mode,
    /// Which detent compensation to inject.
    pub compensation: Compensation,
}

/// Detent compensation. Named `off`, `patent` and `estimated` ([`Compensation::name`],
/// `FromStr`, serde with the `serde` feature).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize), serde(rename_all = "kebab-case"))]
pub enum Compensation {
    /// None (and no friction feed-forward in servo mode).
    #[default]
    Off,
    /// The patent's law: `(1/Km) Σ A sin(kθe + φ)` at `θ_cmd` in open loop (eq. 8), at
    /// `θ_fb` in servo mode with `Fs·sgn(ω_cmd)` (eq. 15); with a ripple that grows with
    /// the current, at the law's operating point ([`crate::ripple`]).
    Patent,
    /// Open loop: the series at the rotor angle estimated by the load-angle observer
    /// ([`crate::observer`]), divided by `cos δ̂` (the q axis of `θc` is `δ̂` off the
    /// rotor's); with a ripple that grows with the current, at the rotor-frame currents of
    /// `δ̂` ([`crate::ripple`]). Servo mode: the same as `Patent` (the encoder is the best
    /// angle there).
    Estimated,
    /// Open loop only: the holding-current vector rotated by `Δ(θ_cmd) = (1/(Km·I_hold))
    /// Σ A sin(kθe + φ)` at constant magnitude, as Prusa's phase stepping and Trinamic
    /// microstep tables do ([`crate::correction::angle_law`]).
    Angle,
    /// Open loop only: reference coil currents replayed from an integer
    /// [`CorrectionTable`] as the drive would ([`crate::correction::table_law`]); build the
    /// configuration with [`Config::with_table`].
    Table,
}

crate::named_choice!(Mode, "mode", "open-loop, servo", [OpenLoop => "open-loop", Servo => "servo"]);
crate::named_choice!(Compensation, "compensation", "off, patent, estimated, angle, table", [
    Off => "off",
    Patent => "patent",
    Estimated => "estimated",
    Angle => "angle",
    Table => "table",
]);

/// Detent harmonics of the `patent-motor` (docs/design.md#presets).
pub const PATENT_MOTOR_DETENT: [Harmonic; 3] = [
    Harmonic { order: 4, amplitude_nm: 0.02, phase_rad: 0.0 },
    Harmonic { order: 2, amplitude_nm: 0.012, phase_rad: 0.7 },
    Harmonic { order: 1, amplitude_nm: 0.008, phase_rad: -1.1 },
];

impl Params<'static> {
    /// The controller of the `patent-motor` preset (Km 0.3 N·m/A, Nr 50, 0.9 Ω, 2.5 mH,
    /// 48 V three-leg stage at 20 kHz with a one-period computation delay, 1.9 A holding,
    /// 3 A limit, 1.5 kHz current loop, 4000-count encoder, 50 Hz servo loop): the
    /// reference configuration of the benchmarks, the tests and the Cortex-M4F firmware.
    pub const fn patent_motor(mode: Mode, compensation: Compensation) -> Params<'static> {
        Params {
            motor: MotorModel {
                km_nm_per_a: 0.3,
                pole_pairs: 50,
                resistance_ohm: 0.9,
                inductance_h: 2.5e-3,
                coulomb_friction_nm: 0.01,
                detent: &PATENT_MOTOR_DETENT,
                current_ripple: CurrentRipple::NONE,
            },
            drive: DriveSettings {
                bus_voltage_v: 48.0,
                pwm_hz: 20_000.0,
                holding_current_a: 1.9,
                current_limit_a: 3.0,
                current_loop_bandwidth_hz: 1500.0,
                topology: Topology::ThreeLeg,
                computation_delay_periods: 1,
            },
            encoder_counts_per_rev: 4000,
            // ServoGains::for_bandwidth(4.0e-5, 50.0, 300.0), spelled out for `const`.
            servo: ServoGains {
                velocity_nm_s_per_rad: 2.0 * 0.7 * 4.0e-5 * (core::f32::consts::TAU * 50.0),
                position_nm_per_rad: 4.0e-5 * (core::f32::consts::TAU * 50.0) * (core::f32::consts::TAU * 50.0),
                position_integral_nm_per_rad_s: 4.0e-5
                    * (core::f32::consts::TAU * 50.0)
                    * (core::f32::consts::TAU * 50.0)
                    * (core::f32::consts::TAU * 50.0)
                    / 10.0,
                velocity_filter_hz: 300.0,
            },
            mode,
            compensation,
        }
    }
}

/// `v` if it is within `limit`, else the error naming `limit.key`.
pub(crate) fn within(limit: &'static Limit, v: f32) -> Result<f32, ConfigError> {
    if limit.contains_f32(v) {
        Ok(v)
    } else {
        Err(ConfigError::Invalid { field: limit.key, value: v, reason: Reason::OutOfRange(limit) })
    }
}

/// Validated, precomputed configuration read by [`crate::step`]. Build once, never mutate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    pub(crate) mode: Mode,
    pub(crate) topology: Topology,
    pub(crate) pole_pairs: u16,
    pub(crate) bus_voltage_v: f32,
    pub(crate) holding_current_a: f32,
    pub(crate) current_limit_a: f32,
    /// Largest |i_q| command in open loop: `sqrt(limit² − I_hold²)`.
    pub(crate) open_loop_iq_limit_a: f32,
    pub(crate) pi: Pi,
    /// Integrator bound: the voltage the bus can make in any direction.
    pub(crate) integral_bound_v: f32,
    /// Position units per period per rad/s.
    pub(crate) units_per_rad_s: f64,
    /// Mechanical rad per position unit.
    pub(crate) rad_per_unit: f32,
    pub(crate) period_s: f32,
    pub(crate) encoder: Encoder,
    /// The ripple the compensation cancels, arranged for the law (all zero when
    /// compensation is off).
    pub(crate) ripple: RippleModel,
    /// Load-angle observer (open loop with `Compensation::Estimated` only).
    pub(crate) observer: Option<LoadAngleObserver>,
    /// Lead of the compensation current: the closed current loop with a delay `Td` inside
    /// is `T(s) = 1/(1 + (s/ωc)·e^{s·Td})`, so its inverse to second order is
    /// `1 + s/ωc + (Td/ωc)·s²`. This is `1/ωc` in s (zero in the patent's open loop).
    pub(crate) compensation_lead_s: f32,
    /// `Td` in s: the computation delay plus half a period of zero-order hold. (Measured on
    /// the simulator: the residual is smallest at exactly these values.)
    pub(crate) compensation_lead2_s: f32,
    /// Velocity gain `Kp_vel/Km`: q current in A per rad/s of velocity error.
    pub(crate) kpv_a: f32,
    /// Position gain `Kp_pos/Km`: q current in A per rad of position error.
    pub(crate) kpp_a: f32,
    /// Position integral gain `Ki_pos/Km`: q current in A per rad·s of integrated position
    /// error.
    pub(crate) kip_a: f32,
    /// Friction feed-forward current `Fs/Km` in A (zero when compensation is off).
    pub(crate) friction_a: f32,
    /// Largest measured current accepted, in A (beyond it a sample is a fault).
    pub(crate) current_sample_limit_a: f32,
    /// `1/Vdc` in 1/V (the modulator's per-period division, done once here).
    pub(crate) inv_bus_voltage: f32,
    /// Largest commanded speed magnitude, rad/s (see [`Config::max_speed_rad_s`]).
    pub(crate) max_speed_rad_s: f32,
    /// Which compensation law (the open-loop step picks the angle and table laws by it).
    pub(crate) compensation_kind: Compensation,
    /// Replayed reference currents ([`Compensation::Table`] only; zeros otherwise).
    pub(crate) table: CorrectionTable,
}

/// Largest advance of the commanded electrical angle per control period, in turns: a
/// quarter turn. Half a turn is the Nyquist limit (beyond it the angle sequence aliases to
/// a slower speed in the other direction, and the current loop sees a frame that turns
/// the wrong way); a quarter keeps a factor two from it, so that the sampled sin/cos still
/// describe the rotation unambiguously, including the one-period computation delay.
pub const MAX_ELECTRICAL_TURN_PER_PERIOD: f64 = 0.25;

/// Largest commanded speed magnitude in rad/s (mechanical) for `pole_pairs` and control
/// period `period_s`: [`MAX_ELECTRICAL_TURN_PER_PERIOD`] of an electrical turn per period,
/// `(π/2)/(Nr·Ts)`. [`Config::max_speed_rad_s`] is this; a simulator that refuses faster
/// commands uses it too. Pass the period the controller uses, `1/pwm_hz` in `f32`.
pub fn max_speed_rad_s(pole_pairs: u16, period_s: f32) -> f32 {
    (core::f64::consts::TAU * MAX_ELECTRICAL_TURN_PER_PERIOD / (f64::from(pole_pairs) * f64::from(period_s))) as f32
}

fn finite(field: &'static str, input: f32, derived: f32) -> Result<(), ConfigError> {
    if derived.is_finite() {
        Ok(())
    } else {
        Err(ConfigError::Invalid {
            field,
            value: input,
            reason: Reason::Other("too large or too small: a derived value is not finite"),
        })
    }
}

/// Corner of the load-angle observer's back-EMF filter, Hz.
const OBSERVER_BANDWIDTH_HZ: f32 = 500.0;

fn non_negative(field: &'static str, v: f32) -> Result<f32, ConfigError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(ConfigError::Invalid { field, value: v, reason: Reason::Other("must be finite and ≥ 0") })
    }
}

/// The inputs of [`Config::build`], each checked against its limit: the first stage of
/// building a [`Config`] (the second derives what the step needs from these).
struct Checked {
    km: f32,
    r: f32,
    l: f32,
    fs: f32,
    vdc: f32,
    pwm: f32,
    limit: f32,
    hold: f32,
    bw: f32,
    cpr: u32,
    kpv: f32,
    kpp: f32,
    kip: f32,
    vf: f32,
    ripple: RippleModel,
}

impl Checked {
    /// Checks every input of `p` against its limit (in profile order: the first
    /// offending parameter is reported) and the combinations the limits cannot express.
    fn new(p: &Params<'_>) -> Result<Checked, ConfigError> {
        let m = &p.motor;
        let d = &p.drive;
        let km = within(&limits::KM_NM_PER_A, m.km_nm_per_a)?;
        within(&limits::POLE_PAIRS, f32::from(m.pole_pairs))?;
        let r = within(&limits::RESISTANCE_OHM, m.resistance_ohm)?;
        let l = within(&limits::INDUCTANCE_H, m.inductance_h)?;
        let fs = within(&limits::COULOMB_FRICTION_NM, m.coulomb_friction_nm)?;
        let vdc = within(&limits::BUS_VOLTAGE_V, d.bus_voltage_v)?;
        let pwm = within(&limits::PWM_HZ, d.pwm_hz)?;
        let limit = within(&limits::CURRENT_LIMIT_A, d.current_limit_a)?;
        let hold = within(&limits::HOLDING_CURRENT_A, d.holding_current_a)?;
        if hold > limit {
            return Err(ConfigError::Invalid {
                field: "drive.holding_current_a",
                value: hold,
                reason: Reason::Other("must not exceed drive.current_limit_a"),
            });
        }
        let bw = within(&limits::CURRENT_LOOP_BANDWIDTH_HZ, d.current_loop_bandwidth_hz)?;
        if f64::from(bw) > f64::from(pwm) * limits::CURRENT_LOOP_BANDWIDTH_PER_PWM {
            return Err(ConfigError::Invalid {
                field: "drive.current_loop_bandwidth_hz",
                value: bw,
                reason: Reason::Other("must be below a quarter of drive.pwm_hz"),
            });
        }
        let cpr = p.encoder_counts_per_rev;
        if !limits::COUNTS_PER_REV.contains(f64::from(cpr)) {
            return Err(ConfigError::Invalid {
                field: limits::COUNTS_PER_REV.key,
                value: cpr as f32,
                reason: Reason::OutOfRange(&limits::COUNTS_PER_REV),
            });
        }
        let s = &p.servo;
        let kpv = non_negative("servo.velocity_nm_s_per_rad", s.velocity_nm_s_per_rad)?;
        let kpp = non_negative("servo.position_nm_per_rad", s.position_nm_per_rad)?;
        let kip = non_negative("servo.position_integral_nm_per_rad_s", s.position_integral_nm_per_rad_s)?;
        let vf = within(&limits::VELOCITY_FILTER_HZ, s.velocity_filter_hz)?;
        let series = HarmonicSeries::new(m.detent, 1.0 / km)?;
        let detent_sum_nm: f32 = m.detent.iter().map(|h| h.amplitude_nm).sum();
        if !limits::detent_within_holding_torque(f64::from(detent_sum_nm), f64::from(km), f64::from(hold)) {
            return Err(ConfigError::Invalid {
                field: "detent.amplitude_nm",
                value: detent_sum_nm,
                reason: Reason::DetentAboveHoldingTorque { holding_torque_nm: km * hold },
            });
        }
        within(&limits::COMPUTATION_DELAY_PERIODS, f32::from(d.computation_delay_periods))?;
        if p.mode == Mode::Servo && matches!(p.compensation, Compensation::Angle | Compensation::Table) {
            return Err(ConfigError::Invalid {
                field: "compensation",
                value: 0.0,
                reason: Reason::Other("angle and table compensation are open-loop laws (use patent in servo mode)"),
            });
        }
        let ripple = RippleModel::new(series, &m.current_ripple, 1.0 / km, hold, p.mode, p.compensation)?;
        Ok(Checked { km, r, l, fs, vdc, pwm, limit, hold, bw, cpr, kpv, kpp, kip, vf, ripple })
    }
}

impl Config {
    /// Validates `p` and precomputes everything the step needs. [`Compensation::Table`]
    /// needs its table: use [`Config::with_table`].
    pub fn new(p: &Params<'_>) -> Result<Config, ConfigError> {
        if p.compensation == Compensation::Table {
            return Err(ConfigError::Invalid {
                field: "compensation",
                value: 0.0,
                reason: Reason::Other("table compensation needs a correction table: build with Config::with_table"),
            });
        }
        Self::build(p)
    }

    /// [`Config::new`] for [`Compensation::Table`] (any other compensation ignores the
    /// table): the table's `full_scale` must be > 0 and its largest entry, scaled to the
    /// holding current, within the current limit.
    pub fn with_table(p: &Params<'_>, table: &CorrectionTable) -> Result<Config, ConfigError> {
        let mut cfg = Self::build(p)?;
        if p.compensation == Compensation::Table {
            crate::correction::check_table(table, cfg.holding_current_a, cfg.current_limit_a)?;
            cfg.table = *table;
        }
        Ok(cfg)
    }

    fn build(p: &Params<'_>) -> Result<Config, ConfigError> {
        let Checked { km, r, l, fs, vdc, pwm, limit, hold, bw, cpr, kpv, kpp, kip, vf, ripple } = Checked::new(p)?;
        let (m, d) = (&p.motor, &p.drive);
        let ts = 1.0 / pwm;
        let on = p.compensation != Compensation::Off;
        let estimated = p.compensation == Compensation::Estimated && p.mode == Mode::OpenLoop;
        let observer_floor_v = 0.02 * r * hold.max(0.1 * limit);
        // Every value derived below must be finite, or the step would compute with inf/NaN:
        // finite inputs can still overflow (a Km of 1e-40 makes 1/Km infinite, a limit of
        // 1e20 A makes limit² infinite). The field named is the input that overflowed.
        // (The observer's; the rest is checked on the built `Config`.)
        finite("motor.inductance_h", l, l / ts)?;
        finite("motor.resistance_ohm", r, observer_floor_v)?;
        let cfg = Config {
            mode: p.mode,
            topology: d.topology,
            pole_pairs: m.pole_pairs,
            bus_voltage_v: vdc,
            holding_current_a: hold,
            current_limit_a: limit,
            open_loop_iq_limit_a: libm::sqrtf(limit * limit - hold * hold),
            pi: Pi::for_winding(r, l, bw, ts),
            integral_bound_v: vdc * d.topology.inscribed_radius_per_vdc(),
            units_per_rad_s: crate::angle::units_per_rad_s(m.pole_pairs, f64::from(ts)),
            rad_per_unit: (core::f64::consts::TAU / crate::angle::UNITS_PER_ELECTRICAL_REV / f64::from(m.pole_pairs))
                as f32,
            period_s: ts,
            encoder: Encoder::new(cpr, m.pole_pairs, ts, vf),
            ripple,
            // Only where the compensation angle is the rotor's own (servo, or the estimate):
            // the patent's open-loop law evaluates at θ_cmd, which the rotor lags anyway.
            compensation_lead_s: if p.mode == Mode::Servo || estimated {
                1.0 / (core::f32::consts::TAU * bw)
            } else {
                0.0
            },
            compensation_lead2_s: (f32::from(d.computation_delay_periods) + 0.5) * ts,
            observer: if estimated {
                // The floor: the back-EMF error of a 2 % resistance error at holding current.
                Some(LoadAngleObserver::new(&ObserverSettings {
                    resistance_ohm: r,
                    inductance_h: l,
                    km_nm_per_a: km,
                    period_s: ts,
                    bandwidth_hz: OBSERVER_BANDWIDTH_HZ,
                    emf_floor_v: observer_floor_v,
                    delay_periods: d.computation_delay_periods,
                    current_loop_bandwidth_hz: bw,
                }))
            } else {
                None
            },
            kpv_a: kpv / km,
            kpp_a: kpp / km,
            kip_a: kip / km,
            friction_a: if on { fs / km } else { 0.0 },
            current_sample_limit_a: 100.0 * limit,
            inv_bus_voltage: 1.0 / vdc,
            max_speed_rad_s: max_speed_rad_s(m.pole_pairs, ts),
            compensation_kind: p.compensation,
            table: CorrectionTable::default(),
        };
        cfg.check_finite(p)?;
        Ok(cfg)
    }

    /// Every `f32` the step reads is finite; else the input that made it overflow.
    fn check_finite(&self, p: &Params<'_>) -> Result<(), ConfigError> {
        let (m, d, s) = (&p.motor, &p.drive, &p.servo);
        finite("motor.km_nm_per_a", m.km_nm_per_a, 1.0 / m.km_nm_per_a)?;
        finite("drive.pwm_hz", d.pwm_hz, self.period_s)?;
        finite("drive.pwm_hz", d.pwm_hz, self.units_per_rad_s as f32)?;
        finite("drive.pwm_hz", d.pwm_hz, self.max_speed_rad_s)?;
        finite("drive.pwm_hz", d.pwm_hz, self.encoder.rad_s_per_count())?;
        finite("drive.bus_voltage_v", d.bus_voltage_v, self.inv_bus_voltage)?;
        finite("drive.bus_voltage_v", d.bus_voltage_v, self.integral_bound_v)?;
        finite("drive.current_limit_a", d.current_limit_a, self.open_loop_iq_limit_a)?;
        finite("drive.current_limit_a", d.current_limit_a, self.current_sample_limit_a)?;
        finite("motor.inductance_h", m.inductance_h, self.pi.kp)?;
        finite("motor.resistance_ohm", m.resistance_ohm, self.pi.ki_ts)?;
        finite("drive.current_loop_bandwidth_hz", d.current_loop_bandwidth_hz, self.compensation_lead_s)?;
        finite("drive.pwm_hz", d.pwm_hz, self.compensation_lead2_s)?;
        finite("servo.velocity_nm_s_per_rad", s.velocity_nm_s_per_rad, self.kpv_a)?;
        finite("servo.position_nm_per_rad", s.position_nm_per_rad, self.kpp_a)?;
        finite("servo.position_integral_nm_per_rad_s", s.position_integral_nm_per_rad_s, self.kip_a)?;
        finite("motor.coulomb_friction_nm", m.coulomb_friction_nm, self.friction_a)?;
        if !self.ripple.is_finite() {
            let r = &m.current_ripple;
            let all = m.detent.iter().chain(r.per_amp_d).chain(r.per_amp_q);
            let largest = all.map(|h| h.amplitude_nm).fold(0.0, f32::max);
            return Err(ConfigError::Invalid {
                field: "detent.amplitude_nm",
                value: largest,
                reason: Reason::Other("too large for motor.km_nm_per_a: the compensation current is not finite"),
            });
        }
        Ok(())
    }

    /// Largest commanded speed magnitude in rad/s (mechanical): the speed at which the
    /// commanded electrical angle advances a quarter turn per period
    /// ([`MAX_ELECTRICAL_TURN_PER_PERIOD`]), `(π/2)/(Nr·Ts)`; 628 rad/s (6000 rpm) for
    /// `Nr = 50` at 20 kHz. [`crate::State::command_speed`] clamps to it.
    pub fn max_speed_rad_s(&self) -> f32 {
        self.max_speed_rad_s
    }

    /// Control period `Ts` in s.
    pub fn period_s(&self) -> f32 {
        self.period_s
    }

    /// Control mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Power stage topology.
    pub fn topology(&self) -> Topology {
        self.topology
    }

    /// Rotor pole pairs `Nr`.
    pub fn pole_pairs(&self) -> u16 {
        self.pole_pairs
    }

    /// Nominal bus voltage in V.
    pub fn bus_voltage_v(&self) -> f32 {
        self.bus_voltage_v
    }

    /// The current-loop PI gains.
    pub fn current_pi(&self) -> Pi {
        self.pi
    }
}
