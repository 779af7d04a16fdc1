//! The C API called as C calls it (through the exported functions and raw pointers):
//! the same numbers as the core, one status per rejected parameter, NULL pointers and
//! uninitialised objects as statuses.
#![allow(unsafe_code, reason = "calls the extern \"C\" API with raw pointers, as C does")]

use std::ptr::{null, null_mut};

use stepdamp_core::{Compensation, Config, CurrentRipple, Harmonic, Measurement, Mode, Params, State, step};
use stepdamp_ffi::*;

fn zeroed_config() -> Box<sd_config> {
    Box::new(sd_config { _opaque: [0; SD_CONFIG_WORDS] })
}

fn zeroed_state() -> Box<sd_state> {
    Box::new(sd_state { _opaque: [0; SD_STATE_WORDS] })
}

fn patent(mode: sd_mode, comp: sd_compensation) -> sd_params {
    let mut p = std::mem::MaybeUninit::<sd_params>::uninit();
    // SAFETY: a valid out pointer.
    assert_eq!(unsafe { sd_params_patent_motor(mode, comp, p.as_mut_ptr()) }, SD_OK);
    // SAFETY: written on SD_OK.
    unsafe { p.assume_init() }
}

fn init(p: &sd_params) -> (sd_status, Box<sd_config>) {
    let mut cfg = zeroed_config();
    // SAFETY: valid pointers; the detent table outlives the call.
    let s = unsafe { sd_config_init(p, &mut *cfg) };
    (s, cfg)
}

/// Runs `periods` through the C API and through the core with the same synthetic samples
/// and checks every output bit for bit.
fn same_as_core(mode: Mode, comp: Compensation, mode_c: sd_mode, comp_c: sd_compensation) {
    same_as_core_with(&patent(mode_c, comp_c), &Params::patent_motor(mode, comp));
}

/// [`same_as_core`] for C parameters `c` and the core's `params`, which must be the same.
fn same_as_core_with(c: &sd_params, params: &Params<'_>) {
    let (s, cfg_c) = init(c);
    assert_eq!(s, SD_OK);
    let mut st_c = zeroed_state();
    let cfg = Config::new(params).unwrap();
    let mut st = State::default();
    // SAFETY: valid pointers throughout.
    unsafe {
        assert_eq!(sd_state_init(&mut *st_c), SD_OK);
        for n in 0..3000u32 {
            let speed = if n < 1000 { 8.4 } else { -3.0 };
            assert_eq!(sd_command_speed(&*cfg_c, &mut *st_c, speed), SD_OK);
            st.command_speed(&cfg, speed);
            let x = n as f32 * 1e-3;
            let m = Measurement {
                i_a_a: if n == 1500 { f32::NAN } else { x.sin() },
                i_b_a: x.cos(),
                encoder_count: n.wrapping_mul(3),
            };
            let mc = sd_measurement { i_a_a: m.i_a_a, i_b_a: m.i_b_a, encoder_count: m.encoder_count };
            let mut out = sd_output::default();
            assert_eq!(sd_step(&*cfg_c, &mut *st_c, &mc, &mut out), SD_OK);
            let o = step(&cfg, &mut st, &m);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&out.duties), bits(&o.duties.0), "period {n}");
            assert_eq!(out.i_q_cmd_a.to_bits(), o.signals.i_dq_cmd.q.to_bits());
            assert_eq!(out.theta_cmd, o.signals.theta_cmd.0);
            assert_eq!(out.theta_fb, o.signals.theta_fb.0);
        }
        let mut info = sd_state_info::default();
        assert_eq!(sd_state_read(&*st_c, &mut info), SD_OK);
        assert_eq!(info.sample_faults, st.sample_faults);
        assert_eq!(info.sample_faults, 1);
        assert_eq!(info.position_command, st.position_command().0);
        assert_eq!(info.observer_r_hat_ohm.to_bits(), st.observer.r_hat_ohm.to_bits());
        assert_eq!(info.observer_delta_rad.to_bits(), st.observer.delta_rad.to_bits());
        assert_eq!(info.speed_command_rad_s, -3.0);
    }
}

#[test]
fn c_api_steps_exactly_like_the_core_in_every_mode() {
    same_as_core(Mode::OpenLoop, Compensation::Patent, SD_MODE_OPEN_LOOP, SD_COMPENSATION_PATENT);
    same_as_core(Mode::OpenLoop, Compensation::Estimated, SD_MODE_OPEN_LOOP, SD_COMPENSATION_ESTIMATED);
    same_as_core(Mode::Servo, Compensation::Patent, SD_MODE_SERVO, SD_COMPENSATION_PATENT);
    same_as_core(Mode::Servo, Compensation::Off, SD_MODE_SERVO, SD_COMPENSATION_OFF);
}

