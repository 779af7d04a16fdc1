//! Each range `sd_status_str()` states is the range `sd_config_init()` enforces: the
//! message quotes the core's limit, and through the C API the limit's ends are accepted
//! and the next representable values beyond them refused with that status.
#![allow(unsafe_code, reason = "calls the extern \"C\" API with raw pointers, as C does")]

use std::ptr::null;

use stepdamp_core::limits::{self as l, Limit, Num};
use stepdamp_ffi::*;

fn patent() -> sd_params {
    let mut p = std::mem::MaybeUninit::<sd_params>::uninit();
    // SAFETY: a valid out pointer.
    assert_eq!(unsafe { sd_params_patent_motor(SD_MODE_SERVO, SD_COMPENSATION_PATENT, p.as_mut_ptr()) }, SD_OK);
    // SAFETY: written on SD_OK.
    let mut p = unsafe { p.assume_init() };
    // No detent: its bound against the holding torque would mask the current ranges.
    p.motor.detent = null();
    p.motor.detent_count = 0;
    p
}

fn init(p: &sd_params) -> sd_status {
    let mut cfg = Box::new(sd_config { _opaque: [0; SD_CONFIG_WORDS] });
    // SAFETY: valid pointers; any detent table outlives the call.
    unsafe { sd_config_init(p, &mut *cfg) }
}

fn text(s: sd_status) -> String {
    // SAFETY: sd_status_str returns a static NUL-terminated string.
    unsafe { std::ffi::CStr::from_ptr(sd_status_str(s)) }.to_str().unwrap().to_owned()
}

/// The next `f32` above (`up`) or below a finite `x` (`f32::next_up` is newer than the MSRV).
fn next(x: f32, up: bool) -> f32 {
    if x == 0.0 {
        let tiny = f32::from_bits(1);
        return if up { tiny } else { -tiny };
    }
    let away_from_zero = (x > 0.0) == up;
    let b = x.to_bits();
    f32::from_bits(if away_from_zero { b + 1 } else { b - 1 })
}

/// The smallest and largest `f32` inside `limit`, and the nearest `f32` outside each end.
fn f32_ends(limit: &Limit) -> [(f32, bool); 4] {
    let mut lo = limit.min as f32;
    while !limit.contains_f32(lo) {
        lo = next(lo, true);
    }
    let mut hi = limit.max as f32;
    while !limit.contains_f32(hi) {
        hi = next(hi, false);
    }
    [(lo, true), (next(lo, false), false), (hi, true), (next(hi, true), false)]
}

/// The smallest and largest integer inside `limit`, and the integers just outside (the
/// one below 0 left out: the C field is unsigned).
fn int_ends(limit: &Limit) -> Vec<(f32, bool)> {
    let (lo, hi) = (limit.min.ceil(), limit.max.floor());
    let mut v = vec![(lo as f32, true), (hi as f32, true), ((hi + 1.0) as f32, false)];
    if lo >= 1.0 {
        v.push(((lo - 1.0) as f32, false));
    }
    v
}

type Set = fn(&mut sd_params, f32);

#[test]
fn each_status_text_states_the_range_the_c_library_enforces() {
    // (status, C name, limit, integer field, setter that also keeps the other keys valid)
    let cases: [(sd_status, &str, &Limit, bool, Set); 13] = [
        (SD_ERR_KM, "motor.km_nm_per_a", &l::KM_NM_PER_A, false, |p, v| p.motor.km_nm_per_a = v),
        (SD_ERR_POLE_PAIRS, "motor.pole_pairs", &l::POLE_PAIRS, true, |p, v| p.motor.pole_pairs = v as u16),
        (SD_ERR_RESISTANCE, "motor.resistance_ohm", &l::RESISTANCE_OHM, false, |p, v| p.motor.resistance_ohm = v),
        (SD_ERR_INDUCTANCE, "motor.inductance_h", &l::INDUCTANCE_H, false, |p, v| p.motor.inductance_h = v),
        (SD_ERR_COULOMB_FRICTION, "motor.coulomb_friction_nm", &l::COULOMB_FRICTION_NM, false, |p, v| {
            p.motor.coulomb_friction_nm = v
        }),
        (SD_ERR_BUS_VOLTAGE, "drive.bus_voltage_v", &l::BUS_VOLTAGE_V, false, |p, v| p.drive.bus_voltage_v = v),
        (SD_ERR_PWM_FREQUENCY, "drive.pwm_hz", &l::PWM_HZ, false, |p, v| {
            p.drive.pwm_hz = v;
            p.drive.current_loop_bandwidth_hz = 100.0;
        }),
        (SD_ERR_CURRENT_LIMIT, "drive.current_limit_a", &l::CURRENT_LIMIT_A, false, |p, v| {
            p.drive.current_limit_a = v;
            p.drive.holding_current_a = p.drive.holding_current_a.min(v);
        }),
        (SD_ERR_HOLDING_CURRENT, "drive.holding_current_a", &l::HOLDING_CURRENT_A, false, |p, v| {
            p.drive.holding_current_a = v;
            p.drive.current_limit_a = l::CURRENT_LIMIT_A.max as f32;
        }),
        (
            SD_ERR_CURRENT_LOOP_BANDWIDTH,
            "drive.current_loop_bandwidth_hz",
            &l::CURRENT_LOOP_BANDWIDTH_HZ,
            false,
            |p, v| {
                p.drive.current_loop_bandwidth_hz = v;
                p.drive.pwm_hz = l::PWM_HZ.max as f32;
            },
        ),
        (SD_ERR_COMPUTATION_DELAY, "drive.computation_delay_periods", &l::COMPUTATION_DELAY_PERIODS, true, |p, v| {
            p.drive.computation_delay_periods = v as u8
        }),
        (SD_ERR_ENCODER_COUNTS, "encoder_counts_per_rev", &l::COUNTS_PER_REV, true, |p, v| {
            p.encoder_counts_per_rev = v as u32
        }),
        (SD_ERR_SERVO_VELOCITY_FILTER, "servo.velocity_filter_hz", &l::VELOCITY_FILTER_HZ, false, |p, v| {
            p.servo.velocity_filter_hz = v
        }),
    ];
    for (status, name, limit, integer, set) in cases {
        let said = text(status);
        assert!(said.starts_with(&format!("{name} must be in {limit}")), "{said}");
        let ends = if integer { int_ends(limit) } else { f32_ends(limit).to_vec() };
        for (v, inside) in ends {
            let mut p = patent();
            set(&mut p, v);
            let want = if inside { SD_OK } else { status };
            assert_eq!(init(&p), want, "{name} = {v:e} (text: {said})");
        }
    }
}

