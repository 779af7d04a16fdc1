//! Acceptance tests of identification on the simulator: identification accuracy on the
//! `patent-motor` preset (through log files written by [`run_plan`]) and on 50 seeded random
//! motors, the open-loop compensation the identified profile achieves, refinement, speed.

use crate::fit::{Fit, FitOptions, Warning, fit, wrap_pi};
use crate::log::{LogOptions, RunLog, read_log};
use crate::model::Model;
use crate::plan::{PlanOptions, plan, run_plan, simulate_plan};
use crate::refine::{RefineOptions, refine};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::sync::OnceLock;
use stepdamp_core::Mode;
use stepdamp_sim::profile::DetentTerm;
use stepdamp_sim::{Compensation, Profile, RunSpec, SimOptions, SweepSpec, sweep};

fn patent() -> Profile {
    Profile::preset("patent-motor").unwrap()
}

/// What a user starts from: the preset's profile with its `J` (the true one may differ) and
/// no detent (the plan then assumes typical amplitudes).
fn user_base() -> Profile {
    patent().edited("user base", |b| b.motor.detent.clear()).unwrap()
}

/// The identified `J` over the true one, and whether the fit warned that it disagrees with
/// the base profile's.
fn inertia_check(truth: &Profile, base: &Profile, f: &Fit) -> (f64, bool) {
    let j = f.inertia_kg_m2.expect("J is identified by default");
    assert!(j.ci95 > 0.0 && j.ci95 < 0.1 * j.value, "J {j:?}");
    let warned = f
        .warnings
        .iter()
        .any(|w| matches!(w, Warning::InertiaDisagrees { base: b, .. } if *b == base.motor.inertia_kg_m2));
    (j.value / truth.motor.inertia_kg_m2, warned)
}

/// Errors of an identified model against the truth: worst amplitude error over its
/// tolerance (`max(5 %, 0.5 mN·m)`), worst phase error (rad) and the relative `Fs` error,
/// over the harmonics of 5 mN·m or more.
struct Errors {
    amplitude_over_tolerance: f64,
    amplitude_relative: f64,
    phase_rad: f64,
    coulomb_relative: f64,
}

fn errors(truth: &Profile, m: &Model) -> Errors {
    let mut e =
        Errors { amplitude_over_tolerance: 0.0, amplitude_relative: 0.0, phase_rad: 0.0, coulomb_relative: 0.0 };
    for t in truth.motor.detent.iter().filter(|t| t.amplitude_nm >= 0.005) {
        let h = m.detent.iter().find(|h| h.order == t.order).expect("order identified");
        let da = (h.amplitude_nm - t.amplitude_nm).abs();
        e.amplitude_over_tolerance = e.amplitude_over_tolerance.max(da / (0.05 * t.amplitude_nm).max(0.0005));
        e.amplitude_relative = e.amplitude_relative.max(da / t.amplitude_nm);
        e.phase_rad = e.phase_rad.max(wrap_pi(h.phase_rad - t.phase_rad).abs());
    }
    e.coulomb_relative = (m.coulomb_friction_nm / truth.motor.coulomb_friction_nm - 1.0).abs();
    e
}

/// `patent-motor` identified from the log files `run_plan` writes (current noise 0.01 A,
/// 4000-count encoder), read back with `read_log`; planned and fitted from [`user_base`]
/// (no detent, the preset's `J`).
fn patent_identified() -> &'static (Fit, Model) {
    static S: OnceLock<(Fit, Model)> = OnceLock::new();
    S.get_or_init(|| {
        let m = patent();
        let dir = tempfile::tempdir().unwrap();
        let o = PlanOptions { electrical_periods: 30.0, ..PlanOptions::default() };
        assert!(o.current_noise_a > 0.0);
        let done = run_plan(&m, &user_base(), dir.path(), &o, &|| {}).unwrap();
        assert!(!done.plan.detent_from_profile);
        let logs: Vec<RunLog> =
            done.files.iter().map(|f| read_log(f, &LogOptions::new(m.motor.pole_pairs)).unwrap()).collect();
        let f = fit(&logs, &FitOptions::for_profile(&done.plan.profile, &[1, 2, 4])).unwrap();
        let model = Model::from_fit(&f);
        (f, model)
    })
}

