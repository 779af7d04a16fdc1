//! The operating-point laws of [`super`]: each cancels a known ripple at its current; bad
//! inputs neither panic nor leak NaN; a model without current parts is the detent-only law.

extern crate std;

use super::*;
use crate::{Config, Measurement, Params, State, step};
use proptest::prelude::*;

/// A 4th- and 2nd-order ripple per ampere of `i_q` large enough that the division by the
/// torque per ampere matters (`cq` up to 0.27), and one per ampere of `i_d`.
static PER_AMP_Q: [Harmonic; 2] = [
    Harmonic { order: 4, amplitude_nm: 0.06, phase_rad: 0.4 },
    Harmonic { order: 2, amplitude_nm: 0.02, phase_rad: -1.0 },
];
static PER_AMP_D: [Harmonic; 2] = [
    Harmonic { order: 4, amplitude_nm: 0.03, phase_rad: 1.2 },
    Harmonic { order: 2, amplitude_nm: 0.005, phase_rad: 0.3 },
];
const RIPPLE: CurrentRipple<'static> = CurrentRipple { per_amp_d: &PER_AMP_D, per_amp_q: &PER_AMP_Q };
const KM: f64 = 0.3;

/// `Σ A·sin(k·θe + φ)` in `f64`: minus the torque the list puts on the rotor.
fn series(h: &[Harmonic], te: f64) -> f64 {
    h.iter().map(|h| f64::from(h.amplitude_nm) * (f64::from(h.order) * te + f64::from(h.phase_rad)).sin()).sum()
}

/// Motor torque plus ripple on the rotor at rotor-frame currents `(i_d, i_q)`, N·m.
fn torque(detent: &[Harmonic], te: f64, i_d: f64, i_q: f64) -> f64 {
    KM * i_q - series(detent, te) - i_d * series(&PER_AMP_D, te) - i_q * series(&PER_AMP_Q, te)
}

