//! Tests of the whole drive step.

extern crate std;

use super::*;
use proptest::prelude::*;
use std::vec::Vec;

const DETENT: [Harmonic; 3] = PATENT_MOTOR_DETENT;

fn params(mode: Mode, compensation: Compensation) -> Params<'static> {
    Params::patent_motor(mode, compensation)
}

#[test]
fn the_reference_servo_gains_are_those_of_a_50_hz_loop() {
    assert_eq!(params(Mode::Servo, Compensation::Off).servo, ServoGains::for_bandwidth(4.0e-5, 50.0, 300.0));
}

#[test]
fn config_rejects_nonsense_with_the_field_named() {
    let mut p = params(Mode::OpenLoop, Compensation::Patent);
    p.motor.km_nm_per_a = 0.0;
    let e = Config::new(&p).unwrap_err();
    assert!(matches!(e, ConfigError::Invalid { field: "motor.km_nm_per_a", .. }), "{e:?}");
    let mut p = params(Mode::OpenLoop, Compensation::Patent);
    p.drive.bus_voltage_v = -48.0;
    assert!(matches!(Config::new(&p), Err(ConfigError::Invalid { field: "drive.bus_voltage_v", .. })));
    let mut p = params(Mode::OpenLoop, Compensation::Patent);
    p.drive.holding_current_a = 4.0;
    assert!(matches!(Config::new(&p), Err(ConfigError::Invalid { field: "drive.holding_current_a", .. })));
    let mut p = params(Mode::OpenLoop, Compensation::Patent);
    p.motor.inductance_h = f32::NAN;
    assert!(matches!(Config::new(&p), Err(ConfigError::Invalid { field: "motor.inductance_h", .. })));
    let mut p = params(Mode::OpenLoop, Compensation::Patent);
    p.drive.current_loop_bandwidth_hz = 6000.0;
    assert!(Config::new(&p).is_err());
    let mut p = params(Mode::OpenLoop, Compensation::Patent);
    p.encoder_counts_per_rev = 0;
    assert!(Config::new(&p).is_err());
}

#[test]
fn a_detent_the_holding_current_cannot_hold_is_refused_with_the_holding_torque() {
    use std::string::ToString;
    // Km·I_hold = 0.3 N·m/A × 1.9 A = 0.57 N·m; 5 N·m is 8.8 times that.
    static BIG: [Harmonic; 1] = [Harmonic { order: 4, amplitude_nm: 5.0, phase_rad: 0.0 }];
    static SUM_AT_LIMIT: [Harmonic; 2] = [
        Harmonic { order: 4, amplitude_nm: 0.3, phase_rad: 0.0 },
        Harmonic { order: 2, amplitude_nm: 0.3, phase_rad: 0.0 },
    ];
    for mode in [Mode::OpenLoop, Mode::Servo] {
        for detent in [&BIG[..], &SUM_AT_LIMIT[..]] {
            let mut p = params(mode, Compensation::Patent);
            p.motor.detent = detent;
            let e = Config::new(&p).unwrap_err();
            assert!(matches!(e, ConfigError::Invalid { field: "detent.amplitude_nm", .. }), "{e:?}");
            let text = e.to_string();
            assert!(text.contains("= 0.57 N·m") && text.contains("cannot hold"), "{text}");
        }
    }
    static HALF: [Harmonic; 1] = [Harmonic { order: 4, amplitude_nm: 0.28, phase_rad: 0.0 }];
    let mut p = params(Mode::OpenLoop, Compensation::Patent);
    p.motor.detent = &HALF;
    assert!(Config::new(&p).is_ok());
}

#[test]
fn config_errors_print_numbers_in_short_form() {
    use std::string::ToString;
    let mut p = params(Mode::OpenLoop, Compensation::Patent);
    p.motor.km_nm_per_a = f32::MAX;
    assert_eq!(
        Config::new(&p).unwrap_err().to_string(),
        "motor.km_nm_per_a = 3.4028235e38: must be in [1e-3, 50] N·m/A"
    );
    p.motor.km_nm_per_a = 1e-40;
    assert!(Config::new(&p).unwrap_err().to_string().starts_with("motor.km_nm_per_a = 1e-40: "));
}

