use super::*;
use crate::capture::{Annotations, Axis, PlannedTimes, TrialSweep};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const FS: f64 = 1344.37;
const SPEED: f64 = 1.5;
/// The firmware's scale for ≥ 6.3.1 (`docs/exporters.md#the-table-and-its-scale`).
const SCALE: f64 = 4.0;

pub(crate) fn recon(start_angle_rad: f64) -> Reconstruction {
    Reconstruction { periods_per_rev: 50, start_angle_rad, first_sample_s: 0.0, mm_per_rev: 40.0 }
}

fn gcode(trial: (f64, f64)) -> Gcode {
    let (mag, pha) = trial;
    let trial = TrialSweep { harmonic: 2, pha_start: pha, pha_end: pha, mag_start: mag, mag_end: mag };
    Gcode::ParamSweep { axis: Axis::X, speed: SPEED, revs: 12.0, trial }
}

/// Rounds like `Print::printFloat(x, 2)`: add 0.005, truncate.
fn printed(x: f64) -> f64 {
    ((x + 0.005) * 100.0).floor() / 100.0
}

/// A synthetic capture of `g`: harmonic 2 with response `y`, a harmonic 4 and a DC offset
/// that the lock-in must ignore, Gaussian noise of `sd` m/s², seeded. Samples follow the
/// angle of `truth`; the annotations are printed as the firmware rounds them.
pub(crate) fn synthetic(g: Gcode, y: Complex, sd: f64, seed: u64, truth: &Reconstruction) -> AccelCapture {
    let t = g.planned_times().unwrap();
    let times = PlannedTimes {
        start_marker: printed(t.start_marker),
        end_marker: printed(t.end_marker),
        signal_start: printed(t.signal_start),
        signal_end: printed(t.signal_end),
    };
    let annotations = Annotations { sampling_freq_hz: FS, movement_ok: true, accel_error: 0, times };
    let n = ((t.end_marker + 0.3) * FS) as usize;
    let mut c = AccelCapture { source: "syn".into(), line: 1, gcode: Some(g), samples: vec![0.0; n], annotations };
    let states = c.commanded(truth).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, sd).unwrap();
    let other = Complex::from_polar(0.6, -0.4);
    for (s, st) in c.samples.iter_mut().zip(&states) {
        let th = st.electrical_rad;
        let wave = |z: Complex, k: f64| (z * Complex::from_polar(1.0, k * th)).im;
        *s = 0.3 + wave(y, 2.0) + wave(other, 4.0) + noise.sample(&mut rng);
    }
    c
}

#[test]
fn the_lock_in_recovers_a_known_response_within_its_interval() {
    let y = Complex::from_polar(0.8, 1.1);
    let mut inside = 0;
    let runs = 40;
    for seed in 0..runs {
        let c = synthetic(gcode((0.0, 0.0)), y, 0.5, seed, &recon(0.3));
        let r = harmonic_response(&c, &recon(0.3), 2, 20).unwrap();
        assert_eq!(r.blocks, 30, "12 revs · 50 periods / 20 per block");
        assert!(r.radius95 < 0.03, "{}", r.radius95);
        if (r.value - y).abs() <= r.radius95 {
            inside += 1;
        }
    }
    // 95 % coverage: 38 of 40 expected; below 34 has probability < 0.3 %.
    assert!(inside >= 34, "{inside} of {runs} intervals hold the true response");
}

#[test]
fn the_influence_step_gives_the_known_cancelling_correction() {
    let (y0, c_true) = (Complex::from_polar(0.9, 2.0), Complex::from_polar(25.0, -0.7));
    let (mag, pha) = (0.004, 0.5);
    let u_t = table_shift(mag, pha, SCALE);
    let base = synthetic(gcode((0.0, 0.0)), y0, 0.3, 1, &recon(0.3));
    let trial = synthetic(gcode((mag, pha)), y0 + c_true * u_t, 0.3, 2, &recon(0.3));
    assert_eq!(trial.gcode.unwrap().to_string(), "M973 X F1.5 R12 H2 A0.5 B0.5 C0.004 D0.004");
    let r0 = harmonic_response(&base, &recon(0.3), 2, 20).unwrap();
    let r1 = harmonic_response(&trial, &recon(0.3), 2, 20).unwrap();
    let inf = influence(&r0, &r1, u_t).unwrap();
    let want = -y0 / c_true;
    assert!((inf.coefficient - c_true).abs() <= inf.coefficient_radius95, "{inf:?}");
    assert!((inf.cancelling - want).abs() <= inf.cancelling_radius95, "{inf:?} vs {want:?}");
    assert!(inf.cancelling_radius95 < 0.1 * want.abs(), "{inf:?}");
    // The same from the captures themselves: harmonic and trial read from their M973.
    let same = influence_of_captures(&base, &trial, &recon(0.3), 20, SCALE).unwrap();
    assert_eq!(same, inf);
    let e = influence_of_captures(&trial, &trial, &recon(0.3), 20, SCALE).unwrap_err().to_string();
    assert!(e.contains("the baseline needs C = D = 0"), "{e}");
    // In the table's form: the item that would cancel, in the firmware's 4x scale.
    let (m, p) = table_item(inf.cancelling, SCALE);
    assert!((m - want.abs() / SCALE).abs() <= inf.cancelling_radius95 / SCALE);
    assert!((p - want.arg()).abs() < 0.1, "{p} vs {}", want.arg());
}