#[test]
fn patent_motor_from_run_plan_logs_is_within_5_percent_and_0_05_rad_and_fs_within_10_percent() {
    let (f, model) = patent_identified();
    let e = errors(&patent(), model);
    eprintln!(
        "patent-motor: worst amplitude error {:.2} % ({:.2} of tolerance), phase {:.4} rad, Fs {:.2} %",
        100.0 * e.amplitude_relative,
        e.amplitude_over_tolerance,
        e.phase_rad,
        100.0 * e.coulomb_relative
    );
    assert!(e.amplitude_over_tolerance <= 1.0, "amplitude error {:.3} of tolerance", e.amplitude_over_tolerance);
    assert!(e.phase_rad <= 0.05, "phase error {}", e.phase_rad);
    assert!(e.coulomb_relative <= 0.10, "Fs error {}", e.coulomb_relative);
    // D too (two speeds): within 20 %.
    let d = f.viscous_nm_s_per_rad.expect("two speeds separate D").value;
    assert!((d / 0.001 - 1.0).abs() < 0.2, "D {d}");
    // J identified (the base profile's is right here): within 10 %, no disagreement warning.
    let (j, warned) = inertia_check(&patent(), &user_base(), f);
    eprintln!("patent-motor: J identified / true {j:.4} ({:?})", f.inertia_kg_m2);
    assert!((j - 1.0).abs() < 0.1 && !warned, "J ratio {j}, warned {warned}");
    // The plan's runs are slow enough for the loop and the encoder: no such warnings.
    assert!(
        !f.warnings.iter().any(|w| matches!(
            w,
            Warning::TooFast { .. }
                | Warning::SlowForEncoder { .. }
                | Warning::OneDirection { .. }
                | Warning::SingleSpeed { .. }
        )),
        "{:?}",
        f.warnings
    );
}

/// A random motor: `patent-motor` with orders 4, 2, 1 of random amplitude (2–40 mN·m) and
/// phase, and the inertia scaled by 0.5–3.
fn random_motor(seed: u64) -> Profile {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut m = patent().to_data();
    m.name = format!("random-{seed}");
    m.motor.inertia_kg_m2 *= rng.random_range(0.5..3.0);
    m.motor.detent = [4u16, 2, 1]
        .iter()
        .map(|&order| DetentTerm {
            order,
            amplitude_nm: rng.random_range(0.002..0.040),
            phase_rad: rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
        })
        .collect();
    m.validate("random motor").unwrap()
}

#[test]
fn fifty_random_motors_are_identified_within_5_percent_0_05_rad_and_fs_within_10_percent() {
    // Shorter runs than the default plan (15 electrical periods, ≥ 1 s steady) to keep the
    // test fast; logs in memory. The user knows neither the detent nor the load: the plan
    // and the fit start from the preset (its J, no detent), the true J is ×0.5–×3 of it.
    let o = PlanOptions { electrical_periods: 15.0, min_steady_s: 1.0, ..PlanOptions::default() };
    let base = user_base();
    let results: Vec<(u64, Errors, f64)> = (0..50u64)
        .into_par_iter()
        .map(|i| {
            let m = random_motor(1000 + i);
            let p = plan(&base, &o).unwrap();
            let logs = simulate_plan(&m, &p.profile, Compensation::Off, &p, o.current_noise_a, 7 + i, &|| {}).unwrap();
            let f = fit(&logs, &FitOptions::for_profile(&p.profile, &[1, 2, 4])).unwrap();
            let (j, warned) = inertia_check(&m, &base, &f);
            let off = (m.motor.inertia_kg_m2 / base.motor.inertia_kg_m2 - 1.0).abs();
            // The disagreement (> 20 %) is warned about when clear, and not when J is close.
            assert!(warned || off < 0.3, "motor {i}: J ×{:.2} of the base, not warned", 1.0 + off);
            assert!(!warned || off > 0.1, "motor {i}: J ×{:.2} of the base, warned", 1.0 + off);
            (i, errors(&m, &Model::from_fit(&f)), j)
        })
        .collect();
    let worst = |g: fn(&Errors) -> f64| results.iter().map(|(_, e, _)| g(e)).fold(0.0, f64::max);
    let j_worst = results.iter().map(|(_, _, j)| (j - 1.0).abs()).fold(0.0, f64::max);
    eprintln!(
        "50 random motors: worst amplitude error {:.2} % ({:.2} of tolerance), phase {:.4} rad, Fs {:.2} %, J {:.2} %",
        100.0 * worst(|e| e.amplitude_relative),
        worst(|e| e.amplitude_over_tolerance),
        worst(|e| e.phase_rad),
        100.0 * worst(|e| e.coulomb_relative),
        100.0 * j_worst
    );
    for (i, e, j) in &results {
        assert!((j - 1.0).abs() <= 0.1, "motor {i}: J identified ×{j:.3} of the truth");
        assert!(
            e.amplitude_over_tolerance <= 1.0,
            "motor {i}: amplitude error {:.3} of tolerance",
            e.amplitude_over_tolerance
        );
        assert!(e.phase_rad <= 0.05, "motor {i}: phase error {}", e.phase_rad);
        assert!(e.coulomb_relative <= 0.10, "motor {i}: Fs error {}", e.coulomb_relative);
    }
}

