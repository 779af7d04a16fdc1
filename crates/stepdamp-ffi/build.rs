//! Writes the texts `sd_status_str()` returns for the parameter statuses from the limits
//! the core enforces (`stepdamp_core::limits`), so that a message states exactly the
//! range `sd_config_init()` accepts: one home for each range. The output,
//! `$OUT_DIR/status_texts.rs`, is one `&CStr` constant per status, included by
//! `src/convert.rs`; `tests/api.rs` probes each range's ends through the C API.

use std::fmt::Write as _;

use stepdamp_core::limits::{self as l, Limit, Num};

/// `name must be in range`, with the C field `name`.
fn range(name: &str, limit: &Limit) -> String {
    format!("{name} must be in {limit}")
}

fn main() {
    let k = Num(l::CURRENT_LOOP_BANDWIDTH_PER_PWM);
    let texts: [(&str, String); 21] = [
        ("HARMONIC_ORDER", format!("a detent harmonic order must be in {}", l::DETENT_ORDER)),
        ("KM", range("motor.km_nm_per_a", &l::KM_NM_PER_A)),
        ("POLE_PAIRS", range("motor.pole_pairs", &l::POLE_PAIRS)),
        ("RESISTANCE", range("motor.resistance_ohm", &l::RESISTANCE_OHM)),
        ("INDUCTANCE", range("motor.inductance_h", &l::INDUCTANCE_H)),
        ("COULOMB_FRICTION", range("motor.coulomb_friction_nm", &l::COULOMB_FRICTION_NM)),
        ("BUS_VOLTAGE", range("drive.bus_voltage_v", &l::BUS_VOLTAGE_V)),
        ("PWM_FREQUENCY", range("drive.pwm_hz", &l::PWM_HZ)),
        ("CURRENT_LIMIT", range("drive.current_limit_a", &l::CURRENT_LIMIT_A)),
        (
            "HOLDING_CURRENT",
            format!("{} and at most drive.current_limit_a", range("drive.holding_current_a", &l::HOLDING_CURRENT_A)),
        ),
        (
            "CURRENT_LOOP_BANDWIDTH",
            format!(
                "{} and at most {k} x drive.pwm_hz",
                range("drive.current_loop_bandwidth_hz", &l::CURRENT_LOOP_BANDWIDTH_HZ)
            ),
        ),
        ("COMPUTATION_DELAY", range("drive.computation_delay_periods", &l::COMPUTATION_DELAY_PERIODS)),
        ("ENCODER_COUNTS", range("encoder_counts_per_rev", &l::COUNTS_PER_REV)),
        (
            "SERVO_VELOCITY_GAIN",
            "servo.velocity_nm_s_per_rad must be finite and >= 0 (and finite divided by motor.km_nm_per_a)".into(),
        ),
        (
            "SERVO_POSITION_GAIN",
            "servo.position_nm_per_rad must be finite and >= 0 (and finite divided by motor.km_nm_per_a)".into(),
        ),
        (
            "SERVO_INTEGRAL_GAIN",
            "servo.position_integral_nm_per_rad_s must be finite and >= 0 (and finite divided by motor.km_nm_per_a)"
                .into(),
        ),
        ("SERVO_VELOCITY_FILTER", range("servo.velocity_filter_hz", &l::VELOCITY_FILTER_HZ)),
        (
            "DETENT_AMPLITUDE",
            format!(
                "each detent amplitude must be in {}, and their sum below {} x motor.km_nm_per_a x \
                 drive.holding_current_a (the open loop's holding torque)",
                l::DETENT_AMPLITUDE_NM,
                Num(l::DETENT_PER_HOLDING_TORQUE)
            ),
        ),
        ("DETENT_PHASE", range("a detent phase", &l::DETENT_PHASE_RAD)),
        ("RIPPLE_AMPLITUDE", range("a current-ripple amplitude (N·m/A)", &l::CURRENT_RIPPLE_NM_PER_A)),
        ("RIPPLE_PHASE", range("a current-ripple phase", &l::CURRENT_RIPPLE_PHASE_RAD)),
    ];
    let mut out = String::from("// Written by build.rs from stepdamp_core::limits. Do not edit.\n");
    for (name, text) in &texts {
        assert!(!text.contains('\0'));
        writeln!(out, "/// `sd_status_str(SD_ERR_{name})`.\npub(crate) const {name}: &core::ffi::CStr = c{text:?};")
            .unwrap();
    }
    let dest = std::path::Path::new(&std::env::var("OUT_DIR").unwrap()).join("status_texts.rs");
    std::fs::write(dest, out).unwrap();
    println!("cargo::rerun-if-changed=build.rs");
}
