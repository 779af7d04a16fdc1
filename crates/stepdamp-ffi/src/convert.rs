//! Conversions between the C structs and the core's types, and status codes and texts.
//! Safe code only: the pointer handling stays in `lib.rs`.

use core::ffi::CStr;

use stepdamp_core::{
    Compensation, Config, ConfigError, CurrentRipple, DriveSettings, Harmonic, Mode, MotorModel, Output,
    PATENT_MOTOR_DETENT, Params, ServoGains, Topology,
};

use crate::types::*;

/// `PATENT_MOTOR_DETENT` in C layout (what `sd_params_patent_motor` points to).
static PATENT_DETENT_C: [sd_harmonic; PATENT_MOTOR_DETENT.len()] = {
    let mut t = [sd_harmonic { order: 0, amplitude_nm: 0.0, phase_rad: 0.0 }; PATENT_MOTOR_DETENT.len()];
    let mut i = 0;
    while i < t.len() {
        t[i] = harmonic_to_c(PATENT_MOTOR_DETENT[i]);
        i += 1;
    }
    t
};

/// A core harmonic in C layout.
pub(crate) const fn harmonic_to_c(h: Harmonic) -> sd_harmonic {
    sd_harmonic { order: h.order, amplitude_nm: h.amplitude_nm, phase_rad: h.phase_rad }
}

pub(crate) fn mode_from_c(m: sd_mode) -> Result<Mode, sd_status> {
    match m {
        SD_MODE_OPEN_LOOP => Ok(Mode::OpenLoop),
        SD_MODE_SERVO => Ok(Mode::Servo),
        _ => Err(SD_ERR_INVALID_MODE),
    }
}

fn mode_to_c(m: Mode) -> sd_mode {
    match m {
        Mode::OpenLoop => SD_MODE_OPEN_LOOP,
        Mode::Servo => SD_MODE_SERVO,
    }
}

pub(crate) fn compensation_from_c(c: sd_compensation) -> Result<Compensation, sd_status> {
    match c {
        SD_COMPENSATION_OFF => Ok(Compensation::Off),
        SD_COMPENSATION_PATENT => Ok(Compensation::Patent),
        SD_COMPENSATION_ESTIMATED => Ok(Compensation::Estimated),
        SD_COMPENSATION_ANGLE => Ok(Compensation::Angle),
        SD_COMPENSATION_TABLE => Ok(Compensation::Table),
        _ => Err(SD_ERR_INVALID_COMPENSATION),
    }
}

fn compensation_to_c(c: Compensation) -> sd_compensation {
    match c {
        Compensation::Off => SD_COMPENSATION_OFF,
        Compensation::Patent => SD_COMPENSATION_PATENT,
        Compensation::Estimated => SD_COMPENSATION_ESTIMATED,
        Compensation::Angle => SD_COMPENSATION_ANGLE,
        Compensation::Table => SD_COMPENSATION_TABLE,
    }
}

fn topology_from_c(t: sd_topology) -> Result<Topology, sd_status> {
    match t {
        SD_TOPOLOGY_THREE_LEG => Ok(Topology::ThreeLeg),
        SD_TOPOLOGY_TWO_H_BRIDGE => Ok(Topology::TwoHBridge),
        _ => Err(SD_ERR_INVALID_TOPOLOGY),
    }
}

fn topology_to_c(t: Topology) -> sd_topology {
    match t {
        Topology::ThreeLeg => SD_TOPOLOGY_THREE_LEG,
        Topology::TwoHBridge => SD_TOPOLOGY_TWO_H_BRIDGE,
    }
}

/// The harmonic tables of a C motor: detent, ripple per ampere of `i_d`, of `i_q`.
pub(crate) type Tables = [[Harmonic; SD_MAX_HARMONICS as usize]; 3];

