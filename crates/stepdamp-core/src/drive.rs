//! One control period of the drive: sample → Park → law → PI → inverse Park → modulator.

use crate::angle::{MicrostepAccumulator, Position, UNITS_PER_ELECTRICAL_REV};
use crate::config::{Compensation, Config, Mode};
use crate::encoder::EncoderState;
use crate::modulator::{LegDuties, Modulated};
use crate::observer::{ObserverInput, ObserverState};
use crate::park::{Ab, Dq, inverse_park, park};
use crate::trig::{sin_cos_rad, sin_cos_turn};

/// Consecutive rejected current samples after which the current sensor is declared
/// faulty: 20 periods, 1 ms at 20 kHz.
///
/// Up to `CURRENT_SENSOR_FAULT_PERIODS − 1` rejected samples in a row (an ADC glitch, a
/// lost conversion) are bridged by repeating the last good sample. From the
/// `CURRENT_SENSOR_FAULT_PERIODS`-th on, the current loop is blind, so the drive stops
/// driving: [`step`] returns the topology's zero-voltage duties (all legs at ½, see
/// [`crate::modulator::Topology::neutral`]), holds the current-loop integrators at zero and
/// raises [`State::current_sensor_fault`], until a good sample arrives. 1 ms is about ten
/// current-loop time constants at 1.5 kHz: long enough to ride out glitches, short
/// compared with the winding time constant `L/R` (2.8 ms for the patent motor), so a
/// stuck sensor cannot drive the current far before the drive lets go.
pub const CURRENT_SENSOR_FAULT_PERIODS: u32 = 20;

/// What the drive samples at the start of a period.
///
/// Directions: a positive phase current flows in the direction a positive winding voltage
/// drives it (`v_a = v_α − v_γ` on three legs, `v_A+ − v_A−` on H-bridges: into the
/// winding from leg α / A+), so that `τ = Km(−i_a sin θe + i_b cos θe)` (docs/design.md#the-plant).
/// The encoder counts up when the rotor turns in the positive direction: positive count
/// = positive `θ`, the direction a positive speed command and a positive `i_q` turn it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Measurement {
    /// Phase A current in A (positive from leg α / A+ into winding A).
    pub i_a_a: f32,
    /// Phase B current in A (positive from leg β / B+ into winding B).
    pub i_b_a: f32,
    /// Raw free-running encoder counter (wrapping; 0 at power-on with the rotor at θ = 0;
    /// counting up for positive rotation). Open loop only records it (leave it 0 when
    /// there is no encoder).
    pub encoder_count: u32,
}

/// Mutable controller state. Start from `State::default()` (rotor and command at 0).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct State {
    command: MicrostepAccumulator,
    speed_cmd_rad_s: f32,
    /// Electrical angle the command advances per period, rad (the increment in rad, set
    /// with the speed, so that the step converts no `i64`).
    dtheta_e_rad: f32,
    encoder: EncoderState,
    integral_d_v: f32,
    integral_q_v: f32,
    position_integral_rad_s: f32,
    last_current: Ab,
    /// Load-angle observer (open loop, estimated compensation).
    pub observer: ObserverState,
    /// The back-EMF of the ripple's current parts fed forward into this period's current
    /// loop, V, control frame ([`crate::ripple::ripple_back_emf_v`]); zero unless the
    /// estimated law runs with a model that has current parts.
    ripple_emf_v: Dq,
    /// Periods whose current sample was rejected (non-finite or beyond 100× the current
    /// limit), in total (saturating); the previous good sample was used instead, or, from
    /// [`CURRENT_SENSOR_FAULT_PERIODS`] in a row on, zero volts.
    pub sample_faults: u32,
    /// Rejected samples in a row (0 after a good one).
    consecutive_sample_faults: u32,
}

