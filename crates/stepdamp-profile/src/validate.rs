//! The checks behind [`crate::ProfileData::validate`].

use crate::data::ProfileData;
use crate::error::ProfileError;
use crate::profile::Profile;
use stepdamp_core::limits::{self, Limit, Num};
use stepdamp_core::{Compensation, Mode};

fn out_of_range(origin: &str, key: &str, value: f64, limit: &'static Limit) -> ProfileError {
    ProfileError::OutOfRange { path: origin.to_string(), key: key.to_string(), value, limit }
}

fn within(origin: &str, key: &str, value: f64, limit: &'static Limit) -> Result<(), ProfileError> {
    if limit.contains(value) { Ok(()) } else { Err(out_of_range(origin, key, value, limit)) }
}

fn invalid(origin: &str, key: &str, value: String, reason: &str) -> ProfileError {
    ProfileError::Invalid { path: origin.to_string(), key: key.to_string(), value, reason: reason.to_string() }
}

/// Every key within its range ([`stepdamp_core::limits`]) and the relations between keys.
pub(crate) fn check(p: &ProfileData, origin: &str) -> Result<(), ProfileError> {
    if let Some(why) = crate::name::name_problem(&p.name) {
        return Err(invalid(origin, "name", crate::name::quoted_name(&p.name), &why));
    }
    let m = &p.motor;
    for (l, v) in [
        (&limits::KM_NM_PER_A, m.km_nm_per_a),
        (&limits::POLE_PAIRS, f64::from(m.pole_pairs)),
        (&limits::RESISTANCE_OHM, m.resistance_ohm),
        (&limits::INDUCTANCE_H, m.inductance_h),
        (&limits::INERTIA_KG_M2, m.inertia_kg_m2),
        (&limits::VISCOUS_NM_S_PER_RAD, m.viscous_nm_s_per_rad),
        (&limits::COULOMB_FRICTION_NM, m.coulomb_friction_nm),
    ] {
        within(origin, l.key, v, l)?;
    }
    for (i, h) in m.detent.iter().enumerate() {
        let key = |f: &str| format!("motor.detent[{i}].{f}");
        within(origin, &key("order"), f64::from(h.order), &limits::DETENT_ORDER)?;
        if m.detent[..i].iter().any(|o| o.order == h.order) {
            return Err(invalid(origin, &key("order"), h.order.to_string(), "this order is listed twice"));
        }
        within(origin, &key("amplitude_nm"), h.amplitude_nm, &limits::DETENT_AMPLITUDE_NM)?;
        within(origin, &key("phase_rad"), h.phase_rad, &limits::DETENT_PHASE_RAD)?;
    }
    let d = &p.drive;
    for (l, v) in [
        (&limits::BUS_VOLTAGE_V, d.bus_voltage_v),
        (&limits::PWM_HZ, d.pwm_hz),
        (&limits::CURRENT_LIMIT_A, d.current_limit_a),
        (&limits::HOLDING_CURRENT_A, d.holding_current_a),
        (&limits::CURRENT_LOOP_BANDWIDTH_HZ, d.current_loop_bandwidth_hz),
        (&limits::COMPUTATION_DELAY_PERIODS, f64::from(d.computation_delay_periods)),
        (&limits::COUNTS_PER_REV, f64::from(p.encoder.counts_per_rev)),
        (&limits::SERVO_BANDWIDTH_HZ, p.servo.bandwidth_hz),
        (&limits::VELOCITY_FILTER_HZ, p.servo.velocity_filter_hz),
    ] {
        within(origin, l.key, v, l)?;
    }
    if d.holding_current_a > d.current_limit_a {
        let key = limits::HOLDING_CURRENT_A.key;
        return Err(invalid(
            origin,
            key,
            Num(d.holding_current_a).to_string(),
            "must not exceed drive.current_limit_a",
        ));
    }
    let detent_sum_nm: f64 = m.detent.iter().map(|h| h.amplitude_nm).sum();
    if !limits::detent_within_holding_torque(detent_sum_nm, m.km_nm_per_a, d.holding_current_a) {
        let holding_torque_nm = (m.km_nm_per_a * d.holding_current_a) as f32;
        let why = stepdamp_core::Reason::DetentAboveHoldingTorque { holding_torque_nm }.to_string();
        let v = format!("{} N·m in all (the sum of the amplitudes)", Num(detent_sum_nm));
        return Err(invalid(origin, "motor.detent", v, &why));
    }
    if d.current_loop_bandwidth_hz > d.pwm_hz * limits::CURRENT_LOOP_BANDWIDTH_PER_PWM {
        let key = limits::CURRENT_LOOP_BANDWIDTH_HZ.key;
        let v = Num(d.current_loop_bandwidth_hz).to_string();
        return Err(invalid(origin, key, v, "must be below a quarter of drive.pwm_hz"));
    }
    check_simulator(p, origin)
}

