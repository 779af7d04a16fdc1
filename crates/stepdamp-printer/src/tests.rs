//! The printer's captures: read back, physics, noise.

use crate::{AccelModel, SimulatedPrinter, Trace};
use stepdamp_accel::influence::harmonic_response;
use stepdamp_accel::{AccelCapture, Axis, Complex, Gcode, Response, TrialSweep, read_captures};
use stepdamp_sim::Profile;

/// The motor of the end-to-end tests: patent-motor with a real motor's flux harmonics.
pub(crate) fn real_motor() -> Profile {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles/patent-motor-real.toml");
    Profile::from_file(std::path::Path::new(path)).unwrap()
}

/// An assumed Core-One-like run current: 0.9 A peak (0.64 A RMS per phase).
pub(crate) const CORE_ONE_CURRENT_A: f64 = 0.9;

fn m973(speed: f64, revs: f64, h: u32, (mag, pha): (f64, f64)) -> Gcode {
    let trial = TrialSweep { harmonic: h, pha_start: pha, pha_end: pha, mag_start: mag, mag_end: mag };
    Gcode::ParamSweep { axis: Axis::X, speed, revs, trial }
}

/// The one capture in `text`, with its G-code set.
pub(crate) fn read_one(text: &str, g: Gcode) -> AccelCapture {
    let mut v = read_captures(text.as_bytes(), "sim").unwrap();
    assert_eq!(v.len(), 1);
    v.remove(0).with_gcode(g)
}

#[test]
fn a_simulated_capture_reads_back_with_the_annotations_and_rate_it_was_given() {
    let p = SimulatedPrinter { seed: 7, ..SimulatedPrinter::new(real_motor(), CORE_ONE_CURRENT_A) };
    let g = m973(2.0, 4.0, 4, (0.01, 0.5));
    let text = p.capture(&g).unwrap();
    let trace = p.simulate(&g).unwrap();
    // As the firmware prints it: samples with LF, annotations with CR LF.
    assert!(text.starts_with("0, "), "{}", &text[..40]);
    let first = text.lines().next().unwrap();
    let value = first.strip_prefix("0, ").unwrap();
    assert_eq!(value, format!("{:.5}", trace.samples_m_s2[0]));
    assert!(text.contains("\nsampling_freq: ") && text.ends_with("\r\n") && text.contains("movement_ok: true\r\n"));
    let c = read_one(&text, g);
    assert_eq!(c.samples.len(), trace.samples_m_s2.len());
    let max_err = c.samples.iter().zip(&trace.samples_m_s2).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(max_err <= 5e-6, "{max_err}");
    let a = c.annotations;
    assert!(a.is_valid());
    assert!((a.sampling_freq_hz - trace.rate_hz).abs() <= 0.005, "{} vs {}", a.sampling_freq_hz, trace.rate_hz);
    assert!((a.sampling_freq_hz - 1344.0).abs() <= 1344.0 * 0.001 + 0.005);
    c.check_annotations().unwrap();
    // The samples cover the whole move, to the last settle block.
    let t = g.planned_times().unwrap();
    let span = c.samples.len() as f64 / a.sampling_freq_hz;
    assert!(span > t.end_marker + 0.2 && span < t.end_marker + 0.22, "{span}");
}

/// The response of harmonic `n` the model predicts without correction: the motor's ripple
/// at the run current, `T(θr) = −A·sin(nθr + φ)` (`stepdamp_profile::ripple`), on the rotor
/// held by the magnetic stiffness `K = Km·I·Nr` with `J + m·r²` and viscous `c`, through the
/// head's transfer function ([`stepdamp_accel::AxisModel::acceleration_per_torque`]), at
/// `w = n·Nr·2π·v`; `lag` (rad) is the mean electrical angle of
/// the rotor against the plan, measured.
fn predicted(p: &SimulatedPrinter, n: u32, speed_signed_rev_s: f64, lag: f64) -> Complex {
    let m = &p.profile.motor;
    let r = stepdamp_sim::profile::ripple(&p.profile, p.run_current_a, 0.0).unwrap();
    let h = r.harmonics.iter().find(|h| u32::from(h.order) == n).unwrap();
    let nr = f64::from(m.pole_pairs);
    let k = m.km_nm_per_a * p.run_current_a * nr;
    let axis = stepdamp_accel::AxisModel::new(&p.head, m.inertia_kg_m2, k, m.viscous_nm_s_per_rad);
    let w = f64::from(n) * nr * std::f64::consts::TAU * speed_signed_rev_s;
    let torque = Complex::from_polar(-h.amplitude_nm, h.phase_rad);
    axis.acceleration_per_torque(w) * torque * Complex::from_polar(1.0, f64::from(n) * lag)
}