/// dB reduction of the peak-to-peak velocity error near each resonance, open loop.
fn open_loop_reductions_db(motor: &Profile, controller: &Profile) -> Vec<(u16, f64)> {
    let mut out = Vec::new();
    for k in [4u16, 2, 1] {
        let w = motor.resonance_speed_rad_s(k);
        let spec = SweepSpec {
            speeds_rad_s: [0.9, 0.95, 1.0, 1.05, 1.1].iter().map(|f| f * w).collect(),
            modes: vec![Mode::OpenLoop],
            compensations: vec![Compensation::Off, Compensation::Patent],
            run: RunSpec::at(w),
            options: SimOptions::default(),
            table: None,
        };
        let rows = sweep(motor, controller, &spec, &|| {}).unwrap();
        let peak = |comp: &str| {
            rows.iter().filter(|r| r.compensation.name() == comp).map(|r| r.vel_err_pp_rad_s).fold(0.0, f64::max)
        };
        out.push((k, 20.0 * (peak("off") / peak("patent")).log10()));
    }
    out
}

#[test]
fn identified_profile_achieves_80_percent_of_the_true_profiles_open_loop_db_reduction_at_every_resonance() {
    let truth = patent();
    let (_, model) = patent_identified();
    let identified = model.apply_to(&truth, Some("identified"), "test").unwrap();
    let want = open_loop_reductions_db(&truth, &truth);
    let got = open_loop_reductions_db(&truth, &identified);
    for ((k, t), (_, g)) in want.iter().zip(&got) {
        eprintln!("resonance k={k}: true profile {t:.1} dB, identified {g:.1} dB ({:.0} %)", 100.0 * g / t);
        assert!(*t > 6.0, "k={k}: the true profile itself reduces only {t:.1} dB");
        assert!(g / t >= 0.8, "k={k}: identified {g:.1} dB < 80 % of {t:.1} dB");
    }
}

#[test]
fn refinement_with_the_feed_forward_on_cuts_the_effort_ripple_and_keeps_the_accuracy() {
    let m = patent();
    let o = PlanOptions { electrical_periods: 15.0, min_steady_s: 1.0, ..PlanOptions::default() };
    let p = plan(&m, &o).unwrap();
    let logs = simulate_plan(&m, &p.profile, Compensation::Off, &p, o.current_noise_a, 3, &|| {}).unwrap();
    let fo = FitOptions::for_profile(&p.profile, &[1, 2, 4]);
    let f0 = fit(&logs, &fo).unwrap();
    let start = Model::from_fit(&f0);
    let r = refine(&m, &p, &start, Some(&f0), &fo, &RefineOptions::default(), &|| {}).unwrap();
    let (before, after) = r.ripple_before_after_nm();
    let (e0, e1) = (errors(&m, &start), errors(&m, &r.model));
    eprintln!(
        "refinement: effort ripple {:.4} → {:.4} mN·m RMS in {} steps; worst amplitude error {:.2} % → {:.2} %, phase {:.4} → {:.4} rad",
        1e3 * before,
        1e3 * after,
        r.steps.len() - 1,
        100.0 * e0.amplitude_relative,
        100.0 * e1.amplitude_relative,
        e0.phase_rad,
        e1.phase_rad
    );
    assert!(after < before / 100.0, "ripple {before} → {after}");
    assert!(r.steps.len() >= 3, "at least two feed-forward-on steps");
    assert!(e1.amplitude_relative < 0.01 && e1.phase_rad < 0.01 && e1.coulomb_relative < 0.05);
    assert!(e1.amplitude_relative <= e0.amplitude_relative + 0.002);
}