/// The simulator-only keys ([`crate::data::sim_limits`]): the friction law's parameters
/// present exactly when the law needs them, and the sensor errors.
fn check_simulator(p: &ProfileData, origin: &str) -> Result<(), ProfileError> {
    use crate::data::{FrictionLawName, sim_limits as sl};
    let f = &p.motor.friction;
    let law = f.law.as_str();
    let needs = |key: &str, v: Option<f64>, needed: bool| -> Result<Option<f64>, ProfileError> {
        match (v, needed) {
            (None, true) => Err(invalid(
                origin,
                &format!("motor.friction.{key}"),
                "(missing)".into(),
                &format!("law = \"{law}\" needs it"),
            )),
            (Some(v), false) => Err(invalid(
                origin,
                &format!("motor.friction.{key}"),
                Num(v).to_string(),
                &format!("law = \"{law}\" does not use it"),
            )),
            (v, _) => Ok(v),
        }
    };
    let smooth = f.law != FrictionLawName::Karnopp;
    let stribeck = f.law == FrictionLawName::Stribeck;
    if let Some(v) = needs("creep_speed_rad_s", f.creep_speed_rad_s, smooth)? {
        within(origin, sl::CREEP_SPEED_RAD_S.key, v, &sl::CREEP_SPEED_RAD_S)?;
    }
    if let Some(v) = needs("stribeck_speed_rad_s", f.stribeck_speed_rad_s, stribeck)? {
        within(origin, sl::STRIBECK_SPEED_RAD_S.key, v, &sl::STRIBECK_SPEED_RAD_S)?;
    }
    if let Some(v) = needs("static_nm", f.static_nm, stribeck)? {
        let fs = p.motor.coulomb_friction_nm;
        let (lo, hi) = (sl::STATIC_PER_COULOMB.min * fs, sl::STATIC_PER_COULOMB.max * fs);
        if !(v.is_finite() && v >= lo && v <= hi) {
            return Err(invalid(
                origin,
                sl::STATIC_PER_COULOMB.key,
                Num(v).to_string(),
                &format!("must be in [{}, {}] N·m (1 to 10 × motor.coulomb_friction_nm)", Num(lo), Num(hi)),
            ));
        }
    }
    let d = &p.drive;
    let max_offset = d.current_limit_a / sl::CURRENT_LIMIT_PER_OFFSET;
    for (i, &o) in d.current_offset_a.iter().enumerate() {
        if !(o.is_finite() && o.abs() <= max_offset) {
            return Err(invalid(
                origin,
                &format!("drive.current_offset_a[{i}]"),
                Num(o).to_string(),
                &format!("must be in [-{0}, {0}] A (10 % of drive.current_limit_a)", Num(max_offset)),
            ));
        }
    }
    for (i, &g) in d.current_gain_error.iter().enumerate() {
        within(origin, &format!("drive.current_gain_error[{i}]"), g, &sl::CURRENT_GAIN_ERROR)?;
    }
    check_flux(p, origin)?;
    let e = &p.encoder;
    within(origin, sl::ECCENTRICITY_RAD.key, e.eccentricity_rad, &sl::ECCENTRICITY_RAD)?;
    within(origin, sl::ECCENTRICITY_PHASE_RAD.key, e.eccentricity_phase_rad, &sl::ECCENTRICITY_PHASE_RAD)?;
    Ok(())
}

/// `[motor.flux]`: odd orders 3 to 15, each once, ratios and phases and the phase-b gain
/// within [`crate::flux::flux_limits`].
fn check_flux(p: &ProfileData, origin: &str) -> Result<(), ProfileError> {
    use crate::flux::{MAX_FLUX_ORDER, flux_limits as fl};
    let f = &p.motor.flux;
    within(origin, fl::PHASE_B_GAIN.key, f.phase_b_gain, &fl::PHASE_B_GAIN)?;
    for (i, h) in f.harmonics.iter().enumerate() {
        let key = |k: &str| format!("motor.flux.harmonic[{i}].{k}");
        if !(3..=MAX_FLUX_ORDER).contains(&h.order) || h.order % 2 == 0 {
            let why = format!(
                "must be odd, 3 to {MAX_FLUX_ORDER}: a magnet's flux has odd harmonics, and the fundamental is Km"
            );
            return Err(invalid(origin, &key("order"), h.order.to_string(), &why));
        }
        if f.harmonics[..i].iter().any(|o| o.order == h.order) {
            return Err(invalid(origin, &key("order"), h.order.to_string(), "this order is listed twice"));
        }
        within(origin, &key("ratio"), h.ratio, &fl::RATIO)?;
        within(origin, &key("phase_rad"), h.phase_rad, &fl::PHASE_RAD)?;
    }
    Ok(())
}

/// The derived quantities are finite and the controller accepts the profile in every mode.
/// Within the ranges this holds; the check keeps it so if a range is ever widened.
pub(crate) fn check_derived(p: &Profile, origin: &str) -> Result<(), ProfileError> {
    let gains = p.servo_gains();
    // Each must be finite and > 0 (the damping ratio ≥ 0: D may be zero).
    let derived = [
        ("the natural frequency ω_n", p.natural_frequency_rad_s()),
        ("the damping ratio", p.damping_ratio() + f64::MIN_POSITIVE),
        ("the first resonance speed", p.resonance_speed_rad_s(1)),
        ("the servo velocity gain", f64::from(gains.velocity_nm_s_per_rad)),
        ("the servo integral gain", f64::from(gains.position_integral_nm_per_rad_s)),
    ];
    for (what, v) in derived {
        if !(v.is_finite() && v > 0.0) {
            return Err(invalid(
                origin,
                limits::INERTIA_KG_M2.key,
                Num(p.motor.inertia_kg_m2).to_string(),
                &format!("with the other keys {what} is {}, not a finite number > 0", Num(v)),
            ));
        }
    }
    for mode in [Mode::OpenLoop, Mode::Servo] {
        for comp in [Compensation::Off, Compensation::Patent, Compensation::Estimated] {
            if let Err(e) = p.controller_config(mode, comp, None) {
                return Err(ProfileError::Controller { path: origin.to_string(), source: e });
            }
        }
    }
    Ok(())
}
