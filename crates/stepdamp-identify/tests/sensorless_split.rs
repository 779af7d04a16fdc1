//! Experiment: can a fast open-loop run show `X₅ − X₃`, the split of the flux's third and
//! fifth harmonics that the sensorless plan's quasi-static runs cannot
//! (docs/sensorless.md#the-flux-shape-without-a-sensor)?
//!
//! At a speed where order 4's frequency `4ω_e` is far above the open-loop resonance, the
//! rotor hardly follows order-4 torques, so the order-4 part of `θ_est − θ_cmd` is mostly the
//! turn of the estimated angle, `Im[(X₅ − X₃)·e^{j4θe}]` (residual against the shape the angle
//! was estimated with). Per motor of the real-motor family this prints the true residual
//! difference, the raw measurement, the rotor's own order-4 motion (from the encoder, which
//! the route does not have) and the measurement with that motion predicted from the
//! identified profile (`J`, ripple) taken off.
//!
//! `cargo test --release -p stepdamp-identify --test sensorless_split -- --ignored --nocapture`

#![cfg(feature = "simulate")]

#[allow(dead_code)]
mod real;

use rayon::prelude::*;
use real::{real_motor, user_base};
use stepdamp_identify::plan::{PlannedRun, run_seed};
use stepdamp_identify::sensorless::flux::FluxOptions;
use stepdamp_identify::sensorless::log::SensorlessLog;
use stepdamp_identify::sensorless::plan::{SensorlessPlanOptions, plan};
use stepdamp_identify::sensorless::{estimate, fit_options, identify, winding_with};
use stepdamp_identify::simulate::simulate_open_loop_run;
use stepdamp_profile::Profile;
use stepdamp_profile::flux::FluxSection;

/// Current-sensor noise, A.
const NOISE_A: f64 = 0.005;

/// `(re, im)` of harmonic `n`'s phasor `h_n·e^{j·a_n}` in `f` (0 when absent).
fn phasor(f: &FluxSection, n: u16) -> (f64, f64) {
    f.harmonics
        .iter()
        .filter(|h| h.order == n)
        .fold((0.0, 0.0), |a, h| (a.0 + h.ratio * h.phase_rad.cos(), a.1 + h.ratio * h.phase_rad.sin()))
}

/// `X₅ − X₃` of `f`.
fn difference(f: &FluxSection) -> (f64, f64) {
    let (t, v) = (phasor(f, 3), phasor(f, 5));
    (v.0 - t.0, v.1 - t.1)
}

/// The order-4 part as the route measures it.
fn order4(theta: &[f64], y: &[f64]) -> (f64, f64) {
    stepdamp_identify::sensorless::turn::order4(theta, y).unwrap()
}

/// The fast run: `factor` × the base's `ω_n` electrical, in direction `sign`.
fn fast_run(base: &Profile, factor: f64, sign: f64) -> PlannedRun {
    let p = plan(base, &SensorlessPlanOptions::default()).unwrap();
    let nr = f64::from(base.motor.pole_pairs);
    let w = factor * p.natural_rad_s / nr;
    PlannedRun {
        name: format!("fast-{sign}"),
        speed_rad_s: sign * w,
        duration_s: 0.2 + 0.4 + 1.0,
        ramp_s: 0.4,
        ..p.runs[0].clone()
    }
}

/// The rotor's order-4 motion predicted from a profile: torque on the rotor
/// `−A·sin(4θe + φ)` (the ripple at `(I_hold, 0)`) moves it by
/// `A·Nr/(J·(Ω² − ω_n²))·sin(4θe + φ)` at `Ω = 4ω_e`: as `D`, `(A·k·cos φ, A·k·sin φ)`.
fn predicted_motion(p: &Profile, w_e: f64) -> (f64, f64) {
    let m = &p.motor;
    let nr = f64::from(m.pole_pairs);
    let i = p.drive.holding_current_a;
    let wn2 = m.km_nm_per_a * i * nr / m.inertia_kg_m2;
    let r = stepdamp_profile::ripple::ripple(p, i, 0.0).unwrap();
    let h = r.harmonics.iter().find(|h| h.order == 4).unwrap();
    let k = nr / (m.inertia_kg_m2 * ((4.0 * w_e).powi(2) - wn2));
    (h.amplitude_nm * k * h.phase_rad.cos(), h.amplitude_nm * k * h.phase_rad.sin())
}

/// What one motor gives: per direction `(true D, raw, rotor motion (encoder), predicted
/// motion (identified), predicted motion (true profile), stalled?)`.
type Row = ((f64, f64), (f64, f64), (f64, f64), (f64, f64), (f64, f64), bool);