#[test]
fn ten_seconds_of_20_khz_logs_parse_and_identify_quickly() {
    // 4 runs of 2.5 s = 10 s at 20 kHz (200 000 rows) and the plan's back-EMF run (1.3 s,
    // 26 000 rows: read, left out of the torque fit), written as CSV, read and fitted.
    let m = patent();
    let dir = tempfile::tempdir().unwrap();
    let o = PlanOptions { electrical_periods: 2.0, min_steady_s: 2.3, ..PlanOptions::default() };
    let done = run_plan(&m, &m, dir.path(), &o, &|| {}).unwrap();
    let t0 = std::time::Instant::now();
    let logs: Vec<RunLog> = done.files.iter().map(|f| read_log(f, &LogOptions::new(50)).unwrap()).collect();
    let read = t0.elapsed().as_secs_f64();
    let f = fit(&logs, &FitOptions::for_profile(&done.plan.profile, &[1, 2, 4])).unwrap();
    let total = t0.elapsed().as_secs_f64();
    let rows: usize = logs[..4].iter().map(RunLog::len).sum();
    assert!((195_000..=205_000).contains(&rows), "{rows} rows");
    assert!(done.plan.runs[4].name.contains("emf") && logs[4].len() == 26_000, "{}", logs[4].len());
    assert!(f.samples_used > rows * 9 / 10);
    let rows = rows + logs[4].len();
    eprintln!("{rows} rows ({:.1} s at 20 kHz): read {read:.3} s, read + identify {total:.3} s", rows as f64 / 20e3);
    // The time is printed, not judged: a shared machine is slower, and debug builds of csv
    // are slow (`.ci/run` reports the release CLI's time on the default plan's logs).
}

/// A synthetic log of the model itself (no servo): θ = ω t quantised to 4000 counts, i_q
/// the torque needed divided by Km, plus white noise.
fn synthetic_log(speed: f64, model: &Model, noise_a: f64, seed: u64) -> RunLog {
    let km = 0.3;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let q = std::f64::consts::TAU / 4000.0;
    let n = (8.0 * std::f64::consts::TAU / (50.0 * speed.abs()) * 20e3) as usize;
    let mut log = RunLog {
        source: format!("synthetic {speed}"),
        t_s: Vec::with_capacity(n),
        theta_fb_rad: Vec::with_capacity(n),
        i_q_a: Vec::with_capacity(n),
        iq_cmd_a: None,
        i_d_a: None,
        iq_source: crate::log::IqSource::Column,
        ignored_columns: Vec::new(),
        phases: None,
    };
    for i in 0..n {
        let t = i as f64 / 20e3;
        let th = speed * t + 1e-4;
        let te = 50.0 * th;
        let tau: f64 =
            model.detent.iter().map(|h| h.amplitude_nm * (f64::from(h.order) * te + h.phase_rad).sin()).sum::<f64>()
                + model.coulomb_friction_nm * speed.signum()
                + model.viscous_nm_s_per_rad * speed;
        let e: f64 = rng.random_range(-1.0..1.0) * noise_a * 3f64.sqrt();
        log.t_s.push(t);
        log.theta_fb_rad.push(((th / q).floor() + 0.5) * q);
        log.i_q_a.push(tau / km + e);
    }
    log
}

fn synthetic_model() -> Model {
    Model {
        detent: vec![
            DetentTerm { order: 4, amplitude_nm: 0.02, phase_rad: 2.5 },
            DetentTerm { order: 2, amplitude_nm: 0.012, phase_rad: -2.9 },
            DetentTerm { order: 1, amplitude_nm: 0.008, phase_rad: -1.1 },
        ],
        coulomb_friction_nm: 0.01,
        viscous_nm_s_per_rad: 0.002,
        inertia_kg_m2: None,
        resistance_ohm: None,
    }
}

fn synthetic_options() -> FitOptions {
    let mut o = FitOptions::for_profile(&patent(), &[1, 2, 4]);
    o.inertia_kg_m2 = 0.0;
    o.fit_inertia = false;
    o.correct_quantisation = false;
    o.servo_bandwidth_hz = None;
    o
}