#[test]
fn open_loop_commands_holding_current_and_compensation_at_theta_cmd() {
    let cfg = Config::new(&params(Mode::OpenLoop, Compensation::Patent)).unwrap();
    let series = HarmonicSeries::new(&DETENT, 1.0 / 0.3).unwrap();
    let mut st = State::default();
    st.command_speed(&cfg, 5.0);
    for _ in 0..500 {
        let out = step(&cfg, &mut st, &Measurement::default());
        let th = out.signals.theta_cmd.electrical_angle_rad();
        assert_eq!(out.signals.i_dq_cmd.d, 1.9);
        assert!((out.signals.i_dq_cmd.q - series.eval(th)).abs() < 1e-5);
    }
    // Without compensation the q command is zero.
    let cfg = Config::new(&params(Mode::OpenLoop, Compensation::Off)).unwrap();
    let mut st = State::default();
    st.command_speed(&cfg, 5.0);
    for _ in 0..100 {
        assert_eq!(step(&cfg, &mut st, &Measurement::default()).signals.i_dq_cmd.q, 0.0);
    }
}

#[test]
fn open_loop_angle_advances_at_the_commanded_speed() {
    let cfg = Config::new(&params(Mode::OpenLoop, Compensation::Off)).unwrap();
    let mut st = State::default();
    st.command_speed(&cfg, 2.0);
    for _ in 0..20_000 {
        step(&cfg, &mut st, &Measurement::default());
    }
    // One second at 2 rad/s.
    assert!((st.position_command().mechanical_rad_f64(50) - 2.0).abs() < 1e-6);
}

#[test]
fn servo_pushes_toward_the_command_and_feeds_friction_forward() {
    let cfg = Config::new(&params(Mode::Servo, Compensation::Patent)).unwrap();
    let mut st = State::default();
    st.command_speed(&cfg, 1.0);
    // Rotor held at 0 while the command moves on: positive q current, d = 0.
    let mut last = 0.0;
    for _ in 0..200 {
        let out = step(&cfg, &mut st, &Measurement::default());
        assert_eq!(out.signals.i_dq_cmd.d, 0.0);
        last = out.signals.i_dq_cmd.q;
    }
    assert!(last > 0.01 / 0.3, "{last}");
    // Rotor ahead of the command: negative q current.
    let cfg = Config::new(&params(Mode::Servo, Compensation::Off)).unwrap();
    let mut st = State::default();
    let out = step(&cfg, &mut st, &Measurement { encoder_count: 40, ..Default::default() });
    assert!(out.signals.i_dq_cmd.q < 0.0);
}

#[test]
fn servo_current_command_is_clamped_to_the_limit() {
    let cfg = Config::new(&params(Mode::Servo, Compensation::Patent)).unwrap();
    let mut st = State::default();
    // Rotor far behind: half a revolution.
    for _ in 0..1000 {
        let out = step(&cfg, &mut st, &Measurement { encoder_count: 2000u32.wrapping_neg(), ..Default::default() });
        assert!(out.signals.i_dq_cmd.q <= 3.0 && out.signals.i_dq_cmd.q > 2.99);
    }
}

#[test]
fn a_nan_sample_acts_as_a_repeat_of_the_last_good_sample() {
    for (mode, comp) in [
        (Mode::OpenLoop, Compensation::Patent),
        (Mode::OpenLoop, Compensation::Estimated),
        (Mode::Servo, Compensation::Patent),
    ] {
        let cfg = Config::new(&params(mode, comp)).unwrap();
        let mut a = State::default();
        let mut b = State::default();
        a.command_speed(&cfg, 3.0);
        b.command_speed(&cfg, 3.0);
        let good = |k: u32| Measurement { i_a_a: 1.0 + 0.001 * k as f32, i_b_a: -0.5, encoder_count: k / 10 };
        for k in 0..100 {
            step(&cfg, &mut a, &good(k));
            step(&cfg, &mut b, &good(k));
        }
        let last = good(99);
        for (k, bad) in [f32::NAN, f32::INFINITY, 1e30].into_iter().enumerate() {
            let oa = step(&cfg, &mut a, &Measurement { i_a_a: bad, ..good(100 + k as u32) });
            let ob = step(&cfg, &mut b, &Measurement { encoder_count: good(100 + k as u32).encoder_count, ..last });
            assert_eq!(oa.duties, ob.duties);
        }
        assert_eq!(a.sample_faults, 3);
        for k in 103..200 {
            assert_eq!(step(&cfg, &mut a, &good(k)).duties, step(&cfg, &mut b, &good(k)).duties);
        }
    }
}