fn one(seed: u64, factor: f64) -> Vec<Row> {
    let (m, base) = (real_motor(seed), user_base());
    let p = plan(&base, &SensorlessPlanOptions::default()).unwrap();
    let nr = f64::from(base.motor.pole_pairs);
    // The quasi-static runs, then the fast pair at `factor` (not the plan's own turn runs).
    let mut runs = p.runs[..4].to_vec();
    runs.push(fast_run(&base, factor, 1.0));
    runs.push(fast_run(&base, factor, -1.0));
    let rows: Vec<_> = runs
        .iter()
        .enumerate()
        .map(|(i, r)| simulate_open_loop_run(&m, &base, r, NOISE_A, run_seed(100 + seed, i as u64)).unwrap())
        .collect();
    let logs: Vec<SensorlessLog> = rows.iter().zip(&runs).map(|(r, p)| SensorlessLog::from_rows(r, &p.name)).collect();
    let fo = fit_options(&base, &[1, 2, 4]);
    let f = identify(&logs[..4], &base, &fo, &FluxOptions::default()).unwrap();
    let with = base.edited(&base.name, |d| d.motor.flux = f.flux.clone()).unwrap();
    let id = f.model().apply_to(&with, Some("sensorless"), "s.toml").unwrap();
    let est = estimate(&logs, &winding_with(&base, &f.flux), &FluxOptions::default()).unwrap();
    let (dt, da) = (difference(&m.motor.flux), difference(&f.flux));
    let truth = (dt.0 - da.0, dt.1 - da.1);
    (4..6)
        .map(|i| {
            let r = &runs[i];
            let w_e = r.speed_rad_s.abs() * nr;
            let t0 = r.dwell_s + r.ramp_s + 0.2;
            let idx: Vec<usize> = (0..rows[i].len()).filter(|&k| rows[i][k].t_s >= t0).collect();
            let th_est: Vec<f64> = idx.iter().map(|&k| est.logs[i].theta_fb_rad[k] * nr).collect();
            let th_cmd: Vec<f64> = idx.iter().map(|&k| rows[i][k].theta_cmd_rad * nr).collect();
            let th_enc: Vec<f64> = idx.iter().map(|&k| rows[i][k].theta_fb_rad * nr).collect();
            let e: Vec<f64> = th_est.iter().zip(&th_cmd).map(|(a, b)| a - b).collect();
            let rotor: Vec<f64> = th_enc.iter().zip(&th_cmd).map(|(a, b)| a - b).collect();
            let stalled = rotor.iter().any(|d| d.abs() > 1.5);
            let _ = m.motor.inertia_kg_m2;
            (
                truth,
                order4(&th_est, &e),
                order4(&th_enc, &rotor),
                predicted_motion(&id, w_e),
                predicted_motion(&m, w_e),
                stalled,
            )
        })
        .collect()
}

#[test]
#[ignore = "experiment, release: prints the fast run's order-4 turn against the truth"]
fn a_fast_open_loop_run_shows_the_difference_of_fifth_and_third() {
    let factor: f64 = std::env::var("FAST_FACTOR").ok().and_then(|s| s.parse().ok()).unwrap_or(2.0);
    let n: u64 = std::env::var("MOTORS").ok().and_then(|s| s.parse().ok()).unwrap_or(12);
    let all: Vec<(u64, Vec<Row>)> = (0..n).into_par_iter().map(|s| (s, one(s, factor))).collect();
    let mut worst: f64 = 0.0;
    for (s, rows) in &all {
        let m = real_motor(*s);
        let j = m.motor.inertia_kg_m2 / user_base().motor.inertia_kg_m2;
        for (dir, (t, raw, rot, pid, ptrue, stalled)) in ["fwd", "rev"].iter().zip(rows) {
            let corr = (raw.0 - pid.0, raw.1 - pid.1);
            let err = (corr.0 - t.0).hypot(corr.1 - t.1);
            worst = worst.max(err);
            println!(
                "motor {s} (J x{j:.2}) {dir}: true D ({:+.5}, {:+.5}) |{:.5}|; raw ({:+.5}, {:+.5}); rotor enc ({:+.5}, {:+.5}); pred id ({:+.5}, {:+.5}); pred true ({:+.5}, {:+.5}); corrected err {err:.5}; raw err {:.5}; raw-rotor err {:.5}{}",
                t.0,
                t.1,
                t.0.hypot(t.1),
                raw.0,
                raw.1,
                rot.0,
                rot.1,
                pid.0,
                pid.1,
                ptrue.0,
                ptrue.1,
                (raw.0 - t.0).hypot(raw.1 - t.1),
                (raw.0 - rot.0 - t.0).hypot(raw.1 - rot.1 - t.1),
                if *stalled { " STALLED" } else { "" }
            );
        }
    }
    println!("factor {factor}: worst corrected error {worst:.5}");
}