#[test]
fn exact_model_data_recovers_every_term_inside_its_interval_in_the_profile_sign_convention() {
    let truth = synthetic_model();
    let logs: Vec<RunLog> =
        [1.0, -1.0, 2.0, -2.0].iter().enumerate().map(|(i, &w)| synthetic_log(w, &truth, 0.02, i as u64)).collect();
    let f = fit(&logs, &synthetic_options()).unwrap();
    for t in &truth.detent {
        let h = f.harmonics.iter().find(|h| h.order == t.order).unwrap();
        assert!((h.amplitude_nm.value - t.amplitude_nm).abs() <= h.amplitude_nm.ci95.max(1e-5), "{h:?}");
        assert!(wrap_pi(h.phase_rad.value - t.phase_rad).abs() <= h.phase_rad.ci95.max(1e-3), "{h:?}");
        assert!(h.amplitude_nm.ci95 > 0.0 && h.amplitude_nm.ci95 < 0.001);
    }
    let (fs, d) = (f.coulomb_friction_nm, f.viscous_nm_s_per_rad.unwrap());
    assert!((fs.value - 0.01).abs() <= fs.ci95.max(1e-5), "{fs:?}");
    assert!((d.value - 0.002).abs() <= d.ci95.max(1e-6), "{d:?}");
    assert!(f.warnings.is_empty(), "{:?}", f.warnings);
}

#[test]
fn one_direction_and_one_speed_are_warned_about_and_d_is_held() {
    let truth = synthetic_model();
    let logs = vec![synthetic_log(1.0, &truth, 0.01, 1)];
    let mut o = synthetic_options();
    o.viscous_fallback_nm_s_per_rad = 0.002;
    let f = fit(&logs, &o).unwrap();
    assert!(f.warnings.iter().any(|w| matches!(w, Warning::OneDirection { direction: "forward" })), "{:?}", f.warnings);
    assert!(f.warnings.iter().any(|w| matches!(w, Warning::SingleSpeed { .. })), "{:?}", f.warnings);
    assert!(f.viscous_nm_s_per_rad.is_none() && f.offset_nm.is_none());
    assert_eq!(f.viscous_used, 0.002);
    // With D held at the truth, Fs is still right; the harmonics do not care.
    assert!((f.coulomb_friction_nm.value - 0.01).abs() < 2e-4);
    let text: Vec<String> = f.warnings.iter().map(ToString::to_string).collect();
    assert!(text.iter().any(|t| t.contains("Fs is confounded")), "{text:?}");
}

#[test]
fn too_fast_and_too_few_periods_are_warned_about() {
    let truth = synthetic_model();
    let logs: Vec<RunLog> =
        [8.0, -8.0].iter().enumerate().map(|(i, &w)| synthetic_log(w, &truth, 0.01, i as u64)).collect();
    let mut o = synthetic_options();
    o.servo_bandwidth_hz = Some(40.0);
    let f = fit(&logs, &o).unwrap();
    // Harmonic 4 at 8 rad/s: 4·50·8/2π = 255 Hz ≫ 40 Hz.
    assert!(
        f.warnings
            .iter()
            .any(|w| matches!(w, Warning::TooFast { order: 4, harmonic_hz, .. } if (harmonic_hz - 254.6).abs() < 1.0)),
        "{:?}",
        f.warnings
    );
    assert!(f.warnings.iter().any(|w| matches!(w, Warning::FewPeriods { .. })), "{:?}", f.warnings);
}

#[test]
fn phase_currents_give_the_same_fit_as_the_q_current() {
    // Log i_a, i_b instead of i_q: the reader parks them at Nr·θ_fb.
    let truth = synthetic_model();
    let log = synthetic_log(1.0, &truth, 0.0, 1);
    let mut csv = String::from("t_s,theta_fb_rad,i_a_a,i_b_a,extra\n");
    for i in 0..log.len() {
        let te = 50.0 * log.theta_fb_rad[i];
        let iq = log.i_q_a[i];
        // i_d = 0: (i_a, i_b) = (−i_q sin θe, i_q cos θe).
        csv.push_str(&format!("{},{},{},{},7\n", log.t_s[i], log.theta_fb_rad[i], -iq * te.sin(), iq * te.cos()));
    }
    let parsed = crate::log::parse_log(csv.as_bytes(), "ab.csv", &LogOptions::new(50)).unwrap();
    assert_eq!(parsed.iq_source, crate::log::IqSource::Park);
    assert_eq!(parsed.ignored_columns, vec!["extra".to_string()]);
    for (a, b) in parsed.i_q_a.iter().zip(&log.i_q_a) {
        assert!((a - b).abs() < 1e-9);
    }
}