#[test]
fn each_rejected_parameter_has_its_own_status() {
    type Edit = fn(&mut sd_params);
    let cases: &[(Edit, sd_status)] = &[
        (|p| p.motor.km_nm_per_a = 0.0, SD_ERR_KM),
        (|p| p.motor.km_nm_per_a = 1e-40, SD_ERR_KM),
        (|p| p.motor.pole_pairs = 0, SD_ERR_POLE_PAIRS),
        (|p| p.motor.resistance_ohm = -1.0, SD_ERR_RESISTANCE),
        (|p| p.motor.inductance_h = f32::INFINITY, SD_ERR_INDUCTANCE),
        (|p| p.motor.coulomb_friction_nm = -0.1, SD_ERR_COULOMB_FRICTION),
        (|p| p.drive.bus_voltage_v = f32::NAN, SD_ERR_BUS_VOLTAGE),
        (|p| p.drive.pwm_hz = 0.0, SD_ERR_PWM_FREQUENCY),
        (|p| p.drive.current_limit_a = 0.0, SD_ERR_CURRENT_LIMIT),
        (|p| p.drive.holding_current_a = 5.0, SD_ERR_HOLDING_CURRENT),
        (|p| p.drive.current_loop_bandwidth_hz = 6000.0, SD_ERR_CURRENT_LOOP_BANDWIDTH),
        (|p| p.drive.computation_delay_periods = 2, SD_ERR_COMPUTATION_DELAY),
        (|p| p.drive.topology = 2, SD_ERR_INVALID_TOPOLOGY),
        (|p| p.encoder_counts_per_rev = 0, SD_ERR_ENCODER_COUNTS),
        (|p| p.servo.velocity_nm_s_per_rad = f32::NAN, SD_ERR_SERVO_VELOCITY_GAIN),
        (|p| p.servo.position_nm_per_rad = -1.0, SD_ERR_SERVO_POSITION_GAIN),
        (|p| p.servo.position_integral_nm_per_rad_s = -1.0, SD_ERR_SERVO_INTEGRAL_GAIN),
        (|p| p.servo.velocity_filter_hz = 0.0, SD_ERR_SERVO_VELOCITY_FILTER),
        (|p| p.mode = 9, SD_ERR_INVALID_MODE),
        (|p| p.compensation = 9, SD_ERR_INVALID_COMPENSATION),
        (|p| p.motor.detent_count = SD_MAX_HARMONICS + 1, SD_ERR_DETENT_COUNT_BEYOND_CAPACITY),
        (|p| p.motor.detent = null(), SD_ERR_DETENT_NULL_WITH_COUNT),
        (|p| p.motor.detent_count = 0, SD_ERR_DETENT_POINTER_WITHOUT_COUNT),
    ];
    let base = patent(SD_MODE_SERVO, SD_COMPENSATION_PATENT);
    for (i, (edit, want)) in cases.iter().enumerate() {
        let mut p = base;
        edit(&mut p);
        let (got, cfg) = init(&p);
        assert_eq!(got, *want, "case {i}");
        // A failed initialisation leaves a config that every call refuses.
        let mut st = zeroed_state();
        // SAFETY: valid pointers.
        unsafe {
            assert_eq!(sd_state_init(&mut *st), SD_OK);
            assert_eq!(sd_command_speed(&*cfg, &mut *st, 1.0), SD_ERR_NOT_INITIALIZED);
        }
    }
    // The detent table's own checks, through a table of the caller's.
    let table_cases: &[([sd_harmonic; 2], sd_status)] = &[
        ([h(0, 0.01, 0.0), h(2, 0.01, 0.0)], SD_ERR_HARMONIC_ORDER),
        ([h(33, 0.01, 0.0), h(2, 0.01, 0.0)], SD_ERR_HARMONIC_ORDER),
        ([h(2, 0.01, 0.0), h(2, 0.02, 0.0)], SD_ERR_DUPLICATE_HARMONIC),
        ([h(1, -0.01, 0.0), h(2, 0.01, 0.0)], SD_ERR_DETENT_AMPLITUDE),
        ([h(1, 0.01, f32::NAN), h(2, 0.01, 0.0)], SD_ERR_DETENT_PHASE),
        ([h(1, 0.01, 0.5), h(32, 0.01, 0.0)], SD_OK),
    ];
    for (table, want) in table_cases {
        let mut p = base;
        p.motor.detent = table.as_ptr();
        p.motor.detent_count = 2;
        assert_eq!(init(&p).0, *want, "{table:?}");
    }
    // No table at all is valid.
    let mut p = base;
    p.motor.detent = null();
    p.motor.detent_count = 0;
    assert_eq!(init(&p).0, SD_OK);
}