/// The core's parameters from the C ones; `harmonics` (the detent, the ripple per ampere of
/// `i_d` and of `i_q`, already bounds-checked) are copied into `tables`, which the result
/// borrows.
pub(crate) fn params_from_c<'t>(
    p: &sd_params,
    harmonics: [&[sd_harmonic]; 3],
    tables: &'t mut Tables,
) -> Result<Params<'t>, sd_status> {
    let mut n = [0usize; 3];
    for ((src, table), n) in harmonics.iter().zip(tables.iter_mut()).zip(&mut n) {
        *n = src.len().min(table.len());
        for (dst, h) in table.iter_mut().zip(*src) {
            *dst = Harmonic { order: h.order, amplitude_nm: h.amplitude_nm, phase_rad: h.phase_rad };
        }
    }
    let [detent, per_amp_d, per_amp_q] = tables;
    let (m, d, s) = (&p.motor, &p.drive, &p.servo);
    Ok(Params {
        motor: MotorModel {
            km_nm_per_a: m.km_nm_per_a,
            pole_pairs: m.pole_pairs,
            resistance_ohm: m.resistance_ohm,
            inductance_h: m.inductance_h,
            coulomb_friction_nm: m.coulomb_friction_nm,
            detent: detent.get(..n[0]).unwrap_or(&[]),
            current_ripple: CurrentRipple {
                per_amp_d: per_amp_d.get(..n[1]).unwrap_or(&[]),
                per_amp_q: per_amp_q.get(..n[2]).unwrap_or(&[]),
            },
        },
        drive: DriveSettings {
            bus_voltage_v: d.bus_voltage_v,
            pwm_hz: d.pwm_hz,
            holding_current_a: d.holding_current_a,
            current_limit_a: d.current_limit_a,
            current_loop_bandwidth_hz: d.current_loop_bandwidth_hz,
            topology: topology_from_c(d.topology)?,
            computation_delay_periods: d.computation_delay_periods,
        },
        encoder_counts_per_rev: p.encoder_counts_per_rev,
        servo: ServoGains {
            velocity_nm_s_per_rad: s.velocity_nm_s_per_rad,
            position_nm_per_rad: s.position_nm_per_rad,
            position_integral_nm_per_rad_s: s.position_integral_nm_per_rad_s,
            velocity_filter_hz: s.velocity_filter_hz,
        },
        mode: mode_from_c(p.mode)?,
        compensation: compensation_from_c(p.compensation)?,
    })
}

/// `Params::patent_motor(mode, compensation)` in C layout.
pub(crate) fn patent_motor_c(mode: sd_mode, compensation: sd_compensation) -> Result<sd_params, sd_status> {
    let p = Params::patent_motor(mode_from_c(mode)?, compensation_from_c(compensation)?);
    Ok(params_to_c(&p, [&PATENT_DETENT_C, &[], &[]]))
}

/// `p` in C layout, its harmonic tables (the detent, the ripple per ampere of `i_d` and of
/// `i_q`) at `tables`, which the result points to (NULL for an empty table).
pub(crate) fn params_to_c(p: &Params<'_>, tables: [&[sd_harmonic]; 3]) -> sd_params {
    let table = |t: &[sd_harmonic]| if t.is_empty() { (core::ptr::null(), 0) } else { (t.as_ptr(), t.len() as u32) };
    let [(detent, detent_count), (per_amp_d, per_amp_d_count), (per_amp_q, per_amp_q_count)] = tables.map(table);
    let (m, d, s) = (&p.motor, &p.drive, &p.servo);
    sd_params {
        motor: sd_motor {
            km_nm_per_a: m.km_nm_per_a,
            pole_pairs: m.pole_pairs,
            resistance_ohm: m.resistance_ohm,
            inductance_h: m.inductance_h,
            coulomb_friction_nm: m.coulomb_friction_nm,
            detent,
            detent_count,
            ripple_per_amp_d: per_amp_d,
            ripple_per_amp_d_count: per_amp_d_count,
            ripple_per_amp_q: per_amp_q,
            ripple_per_amp_q_count: per_amp_q_count,
        },
        drive: sd_drive {
            bus_voltage_v: d.bus_voltage_v,
            pwm_hz: d.pwm_hz,
            holding_current_a: d.holding_current_a,
            current_limit_a: d.current_limit_a,
            current_loop_bandwidth_hz: d.current_loop_bandwidth_hz,
            topology: topology_to_c(d.topology),
            computation_delay_periods: d.computation_delay_periods,
        },
        encoder_counts_per_rev: p.encoder_counts_per_rev,
        servo: sd_servo {
            velocity_nm_s_per_rad: s.velocity_nm_s_per_rad,
            position_nm_per_rad: s.position_nm_per_rad,
            position_integral_nm_per_rad_s: s.position_integral_nm_per_rad_s,
            velocity_filter_hz: s.velocity_filter_hz,
        },
        mode: mode_to_c(p.mode),
        compensation: compensation_to_c(p.compensation),
    }
}