/// `log` with a constant torque `c_nm` (a load, or a current offset) added to the effort.
fn with_constant_torque(mut log: RunLog, c_nm: f64) -> RunLog {
    let km = synthetic_options().km_nm_per_a;
    for i in &mut log.i_q_a {
        *i += c_nm / km;
    }
    log
}

#[test]
fn forward_at_one_speed_and_reverse_at_another_fit_fs_and_the_constant_torque_with_d_held() {
    // Two levels (forward 1 rad/s, reverse 2 rad/s) for Fs, D and c: D is held, not a
    // linear-dependence error.
    let truth = synthetic_model();
    let logs: Vec<RunLog> = [1.0, -2.0]
        .iter()
        .enumerate()
        .map(|(i, &w)| with_constant_torque(synthetic_log(w, &truth, 0.01, i as u64), 0.005))
        .collect();
    let mut o = synthetic_options();
    o.viscous_fallback_nm_s_per_rad = 0.002;
    let f = fit(&logs, &o).unwrap();
    assert!(f.viscous_nm_s_per_rad.is_none());
    assert_eq!(f.viscous_used, 0.002);
    let c = f.offset_nm.expect("both directions: the constant torque is fitted");
    assert!((c.value - 0.005).abs() < 2e-4, "{c:?}");
    assert!((f.coulomb_friction_nm.value - 0.01).abs() < 2e-4, "{:?}", f.coulomb_friction_nm);
    for t in &truth.detent {
        let h = f.harmonics.iter().find(|h| h.order == t.order).unwrap();
        assert!((h.amplitude_nm.value - t.amplitude_nm).abs() < 5e-4, "{h:?}");
    }
    assert!(
        f.warnings.iter().any(|w| matches!(
            w,
            Warning::OneSpeedPerDirection { add_run: ("forward", s), viscous_used, .. }
                if (s - 2.0).abs() < 0.01 && *viscous_used == 0.002
        )),
        "{:?}",
        f.warnings
    );
    assert!(!f.warnings.iter().any(|w| matches!(w, Warning::SingleSpeed { .. } | Warning::OneDirection { .. })));
    let text: Vec<String> = f.warnings.iter().map(ToString::to_string).collect();
    assert!(text.iter().any(|t| t.contains("D held at 2.000e-3") && t.contains("forward at 2.000 rad/s")), "{text:?}");
}

#[test]
fn every_combination_of_directions_and_speeds_fits_the_terms_its_levels_separate() {
    let truth = synthetic_model();
    let speeds = [1.0, -1.0, 2.0, -2.0];
    let all: Vec<RunLog> = speeds
        .iter()
        .enumerate()
        .map(|(i, &w)| with_constant_torque(synthetic_log(w, &truth, 0.005, 10 + i as u64), 0.004))
        .collect();
    let mut o = synthetic_options();
    o.viscous_fallback_nm_s_per_rad = 0.002;
    for mask in 1u32..16 {
        let chosen: Vec<f64> = (0..4).filter(|b| mask & (1 << b) != 0).map(|b| speeds[b]).collect();
        let logs: Vec<RunLog> = (0..4).filter(|b| mask & (1 << b) != 0).map(|b| all[b].clone()).collect();
        let f = fit(&logs, &o).unwrap_or_else(|e| panic!("{chosen:?}: {e}"));
        let both = chosen.iter().any(|&w| w > 0.0) && chosen.iter().any(|&w| w < 0.0);
        let two_speeds_one_way = [1.0, -1.0].iter().any(|&d| chosen.contains(&d) && chosen.contains(&(2.0 * d)));
        assert_eq!(f.offset_nm.is_some(), both, "{chosen:?}");
        assert_eq!(f.viscous_nm_s_per_rad.is_some(), two_speeds_one_way, "{chosen:?}");
        // Whatever is held is named in a warning.
        if !both {
            assert!(f.warnings.iter().any(|w| matches!(w, Warning::OneDirection { .. })), "{chosen:?}");
        }
        if !two_speeds_one_way {
            assert!(
                f.warnings
                    .iter()
                    .any(|w| matches!(w, Warning::SingleSpeed { .. } | Warning::OneSpeedPerDirection { .. })),
                "{chosen:?}: {:?}",
                f.warnings
            );
        }
        // The harmonics never depend on which friction terms were fitted; Fs is right
        // whenever c is separated from it (D held at the truth otherwise).
        for t in &truth.detent {
            let h = f.harmonics.iter().find(|h| h.order == t.order).unwrap();
            assert!((h.amplitude_nm.value - t.amplitude_nm).abs() < 5e-4, "{chosen:?}: {h:?}");
        }
        if both {
            assert!((f.coulomb_friction_nm.value - 0.01).abs() < 3e-4, "{chosen:?}: {:?}", f.coulomb_friction_nm);
        }
    }
}