fn params(mode: Mode, comp: Compensation, ripple: CurrentRipple<'static>) -> Params<'static> {
    let mut p = Params::patent_motor(mode, comp);
    p.motor.current_ripple = ripple;
    p
}

/// A servo with a position gain alone (16 A/rad) and no friction, so that a configuration
/// with the compensation off gives the feedback current alone, `Kp_pos·θ_err/Km`.
fn servo(comp: Compensation, ripple: CurrentRipple<'static>) -> Config {
    let mut p = params(Mode::Servo, comp, ripple);
    p.motor.coulomb_friction_nm = 0.0;
    p.servo = crate::ServoGains {
        velocity_nm_s_per_rad: 0.0,
        position_nm_per_rad: 4.8,
        position_integral_nm_per_rad_s: 0.0,
        velocity_filter_hz: 300.0,
    };
    Config::new(&p).unwrap()
}

#[test]
fn the_servo_law_cancels_the_ripple_at_the_feedback_current() {
    // Command at rest, rotor held at `count`: the feedback current i_q,ctrl is the q command
    // of the same loop without compensation; with it, the torque on the rotor (motor,
    // detent and the ripple of the total current) must be exactly Km·i_q,ctrl.
    let (off, on) = (servo(Compensation::Off, RIPPLE), servo(Compensation::Patent, RIPPLE));
    let (mut worst, mut worst_undivided, mut largest) = (0.0f64, 0.0f64, 0.0f64);
    for count in -40i32..40 {
        let m = Measurement { encoder_count: count as u32, ..Default::default() };
        let (mut a, mut b) = (State::default(), State::default());
        let (oa, ob) = (step(&off, &mut a, &m), step(&on, &mut b, &m));
        let ctrl = f64::from(oa.signals.i_dq_cmd.q);
        let total = f64::from(ob.signals.i_dq_cmd.q);
        let te = f64::from(ob.signals.theta_fb.electrical_angle_rad());
        largest = largest.max(ctrl.abs());
        worst = worst.max((torque(&PATENT, te, 0.0, total) - KM * ctrl).abs());
        // Without the division the compensation's own ripple would stay.
        let s = (series(&PATENT, te) + ctrl * series(&PER_AMP_Q, te)) / KM;
        worst_undivided = worst_undivided.max((torque(&PATENT, te, 0.0, ctrl + s) - KM * ctrl).abs());
    }
    assert!(largest > 0.9, "the feedback carries up to {largest} A only");
    assert!(worst < 2e-6, "residual torque {worst} N·m");
    assert!(worst_undivided > 100.0 * worst, "the division does nothing: {worst_undivided} vs {worst}");
}

const PATENT: [Harmonic; 3] = crate::PATENT_MOTOR_DETENT;

#[test]
fn a_servo_runs_the_detent_law_when_only_i_d_makes_ripple() {
    // i_d = 0 in servo: a ripple per ampere of i_d changes nothing, bit for bit.
    let d_only = CurrentRipple { per_amp_d: &PER_AMP_D, per_amp_q: &[] };
    let (plain, with_d) = (servo(Compensation::Patent, CurrentRipple::NONE), servo(Compensation::Patent, d_only));
    assert_eq!(plain, with_d);
    assert!(!with_d.ripple.is_current_dependent());
}

#[test]
fn the_open_loop_law_at_theta_cmd_feeds_the_ripple_at_the_holding_current() {
    let cfg = Config::new(&params(Mode::OpenLoop, Compensation::Patent, RIPPLE)).unwrap();
    assert!(!cfg.ripple.is_current_dependent(), "folded into one table at configuration");
    let mut st = State::default();
    st.command_speed(&cfg, 5.0);
    for _ in 0..400 {
        let out = step(&cfg, &mut st, &Measurement::default());
        let te = f64::from(out.signals.theta_cmd.electrical_angle_rad());
        let want = (series(&PATENT, te) + 1.9 * series(&PER_AMP_D, te)) / KM;
        assert!((f64::from(out.signals.i_dq_cmd.q) - want).abs() < 2e-6, "θe {te}");
        assert_eq!(out.signals.i_dq_cmd.d, 1.9);
    }
}

#[test]
fn the_estimated_law_cancels_the_ripple_at_the_load_angle() {
    // The law of the module doc at the rotor's angle θe and load angle δ (within ±0.5 rad,
    // where the divisor's bound does not act on this ripple): the holding
    // current on d of θc = θe + δ and i_comp on its q axis make, with the ripple, the
    // torque of a pure-sine motor, Km·I·sin δ.
    let cfg = Config::new(&params(Mode::OpenLoop, Compensation::Estimated, RIPPLE)).unwrap();
    let m = cfg.ripple;
    assert!(m.is_current_dependent());
    let i = 1.9f32;
    for n in 0..200 {
        let te = 0.0314 * n as f32;
        let delta = 0.5 * libm::sinf(0.37 * n as f32);
        let (s1, c1) = libm::sincosf(te);
        let (sd, cd) = libm::sincosf(delta);
        let v = m.eval(s1, c1, i * cd, i * sd);
        let comp = f64::from(v.current_a / divisor(&v, sd, cd));
        let (te, delta) = (f64::from(te), f64::from(delta));
        let (i_d, i_q) = (1.9 * delta.cos() - comp * delta.sin(), 1.9 * delta.sin() + comp * delta.cos());
        let residual = torque(&PATENT, te, i_d, i_q) - KM * 1.9 * delta.sin();
        assert!(residual.abs() < 2e-6, "θe {te} δ {delta}: {residual} N·m");
    }
}

#[test]
fn the_estimated_law_at_standstill_divides_the_ripple_at_the_holding_current() {
    // At rest the observer's δ̂ is 0: i_comp = S(θc, I_hold, 0) / (1 − cq(θc)).
    let cfg = Config::new(&params(Mode::OpenLoop, Compensation::Estimated, RIPPLE)).unwrap();
    let mut st = State::default();
    for n in 0..50 {
        let count = n * 977;
        let out = step(&cfg, &mut st, &Measurement { i_a_a: 1.9, i_b_a: 0.0, encoder_count: count });
        let te = f64::from(out.signals.theta_cmd.electrical_angle_rad());
        let s = (series(&PATENT, te) + 1.9 * series(&PER_AMP_D, te)) / KM;
        let want = s / (1.0 - series(&PER_AMP_Q, te) / KM);
        assert!((f64::from(out.signals.i_dq_cmd.q) - want).abs() < 2e-6, "period {n}");
    }
}

#[test]
fn the_divisor_is_bounded_and_nan_gives_the_bound() {
    let v = |q: f32, d: f32| RippleValue { per_amp_q: q, per_amp_d: d, ..Default::default() };
    assert_eq!(divisor(&v(0.0, 0.0), 0.0, 1.0), 1.0);
    assert_eq!(divisor(&v(0.9, 0.0), 0.0, 1.0), MIN_DIVISOR);
    assert_eq!(divisor(&v(0.2, 0.0), 0.0, -1.0), MIN_DIVISOR);
    assert_eq!(divisor(&v(f32::NAN, 0.0), 0.0, 1.0), MIN_DIVISOR);
    assert_eq!(divisor(&v(0.0, f32::INFINITY), -1.0, 0.0), MIN_DIVISOR);
    assert!((divisor(&v(-0.1, 0.2), 0.6, 0.8) - (0.8 * 1.1 + 0.6 * 0.2)).abs() < 1e-6);
}

#[test]
fn bad_current_ripple_is_refused_with_its_key() {
    static NEG: [Harmonic; 1] = [Harmonic { order: 4, amplitude_nm: -0.1, phase_rad: 0.0 }];
    static DEG: [Harmonic; 1] = [Harmonic { order: 4, amplitude_nm: 0.1, phase_rad: 90.0 }];
    static ORDER: [Harmonic; 1] = [Harmonic { order: 40, amplitude_nm: 0.1, phase_rad: 0.0 }];
    let field = |r: CurrentRipple<'static>| match Config::new(&params(Mode::Servo, Compensation::Off, r)) {
        Err(ConfigError::Invalid { field, .. }) => field,
        other => panic!("{other:?}"),
    };
    assert_eq!(field(CurrentRipple { per_amp_d: &NEG, per_amp_q: &[] }), "current_ripple.amplitude_nm_per_a");
    assert_eq!(field(CurrentRipple { per_amp_d: &[], per_amp_q: &DEG }), "current_ripple.phase_rad");
    let r = CurrentRipple { per_amp_d: &[], per_amp_q: &ORDER };
    assert_eq!(Config::new(&params(Mode::Servo, Compensation::Off, r)), Err(ConfigError::HarmonicOrder { order: 40 }));
}

