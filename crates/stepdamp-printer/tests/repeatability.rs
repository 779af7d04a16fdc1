//! How much a measured response and the vibration score move from one noise seed to the
//! next, the capture setting fixed (`docs/accelerometer.md#repeatability-and-the-vibration-score`).

use stepdamp_accel::influence::harmonic_response;
use stepdamp_accel::{AccelCapture, Axis, Gcode, Response, TrialSweep, read_captures};
use stepdamp_export::Correction;
use stepdamp_export::prusa::{Firmware, fit};
use stepdamp_printer::{SimulatedPrinter, VibrationScore, family_printer};

const SEEDS: u64 = 10;
const HARMONICS: [u32; 3] = [4, 2, 1];

/// `M973 X F2 R6 H4` without a trial: the planned baseline of every harmonic here.
fn baseline() -> Gcode {
    let trial = TrialSweep { harmonic: 4, pha_start: 0.0, pha_end: 0.0, mag_start: 0.0, mag_end: 0.0 };
    Gcode::ParamSweep { axis: Axis::X, speed: 2.0, revs: 6.0, trial }
}

/// The responses at [`HARMONICS`] of the capture with noise seed `seed`, and of the same
/// capture without noise (the truth the noisy one estimates).
fn responses(p: &SimulatedPrinter, seed: u64) -> (Vec<Response>, Vec<Response>) {
    let p = SimulatedPrinter { seed, ..p.clone() };
    let g = baseline();
    let trace = p.simulate(&g).unwrap();
    let noisy = read_captures(p.print(&trace).as_bytes(), "seed").unwrap().remove(0).with_gcode(g);
    let clean = AccelCapture { samples: trace.clean_m_s2.clone(), ..noisy.clone() };
    let r = p.reconstruction();
    let at = |c: &AccelCapture| HARMONICS.iter().map(|&h| harmonic_response(c, &r, h, 20).unwrap()).collect();
    (at(&noisy), at(&clean))
}

/// Mean, standard deviation and max − min of `v`.
fn spread(v: &[f64]) -> (f64, f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let std = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let (lo, hi) = v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
    (mean, std, hi - lo)
}

/// Over [`SEEDS`] noise seeds: each harmonic's |Y| in dB re 1 m/s² and the score, printed
/// with their spreads; returns how many seeds' score intervals held the noise-free score.
fn repeat(name: &str, p: &SimulatedPrinter) -> u64 {
    let runs: Vec<_> = (0..SEEDS).map(|s| responses(p, 1000 + s)).collect();
    for (k, h) in HARMONICS.iter().enumerate() {
        let db: Vec<f64> = runs.iter().map(|(y, _)| 20.0 * y[k].value.abs().log10()).collect();
        let (mean, std, range) = spread(&db);
        let truth = 20.0 * runs[0].1[k].value.abs().log10();
        println!("{name} H{h}: {mean:.2} dB re 1 m/s² (noise-free {truth:.2}), std {std:.2} dB, max-min {range:.2} dB");
    }
    let scores: Vec<VibrationScore> = runs.iter().map(|(y, _)| VibrationScore::of(y)).collect();
    let truth = VibrationScore::of(&runs[0].1).rms_m_s2;
    let s: Vec<f64> = scores.iter().map(|s| s.rms_m_s2).collect();
    let (mean, std, range) = spread(&s);
    let half = scores.iter().map(|s| s.half_width_m_s2).sum::<f64>() / SEEDS as f64;
    let covered = scores.iter().filter(|s| (s.interval().0..=s.interval().1).contains(&truth)).count() as u64;
    let db: Vec<f64> = s.iter().map(|x| 20.0 * x.log10()).collect();
    let (_, std_db, range_db) = spread(&db);
    println!(
        "{name} score: {mean:.4} m/s² RMS (noise-free {truth:.4}), mean ± {half:.4}, std {std:.4} ({std_db:.2} dB), \
         max-min {range:.4} ({range_db:.2} dB); the interval held the noise-free score in {covered} of {SEEDS}"
    );
    covered
}

#[test]
fn the_score_repeats_over_noise_seeds_and_its_interval_holds_the_noise_free_score() {
    let p = family_printer(1);
    // The corrected axis: the true motor's model correction at the run current, in both
    // tables (what a perfect identification would write).
    let c = Correction::from_profile(&p.profile, Some(p.run_current_a)).unwrap();
    let corrected = SimulatedPrinter { correction: fit(&c, Firmware::V6_3_1).unwrap().correction, ..p.clone() };
    assert!(repeat("baseline", &p) >= SEEDS - 2);
    assert!(repeat("corrected", &corrected) >= SEEDS - 2);
}