/// Internal signals of one period (what a run log records).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Signals {
    /// Commanded position `θ_cmd` used this period.
    pub theta_cmd: Position,
    /// Encoder position `θ_fb` (read in both modes; only servo mode acts on it).
    pub theta_fb: Position,
    /// Filtered encoder velocity in rad/s.
    pub omega_fb_rad_s: f32,
    /// Measured currents in the controller's frame, A.
    pub i_dq: Dq,
    /// Current commands, A.
    pub i_dq_cmd: Dq,
    /// Applied winding voltages after limiting, V.
    pub v_ab: Ab,
    /// Voltage scale applied by the modulator (1 = not limited).
    pub voltage_scale: f32,
}

/// Output of one period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Output {
    /// Leg duties to load into the PWM timer, each in `[0, 1]`.
    pub duties: LegDuties,
    /// Internal signals.
    pub signals: Signals,
}

impl State {
    /// Sets the commanded speed in rad/s (mechanical), clamped to
    /// `±`[`Config::max_speed_rad_s`] (beyond a quarter electrical turn per period the
    /// sampled angle would alias). A non-finite speed is ignored.
    pub fn command_speed(&mut self, cfg: &Config, speed_rad_s: f32) {
        if speed_rad_s.is_finite() {
            let max = cfg.max_speed_rad_s;
            let speed = crate::bound(speed_rad_s, -max, max);
            self.speed_cmd_rad_s = speed;
            self.command.set_speed(speed, cfg.units_per_rad_s);
            self.dtheta_e_rad =
                self.command.increment as f32 * (core::f32::consts::TAU / UNITS_PER_ELECTRICAL_REV as f32);
        }
    }

    /// Whether the current sensor is declared faulty: the last
    /// [`CURRENT_SENSOR_FAULT_PERIODS`] or more samples in a row were rejected. While it
    /// is, [`step`] puts zero volts on the windings; it clears on the next good sample.
    pub fn current_sensor_fault(&self) -> bool {
        self.consecutive_sample_faults >= CURRENT_SENSOR_FAULT_PERIODS
    }

    /// The current-loop integrators (d, q) in V.
    pub fn current_loop_integrals_v(&self) -> Dq {
        Dq { d: self.integral_d_v, q: self.integral_q_v }
    }

    /// The commanded speed in rad/s.
    pub fn speed_command_rad_s(&self) -> f32 {
        self.speed_cmd_rad_s
    }

    /// The commanded position `θ_cmd` of the next period.
    pub fn position_command(&self) -> Position {
        self.command.position
    }
}

/// Runs one control period. Never panics; the duties are always in `[0, 1]`.
///
/// Faults: a non-finite or absurd (beyond 100× the current limit) current sample is
/// replaced by the last good one and counted in [`State::sample_faults`]; the integrators
/// stay bounded and finite, so control resumes normally on the next good sample. From the
/// [`CURRENT_SENSOR_FAULT_PERIODS`]-th rejected sample in a row on, the step returns the
/// zero-voltage duties instead ([`State::current_sensor_fault`]): current loop integrators
/// zero, the load-angle observer restarted (keeping its `R̂`, `K̂m`), the servo position
/// integral held, zero currents and volts and a voltage scale of 0 in the signals; the
/// command angle and the encoder keep running. The next good sample resumes control.
#[inline]
pub fn step(cfg: &Config, st: &mut State, m: &Measurement) -> Output {
    let i_ab = accept_sample(cfg, st, m);
    let theta_cmd = st.command.position;

    // The encoder is read in both modes; open loop only records it.
    let theta_fb = cfg.encoder.update(&mut st.encoder, m.encoder_count);

    if st.current_sensor_fault() {
        return sensor_fault(cfg, st, theta_cmd, theta_fb);
    }
    let theta_ctl = match cfg.mode {
        Mode::OpenLoop => theta_cmd,
        Mode::Servo => theta_fb,
    };
    // The low 32 bits are the electrical angle as a fraction of a turn.
    let (sin, cos) = sin_cos_turn(theta_ctl.0 as u32);
    let i_dq = park(i_ab, sin, cos);
    let i_dq_cmd = match cfg.mode {
        Mode::OpenLoop => {
            // The operating point of the estimated law: the holding current on d of θc.
            let op = Dq { d: cfg.holding_current_a, q: 0.0 };
            let at = rotor_angle(cfg, st, i_ab, sin, cos);
            let comp_a = compensation_current(cfg, st, &at, op);
            open_loop_command(cfg, st, theta_cmd, comp_a, sin, cos)
        }
        Mode::Servo => servo_law(cfg, st, theta_cmd, theta_fb, sin, cos),
    };
    let (v_ab, modulated) = current_loop(cfg, st, i_dq_cmd, i_dq, sin, cos);

    st.command.advance();
    Output {
        duties: modulated.duties,
        signals: Signals {
            theta_cmd,
            theta_fb,
            omega_fb_rad_s: st.encoder.velocity_rad_s,
            i_dq,
            i_dq_cmd,
            v_ab,
            voltage_scale: modulated.scale,
        },
    }
}