fn h(order: u16, amplitude_nm: f32, phase_rad: f32) -> sd_harmonic {
    sd_harmonic { order, amplitude_nm, phase_rad }
}

/// `patent-motor-real`'s parts per ampere (`stepdamp motor ripple`'s `per_amp_d`, `per_amp_q`
/// rounded), N·m/A.
const PER_AMP_D: [sd_harmonic; 2] = [
    sd_harmonic { order: 4, amplitude_nm: 0.0145, phase_rad: 0.35 },
    sd_harmonic { order: 2, amplitude_nm: 0.0045, phase_rad: 0.0 },
];
const PER_AMP_Q: [sd_harmonic; 2] = [
    sd_harmonic { order: 4, amplitude_nm: 0.0083, phase_rad: -1.2 },
    sd_harmonic { order: 2, amplitude_nm: 0.0045, phase_rad: core::f32::consts::FRAC_PI_2 },
];

#[test]
fn the_ripple_that_grows_with_the_current_steps_exactly_like_the_core_in_every_mode() {
    let core = |t: &[sd_harmonic]| -> Vec<Harmonic> {
        t.iter().map(|h| Harmonic { order: h.order, amplitude_nm: h.amplitude_nm, phase_rad: h.phase_rad }).collect()
    };
    let (d, q) = (core(&PER_AMP_D), core(&PER_AMP_Q));
    for (mode, mode_c) in [(Mode::OpenLoop, SD_MODE_OPEN_LOOP), (Mode::Servo, SD_MODE_SERVO)] {
        for (comp, comp_c) in
            [(Compensation::Patent, SD_COMPENSATION_PATENT), (Compensation::Estimated, SD_COMPENSATION_ESTIMATED)]
        {
            let mut c = patent(mode_c, comp_c);
            c.motor.ripple_per_amp_d = PER_AMP_D.as_ptr();
            c.motor.ripple_per_amp_d_count = 2;
            c.motor.ripple_per_amp_q = PER_AMP_Q.as_ptr();
            c.motor.ripple_per_amp_q_count = 2;
            let mut params = Params::patent_motor(mode, comp);
            params.motor.current_ripple = CurrentRipple { per_amp_d: &d, per_amp_q: &q };
            same_as_core_with(&c, &params);
            // And the ripple is used: the configuration differs from the one without it.
            assert_ne!(Config::new(&params).unwrap(), Config::new(&Params::patent_motor(mode, comp)).unwrap());
        }
    }
}

#[test]
fn a_ripple_table_whose_pointer_and_count_disagree_or_whose_values_are_out_of_range_is_refused() {
    let base = patent(SD_MODE_OPEN_LOOP, SD_COMPENSATION_PATENT);
    let mut p = base;
    p.motor.ripple_per_amp_d_count = 1;
    assert_eq!(init(&p).0, SD_ERR_RIPPLE_TABLE, "NULL with a count");
    let mut p = base;
    p.motor.ripple_per_amp_q = PER_AMP_Q.as_ptr();
    assert_eq!(init(&p).0, SD_ERR_RIPPLE_TABLE, "a pointer with a count of 0");
    let mut p = base;
    p.motor.ripple_per_amp_q = PER_AMP_Q.as_ptr();
    p.motor.ripple_per_amp_q_count = SD_MAX_HARMONICS + 1;
    assert_eq!(init(&p).0, SD_ERR_RIPPLE_TABLE, "beyond capacity");
    for (bad, want) in [(h(4, -0.01, 0.0), SD_ERR_RIPPLE_AMPLITUDE), (h(4, 0.01, f32::NAN), SD_ERR_RIPPLE_PHASE)] {
        let table = [bad];
        let mut p = base;
        p.motor.ripple_per_amp_d = table.as_ptr();
        p.motor.ripple_per_amp_d_count = 1;
        assert_eq!(init(&p).0, want, "{bad:?}");
    }
}