#[test]
fn the_relations_between_parameters_are_stated_as_enforced() {
    // The bandwidth: at most CURRENT_LOOP_BANDWIDTH_PER_PWM of the PWM frequency.
    let said = text(SD_ERR_CURRENT_LOOP_BANDWIDTH);
    assert!(said.ends_with(&format!("at most {} x drive.pwm_hz", Num(l::CURRENT_LOOP_BANDWIDTH_PER_PWM))), "{said}");
    let mut p = patent();
    p.drive.pwm_hz = 20_000.0;
    p.drive.current_loop_bandwidth_hz = (20_000.0 * l::CURRENT_LOOP_BANDWIDTH_PER_PWM) as f32;
    assert_eq!(init(&p), SD_OK);
    p.drive.current_loop_bandwidth_hz = next(p.drive.current_loop_bandwidth_hz, true);
    assert_eq!(init(&p), SD_ERR_CURRENT_LOOP_BANDWIDTH);
    // The holding current: at most the current limit.
    assert!(text(SD_ERR_HOLDING_CURRENT).ends_with("and at most drive.current_limit_a"));
    let mut p = patent();
    p.drive.holding_current_a = p.drive.current_limit_a;
    assert_eq!(init(&p), SD_OK);
    p.drive.holding_current_a = next(p.drive.current_limit_a, true);
    assert_eq!(init(&p), SD_ERR_HOLDING_CURRENT);
}

#[test]
fn the_detent_texts_state_the_order_amplitude_phase_and_holding_torque_bounds() {
    let one = |order: u16, amplitude_nm: f32, phase_rad: f32| {
        let table = [sd_harmonic { order, amplitude_nm, phase_rad }];
        let mut p = patent();
        // Km·I_hold = 50 N·m/A × 100 A: room for the largest amplitude.
        p.motor.km_nm_per_a = 50.0;
        p.drive.current_limit_a = 100.0;
        p.drive.holding_current_a = 100.0;
        p.motor.detent = table.as_ptr();
        p.motor.detent_count = 1;
        init(&p)
    };
    assert!(text(SD_ERR_HARMONIC_ORDER).ends_with(&format!("must be in {}", l::DETENT_ORDER)));
    for (v, inside) in int_ends(&l::DETENT_ORDER) {
        assert_eq!(one(v as u16, 0.01, 0.0), if inside { SD_OK } else { SD_ERR_HARMONIC_ORDER }, "order {v}");
    }
    assert!(
        text(SD_ERR_DETENT_AMPLITUDE)
            .starts_with(&format!("each detent amplitude must be in {}", l::DETENT_AMPLITUDE_NM))
    );
    for (v, inside) in f32_ends(&l::DETENT_AMPLITUDE_NM) {
        assert_eq!(one(4, v, 0.0), if inside { SD_OK } else { SD_ERR_DETENT_AMPLITUDE }, "amplitude {v:e}");
    }
    assert!(text(SD_ERR_DETENT_PHASE).ends_with(&format!("must be in {}", l::DETENT_PHASE_RAD)));
    for (v, inside) in f32_ends(&l::DETENT_PHASE_RAD) {
        assert_eq!(one(4, 0.01, v), if inside { SD_OK } else { SD_ERR_DETENT_PHASE }, "phase {v:e}");
    }
    // The sum against the holding torque: the patent motor's Km·I_hold is 0.3 × 1.9 = 0.57 N·m.
    let said = text(SD_ERR_DETENT_AMPLITUDE);
    let bound =
        format!("their sum below {} x motor.km_nm_per_a x drive.holding_current_a", Num(l::DETENT_PER_HOLDING_TORQUE));
    assert!(said.contains(&bound), "{said}");
    for (a, want) in [(0.56f32, SD_OK), (0.58, SD_ERR_DETENT_AMPLITUDE), (5.0, SD_ERR_DETENT_AMPLITUDE)] {
        let table = [sd_harmonic { order: 4, amplitude_nm: a, phase_rad: 0.0 }];
        let mut p = patent();
        p.motor.detent = table.as_ptr();
        p.motor.detent_count = 1;
        assert_eq!(init(&p), want, "{a}");
    }
}