pub(crate) fn from_output(o: &Output) -> sd_output {
    let s = &o.signals;
    sd_output {
        duties: o.duties.0,
        theta_cmd: s.theta_cmd.0,
        theta_fb: s.theta_fb.0,
        omega_fb_rad_s: s.omega_fb_rad_s,
        i_d_a: s.i_dq.d,
        i_q_a: s.i_dq.q,
        i_d_cmd_a: s.i_dq_cmd.d,
        i_q_cmd_a: s.i_dq_cmd.q,
        v_a_v: s.v_ab.a,
        v_b_v: s.v_ab.b,
        voltage_scale: s.voltage_scale,
    }
}

pub(crate) fn config_info(cfg: &Config) -> sd_config_info {
    sd_config_info {
        period_s: cfg.period_s(),
        max_speed_rad_s: cfg.max_speed_rad_s(),
        bus_voltage_v: cfg.bus_voltage_v(),
        pole_pairs: cfg.pole_pairs(),
        legs: cfg.topology().legs() as u32,
        mode: mode_to_c(cfg.mode()),
        topology: topology_to_c(cfg.topology()),
    }
}

/// The status of a core configuration error: one code per parameter the core names.
pub(crate) fn status_of(e: &ConfigError) -> sd_status {
    match e {
        ConfigError::HarmonicOrder { .. } => SD_ERR_HARMONIC_ORDER,
        ConfigError::DuplicateHarmonic { .. } => SD_ERR_DUPLICATE_HARMONIC,
        ConfigError::Invalid { field, .. } => match *field {
            "motor.km_nm_per_a" => SD_ERR_KM,
            "motor.pole_pairs" => SD_ERR_POLE_PAIRS,
            "motor.resistance_ohm" => SD_ERR_RESISTANCE,
            "motor.inductance_h" => SD_ERR_INDUCTANCE,
            "motor.coulomb_friction_nm" => SD_ERR_COULOMB_FRICTION,
            "drive.bus_voltage_v" => SD_ERR_BUS_VOLTAGE,
            "drive.pwm_hz" => SD_ERR_PWM_FREQUENCY,
            "drive.current_limit_a" => SD_ERR_CURRENT_LIMIT,
            "drive.holding_current_a" => SD_ERR_HOLDING_CURRENT,
            "drive.current_loop_bandwidth_hz" => SD_ERR_CURRENT_LOOP_BANDWIDTH,
            "drive.computation_delay_periods" => SD_ERR_COMPUTATION_DELAY,
            "encoder.counts_per_rev" => SD_ERR_ENCODER_COUNTS,
            "servo.velocity_nm_s_per_rad" => SD_ERR_SERVO_VELOCITY_GAIN,
            "servo.position_nm_per_rad" => SD_ERR_SERVO_POSITION_GAIN,
            "servo.position_integral_nm_per_rad_s" => SD_ERR_SERVO_INTEGRAL_GAIN,
            "servo.velocity_filter_hz" => SD_ERR_SERVO_VELOCITY_FILTER,
            "detent.amplitude_nm" => SD_ERR_DETENT_AMPLITUDE,
            "detent.phase_rad" => SD_ERR_DETENT_PHASE,
            "current_ripple.amplitude_nm_per_a" => SD_ERR_RIPPLE_AMPLITUDE,
            "current_ripple.phase_rad" => SD_ERR_RIPPLE_PHASE,
            "i_d_a" | "i_q_a" => SD_ERR_OPERATING_CURRENT,
            _ => SD_ERR_INVALID_PARAMETER,
        },
    }
}

/// The range texts of the parameter statuses, written by `build.rs` from the core's
/// limits.
mod texts {
    include!(concat!(env!("OUT_DIR"), "/status_texts.rs"));
}

