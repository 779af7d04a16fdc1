//! Tests of reading, validating and naming profiles.

use super::*;
use stepdamp_core::{Compensation, Mode, Params};

const PATENT_MOTOR: &str = include_str!("../presets/patent-motor.toml");

#[test]
fn presets_parse_and_validate() {
    for name in PRESETS {
        let p = Profile::preset(name).expect(name);
        assert_eq!(p.name, name);
        assert_eq!(p.motor.pole_pairs, 50);
    }
}

#[test]
fn patent_motor_resonances_are_where_the_issue_says() {
    let p = Profile::preset("patent-motor").unwrap();
    let w: Vec<f64> = [4, 2, 1].iter().map(|&k| p.resonance_speed_rad_s(k)).collect();
    assert!((w[0] - 4.22).abs() < 0.02 && (w[1] - 8.44).abs() < 0.03 && (w[2] - 16.88).abs() < 0.05, "{w:?}");
}

#[test]
fn round_trips_through_toml() {
    let p = Profile::preset("patent-motor").unwrap();
    let back = Profile::from_toml_str(&p.to_toml_string(), "x").unwrap();
    assert_eq!(p, back);
}

fn with(edit: impl Fn(&mut String)) -> Result<Profile, ProfileError> {
    let mut s = PATENT_MOTOR.to_string();
    edit(&mut s);
    Profile::from_toml_str(&s, "m.toml")
}

fn replaced(from: &str, to: &str) -> String {
    assert!(PATENT_MOTOR.contains(from), "{from}");
    with(|s| *s = s.replacen(from, to, 1)).unwrap_err().to_string()
}

#[test]
fn bad_values_are_rejected_with_file_key_and_reason() {
    let e = replaced("resistance_ohm = 0.9", "resistance_ohm = -0.9");
    assert!(e.contains("m.toml") && e.contains("motor.resistance_ohm") && e.contains("[1e-3, 1000] Ω"), "{e}");
    let e = replaced("inertia_kg_m2 = 4.0e-5", "inertia_kg_m2 = 0.0");
    assert!(e.contains("motor.inertia_kg_m2"), "{e}");
    let e = replaced("inductance_h = 2.5e-3", "inductance_h = nan");
    assert!(e.contains("motor.inductance_h"), "{e}");
    let e = replaced("order = 2", "order = 4");
    assert!(e.contains("motor.detent[1].order") && e.contains("twice"), "{e}");
}

#[test]
fn implausible_values_name_file_key_value_as_written_and_range_once() {
    for (from, to, want) in [
        ("km_nm_per_a = 0.3", "km_nm_per_a = 1e308", "m.toml: motor.km_nm_per_a = 1e308: must be in [1e-3, 50] N·m/A"),
        (
            "inertia_kg_m2 = 4.0e-5",
            "inertia_kg_m2 = 1e-308",
            "m.toml: motor.inertia_kg_m2 = 1e-308: must be in [1e-8, 1] kg·m²",
        ),
        (
            "holding_current_a = 1.9",
            "holding_current_a = 0",
            "m.toml: drive.holding_current_a = 0: must be in (0, 100] A",
        ),
        ("phase_rad = 0.7", "phase_rad = 40.0", "m.toml: motor.detent[1].phase_rad = 40: must be in"),
        ("bus_voltage_v = 48.0", "bus_voltage_v = 1e6", "m.toml: drive.bus_voltage_v = 1e6: must be in [1, 1000] V"),
    ] {
        let e = replaced(from, to);
        assert!(e.starts_with(want), "{e}\nwanted {want}");
        assert_eq!(e.matches("m.toml").count(), 1, "{e}");
        assert!(!e.contains("inf") && !e.contains("NaN"), "{e}");
    }
}

#[test]
fn every_value_inside_the_ranges_gives_finite_derived_quantities() {
    // The corners of the ranges that make ω_n and the gains largest and smallest.
    use stepdamp_core::limits as l;
    let p = Profile::preset("patent-motor").unwrap();
    for (j, km, hold, nr) in [
        (l::INERTIA_KG_M2.min, l::KM_NM_PER_A.max, l::CURRENT_LIMIT_A.max, l::POLE_PAIRS.max),
        (l::INERTIA_KG_M2.max, l::KM_NM_PER_A.min, 1e-6, l::POLE_PAIRS.min),
    ] {
        let q = p
            .edited("corner", |d| {
                d.motor.inertia_kg_m2 = j;
                d.motor.km_nm_per_a = km;
                d.drive.current_limit_a = l::CURRENT_LIMIT_A.max;
                d.drive.holding_current_a = hold;
                d.motor.pole_pairs = nr as u16;
                // Within the holding torque at this corner's current (else implausible).
                for t in &mut d.motor.detent {
                    t.amplitude_nm = t.amplitude_nm.min(0.1 * km * hold);
                }
            })
            .unwrap();
        assert!(q.natural_frequency_rad_s().is_finite() && q.resonance_speed_rad_s(32).is_finite());
    }
}