#[test]
fn a_start_angle_shared_by_both_captures_cancels_out_of_the_correction() {
    let (y0, c_true) = (Complex::from_polar(0.9, 2.0), Complex::from_polar(25.0, -0.7));
    let u_t = table_shift(0.004, 0.5, SCALE);
    let base = synthetic(gcode((0.0, 0.0)), y0, 0.0, 1, &recon(0.3));
    let trial = synthetic(gcode((0.004, 0.5)), y0 + c_true * u_t, 0.0, 2, &recon(0.3));
    let step = |angle: f64| {
        let r0 = harmonic_response(&base, &recon(angle), 2, 20).unwrap();
        let r1 = harmonic_response(&trial, &recon(angle), 2, 20).unwrap();
        (r0.value, influence(&r0, &r1, u_t).unwrap().cancelling)
    };
    let (y_right, u_right) = step(0.3);
    let (y_wrong, u_wrong) = step(1.0);
    assert!((y_right - y_wrong).abs() > 0.5, "the wrong angle turns the response");
    assert!((u_right - u_wrong).abs() < 1e-9 * u_right.abs(), "{u_right:?} vs {u_wrong:?}");
}

/// A plant with a mildly nonlinear response to the shift, for the iteration.
fn plant(u: Complex) -> Complex {
    let (y0, c) = (Complex::from_polar(0.9, 2.0), Complex::from_polar(25.0, -0.7));
    y0 + c * u + c * u * Complex::new(u.norm_sqr() * 40.0, 0.0)
}

fn measured(u: Complex, radius: f64) -> Step {
    let response = Response {
        harmonic: 2,
        value: plant(u),
        radius95: radius,
        blocks: 30,
        periods_per_block: 20,
        speed_rev_s: -SPEED,
    };
    Step { shift: u, response }
}

#[test]
fn the_iteration_converges_and_stops_within_the_noise() {
    let mut steps = vec![measured(Complex::default(), 0.01), measured(table_shift(0.004, 0.5, SCALE), 0.01)];
    for _ in 0..20 {
        match next_shift(&steps, 2, 0.2).unwrap() {
            Next::Try(u) => steps.push(measured(u, 0.01)),
            Next::Stop { best, reason } => {
                assert_eq!(reason, StopReason::WithinNoise);
                assert!(steps[best].response.value.abs() <= 0.01);
                assert!(steps.len() <= 8, "{} steps", steps.len());
                return;
            }
        }
    }
    panic!("no stop after 20 steps");
}

#[test]
fn the_iteration_stops_when_the_residual_stops_falling() {
    // A disturbance the shift cannot cancel: 0.3 m/s² at another phase in every capture
    // (drift between captures), far above each capture's own 0.01 m/s² radius.
    let disturbed = |u: Complex, k: usize| {
        let mut s = measured(u, 0.01);
        s.response.value = s.response.value + Complex::from_polar(0.3, 2.0 * k as f64);
        s
    };
    let mut steps = vec![disturbed(Complex::default(), 0), disturbed(table_shift(0.004, 0.5, SCALE), 1)];
    for k in 2..12 {
        match next_shift(&steps, 3, 0.2).unwrap() {
            Next::Try(u) => steps.push(disturbed(u, k)),
            Next::Stop { best, reason } => {
                assert_eq!(reason, StopReason::NotFalling);
                assert!(steps[best].response.value.abs() > 0.05, "the disturbance stays");
                assert!(steps.len() >= 3);
                return;
            }
        }
    }
    panic!("no stop after 12 steps");
}

#[test]
fn captures_that_cannot_give_a_response_are_refused() {
    let c = synthetic(gcode((0.0, 0.0)), Complex::default(), 0.1, 0, &recon(0.0));
    let e = harmonic_response(&c, &recon(0.0), 10, 20).unwrap_err().to_string();
    assert!(e.contains("750.0 Hz, at or above the accelerometer's Nyquist 672.2 Hz"), "{e}");
    let e = harmonic_response(&c, &recon(0.0), 2, 300).unwrap_err().to_string();
    assert!(e.contains("2 block(s) of 300 electrical periods"), "{e}");
    let mut cut = c.clone();
    cut.samples.truncate(FS as usize * 5);
    let e = harmonic_response(&cut, &recon(0.0), 2, 20).unwrap_err().to_string();
    assert!(e.contains("do not cover the constant-speed window"), "{e}");
    let mut bad = c.clone();
    bad.annotations.movement_ok = false;
    assert!(harmonic_response(&bad, &recon(0.0), 2, 20).unwrap_err().to_string().contains("not a valid capture"));
    let mut sweep = c.clone();
    sweep.gcode = Some(Gcode::SpeedSweep { axis: Axis::X, start_speed: 0.5, end_speed: 2.0, revs: 6.0 });
    let e = harmonic_response(&sweep, &recon(0.0), 2, 20).unwrap_err().to_string();
    assert!(e.contains("sweeps the speed"), "{e}");
    let r = harmonic_response(&c, &recon(0.0), 2, 20).unwrap();
    let e = influence(&r, &r, table_shift(0.004, 0.5, SCALE)).unwrap_err().to_string();
    assert!(e.contains("within the noise"), "{e}");
}

#[test]
fn the_f_quantile_matches_tables() {
    // F(2, 10) = 4.1028, F(2, 58) ≈ 3.1559 (0.95 quantiles).
    assert!((f2_quantile_95(10.0) - 4.1028).abs() < 1e-4);
    assert!((f2_quantile_95(58.0) - 3.1559).abs() < 1e-3);
}