#[test]
fn null_pointers_and_uninitialised_objects_are_statuses_not_crashes() {
    let p = patent(SD_MODE_OPEN_LOOP, SD_COMPENSATION_PATENT);
    let (s, cfg) = init(&p);
    assert_eq!(s, SD_OK);
    let mut st = zeroed_state();
    let m = sd_measurement::default();
    let mut out = sd_output::default();
    let (mut a, mut b) = (0.0f32, 0.0f32);
    let blank = zeroed_config();
    // SAFETY: every pointer is valid or NULL, which the API checks.
    unsafe {
        assert_eq!(sd_params_patent_motor(SD_MODE_SERVO, SD_COMPENSATION_OFF, null_mut()), SD_ERR_NULL_POINTER);
        assert_eq!(sd_config_init(null(), &mut *zeroed_config()), SD_ERR_NULL_POINTER);
        assert_eq!(sd_config_init(&p, null_mut()), SD_ERR_NULL_POINTER);
        assert_eq!(sd_state_init(null_mut()), SD_ERR_NULL_POINTER);
        // Used before sd_state_init: refused.
        assert_eq!(sd_step(&*cfg, &mut *st, &m, &mut out), SD_ERR_NOT_INITIALIZED);
        assert_eq!(sd_state_init(&mut *st), SD_OK);
        assert_eq!(sd_step(&*blank, &mut *st, &m, &mut out), SD_ERR_NOT_INITIALIZED);
        assert_eq!(sd_step(null(), &mut *st, &m, &mut out), SD_ERR_NULL_POINTER);
        assert_eq!(sd_step(&*cfg, null_mut(), &m, &mut out), SD_ERR_NULL_POINTER);
        assert_eq!(sd_step(&*cfg, &mut *st, null(), &mut out), SD_ERR_NULL_POINTER);
        assert_eq!(sd_step(&*cfg, &mut *st, &m, null_mut()), SD_ERR_NULL_POINTER);
        assert_eq!(sd_command_speed(null(), &mut *st, 1.0), SD_ERR_NULL_POINTER);
        assert_eq!(sd_command_speed(&*cfg, null_mut(), 1.0), SD_ERR_NULL_POINTER);
        assert_eq!(sd_state_read(null(), &mut sd_state_info::default()), SD_ERR_NULL_POINTER);
        assert_eq!(sd_state_read(&*st, null_mut()), SD_ERR_NULL_POINTER);
        assert_eq!(sd_config_read(null(), &mut sd_config_info::default()), SD_ERR_NULL_POINTER);
        assert_eq!(sd_config_read(&*cfg, null_mut()), SD_ERR_NULL_POINTER);
        assert_eq!(sd_winding_voltages_per_vdc(&*cfg, &out, null_mut(), &mut b), SD_ERR_NULL_POINTER);
        assert_eq!(sd_winding_voltages_per_vdc(&*cfg, &out, &mut a, null_mut()), SD_ERR_NULL_POINTER);
        assert_eq!(sd_winding_voltages_per_vdc(&*cfg, null(), &mut a, &mut b), SD_ERR_NULL_POINTER);
        assert_eq!(sd_ref_sincosf(1.0, null_mut(), &mut b), SD_ERR_NULL_POINTER);
        // A misaligned config is refused, not read.
        let words = &mut *zeroed_config();
        let odd = (words as *mut sd_config).cast::<u8>().add(4).cast::<sd_config>();
        assert_eq!(sd_config_init(&p, odd), SD_ERR_MISALIGNED);
        // The state survived all the refused calls unchanged and still works.
        assert_eq!(sd_step(&*cfg, &mut *st, &m, &mut out), SD_OK);
        assert!(out.duties.iter().all(|d| (0.0..=1.0).contains(d)));
    }
}

#[test]
fn config_info_reports_the_reference_drive() {
    let (_, cfg) = init(&patent(SD_MODE_OPEN_LOOP, SD_COMPENSATION_PATENT));
    let mut info = sd_config_info::default();
    // SAFETY: valid pointers.
    assert_eq!(unsafe { sd_config_read(&*cfg, &mut info) }, SD_OK);
    let core = Config::new(&Params::patent_motor(Mode::OpenLoop, Compensation::Patent)).unwrap();
    assert_eq!(info.period_s, core.period_s());
    assert_eq!(info.max_speed_rad_s, core.max_speed_rad_s());
    assert_eq!(
        (info.pole_pairs, info.legs, info.mode, info.topology),
        (50, 3, SD_MODE_OPEN_LOOP, SD_TOPOLOGY_THREE_LEG)
    );
}

#[test]
fn status_texts_are_nul_terminated_and_distinct_through_the_c_call() {
    let text = |s| {
        // SAFETY: sd_status_str returns a static NUL-terminated string.
        unsafe { std::ffi::CStr::from_ptr(sd_status_str(s)) }.to_str().unwrap().to_owned()
    };
    assert_eq!(text(SD_OK), "ok");
    assert!(text(SD_ERR_BUS_VOLTAGE).contains("drive.bus_voltage_v"));
    let all: std::collections::HashSet<_> = (SD_OK..=SD_ERR_INVALID_PARAMETER).map(text).collect();
    assert_eq!(all.len() as i32, SD_ERR_INVALID_PARAMETER + 1);
    assert_eq!(text(1000), "unknown status");
}