/// Every status code with its text (one home: `sd_status_str` and the tests read it; the
/// ranges come from [`texts`]).
pub(crate) const STATUS_TEXTS: [(sd_status, &CStr); 36] = [
    (SD_OK, c"ok"),
    (SD_ERR_NULL_POINTER, c"a pointer argument is NULL"),
    (SD_ERR_NOT_INITIALIZED, c"sd_config/sd_state not initialised (or its initialisation failed)"),
    (SD_ERR_MISALIGNED, c"sd_config/sd_state not aligned to 8 bytes"),
    (SD_ERR_INVALID_MODE, c"mode is not an SD_MODE_* value"),
    (SD_ERR_INVALID_COMPENSATION, c"compensation is not an SD_COMPENSATION_* value"),
    (SD_ERR_INVALID_TOPOLOGY, c"drive.topology is not an SD_TOPOLOGY_* value"),
    (SD_ERR_DETENT_COUNT_BEYOND_CAPACITY, c"motor.detent_count exceeds SD_MAX_HARMONICS"),
    (SD_ERR_DETENT_NULL_WITH_COUNT, c"motor.detent is NULL but motor.detent_count > 0"),
    (SD_ERR_DETENT_POINTER_WITHOUT_COUNT, c"motor.detent is not NULL but motor.detent_count is 0"),
    (SD_ERR_HARMONIC_ORDER, texts::HARMONIC_ORDER),
    (SD_ERR_DUPLICATE_HARMONIC, c"a detent harmonic order is given more than once"),
    (SD_ERR_KM, texts::KM),
    (SD_ERR_POLE_PAIRS, texts::POLE_PAIRS),
    (SD_ERR_RESISTANCE, texts::RESISTANCE),
    (SD_ERR_INDUCTANCE, texts::INDUCTANCE),
    (SD_ERR_COULOMB_FRICTION, texts::COULOMB_FRICTION),
    (SD_ERR_BUS_VOLTAGE, texts::BUS_VOLTAGE),
    (SD_ERR_PWM_FREQUENCY, texts::PWM_FREQUENCY),
    (SD_ERR_CURRENT_LIMIT, texts::CURRENT_LIMIT),
    (SD_ERR_HOLDING_CURRENT, texts::HOLDING_CURRENT),
    (SD_ERR_CURRENT_LOOP_BANDWIDTH, texts::CURRENT_LOOP_BANDWIDTH),
    (SD_ERR_COMPUTATION_DELAY, texts::COMPUTATION_DELAY),
    (SD_ERR_ENCODER_COUNTS, texts::ENCODER_COUNTS),
    (SD_ERR_SERVO_VELOCITY_GAIN, texts::SERVO_VELOCITY_GAIN),
    (SD_ERR_SERVO_POSITION_GAIN, texts::SERVO_POSITION_GAIN),
    (SD_ERR_SERVO_INTEGRAL_GAIN, texts::SERVO_INTEGRAL_GAIN),
    (SD_ERR_SERVO_VELOCITY_FILTER, texts::SERVO_VELOCITY_FILTER),
    (SD_ERR_DETENT_AMPLITUDE, texts::DETENT_AMPLITUDE),
    (SD_ERR_DETENT_PHASE, texts::DETENT_PHASE),
    (SD_ERR_INVALID_PARAMETER, c"a parameter was rejected (no dedicated code in this version)"),
    (
        SD_ERR_RIPPLE_TABLE,
        c"motor.ripple_per_amp_d/_q: more than SD_MAX_HARMONICS entries, or NULL with a count, or a pointer with a count of 0",
    ),
    (SD_ERR_RIPPLE_AMPLITUDE, texts::RIPPLE_AMPLITUDE),
    (SD_ERR_RIPPLE_PHASE, texts::RIPPLE_PHASE),
    (
        SD_ERR_OPERATING_CURRENT,
        c"sd_motor_ripple: i_d_a or i_q_a is not finite, or the current vector is beyond drive.current_limit_a",
    ),
    (
        SD_ERR_CAPACITY_TOO_SMALL,
        c"sd_motor_ripple: capacity is smaller than the harmonics to write (*count says how many)",
    ),
];

pub(crate) fn status_text(s: sd_status) -> &'static CStr {
    STATUS_TEXTS.iter().find(|(code, _)| *code == s).map_or(c"unknown status", |(_, t)| t)
}

#[cfg(test)]
mod tests;