proptest! {
    #[test]
    fn any_input_sequence_gives_duties_in_range_and_finite_state(
        seq in proptest::collection::vec(
            (proptest::num::f32::ANY, proptest::num::f32::ANY, any::<u32>(), proptest::num::f32::ANY), 1..60),
        servo in any::<bool>(),
        comp in 0usize..3,
    ) {
        let mode = if servo { Mode::Servo } else { Mode::OpenLoop };
        let comp = [Compensation::Off, Compensation::Patent, Compensation::Estimated][comp];
        let cfg = Config::new(&params(mode, comp)).unwrap();
        let mut st = State::default();
        for (ia, ib, enc, w) in seq {
            st.command_speed(&cfg, w);
            let out = step(&cfg, &mut st, &Measurement { i_a_a: ia, i_b_a: ib, encoder_count: enc });
            for d in out.duties.0 {
                prop_assert!((0.0..=1.0).contains(&d));
            }
            prop_assert!(out.signals.v_ab.a.is_finite() && out.signals.v_ab.b.is_finite());
        }
        // After garbage, good samples still give sane, finite control.
        for _ in 0..10 {
            let out = step(&cfg, &mut st, &Measurement::default());
            prop_assert!(out.signals.i_dq_cmd.q.is_finite());
        }
    }
}