/// The largest ripple the limits let through: `cq` far beyond 1, so the divisor's bound acts.
static HUGE_Q: [Harmonic; 2] = [
    Harmonic { order: 4, amplitude_nm: 100.0, phase_rad: 0.0 },
    Harmonic { order: 32, amplitude_nm: 100.0, phase_rad: -6.0 },
];

proptest! {
    #[test]
    fn any_input_with_current_ripple_gives_duties_in_range_and_finite_commands(
        seq in proptest::collection::vec(
            (proptest::num::f32::ANY, proptest::num::f32::ANY, any::<u32>(), proptest::num::f32::ANY), 1..60),
        servo in any::<bool>(),
        comp in 0usize..3,
        huge in any::<bool>(),
    ) {
        let mode = if servo { Mode::Servo } else { Mode::OpenLoop };
        let comp = [Compensation::Off, Compensation::Patent, Compensation::Estimated][comp];
        let ripple = if huge { CurrentRipple { per_amp_d: &HUGE_Q, per_amp_q: &HUGE_Q } } else { RIPPLE };
        let cfg = Config::new(&params(mode, comp, ripple)).unwrap();
        let mut st = State::default();
        for (ia, ib, enc, w) in seq {
            st.command_speed(&cfg, w);
            let out = step(&cfg, &mut st, &Measurement { i_a_a: ia, i_b_a: ib, encoder_count: enc });
            prop_assert!(out.duties.0.iter().all(|d| (0.0..=1.0).contains(d)));
            prop_assert!(out.signals.i_dq_cmd.q.is_finite() && out.signals.i_dq_cmd.d.is_finite());
            prop_assert!(out.signals.v_ab.a.is_finite() && out.signals.v_ab.b.is_finite());
        }
    }
}

