//! `sd_motor_ripple` through its C signature: the command line's `motor ripple` (the
//! profile's f64 transform) on the parameters `export c-header` writes for a real motor, and
//! the refusals.
#![allow(unsafe_code, reason = "calls the extern \"C\" function with raw pointers, as C does")]

extern crate std;

use std::vec::Vec;

use stepdamp_core::{Compensation, Mode};
use stepdamp_profile::{Profile, ripple};

use super::*;
use crate::convert::params_to_c;

/// `sd_motor_ripple` into a table of `capacity`: the status and what it wrote.
fn call(p: &sd_params, i_d: f32, i_q: f32, capacity: u32) -> (sd_status, u32, Vec<sd_harmonic>) {
    let mut out = std::vec![sd_harmonic::default(); capacity as usize];
    let mut count = u32::MAX;
    // SAFETY: `p`'s tables outlive the call; `out` holds `capacity` harmonics.
    let s = unsafe { sd_motor_ripple(p, i_d, i_q, out.as_mut_ptr(), capacity, &mut count) };
    out.truncate(if s == SD_OK { count as usize } else { 0 });
    (s, count, out)
}

/// Runs `f` on the C parameters of `docs/profiles/patent-motor-real.toml` as `export
/// c-header` writes them: the profile's values in `f32` and the controller's harmonic tables
/// (`Profile::controller_harmonics`), open loop with the patent's law.
fn with_real_motor(f: impl FnOnce(&Profile, &sd_params)) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles/patent-motor-real.toml");
    let profile = Profile::from_file(std::path::Path::new(path)).unwrap();
    let model = profile.controller_harmonics();
    let c = |t: &[stepdamp_core::Harmonic]| t.iter().copied().map(harmonic_to_c).collect::<Vec<_>>();
    let tables = [c(&model.detent), c(&model.per_amp_d), c(&model.per_amp_q)];
    assert!(!tables[1].is_empty() && !tables[2].is_empty(), "the real motor has current parts");
    let params = params_to_c(
        &profile.params(&model, Mode::OpenLoop, Compensation::Patent),
        [&tables[0], &tables[1], &tables[2]],
    );
    f(&profile, &params);
}

#[test]
fn the_c_ripple_of_the_real_motor_equals_the_command_lines_at_every_order() {
    with_real_motor(|profile, p| {
        let hold = p.drive.holding_current_a;
        for (i_d, i_q) in [(hold, 0.0), (hold / 2.0, 0.0), (0.0, 0.5)] {
            let (s, count, got) = call(p, i_d, i_q, SD_MAX_HARMONICS);
            assert_eq!(s, SD_OK);
            assert_eq!(got.len(), count as usize);
            let want = ripple(profile, f64::from(i_d), f64::from(i_q)).unwrap();
            // Every order either reports: the difference of the two complex amplitudes.
            let phasor = |a: f64, p: f64| (a * p.cos(), a * p.sin());
            let orders = want.harmonics.iter().map(|h| h.order).chain(got.iter().map(|h| h.order));
            let mut worst = 0.0f64;
            for k in orders {
                let c = got
                    .iter()
                    .find(|h| h.order == k)
                    .map_or((0.0, 0.0), |h| phasor(f64::from(h.amplitude_nm), f64::from(h.phase_rad)));
                let r = want
                    .harmonics
                    .iter()
                    .find(|h| h.order == k)
                    .map_or((0.0, 0.0), |h| phasor(h.amplitude_nm, h.phase_rad));
                worst = worst.max((c.0 - r.0).hypot(c.1 - r.1));
            }
            std::eprintln!("(i_d, i_q) = ({i_d}, {i_q}) A: {count} orders, largest difference {worst:.1e} N·m");
            assert!(worst < 1e-5, "({i_d}, {i_q}) A: {worst} N·m");
            let largest = want.harmonics.iter().map(|h| h.amplitude_nm).fold(0.0, f64::max);
            assert!(got.iter().all(|h| h.amplitude_nm > 0.0) && largest > 1e-2, "{got:?}");
        }
        // The current parts matter at these points: at I_hold the 4th order is more than
        // 10 mN·m off the detent's alone (at (0, 0)), a thousand times the tolerance.
        let fourth = |i_d| call(p, i_d, 0.0, SD_MAX_HARMONICS).2.iter().find(|h| h.order == 4).unwrap().amplitude_nm;
        assert!((fourth(hold) - fourth(0.0)).abs() > 1e-2, "{} {}", fourth(hold), fourth(0.0));
    });
}

#[test]
fn bad_currents_a_small_table_and_null_pointers_are_statuses() {
    with_real_motor(|_, p| {
        let limit = p.drive.current_limit_a;
        for (i_d, i_q) in [(f32::NAN, 0.0), (0.0, f32::INFINITY), (limit * 1.01, 0.0), (0.0, -limit * 1.01), (2.5, 2.5)]
        {
            let (s, count, _) = call(p, i_d, i_q, SD_MAX_HARMONICS);
            assert_eq!((s, count), (SD_ERR_OPERATING_CURRENT, 0), "({i_d}, {i_q})");
        }
        let (s, needed, _) = call(p, 1.9, 0.0, SD_MAX_HARMONICS);
        assert_eq!(s, SD_OK);
        let (s, count, _) = call(p, 1.9, 0.0, needed - 1);
        assert_eq!((s, count), (SD_ERR_CAPACITY_TOO_SMALL, needed));
        let mut count = 0;
        // SAFETY: a NULL table of capacity 0 asks for the count; the other calls pass NULL
        // where the function must refuse it before reading or writing.
        unsafe {
            assert_eq!(sd_motor_ripple(p, 1.9, 0.0, core::ptr::null_mut(), 0, &mut count), SD_ERR_CAPACITY_TOO_SMALL);
            assert_eq!(count, needed);
            assert_eq!(sd_motor_ripple(p, 1.9, 0.0, core::ptr::null_mut(), 4, &mut count), SD_ERR_NULL_POINTER);
            let mut one = [sd_harmonic::default(); 1];
            assert_eq!(sd_motor_ripple(p, 1.9, 0.0, one.as_mut_ptr(), 1, core::ptr::null_mut()), SD_ERR_NULL_POINTER);
            assert_eq!(
                sd_motor_ripple(core::ptr::null(), 1.9, 0.0, one.as_mut_ptr(), 1, &mut count),
                SD_ERR_NULL_POINTER
            );
        }
    });
}

#[test]
fn parameters_are_refused_with_the_statuses_of_sd_config_init() {
    with_real_motor(|_, p| {
        let mut bad = *p;
        bad.motor.km_nm_per_a = 0.0;
        assert_eq!(call(&bad, 1.9, 0.0, SD_MAX_HARMONICS).0, SD_ERR_KM);
        let mut bad = *p;
        bad.motor.ripple_per_amp_q_count = 0;
        assert_eq!(call(&bad, 1.9, 0.0, SD_MAX_HARMONICS).0, SD_ERR_RIPPLE_TABLE);
        let mut bad = *p;
        bad.mode = 9;
        assert_eq!(call(&bad, 1.9, 0.0, SD_MAX_HARMONICS).0, SD_ERR_INVALID_MODE);
        for (s, label) in [(SD_ERR_OPERATING_CURRENT, "i_d_a"), (SD_ERR_CAPACITY_TOO_SMALL, "capacity")] {
            let text = convert::status_text(s).to_str().unwrap();
            assert!(text.contains(label), "{text}");
        }
    });
}