/// Stage 1, the sample: the measured phase currents if they are finite and within
/// `Config::current_sample_limit_a`, else the last good sample (counted as a fault).
#[inline(always)]
fn accept_sample(cfg: &Config, st: &mut State, m: &Measurement) -> Ab {
    let lim = cfg.current_sample_limit_a;
    if m.i_a_a.is_finite() && m.i_b_a.is_finite() && m.i_a_a.abs() <= lim && m.i_b_a.abs() <= lim {
        let x = Ab { a: m.i_a_a, b: m.i_b_a };
        st.last_current = x;
        st.consecutive_sample_faults = 0;
        x
    } else {
        st.sample_faults = st.sample_faults.saturating_add(1);
        st.consecutive_sample_faults = st.consecutive_sample_faults.saturating_add(1);
        st.last_current
    }
}

/// Where the compensation is evaluated ([`rotor_angle`]): `(sin, cos)` of the angle, and
/// the load angle `δ̂` it is off the control frame (0 unless observed).
#[derive(Clone, Copy)]
struct CompensationAngle {
    sin: f32,
    cos: f32,
    sin_delta: f32,
    cos_delta: f32,
    /// `Km/K̂m` (1 unless observed).
    km_gain: f32,
    observed: bool,
}

impl CompensationAngle {
    /// The control angle itself (θ_cmd in open loop without the observer, θ_fb in servo).
    #[inline(always)]
    fn control(sin: f32, cos: f32) -> Self {
        CompensationAngle { sin, cos, sin_delta: 0.0, cos_delta: 1.0, km_gain: 1.0, observed: false }
    }
}

/// Stage 2a in open loop, where the compensation angle is: θ_cmd (patent), or the
/// observer's rotor angle θc − δ̂ (estimated; this runs the observer). `sin`, `cos` are
/// those of θ_cmd.
#[inline(always)]
fn rotor_angle(cfg: &Config, st: &mut State, i_ab: Ab, sin: f32, cos: f32) -> CompensationAngle {
    match &cfg.observer {
        Some(obs) => {
            let input = ObserverInput {
                current: i_ab,
                sin,
                cos,
                dtheta_e_rad: st.dtheta_e_rad,
                speed_rad_s: st.speed_cmd_rad_s,
            };
            let delta = obs.update(&mut st.observer, &input);
            let (sd, cd) = sin_cos_rad(delta);
            CompensationAngle {
                sin: sin * cd - cos * sd,
                cos: cos * cd + sin * sd,
                sin_delta: sd,
                cos_delta: cd,
                // Correct the configured Km by the back-EMF's measure of it.
                km_gain: obs.km_correction(&st.observer),
                observed: true,
            }
        }
        None => CompensationAngle::control(sin, cos),
    }
}