/// The motor of [`params`] with `ripple`, for [`total_ripple`].
fn motor(ripple: CurrentRipple<'static>) -> crate::MotorModel<'static> {
    params(Mode::OpenLoop, Compensation::Patent, ripple).motor
}

/// `Σ A·sin(k·θe + φ)` of [`total_ripple`]'s harmonics: minus the torque on the rotor.
fn total_series(t: &TotalRipple, te: f64) -> f64 {
    series(t.harmonics(), te)
}

#[test]
fn the_detent_alone_reads_back_at_zero_current() {
    let t = total_ripple(&motor(RIPPLE), 3.0, 0.0, 0.0).unwrap();
    let mut want = PATENT;
    want.sort_by_key(|h| h.order);
    assert_eq!(t.harmonics().len(), want.len());
    for (got, want) in t.harmonics().iter().zip(&want) {
        assert_eq!(got.order, want.order);
        assert!((got.amplitude_nm - want.amplitude_nm).abs() < 1e-9, "{got:?} {want:?}");
        assert!((got.phase_rad - want.phase_rad).abs() < 1e-6, "{got:?} {want:?}");
    }
}

#[test]
fn a_single_term_reads_back_scaled_by_its_current_with_the_phase_wrapped() {
    static ONE: [Harmonic; 1] = [Harmonic { order: 3, amplitude_nm: 0.05, phase_rad: 2.0 }];
    let mut m = motor(CurrentRipple { per_amp_d: &[], per_amp_q: &ONE });
    m.detent = &[];
    for (i_q, phase) in [(2.0f32, 2.0f32), (-2.0, 2.0 - core::f32::consts::PI)] {
        let t = total_ripple(&m, 3.0, 0.0, i_q).unwrap();
        let [h] = t.harmonics() else { panic!("{t:?}") };
        assert_eq!(h.order, 3);
        assert!((h.amplitude_nm - 0.1).abs() < 1e-8 && (h.phase_rad - phase).abs() < 1e-6, "{h:?}");
    }
    // atan2's −π (a sine coefficient below 0, a cosine one of −0 or below its rounding) is
    // given as π: the range is (−π, π]; −0 is 0.
    use core::f32::consts::PI;
    assert_eq!(libm::atan2f(-0.0, -1.0), -PI);
    assert_eq!(polar(-1.0, -0.0), (1.0, PI));
    assert_eq!(polar(-1.0, -1e-30), (1.0, PI));
    assert_eq!(polar(-1.0, 0.0), (1.0, PI));
    assert_eq!(polar(2.0, -0.0).1.to_bits(), 0.0f32.to_bits());
}

#[test]
fn an_order_whose_total_is_zero_is_left_out() {
    // The detent's 4th (0.02 N·m at phase 0) cancelled exactly by −2 A of a 0.01 N·m/A 4th.
    static CANCEL: [Harmonic; 1] = [Harmonic { order: 4, amplitude_nm: 0.01, phase_rad: 0.0 }];
    let t = total_ripple(&motor(CurrentRipple { per_amp_d: &CANCEL, per_amp_q: &[] }), 3.0, -2.0, 0.0).unwrap();
    assert_eq!(t.harmonics().iter().map(|h| h.order).collect::<std::vec::Vec<_>>(), [1, 2]);
}

#[test]
fn currents_not_finite_or_beyond_the_limit_are_refused_with_their_name() {
    let m = motor(RIPPLE);
    let field = |i_d, i_q| match total_ripple(&m, 3.0, i_d, i_q) {
        Err(ConfigError::Invalid { field, .. }) => field,
        other => panic!("{other:?}"),
    };
    assert_eq!(field(f32::NAN, 0.0), "i_d_a");
    assert_eq!(field(0.0, f32::INFINITY), "i_q_a");
    assert_eq!(field(-3.5, 0.0), "i_d_a");
    assert_eq!(field(2.5, 2.5), "i_q_a", "each within 3 A, the vector 3.5 A");
    assert!(total_ripple(&m, 3.0, 3.0, 0.0).is_ok() && total_ripple(&m, 3.0, 0.0, -3.0).is_ok());
    static ORDER: [Harmonic; 1] = [Harmonic { order: 40, amplitude_nm: 0.1, phase_rad: 0.0 }];
    let bad = motor(CurrentRipple { per_amp_d: &ORDER, per_amp_q: &[] });
    assert_eq!(total_ripple(&bad, 3.0, 1.0, 0.0), Err(ConfigError::HarmonicOrder { order: 40 }));
}

proptest! {
    #[test]
    fn the_total_is_the_detent_plus_each_part_times_its_current(
        i_d in -2.0f32..2.0, i_q in -2.0f32..2.0, te in -4.0f64..4.0,
    ) {
        // Linear in the currents at every angle: T0 + i_d·D + i_q·Q̃ (torque on the rotor with
        // the sign flipped), to f32 rounding of terms up to 0.2 N·m.
        let t = total_ripple(&motor(RIPPLE), 3.0, i_d, i_q).unwrap();
        let (d, q) = (f64::from(i_d), f64::from(i_q));
        let want = series(&PATENT, te) + d * series(&PER_AMP_D, te) + q * series(&PER_AMP_Q, te);
        prop_assert!((total_series(&t, te) - want).abs() < 1e-6, "{} vs {want}", total_series(&t, te));
        prop_assert!(t.harmonics().iter().all(|h| h.amplitude_nm > 0.0
            && h.phase_rad > -core::f32::consts::PI && h.phase_rad <= core::f32::consts::PI));
    }

    #[test]
    fn the_fed_forward_back_emf_carries_the_ripples_power(
        te in -4.0f32..4.0, delta in -1.5f32..1.5, i_d in -2.0f32..2.0, i_q in -2.0f32..2.0,
        omega in -40.0f32..40.0,
    ) {
        // Power balance, e·i = τ·ω: the back-EMF fed forward in the frame δ ahead of the
        // rotor, times the rotor-frame current (i_d, i_q) written in that frame, is the power
        // of the ripple's current parts at speed ω (torque per ampere −Km·cd, −Km·cq).
        let cfg = Config::new(&params(Mode::OpenLoop, Compensation::Estimated, RIPPLE)).unwrap();
        let (s1, c1) = libm::sincosf(te);
        let (sd, cd) = libm::sincosf(delta);
        let v = cfg.ripple.eval(s1, c1, 0.0, 0.0);
        let e = ripple_back_emf_v(&v, KM as f32 * omega, sd, cd);
        let (id, iq, sd, cd) = (f64::from(i_d), f64::from(i_q), f64::from(sd), f64::from(cd));
        // The rotor-frame current in the frame δ ahead (turned back by δ).
        let (ic_d, ic_q) = (id * cd + iq * sd, iq * cd - id * sd);
        let power = f64::from(e.d) * ic_d + f64::from(e.q) * ic_q;
        let te = f64::from(te);
        let ripple_torque = -id * series(&PER_AMP_D, te) - iq * series(&PER_AMP_Q, te);
        let want = ripple_torque * f64::from(omega);
        prop_assert!((power - want).abs() < 1e-4 * (1.0 + want.abs()), "{power} W vs {want} W");
    }

    #[test]
    fn any_current_and_limit_give_finite_harmonics_or_an_error(
        i_d in proptest::num::f32::ANY, i_q in proptest::num::f32::ANY, limit in proptest::num::f32::ANY,
    ) {
        static HUGE: CurrentRipple<'static> = CurrentRipple { per_amp_d: &HUGE_Q, per_amp_q: &HUGE_Q };
        if let Ok(t) = total_ripple(&motor(HUGE), limit, i_d, i_q) {
            prop_assert!(t.harmonics().iter().all(|h| h.amplitude_nm.is_finite() && h.phase_rad.is_finite()));
        }
    }
}

#[test]
fn the_back_emf_angle_moved_by_a_lag_is_the_angle_at_the_lagging_rotor() {
    // `back_emf_angle_rad(v(θ), lag)` is `ε(θ − lag)` to first order: at 10 mrad its error is
    // second order (measured 1.2e-4 rad at worst), where ignoring the lag errs by `ε'·lag`
    // (5.0e-3 rad here, with `cd` up to 0.1 A/A at order 4).
    let cfg = Config::new(&params(Mode::OpenLoop, Compensation::Estimated, RIPPLE)).unwrap();
    let lag = 0.01f32;
    let at = |te: f32| {
        let (s, c) = libm::sincosf(te);
        cfg.ripple.eval_with_emf_slopes(s, c, 1.9, 0.0)
    };
    let (mut worst, mut worst_ignored) = (0.0f32, 0.0f32);
    for n in 0..200 {
        let te = n as f32 * core::f32::consts::TAU / 200.0 - core::f32::consts::PI;
        let exact = back_emf_angle_rad(&at(te - lag), 0.0);
        worst = worst.max((back_emf_angle_rad(&at(te), lag) - exact).abs());
        worst_ignored = worst_ignored.max((back_emf_angle_rad(&at(te), 0.0) - exact).abs());
    }
    assert!(worst < 2.5e-4, "first-order move off by {worst} rad");
    assert!(worst_ignored > 2e-3, "the lag hardly matters here ({worst_ignored} rad): the test proves nothing");
}

#[test]
fn the_back_emf_angle_of_a_pure_sine_is_zero_at_any_lag() {
    let v = RippleValue::default();
    assert_eq!(back_emf_angle_rad(&v, 0.0), 0.0);
    assert_eq!(back_emf_angle_rad(&v, 0.3), 0.0);
}

#[test]
fn the_back_emf_angle_stays_finite_where_the_torque_per_ampere_collapses() {
    // `1 − cq` at or below 0 (a q current that makes no torque, or NaN): the divisor is
    // bounded at MIN_DIVISOR, so ε is `−cd/MIN_DIVISOR`, not ±∞ or a sign flip.
    for cq in [1.0f32, 1.7, f32::NAN] {
        let v = RippleValue { per_amp_d: 0.05, per_amp_q: cq, ..RippleValue::default() };
        assert_eq!(back_emf_angle_rad(&v, 0.0), -0.05 / MIN_DIVISOR, "cq {cq}");
        // The slope's divisor is the same bounded one: ε' = −(cd' − ε·cq')/MIN_DIVISOR.
        let v = RippleValue { per_amp_d_slope: 0.2, per_amp_q_slope: 0.4, ..v };
        let eps = -0.05 / MIN_DIVISOR;
        let slope = -(0.2 - eps * 0.4) / MIN_DIVISOR;
        let got = back_emf_angle_rad(&v, 0.01);
        assert!((got - (eps - slope * 0.01)).abs() < 1e-6, "cq {cq}: {got}");
    }
}
