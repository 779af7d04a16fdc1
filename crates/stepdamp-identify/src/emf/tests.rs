use super::*;
#[cfg(feature = "simulate")]
use crate::plan::{PlannedRun, RunDrive};
use stepdamp_profile::Profile;

/// A servo run of `motor` at `speed` rad/s for `steady` s (the plan's settings, 0.01 A of
/// current noise), as a log.
#[cfg(feature = "simulate")]
fn servo_run(motor: &Profile, speed: f64, steady: f64, seed: u64) -> RunLog {
    let r = PlannedRun {
        name: format!("servo-{speed}"),
        drive: RunDrive::Servo { servo_bandwidth_hz: 60.0, velocity_filter_hz: 60.0, d_current_a: 0.0 },
        speed_rad_s: speed,
        dwell_s: 0.05,
        ramp_s: 0.2,
        duration_s: 0.25 + steady,
        reason: String::new(),
    };
    let base = motor.edited("controller", |d| d.motor.flux = Default::default()).unwrap();
    let rows = crate::simulate::simulate_run(motor, &base, stepdamp_sim::Compensation::Off, &r, 0.01, seed).unwrap();
    RunLog::from_rows(&rows, &r.name)
}

#[cfg(feature = "simulate")]
#[test]
fn the_back_emf_of_a_fast_servo_run_gives_the_flux_harmonics_and_the_phase_imbalance() {
    let motor = Profile::from_file(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../docs/profiles/patent-motor-real.toml"
    )))
    .unwrap();
    let log = servo_run(&motor, 22.0, 1.0, 3);
    let f = fit_flux(&[log], &EmfOptions::for_profile(&motor)).unwrap().unwrap();
    println!("{f}");
    let truth = &motor.motor.flux;
    assert!((f.phase_b_gain.value - truth.phase_b_gain).abs() < 0.002, "{:?}", f.phase_b_gain);
    assert!((f.km_nm_per_a.value / 0.3 - 1.0).abs() < 0.005, "{:?}", f.km_nm_per_a);
    for t in &truth.harmonics {
        let h = f.harmonics.iter().find(|h| h.order == t.order).unwrap();
        // Within 5 % of the ratio (or 2e-4 absolute) and 0.1 rad (measured: third 1.4 % low,
        // 0.003 rad; fifth 4 % high, 0.063 rad).
        assert!((h.ratio.value - t.ratio).abs() < (0.05 * t.ratio).max(2e-4), "{h:?}");
        assert!(crate::fit::wrap_pi(h.phase_rad.value - t.phase_rad).abs() < 0.1, "{h:?}");
        assert!(h.ratio.ci95 < 0.1 * t.ratio, "{h:?}");
    }
    let h7 = f.harmonics.iter().find(|h| h.order == 7).unwrap();
    assert!(h7.ratio.value < 3e-4, "{h7:?}");
    // The section written: g, the third and the fifth; the 7th is noise and left out.
    let sec = f.section();
    assert_eq!(sec.harmonics.iter().map(|h| h.order).collect::<Vec<_>>(), [3, 5]);
    assert_eq!(sec.phase_b_gain, f.phase_b_gain.value);
    assert_eq!(f.left_out(), ["harmonic 7"]);
}

#[cfg(feature = "simulate")]
#[test]
fn a_sine_motor_shows_no_flux_harmonics_and_slow_runs_are_not_back_emf_runs() {
    let motor = Profile::preset("patent-motor").unwrap();
    let fast = servo_run(&motor, -22.0, 0.6, 4);
    let slow = servo_run(&motor, 1.0, 0.5, 5);
    assert!(is_emf_run(&fast, 50) && !is_emf_run(&slow, 50));
    assert!(fit_flux(std::slice::from_ref(&slow), &EmfOptions::for_profile(&motor)).unwrap().is_none());
    let f = fit_flux(&[slow, fast], &EmfOptions::for_profile(&motor)).unwrap().unwrap();
    println!("{f}");
    assert_eq!(f.runs.len(), 1);
    assert!(
        f.phase_b_gain.value.abs() < 0.01 && f.phase_b_gain.value.abs() < 2.0 * f.phase_b_gain.ci95,
        "{:?}",
        f.phase_b_gain
    );
    for h in &f.harmonics {
        // Within noise.
        assert!(h.ratio.value < 2e-3 && h.ratio.value < 2.0 * h.ratio.ci95, "{h:?}");
    }
    // Nothing stands out of the noise here: no section is written.
    assert!(f.section().is_default(), "{:?}", f.section());
}

#[test]
fn even_or_out_of_range_orders_are_refused() {
    let o = EmfOptions { orders: vec![3, 4], ..EmfOptions::for_profile(&Profile::preset("patent-motor").unwrap()) };
    let e = fit_flux(&[], &o).unwrap_err();
    assert_eq!(e.to_string(), "flux harmonic order 4: must be odd, 3 to 15");
}

#[test]
fn a_back_emf_run_sampled_too_slowly_is_refused_naming_its_rate_not_a_panic() {
    // 4 Hz samples of a rotor at 10 rad/s (about 80 Hz electrical): the 7th harmonic needs
    // 4 samples per period, about 2230 Hz.
    let n = 40;
    let t: Vec<f64> = (0..n).map(|k| 0.25 * k as f64).collect();
    let log = RunLog {
        source: "slow.csv".into(),
        theta_fb_rad: t.iter().map(|t| 10.0 * t).collect(),
        i_q_a: vec![0.0; n],
        iq_cmd_a: None,
        i_d_a: None,
        iq_source: crate::log::IqSource::Column,
        ignored_columns: Vec::new(),
        phases: Some(PhaseSignals {
            i_a_a: vec![0.0; n],
            i_b_a: vec![0.0; n],
            v_a_v: vec![0.0; n],
            v_b_v: vec![0.0; n],
        }),
        t_s: t,
    };
    assert!(is_emf_run(&log, 50));
    let e = fit_flux(&[log], &EmfOptions::for_profile(&Profile::preset("patent-motor").unwrap())).unwrap_err();
    assert_eq!(
        e.to_string(),
        "slow.csv: sampled at 4 Hz, a back-EMF run needs at least 2228 Hz (4 samples per period of its highest fitted flux harmonic); log every control period"
    );
}