/// Servo parameters with all loop gains zero, so the q command is the feed-forward alone.
fn feed_forward_only(compensation: Compensation, detent: &'static [Harmonic]) -> Params<'static> {
    let mut p = params(Mode::Servo, compensation);
    p.servo = ServoGains {
        velocity_nm_s_per_rad: 0.0,
        position_nm_per_rad: 0.0,
        position_integral_nm_per_rad_s: 0.0,
        velocity_filter_hz: 300.0,
    };
    p.motor.detent = detent;
    p
}

#[test]
fn servo_friction_feed_forward_is_fs_over_km_signed_by_the_speed_command() {
    let off = Config::new(&feed_forward_only(Compensation::Off, &[])).unwrap();
    let on = Config::new(&feed_forward_only(Compensation::Patent, &[])).unwrap();
    let fs_over_km = 0.01f32 / 0.3f32;
    for (speed, want) in [(5.0, fs_over_km), (-5.0, -fs_over_km), (0.0, 0.0)] {
        let (mut a, mut b) = (State::default(), State::default());
        a.command_speed(&off, speed);
        b.command_speed(&on, speed);
        for k in 0..50u32 {
            // The rotor creeps the other way: position, velocity and integral errors all
            // exist, but their gains are zero.
            let m = Measurement { i_a_a: 0.1, i_b_a: -0.2, encoder_count: k.wrapping_neg() };
            let qa = step(&off, &mut a, &m).signals.i_dq_cmd.q;
            let qb = step(&on, &mut b, &m).signals.i_dq_cmd.q;
            assert_eq!(qa, 0.0, "speed {speed}");
            assert_eq!(qb - qa, want, "speed {speed}, period {k}");
        }
    }
}

#[test]
fn servo_compensation_is_evaluated_at_theta_fb_not_theta_cmd() {
    let cfg = Config::new(&feed_forward_only(Compensation::Patent, &DETENT)).unwrap();
    let series = HarmonicSeries::new(&DETENT, 1.0 / 0.3).unwrap();
    // Rotor held at count 30 of 4000: the centre of the count, 30.5/80 electrical turn.
    let held = Measurement { encoder_count: 30, ..Default::default() };
    let th_fb = 30.5 / 80.0 * core::f32::consts::TAU;
    let (s, c) = libm::sincosf(th_fb);
    let (at_fb, slope, curv) = series.eval_with_derivatives(s, c);

    // Standstill command at θ = 0: the lead terms vanish (ωe = 0), no friction.
    let mut st = State::default();
    for _ in 0..10 {
        let out = step(&cfg, &mut st, &held);
        assert!((out.signals.theta_fb.electrical_angle_rad() - th_fb).abs() < 1e-6);
        assert_eq!(out.signals.theta_cmd.electrical_angle_rad(), 0.0);
        let q = out.signals.i_dq_cmd.q;
        assert!((q - at_fb).abs() < 1e-5, "{q} vs series at θ_fb {at_fb}");
        assert!((q - series.eval(0.0)).abs() > 0.01, "{q} looks like the series at θ_cmd");
    }

    // Moving command (2 rad/s, ωe = 100 rad/s): the series at θ_fb plus its lead
    // `(1/ωc)·ωe·(S' + Td·ωe·S'')` (ωc = 2π·1.5 kHz, Td = 1.5 periods) and the friction.
    let mut st = State::default();
    st.command_speed(&cfg, 2.0);
    let we = 2.0 * 50.0;
    let lead = 1.0 / (core::f32::consts::TAU * 1500.0) * we * (slope + 1.5 / 20_000.0 * we * curv);
    let want = at_fb + lead + 0.01 / 0.3;
    for k in 0..200 {
        let out = step(&cfg, &mut st, &held);
        let q = out.signals.i_dq_cmd.q;
        assert!((q - want).abs() < 1e-5, "period {k}: {q} vs {want}");
        // θ_cmd moves on, θ_fb does not: the command's own angle would give another value.
        let th_cmd = out.signals.theta_cmd.electrical_angle_rad();
        if k > 100 {
            assert!((th_cmd - th_fb).abs() > 0.1);
            let (sc, cc) = libm::sincosf(th_cmd);
            let (v, sl, cu) = series.eval_with_derivatives(sc, cc);
            let at_cmd = v + 1.0 / (core::f32::consts::TAU * 1500.0) * we * (sl + 1.5 / 20_000.0 * we * cu);
            if (at_cmd - at_fb - lead).abs() > 1e-3 {
                assert!((q - at_cmd - 0.01 / 0.3).abs() > 1e-4);
            }
        }
    }
}

#[test]
fn measured_currents_are_parked_with_the_design_q_sign() {
    // docs/design.md#the-plant: i_q = −i_a sin θe + i_b cos θe, i_d = i_a cos θe + i_b sin θe.
    let cfg = Config::new(&params(Mode::OpenLoop, Compensation::Off)).unwrap();
    let mut st = State::default();
    // θ_cmd = 0: phase B current is +q, phase A current is +d.
    let out = step(&cfg, &mut st, &Measurement { i_a_a: 0.0, i_b_a: 1.0, encoder_count: 0 });
    assert_eq!(out.signals.i_dq, Dq { d: 0.0, q: 1.0 });
    let out = step(&cfg, &mut st, &Measurement { i_a_a: 1.0, i_b_a: 0.0, encoder_count: 0 });
    assert_eq!(out.signals.i_dq, Dq { d: 1.0, q: 0.0 });
    // One period at the largest speed: θ_cmd = a quarter electrical turn (sin 1, cos 0),
    // where phase A current is −q.
    st.command_speed(&cfg, cfg.max_speed_rad_s());
    step(&cfg, &mut st, &Measurement::default());
    st.command_speed(&cfg, 0.0);
    let out = step(&cfg, &mut st, &Measurement { i_a_a: 1.0, i_b_a: 0.0, encoder_count: 0 });
    assert!((out.signals.theta_cmd.electrical_angle_rad() - core::f32::consts::FRAC_PI_2).abs() < 1e-6);
    assert!((out.signals.i_dq.q + 1.0).abs() < 1e-6 && out.signals.i_dq.d.abs() < 1e-6, "{:?}", out.signals.i_dq);
}

#[test]
fn speed_command_is_clamped_to_a_quarter_electrical_turn_per_period() {
    let cfg = Config::new(&params(Mode::OpenLoop, Compensation::Off)).unwrap();
    // (π/2)/(Nr·Ts) = 1.5708/(50·5e-5) = 628.3 rad/s.
    let max = cfg.max_speed_rad_s();
    assert!((max - 628.318_5).abs() < 1e-3, "{max}");
    for (ask, want) in [(1e6, max), (-1e30, -max), (f32::MAX, max), (300.0, 300.0), (-max, -max)] {
        let mut st = State::default();
        st.command_speed(&cfg, ask);
        assert_eq!(st.speed_command_rad_s(), want);
        step(&cfg, &mut st, &Measurement::default());
        let turn = st.position_command().electrical_angle_rad() / core::f32::consts::TAU;
        let want_turn = want / max * 0.25;
        assert!((turn - want_turn).abs() < 1e-6, "{ask}: {turn} turn per period");
    }
    // Other pole counts and rates scale it.
    let mut p = params(Mode::OpenLoop, Compensation::Off);
    p.motor.pole_pairs = 100;
    p.drive.pwm_hz = 40_000.0;
    assert!((Config::new(&p).unwrap().max_speed_rad_s() - 628.318_5).abs() < 1e-3);
}

#[test]
fn config_rejects_finite_values_whose_derived_numbers_overflow() {
    fn field_of(f: impl FnOnce(&mut Params<'static>)) -> &'static str {
        let mut p = params(Mode::Servo, Compensation::Patent);
        f(&mut p);
        match Config::new(&p) {
            Err(ConfigError::Invalid { field, .. }) => field,
            other => panic!("accepted or other error: {other:?}"),
        }
    }
    assert_eq!(field_of(|p| p.motor.km_nm_per_a = 1e-40), "motor.km_nm_per_a");
    assert_eq!(
        field_of(|p| {
            p.drive.current_limit_a = 3e38;
            p.drive.holding_current_a = 3e38;
        }),
        "drive.current_limit_a"
    );
    assert_eq!(field_of(|p| p.drive.current_limit_a = 1e37), "drive.current_limit_a");
    assert_eq!(field_of(|p| p.drive.bus_voltage_v = 1e-39), "drive.bus_voltage_v");
    assert_eq!(field_of(|p| p.drive.current_loop_bandwidth_hz = 1e-40), "drive.current_loop_bandwidth_hz");
    assert_eq!(
        field_of(|p| {
            p.drive.pwm_hz = 1e-39;
            p.drive.current_loop_bandwidth_hz = 1e-40;
        }),
        "drive.pwm_hz"
    );
    assert_eq!(field_of(|p| p.servo.velocity_nm_s_per_rad = 3e38), "servo.velocity_nm_s_per_rad");
    assert_eq!(field_of(|p| p.motor.coulomb_friction_nm = 3e38), "motor.coulomb_friction_nm");
    assert_eq!(field_of(|p| p.motor.inductance_h = 1e36), "motor.inductance_h");
    static HUGE: [Harmonic; 1] = [Harmonic { order: 4, amplitude_nm: 3e38, phase_rad: 0.3 }];
    assert_eq!(field_of(|p| p.motor.detent = &HUGE), "detent.amplitude_nm");
    // The estimated-angle observer's numbers too.
    let mut p = params(Mode::OpenLoop, Compensation::Estimated);
    p.motor.resistance_ohm = 3e38;
    assert!(matches!(Config::new(&p), Err(ConfigError::Invalid { field: "motor.resistance_ohm", .. })));
}

#[test]
fn a_stuck_nan_current_sensor_lets_go_of_the_windings_then_recovers() {
    for (mode, comp, topology) in [
        (Mode::OpenLoop, Compensation::Patent, Topology::ThreeLeg),
        (Mode::OpenLoop, Compensation::Estimated, Topology::TwoHBridge),
        (Mode::Servo, Compensation::Patent, Topology::ThreeLeg),
    ] {
        let mut p = params(mode, comp);
        p.drive.topology = topology;
        let cfg = Config::new(&p).unwrap();
        let mut st = State::default();
        st.command_speed(&cfg, 3.0);
        let good = |k: u32| Measurement { i_a_a: 1.0 + 0.001 * k as f32, i_b_a: -0.5, encoder_count: k / 10 };
        let bad = |k: u32| Measurement { i_a_a: f32::NAN, i_b_a: f32::NAN, ..good(k) };
        for k in 0..100 {
            step(&cfg, &mut st, &good(k));
        }
        assert_ne!(st.current_loop_integrals_v(), Dq::default());
        // Glitches shorter than the limit are bridged, and a good sample restarts the count.
        for round in 0..3 {
            for k in 0..CURRENT_SENSOR_FAULT_PERIODS - 1 {
                let out = step(&cfg, &mut st, &bad(100 + k));
                assert!(!st.current_sensor_fault(), "{mode:?} round {round} period {k}");
                assert_ne!(out.duties, cfg.topology().neutral());
            }
            step(&cfg, &mut st, &good(200));
        }
        // A long run of NaN: from the CURRENT_SENSOR_FAULT_PERIODS-th on, zero volts.
        let before = st.sample_faults;
        let pos0 = st.position_command();
        for k in 0..2000 {
            let out = step(&cfg, &mut st, &bad(300 + k));
            let tripped = k + 1 >= CURRENT_SENSOR_FAULT_PERIODS;
            assert_eq!(st.current_sensor_fault(), tripped, "{mode:?} period {k}");
            if tripped {
                assert_eq!(out.duties, cfg.topology().neutral());
                assert_eq!(cfg.topology().winding_voltages_per_vdc(&out.duties), (0.0, 0.0));
                assert_eq!(st.current_loop_integrals_v(), Dq::default());
                assert_eq!(out.signals.voltage_scale, 0.0);
                assert_eq!(out.signals.v_ab, Ab::default());
            }
        }
        assert_eq!(st.sample_faults, before + 2000);
        // The command kept running through the fault.
        assert_eq!(st.position_command().wrapping_diff(pos0), 2000 * st_increment(&cfg, 3.0));
        // Good samples: the flag clears at once and control resumes, finite and in range.
        let out = step(&cfg, &mut st, &good(2400));
        assert!(!st.current_sensor_fault());
        assert_ne!(out.duties, cfg.topology().neutral());
        for k in 2401..3000 {
            let out = step(&cfg, &mut st, &good(k));
            assert!(out.duties.0.iter().all(|d| (0.0..=1.0).contains(d)));
            assert!(out.signals.i_dq_cmd.q.is_finite() && out.signals.v_ab.a.is_finite());
        }
        assert!(!st.current_sensor_fault());
        assert_eq!(st.sample_faults, before + 2000);
    }
}

/// The accumulator increment of a speed command.
fn st_increment(cfg: &Config, speed: f32) -> i64 {
    let mut st = State::default();
    st.command_speed(cfg, speed);
    step(cfg, &mut st, &Measurement::default());
    st.position_command().0
}

/// Runs the drive at standstill on two RL windings (the patent motor's R, L, no back-EMF),
/// the duties taking effect `delay` periods after they are computed, exactly integrated.
/// Returns per period: (i_a, voltage scale, d and q integrators).
fn run_on_rl_windings(cfg: &Config, st: &mut State, delay: usize, n: usize) -> Vec<(f32, f32, Dq)> {
    let (r, l, ts) = (0.9f32, 2.5e-3f32, cfg.period_s());
    let decay = libm::expf(-r * ts / l);
    let gain = (1.0 - decay) / r;
    let (mut ia, mut ib) = (0.0f32, 0.0f32);
    let mut pending = [cfg.topology().neutral(); 2];
    let mut log = Vec::new();
    for _ in 0..n {
        let out = step(cfg, st, &Measurement { i_a_a: ia, i_b_a: ib, encoder_count: 0 });
        log.push((ia, out.signals.voltage_scale, st.current_loop_integrals_v()));
        pending[1] = pending[0];
        pending[0] = out.duties;
        let (ua, ub) = cfg.topology().winding_voltages_per_vdc(&pending[delay]);
        let vdc = cfg.bus_voltage_v();
        ia = decay * ia + gain * ua * vdc;
        ib = decay * ib + gain * ub * vdc;
    }
    log
}

#[test]
fn current_loop_recovers_from_bus_saturation_without_windup_through_step() {
    // 2.5 V bus: holding 1.9 A along phase A needs R·I = 1.71 V, which fits, but the PI's
    // step demand (L·ωc·1.9 A ≈ 45 V) does not: the loop saturates for about 3 ms (the
    // winding charging towards 2.5 V/0.9 Ω), then must settle on 1.9 A without overshoot.
    for (topology, delay) in [(Topology::ThreeLeg, 1u8), (Topology::TwoHBridge, 0u8)] {
        let mut p = params(Mode::OpenLoop, Compensation::Off);
        p.drive.bus_voltage_v = 2.5;
        p.drive.topology = topology;
        p.drive.computation_delay_periods = delay;
        let cfg = Config::new(&p).unwrap();
        let mut st = State::default();
        let log = run_on_rl_windings(&cfg, &mut st, usize::from(delay), 600);
        let bound = 2.5 * topology.inscribed_radius_per_vdc();
        let saturated: Vec<usize> = (0..log.len()).filter(|&k| log[k].1 < 1.0).collect();
        assert!(saturated.len() >= 40, "{topology:?}: saturated only {} periods", saturated.len());
        let end = *saturated.last().unwrap();
        assert!(end < 100, "{topology:?}: still saturated at period {end}");
        for (k, (ia, _, integ)) in log.iter().enumerate() {
            assert!(integ.d.abs() <= bound && integ.q.abs() <= bound, "{topology:?} period {k}: {integ:?}");
            // No windup: the integrator never holds more than the steady state needs
            // (R·I = 1.71 V); an integrator that ran on while saturated would sit at the
            // bound (1.77 V or 2.5 V) when saturation ends.
            assert!(integ.d <= 0.9 * 1.9 + 0.01, "{topology:?} period {k}: wound up to {integ:?}");
            // No overshoot beyond 0.5 %, during or after saturation.
            assert!(*ia <= 1.9 * 1.005, "{topology:?} period {k}: i_a = {ia}");
        }
        // After saturation the current is close at once, then settles. The integrator was
        // held (conditional integration) and starts short of R·I, and with the PI zero on
        // the winding pole that shortfall decays with the winding's L/R = 2.8 ms (56
        // periods): within 5 % after 5 periods, within 1 % after 150 (≈ 3 L/R).
        for (k, (ia, _, _)) in log.iter().enumerate().skip(end + 5) {
            assert!((ia - 1.9).abs() < 0.05 * 1.9, "{topology:?} period {k}: i_a = {ia}");
            if k >= end + 150 {
                assert!((ia - 1.9).abs() < 0.01 * 1.9, "{topology:?} period {k}: i_a = {ia}");
            }
        }
        // And the integrator holds the winding's R·I, not a wound-up value.
        let last = log.last().unwrap().2;
        assert!((last.d - 0.9 * 1.9).abs() < 0.02 && last.q.abs() < 1e-3, "{topology:?}: {last:?}");
    }
}

#[test]
fn mode_and_compensation_names_parse_back() {
    use core::str::FromStr;
    for &m in Mode::ALL {
        assert_eq!(Mode::from_str(m.name()), Ok(m));
    }
    for &c in Compensation::ALL {
        assert_eq!(Compensation::from_str(c.name()), Ok(c));
    }
    let e = Mode::from_str("closed").unwrap_err();
    assert_eq!((e.what, e.expected), ("mode", "open-loop, servo"));
}