/// The mean electrical angle (rad) of the rotor against the plan over `[from, to]` s.
fn mean_lag(t: &Trace, from: f64, to: f64) -> f64 {
    let d: Vec<f64> = (0..t.mid_s.len())
        .filter(|&j| t.mid_s[j] >= from && t.mid_s[j] <= to)
        .map(|j| t.rotor_rad[j] - t.planned_rad[j])
        .collect();
    d.iter().sum::<f64>() / d.len() as f64
}

fn response(p: &SimulatedPrinter, g: Gcode, n: u32) -> (Response, Trace) {
    let c = read_one(&p.capture(&g).unwrap(), g);
    (harmonic_response(&c, &p.reconstruction(), n, 20).unwrap(), p.simulate(&g).unwrap())
}

/// The largest relative difference `|Y − Y_pred|/|Y_pred|` of harmonic 4 without correction
/// over `cases` (speed rev/s, R), each printed.
fn worst_difference(p: &SimulatedPrinter, cases: &[(f64, f64)]) -> f64 {
    let mut worst: f64 = 0.0;
    for &(speed, revs) in cases {
        let g = m973(speed, revs, 4, (0.0, 0.0));
        let (y, trace) = response(p, g, 4);
        let t = g.planned_times().unwrap();
        let lag = mean_lag(&trace, t.signal_start, t.signal_end);
        let want = predicted(p, 4, y.speed_rev_s, lag);
        let err = (y.value - want).abs() / want.abs();
        println!(
            "{}: F{speed} R{revs}: measured {:.4} m/s² at {:.3} rad, predicted {:.4} m/s² at {:.3} rad \
             (lag {lag:.4} rad), relative difference {err:.3}",
            p.profile.name,
            y.value.abs(),
            y.value.arg(),
            want.abs(),
            want.arg()
        );
        worst = worst.max(err);
    }
    worst
}

/// Both directions at 1, 1.5, 2 and 3 rev/s: harmonic 4 at 200 to 600 Hz, around the
/// default belt mode (225 Hz) and well above the motor's resonance (about 80 Hz at 0.9 A).
const SPEEDS: [(f64, f64); 8] =
    [(1.0, 2.0), (1.0, -2.0), (1.5, 3.0), (1.5, -3.0), (2.0, 4.0), (2.0, -4.0), (3.0, 6.0), (3.0, -6.0)];

#[test]
fn without_correction_harmonic_4_is_the_motors_ripple_through_the_rotor_and_the_belt() {
    // The real motor's order-4 detent alone: the linear prediction is the whole story.
    let m = real_motor()
        .edited("patent-motor-real, order 4 only", |d| {
            d.name = "patent-motor-real, order 4 only".into();
            d.motor.detent.retain(|h| h.order == 4);
            d.motor.flux = Default::default();
        })
        .unwrap();
    let p = SimulatedPrinter { accel: AccelModel::ideal(), ..SimulatedPrinter::new(m, CORE_ONE_CURRENT_A) };
    let worst = worst_difference(&p, &SPEEDS);
    assert!(worst < 0.1, "{worst}");
}

#[test]
fn on_the_real_motor_harmonic_4_at_2_and_3_rev_s_is_its_ripple_at_the_run_current() {
    // Detent and flux ripple at 0.9 A. Below 2 rev/s the rotor's motion at the other
    // harmonics (order 2 above all) feeds harmonic 4 through the angle the ripple depends
    // on, which the linear prediction leaves out: 14-17 % at 1.5 rev/s (printed, not asserted).
    let p = SimulatedPrinter { accel: AccelModel::ideal(), ..SimulatedPrinter::new(real_motor(), CORE_ONE_CURRENT_A) };
    let worst = worst_difference(&p, &SPEEDS[4..]);
    assert!(worst < 0.1, "{worst}");
    worst_difference(&p, &SPEEDS[2..4]);
}