/// Stage 2b, the compensation current in A (q axis of the control frame, before the law
/// limits it) at `at`; `op` is the law's operating point in the control frame (open loop
/// `(I_hold, 0)`, servo `(0, i_q,ctrl)`), used only by a model with current parts
/// ([`crate::ripple`]).
#[inline(always)]
fn compensation_current(cfg: &Config, st: &mut State, at: &CompensationAngle, op: Dq) -> f32 {
    let omega_e = st.speed_cmd_rad_s * f32::from(cfg.pole_pairs);
    let (cs, cc, sd, cd) = (at.sin, at.cos, at.sin_delta, at.cos_delta);
    // The closed current loop is `1/(1 + (s/ωc)·e^{s·Td})`: command the compensation
    // through its inverse along the commanded electrical speed,
    // `S + (1/ωc)·ωe·(S' + Td·ωe·S'')`, so the current itself lands on the detent at every
    // harmonic order. Applied where
    // the angle is the rotor's own (servo, estimated); zero in the patent's open loop.
    let lead = |s: f32, slope: f32, curv: f32| {
        s + cfg.compensation_lead_s * omega_e * (slope + cfg.compensation_lead2_s * omega_e * curv)
    };
    if !cfg.ripple.current_dependent {
        // q of θc is δ̂ off the rotor's q axis: divide by cos δ̂ (bounded).
        let gain = if at.observed { at.km_gain / crate::at_least(cd, crate::ripple::MIN_DIVISOR) } else { 1.0 };
        let (series, slope, curv) = cfg.ripple.fixed.eval_with_derivatives(cs, cc);
        return gain * lead(series, slope, curv);
    }
    // The operating point in the rotor's frame (δ̂ = 0 without the observer), and the
    // torque per ampere the compensation current itself makes there (docs/design.md#real-motors-flux-harmonics).
    let (i_d, i_q) = (op.d * cd - op.q * sd, op.d * sd + op.q * cd);
    let v =
        if at.observed { cfg.ripple.eval_with_emf_slopes(cs, cc, i_d, i_q) } else { cfg.ripple.eval(cs, cc, i_d, i_q) };
    if at.observed {
        // The back-EMF's lead at this rotor angle, for the observer's next period,
        // evaluated where the rotor is, ahead of the filter's delayed estimate.
        st.observer.emf_angle_error_rad = crate::ripple::back_emf_angle_rad(&v, st.observer.delta_lead_rad);
        // Its harmonics, which the current loop cannot follow, fed forward (at the
        // commanded speed and the measured torque constant).
        let km_omega = st.observer.km_hat * st.speed_cmd_rad_s;
        st.ripple_emf_v = crate::ripple::ripple_back_emf_v(&v, km_omega, sd, cd);
    }
    at.km_gain * lead(v.current_a, v.slope, v.curvature) / crate::ripple::divisor(&v, sd, cd)
}

/// Stage 3 in open loop: the d/q current commands in A of the compensation law (holding
/// current on d and the compensation on q, or the angle or table law).
#[inline(always)]
fn open_loop_command(cfg: &Config, st: &State, theta_cmd: Position, comp_a: f32, sin: f32, cos: f32) -> Dq {
    match cfg.compensation_kind {
        Compensation::Angle => crate::correction::angle_law(cfg.holding_current_a, comp_a),
        Compensation::Table => crate::correction::table_law(
            &cfg.table,
            crate::correction::tick_of(theta_cmd),
            st.speed_cmd_rad_s,
            cfg.holding_current_a,
            sin,
            cos,
        ),
        _ => {
            let q = cfg.open_loop_iq_limit_a;
            Dq { d: cfg.holding_current_a, q: crate::bound(comp_a, -q, q) }
        }
    }
}