#[test]
fn a_least_squares_failure_prints_its_cause_once_in_an_error_chain() {
    use std::error::Error as _;
    let e = crate::fit::FitError::from(crate::lsq::LsqError::Singular(9.8e12));
    // What anyhow's `{:#}` prints: the message, then ": " and each source in turn.
    let mut chain = e.to_string();
    let mut src = e.source();
    while let Some(s) = src {
        chain += &format!(": {s}");
        src = s.source();
    }
    assert_eq!(chain.matches("linearly dependent").count(), 1, "{chain}");
    assert!(chain.starts_with("least squares failed: the regressors are linearly dependent"), "{chain}");
}

/// A log of `n` samples at 20 kHz turning at `speed` rad/s, with a constant current.
fn constant_speed_log(speed: f64, n: usize) -> RunLog {
    let q = std::f64::consts::TAU / 4000.0;
    RunLog {
        source: format!("const {speed} x{n}"),
        t_s: (0..n).map(|i| i as f64 / 20e3).collect(),
        theta_fb_rad: (0..n).map(|i| ((speed * i as f64 / 20e3 / q).floor() + 0.5) * q).collect(),
        i_q_a: vec![0.1; n],
        iq_cmd_a: None,
        i_d_a: None,
        iq_source: crate::log::IqSource::Column,
        ignored_columns: Vec::new(),
        phases: None,
    }
}

#[test]
fn a_short_fast_log_is_reported_as_too_short_not_as_a_rotor_that_does_not_move() {
    let o = synthetic_options();
    // 40 samples (2 ms) at 500 rad/s: moving, but the speed filter's start-up takes most of it.
    let e = fit(&[constant_speed_log(500.0, 40)], &o).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, crate::fit::FitError::TooShort { samples: 40, needed, .. } if needed > 40), "{e:?}");
    assert!(text.contains("too short") && text.contains("5.000e2 rad/s") && !text.contains("does not move"), "{text}");
    // Fewer samples than any fit needs.
    let e = fit(&[constant_speed_log(500.0, 10)], &o).unwrap_err();
    assert!(matches!(e, crate::fit::FitError::TooShort { samples: 10, .. }), "{e:?}");
    // A long log that stands still is the one that "does not move".
    let e = fit(&[constant_speed_log(0.0, 4000)], &o).unwrap_err();
    assert!(matches!(e, crate::fit::FitError::NoMotion { periods, .. } if periods < 1e-9), "{e:?}");
    assert!(e.to_string().contains("does not move"), "{e}");
}

#[test]
fn negative_fs_from_a_one_direction_load_is_warned_about_and_clamped_to_zero_in_the_profile() {
    // Forward only, with a load pushing the rotor along by 30 mN·m: Fs comes out ≈ −20 mN·m.
    let truth = synthetic_model();
    let logs = vec![with_constant_torque(synthetic_log(1.0, &truth, 0.01, 5), -0.03)];
    let mut o = synthetic_options();
    o.viscous_fallback_nm_s_per_rad = 0.002;
    let f = fit(&logs, &o).unwrap();
    assert!((f.coulomb_friction_nm.value + 0.02).abs() < 5e-4, "{:?}", f.coulomb_friction_nm);
    assert!(
        f.warnings.iter().any(|w| matches!(w, Warning::CoulombNotPositive { one_direction: Some("forward"), .. })),
        "{:?}",
        f.warnings
    );
    let text: Vec<String> = f.warnings.iter().map(ToString::to_string).collect();
    assert!(
        text.iter().any(|t| t.contains("clamped to 0 in the profile") && t.contains("only forward travel")),
        "{text:?}"
    );
    assert_eq!(Model::from_fit(&f).coulomb_friction_nm, 0.0);
    // A clearly positive Fs gives no such warning.
    let f = fit(&[synthetic_log(1.0, &truth, 0.01, 5)], &o).unwrap();
    assert!(!f.warnings.iter().any(|w| matches!(w, Warning::CoulombNotPositive { .. })), "{:?}", f.warnings);
}