#[test]
fn with_accelerometer_noise_the_95_interval_covers_the_noise_free_response_in_most_seeds() {
    let base = SimulatedPrinter::new(real_motor(), CORE_ONE_CURRENT_A);
    let g = m973(2.0, 4.0, 4, (0.0, 0.0));
    let seeds = 20;
    let mut covered = 0;
    for seed in 0..seeds {
        let p = SimulatedPrinter { seed, ..base.clone() };
        let trace = p.simulate(&g).unwrap();
        let noisy = read_one(&crate::format::capture_text(&trace.samples_m_s2, &trace.annotations), g);
        let clean = AccelCapture { samples: trace.clean_m_s2.clone(), ..noisy.clone() };
        let r = p.reconstruction();
        let y = harmonic_response(&noisy, &r, 4, 20).unwrap();
        let truth = harmonic_response(&clean, &r, 4, 20).unwrap();
        covered += usize::from((y.value - truth.value).abs() <= y.radius95);
    }
    println!("the 95 % disc covered the noise-free response in {covered} of {seeds} seeds");
    assert!(covered >= 16, "{covered} of {seeds}");
}

#[test]
fn a_speed_sweep_capture_reads_back_and_its_annotations_match_the_plan() {
    let p = SimulatedPrinter::new(real_motor(), CORE_ONE_CURRENT_A);
    let g = Gcode::SpeedSweep { axis: Axis::Y, start_speed: 1.0, end_speed: 3.0, revs: -8.0 };
    let text = p.capture_m974(Axis::Y, 1.0, 3.0, -8.0).unwrap();
    let c = read_one(&text, g);
    c.check_annotations().unwrap();
    let t = g.planned_times().unwrap();
    assert!((t.signal_end - t.signal_start - 4.0).abs() < 1e-12);
    let span = c.samples.len() as f64 / c.annotations.sampling_freq_hz;
    assert!(span > t.end_marker + 0.2 && span < t.end_marker + 0.22, "{span}");
    // The head moves most during the sweep: its RMS there exceeds the settle block's.
    let rms = |from: f64, to: f64| {
        let fs = c.annotations.sampling_freq_hz;
        let s = &c.samples[(from * fs) as usize..(to * fs) as usize];
        (s.iter().map(|y| y * y).sum::<f64>() / s.len() as f64).sqrt()
    };
    assert!(rms(t.signal_start, t.signal_end) > 2.0 * rms(0.0, t.start_marker), "{}", rms(0.0, t.start_marker));
}

#[test]
fn a_sweeping_trial_an_overflowing_table_and_a_current_beyond_the_drive_are_refused() {
    let p = SimulatedPrinter::new(real_motor(), CORE_ONE_CURRENT_A);
    let g = Gcode::ParamSweep {
        axis: Axis::X,
        speed: 2.0,
        revs: 4.0,
        trial: TrialSweep { harmonic: 4, pha_start: 0.0, pha_end: 1.0, mag_start: 0.0, mag_end: 0.01 },
    };
    let e = p.capture(&g).unwrap_err().to_string();
    assert!(e.contains("M973 X F2 R4 H4 A0 B1 C0 D0.01") && e.contains("a constant trial"), "{e}");
    let mut big = p.clone();
    big.correction.forward.mag[1] = 1e6;
    let e = big.capture_m974(Axis::X, 1.0, 2.0, -2.0).unwrap_err().to_string();
    assert!(e.contains("overflow"), "{e}");
    let p = SimulatedPrinter { run_current_a: 5.0, ..p };
    let e = p.capture_m973(Axis::X, 2.0, 4.0, 4, (0.0, 0.0)).unwrap_err().to_string();
    assert_eq!(e, "run_current_a = 5: must be in (0, 3] A (the profile's drive.current_limit_a)");
}