#[test]
fn unknown_and_missing_keys_are_rejected_by_name() {
    let e = replaced("pole_pairs = 50", "pole_pairs = 50\nteeth = 3");
    assert!(e.contains("m.toml") && e.contains("teeth"), "{e}");
    let e = replaced("km_nm_per_a = 0.3\n", "");
    assert!(e.contains("km_nm_per_a"), "{e}");
    let e = replaced("counts_per_rev = 4000", "counts_per_rev = \"many\"");
    assert!(e.contains("counts_per_rev"), "{e}");
}

#[test]
fn bad_toml_syntax_names_the_file_and_the_line_on_one_line() {
    let e = replaced("[drive]", "[drive");
    assert!(e.starts_with("m.toml: TOML parse error at line ") && !e.contains('\n'), "{e}");
    assert!(e.contains("`[drive`") && !e.contains('^'), "{e}");
}

#[test]
fn unknown_preset_lists_the_presets() {
    let e = Profile::load("no-such-motor").unwrap_err().to_string();
    assert!(e.contains("no-such-motor") && e.contains("patent-motor"), "{e}");
}

#[test]
fn a_name_with_a_slash_or_toml_suffix_is_a_file_and_a_bare_name_a_preset() {
    assert_eq!(MotorRef::parse("./patent-motor").unwrap(), MotorRef::File("./patent-motor".as_ref()));
    assert_eq!(MotorRef::parse("dir/m").unwrap(), MotorRef::File("dir/m".as_ref()));
    assert_eq!(MotorRef::parse("m.toml").unwrap(), MotorRef::File("m.toml".as_ref()));
    assert_eq!(MotorRef::parse("nema23-57mm").unwrap(), MotorRef::Preset("nema23-57mm"));
    let e = Profile::load("./no-such-file").unwrap_err().to_string();
    assert!(e.contains("./no-such-file") && e.contains("no such"), "{e}");
}

#[test]
fn a_bare_name_that_is_both_a_preset_and_a_file_is_an_error() {
    // The rule reads the working directory: run the probe below in a directory that holds
    // a file named like a preset (tests share the working directory, so not here).
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("patent-motor"), PATENT_MOTOR).unwrap();
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "tests::ambiguity_probe", "--ignored", "--nocapture"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains("AMBIGUOUS-OK"), "{text}");
}

/// Run by [`a_bare_name_that_is_both_a_preset_and_a_file_is_an_error`] in a directory that
/// holds a file named `patent-motor`.
#[test]
#[ignore = "run by a_bare_name_that_is_both_a_preset_and_a_file_is_an_error"]
fn ambiguity_probe() {
    let e = Profile::load("patent-motor").unwrap_err();
    assert!(matches!(&e, ProfileError::Ambiguous(n) if n == "patent-motor"), "{e}");
    assert!(e.to_string().contains("./patent-motor"), "{e}");
    println!("AMBIGUOUS-OK");
}

#[test]
fn the_patent_motor_preset_is_the_cores_reference_controller() {
    // One patent motor: the preset file. The core's `Params::patent_motor` (used by the
    // benchmarks and the Cortex-M4F firmware) must be the preset's controller, except for
    // the servo loop, which the core's reference runs at 50 Hz with a 300 Hz filter.
    let p = Profile::preset("patent-motor").unwrap();
    let p = p
        .edited("patent-motor", |d| {
            d.servo.bandwidth_hz = 50.0;
            d.servo.velocity_filter_hz = 300.0;
        })
        .unwrap();
    let h = p.controller_harmonics();
    for mode in [Mode::OpenLoop, Mode::Servo] {
        for comp in [Compensation::Off, Compensation::Patent, Compensation::Estimated] {
            let mine = p.params(&h, mode, comp);
            let core = Params::patent_motor(mode, comp);
            assert_eq!(mine.motor, core.motor, "{mode:?} {comp:?}");
            assert_eq!(mine.drive, core.drive);
            assert_eq!(mine.encoder_counts_per_rev, core.encoder_counts_per_rev);
            let rel = |a: f32, b: f32| ((a - b) / b).abs() < 1e-6;
            assert!(rel(mine.servo.velocity_nm_s_per_rad, core.servo.velocity_nm_s_per_rad));
            assert!(rel(mine.servo.position_nm_per_rad, core.servo.position_nm_per_rad));
            assert!(rel(mine.servo.position_integral_nm_per_rad_s, core.servo.position_integral_nm_per_rad_s));
            assert_eq!(mine.servo.velocity_filter_hz, core.servo.velocity_filter_hz);
        }
    }
}