#[test]
fn currents_out_of_range_are_an_error_naming_the_logs_not_a_profile_with_infinite_values() {
    let truth = synthetic_model();
    let o = synthetic_options();
    let mut logs: Vec<RunLog> =
        [1.0, -1.0].iter().enumerate().map(|(i, &w)| synthetic_log(w, &truth, 0.01, i as u64)).collect();
    for i in &mut logs[1].i_q_a {
        *i *= 1e200;
    }
    let e = fit(&logs, &o).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, crate::fit::FitError::NonFinite { .. }), "{e:?}");
    assert!(text.contains("synthetic 1") && text.contains("synthetic -1") && text.contains("out of range"), "{text}");
    assert!(text.contains("in synthetic -1"), "the log with the largest current is named: {text}");
    // A current that is not a number (an in-memory log; files are checked when read).
    logs[1].i_q_a.iter_mut().for_each(|i| *i *= 1e-200);
    logs[1].i_q_a[500] = f64::NAN;
    let text = fit(&logs, &o).unwrap_err().to_string();
    assert!(text.contains("not a number in synthetic -1"), "{text}");
}

#[test]
fn a_single_log_fits_what_it_determines_and_holds_j_and_d_at_the_base_saying_which() {
    // Identification from any subset of runs: one run used to fail with "regressors are linearly dependent" (J's
    // instrument is a combination of the harmonic regressors within one log).
    let m = patent();
    let o = PlanOptions { electrical_periods: 15.0, min_steady_s: 1.0, ..PlanOptions::default() };
    let mut p = plan(&user_base(), &o).unwrap();
    p.runs.truncate(1);
    let logs = simulate_plan(&m, &p.profile, Compensation::Off, &p, o.current_noise_a, 5, &|| {}).unwrap();
    assert_eq!(logs.len(), 1);
    let f = fit(&logs, &FitOptions::for_profile(&p.profile, &[1, 2, 4])).unwrap();
    assert!(f.inertia_kg_m2.is_none() && f.inertia_used == p.profile.motor.inertia_kg_m2);
    let said: Vec<String> = f.decisions.iter().map(ToString::to_string).collect();
    assert!(said.iter().any(|d| d.starts_with("J held at the base profile's") && d.contains("one log")), "{said:?}");
    assert!(f.viscous_nm_s_per_rad.is_none() && f.warnings.iter().any(|w| matches!(w, Warning::SingleSpeed { .. })));
    // The harmonics are still determined (J is right here): within the usual tolerance.
    let e = errors(&m, &Model::from_fit(&f));
    assert!(
        e.amplitude_over_tolerance <= 1.0 && e.phase_rad <= 0.05,
        "{:.3} {:.4}",
        e.amplitude_over_tolerance,
        e.phase_rad
    );
}

#[test]
fn inertia_mode_fit_on_a_single_log_still_reports_the_dependence() {
    let m = patent();
    let o = PlanOptions { electrical_periods: 15.0, min_steady_s: 1.0, ..PlanOptions::default() };
    let mut p = plan(&user_base(), &o).unwrap();
    p.runs.truncate(1);
    let logs = simulate_plan(&m, &p.profile, Compensation::Off, &p, o.current_noise_a, 5, &|| {}).unwrap();
    let mut fo = FitOptions::for_profile(&p.profile, &[1, 2, 4]);
    fo.inertia = crate::conditions::InertiaMode::Fit;
    let e = fit(&logs, &fo).unwrap_err().to_string();
    assert!(e.contains("linearly dependent"), "{e}");
    fo.inertia = crate::conditions::InertiaMode::Base;
    let f = fit(&logs, &fo).unwrap();
    assert!(f.decisions.iter().any(|d| d.to_string().contains("--inertia base")));
}