/// Stage 4, the current loop: PI on d and q, inverse Park, limit the vector on the bus,
/// anti-windup, and hand the applied voltage to the observer. Returns the applied winding
/// voltages in V and the modulator's duties and scale.
#[inline(always)]
fn current_loop(cfg: &Config, st: &mut State, i_dq_cmd: Dq, i_dq: Dq, sin: f32, cos: f32) -> (Ab, Modulated) {
    let e = Dq { d: i_dq_cmd.d - i_dq.d, q: i_dq_cmd.q - i_dq.q };
    // With the observer, the integral gain `Ki = R·ωc` follows the resistance it measured
    // at standstill, so the PI's zero keeps cancelling the winding pole.
    let pi = match &cfg.observer {
        Some(obs) => obs.current_pi(&cfg.pi, &st.observer),
        None => cfg.pi,
    };
    let mut v_unlim = Dq { d: pi.output(st.integral_d_v, e.d), q: pi.output(st.integral_q_v, e.q) };
    if cfg.ripple.is_current_dependent() {
        // The ripple's back-EMF (zero in servo and before the observer runs).
        v_unlim.d += st.ripple_emf_v.d;
        v_unlim.q += st.ripple_emf_v.q;
    }
    let v_ab_req = inverse_park(v_unlim, sin, cos);
    let modulated = cfg.topology.modulate_with_inverse(v_ab_req, cfg.bus_voltage_v, cfg.inv_bus_voltage);
    let limited = modulated.scale < 1.0;
    let bound = cfg.integral_bound_v;
    pi.commit(&mut st.integral_d_v, e.d, v_unlim.d, limited, bound);
    pi.commit(&mut st.integral_q_v, e.q, v_unlim.q, limited, bound);
    let v_ab = Ab { a: v_ab_req.a * modulated.scale, b: v_ab_req.b * modulated.scale };
    if let Some(obs) = &cfg.observer {
        obs.record(&mut st.observer, v_ab, i_dq_cmd);
    }
    (v_ab, modulated)
}

/// The period of a declared current-sensor fault: zero volts, no integration.
#[cold]
fn sensor_fault(cfg: &Config, st: &mut State, theta_cmd: Position, theta_fb: Position) -> Output {
    st.integral_d_v = 0.0;
    st.integral_q_v = 0.0;
    if let Some(obs) = &cfg.observer {
        // Its current and voltage history is broken: restart it on the next good sample,
        // keeping what it learnt of the motor.
        obs.restart(&mut st.observer);
    }
    st.command.advance();
    Output {
        duties: cfg.topology.neutral(),
        signals: Signals {
            theta_cmd,
            theta_fb,
            omega_fb_rad_s: st.encoder.velocity_rad_s,
            i_dq: Dq::default(),
            i_dq_cmd: Dq::default(),
            v_ab: Ab::default(),
            voltage_scale: 0.0,
        },
    }
}

/// Stage 3 in servo mode, patent eq. 15:
/// `i_q = (1/Km)[Kpv ω_err + Kpp θ_err + Kip ∫θ_err + Σ A sin(kθe_fb+φ) + Fs sgn(ω_cmd)]`,
/// clamped to the current limit; the position integral stops while the clamp pushes the
/// same way (anti-windup). With current parts in the ripple model the compensation is
/// evaluated at `i_q,ctrl`, the feedback and friction terms of this period (bounded to the
/// limit), and divided by the torque per ampere at `θ_fb` ([`crate::ripple`]). `sin`, `cos`
/// are those of `θ_fb`.
#[inline]
fn servo_law(cfg: &Config, st: &mut State, theta_cmd: Position, theta_fb: Position, sin: f32, cos: f32) -> Dq {
    let theta_err = theta_cmd.wrapping_diff(theta_fb) as f32 * cfg.rad_per_unit;
    let omega_err = st.speed_cmd_rad_s - st.encoder.velocity_rad_s;
    let friction = if st.speed_cmd_rad_s > 0.0 {
        cfg.friction_a
    } else if st.speed_cmd_rad_s < 0.0 {
        -cfg.friction_a
    } else {
        0.0
    };
    let integral_next = st.position_integral_rad_s + theta_err * cfg.period_s;
    let feedback = cfg.kpv_a * omega_err + cfg.kpp_a * theta_err + cfg.kip_a * integral_next;
    let lim = cfg.current_limit_a;
    let op = Dq { d: 0.0, q: crate::bound(feedback + friction, -lim, lim) };
    let comp_a = compensation_current(cfg, st, &CompensationAngle::control(sin, cos), op);
    let iq = feedback + comp_a + friction;
    let clamped = crate::bound(iq, -lim, lim);
    if clamped == iq || theta_err * iq < 0.0 {
        st.position_integral_rad_s = integral_next;
    }
    if !st.position_integral_rad_s.is_finite() {
        st.position_integral_rad_s = 0.0;
    }
    Dq { d: 0.0, q: clamped }
}