#[test]
fn an_endless_or_huge_file_is_refused_after_reading_the_profile_limit() {
    // `motor check /dev/zero` read without end before the bound.
    let e = Profile::from_file(std::path::Path::new("/dev/zero")).unwrap_err().to_string();
    assert!(e.contains("/dev/zero") && e.contains(&MAX_PROFILE_BYTES.to_string()), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let big = dir.path().join("big.toml");
    std::fs::write(&big, vec![b'#'; MAX_PROFILE_BYTES as usize + 10]).unwrap();
    assert!(Profile::from_file(&big).is_err());
}

/// The patent motor with its Coulomb friction smooth or Stribeck and every sensor error.
fn with_simulator_keys(law: &str) -> String {
    let friction = match law {
        "smooth" => "\n[motor.friction]\nlaw = \"smooth\"\ncreep_speed_rad_s = 0.002\n",
        _ => {
            "\n[motor.friction]\nlaw = \"stribeck\"\ncreep_speed_rad_s = 0.002\nstatic_nm = 0.015\nstribeck_speed_rad_s = 0.05\n"
        }
    };
    PATENT_MOTOR
        .replacen(
            "\n[drive]\n",
            &format!("{friction}\n[drive]\ncurrent_offset_a = [0.02, -0.01]\ncurrent_gain_error = [0.03, -0.02]\n"),
            1,
        )
        .replacen(
            "counts_per_rev = 4000",
            "counts_per_rev = 4000\neccentricity_rad = 0.002\neccentricity_phase_rad = 0.5",
            1,
        )
}

#[test]
fn friction_laws_and_sensor_errors_round_trip_through_toml() {
    use crate::data::FrictionLawName;
    for law in ["smooth", "stribeck"] {
        let p = Profile::from_toml_str(&with_simulator_keys(law), "m.toml").unwrap();
        assert_eq!(p.motor.friction.law.as_str(), law);
        assert_eq!(p.motor.friction.creep_speed_rad_s, Some(0.002));
        assert_eq!(p.drive.current_offset_a, [0.02, -0.01]);
        assert_eq!(p.drive.current_gain_error, [0.03, -0.02]);
        assert_eq!((p.encoder.eccentricity_rad, p.encoder.eccentricity_phase_rad), (0.002, 0.5));
        let back = Profile::from_toml_str(&p.to_toml_string(), "x").unwrap();
        assert_eq!(p, back);
        if law == "stribeck" {
            assert_eq!(p.motor.friction.law, FrictionLawName::Stribeck);
            assert_eq!((p.motor.friction.static_nm, p.motor.friction.stribeck_speed_rad_s), (Some(0.015), Some(0.05)));
        }
    }
}

#[test]
fn todays_profiles_keep_karnopp_and_ideal_sensors_and_write_no_new_key() {
    let p = Profile::preset("patent-motor").unwrap();
    assert!(p.motor.friction.is_default());
    assert_eq!((p.drive.current_offset_a, p.drive.current_gain_error), ([0.0; 2], [0.0; 2]));
    assert_eq!((p.encoder.eccentricity_rad, p.encoder.eccentricity_phase_rad), (0.0, 0.0));
    let text = p.to_toml_string();
    for key in ["[motor.friction]", "law", "current_offset_a", "current_gain_error", "eccentricity"] {
        assert!(!text.contains(key), "{key} written for a profile without it:\n{text}");
    }
    // Writing the defaults out is the same profile.
    let explicit = PATENT_MOTOR.replacen("\n[drive]\n", "\n[motor.friction]\nlaw = \"karnopp\"\n\n[drive]\n", 1);
    assert_eq!(Profile::from_toml_str(&explicit, "preset").unwrap().motor, p.motor);
}

#[test]
fn bad_simulator_keys_name_file_key_value_and_range() {
    let bad = |from: &str, to: &str, law: &str| {
        let s = with_simulator_keys(law);
        assert!(s.contains(from), "{from}");
        Profile::from_toml_str(&s.replacen(from, to, 1), "m.toml").unwrap_err().to_string()
    };
    for (law, from, to, want) in [
        (
            "smooth",
            "creep_speed_rad_s = 0.002",
            "creep_speed_rad_s = 0",
            "m.toml: motor.friction.creep_speed_rad_s = 0: must be in (0, 10] rad/s",
        ),
        (
            "smooth",
            "creep_speed_rad_s = 0.002",
            "",
            "m.toml: motor.friction.creep_speed_rad_s = (missing): law = \"smooth\" needs it",
        ),
        (
            "smooth",
            "creep_speed_rad_s = 0.002",
            "creep_speed_rad_s = 0.002\nstatic_nm = 0.02",
            "m.toml: motor.friction.static_nm = 0.02: law = \"smooth\" does not use it",
        ),
        (
            "stribeck",
            "static_nm = 0.015",
            "static_nm = 0.005",
            "m.toml: motor.friction.static_nm = 5e-3: must be in [0.01, 0.1] N·m (1 to 10 × motor.coulomb_friction_nm)",
        ),
        (
            "stribeck",
            "stribeck_speed_rad_s = 0.05",
            "stribeck_speed_rad_s = 11",
            "m.toml: motor.friction.stribeck_speed_rad_s = 11: must be in (0, 10] rad/s",
        ),
        (
            "smooth",
            "current_offset_a = [0.02, -0.01]",
            "current_offset_a = [0.02, -0.5]",
            "m.toml: drive.current_offset_a[1] = -0.5: must be in [-0.3, 0.3] A (10 % of drive.current_limit_a)",
        ),
        (
            "smooth",
            "current_gain_error = [0.03, -0.02]",
            "current_gain_error = [0.3, -0.02]",
            "m.toml: drive.current_gain_error[0] = 0.3: must be in [-0.2, 0.2]",
        ),
        (
            "smooth",
            "eccentricity_rad = 0.002",
            "eccentricity_rad = 0.02",
            "m.toml: encoder.eccentricity_rad = 0.02: must be in [0, 0.01] rad",
        ),
        ("smooth", "law = \"smooth\"", "law = \"coulomb\"", "unknown variant `coulomb`"),
    ] {
        let e = bad(from, to, law);
        assert!(e.contains(want), "{e}\nwant: {want}");
    }
}

#[test]
fn a_hostile_name_is_refused_with_file_key_escaped_value_and_rule() {
    for (name, shows) in [
        ("m\\n[gcode_macro PWNED]\\ngcode: M112", "\"m\\u{a}[gcode_macro PWNED]\\u{a}gcode: M112\""),
        ("m\\u001b[2J", "\"m\\u{1b}[2J\""),
        ("m */ #include <x> /*", "\"m */ #include <x> /*\""),
    ] {
        let e = replaced("name = \"patent-motor\"", &format!("name = \"{name}\"")).to_string();
        assert!(e.starts_with(&format!("m.toml: name = {shows}: ")), "{e}");
        assert!(e.contains("one printable line") && !e.contains('\n') && !e.contains('\u{1b}'), "{e}");
    }
}

#[test]
fn a_detent_beyond_the_holding_torque_is_refused_with_the_reason() {
    // Km·I_hold = 0.3 × 1.9 = 0.57 N·m; a 5 N·m detent is 8.8 times that.
    let e = replaced("amplitude_nm = 0.02", "amplitude_nm = 5.0");
    assert!(e.starts_with("m.toml: motor.detent = 5.02 N·m in all (the sum of the amplitudes): "), "{e}");
    assert!(e.contains("km_nm_per_a × drive.holding_current_a = 0.57 N·m") && e.contains("cannot hold"), "{e}");
    // The same detent is plausible at a holding current that holds it.
    let ok = with(|s| {
        *s = s.replacen("amplitude_nm = 0.02", "amplitude_nm = 0.4", 1);
    });
    assert!(ok.is_ok(), "{ok:?}");
}

#[test]
fn a_value_far_outside_its_range_prints_in_short_form() {
    let e = replaced("km_nm_per_a = 0.3", "km_nm_per_a = 1.7976931348623157e308");
    assert!(e.starts_with("m.toml: motor.km_nm_per_a = 1.7976931348623157e308: "), "{e}");
    let e = replaced("inertia_kg_m2 = 4.0e-5", "inertia_kg_m2 = 5e-324");
    assert!(e.starts_with("m.toml: motor.inertia_kg_m2 = 5e-324: ") && e.len() < 200, "{e}");
}

#[test]
fn a_parse_error_quoting_control_characters_escapes_them() {
    for (from, to) in
        [("name = \"patent-motor\"", "name = \"m\u{1b}[2Jx\""), ("pole_pairs = 50", "pole_pairs\u{1b}[31m = 50")]
    {
        let e = replaced(from, to);
        assert!(e.contains("\\u{1b}[") && !e.contains('\u{1b}') && !e.contains('\n'), "{e:?}");
    }
}
