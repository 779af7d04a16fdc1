//! The identified-ripple TOML (docs/files.md#identified-ripple-toml): a [`RippleFit`] with the
//! motor, axis and run current it was identified at, as `stepdamp identify --accel` writes it
//! and the Python binding returns it. Not a motor profile.

use super::{Interval95, RippleFit};
use serde::Serialize;

/// The file's comment lines, before the keys.
const HEADER: &str = "# stepdamp identify --accel: the head and the motor's ripple at one run current, per direction\n\
                      # (docs/files.md#identified-ripple-toml). Not a motor profile.\n";

/// The identified-ripple file: keys and order as docs/files.md#identified-ripple-toml lists
/// them. Intervals are `[low, high]` pairs (95 %); units are in the key names.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RippleFile {
    motor: String,
    axis: String,
    current_peak_a: f64,
    captures: usize,
    blocks: usize,
    explained_share: f64,
    head: HeadSection,
    ripple: Vec<RippleRow>,
    not_identified: Vec<MissingRow>,
}

/// `[head]`: the identified head.
#[derive(Debug, Clone, PartialEq, Serialize)]
struct HeadSection {
    pulley_radius_m: f64,
    total_inertia_kg_m2: f64,
    total_inertia_95_kg_m2: [f64; 2],
    carriage_mass_kg: f64,
    carriage_mass_95_kg: [f64; 2],
    belt_hz: f64,
    belt_95_hz: [f64; 2],
    belt_damping_ratio: f64,
    belt_damping_ratio_95: [f64; 2],
    belt_stiffness_n_per_m: f64,
    rotor_damping_nm_s_per_rad: f64,
    rotor_damping_95_nm_s_per_rad: [f64; 2],
    shift_delay_s: f64,
    shift_delay_95_s: [f64; 2],
    sensor_gain: f64,
    sensor_sign_fitted: bool,
}

/// `[[ripple]]`: one identified harmonic of one direction.
#[derive(Debug, Clone, PartialEq, Serialize)]
struct RippleRow {
    direction: &'static str,
    order: u32,
    amplitude_nm: f64,
    amplitude_95_nm: [f64; 2],
    phase_rad: f64,
    phase_95_rad: [f64; 2],
    radius95_nm: f64,
    blocks: usize,
    speeds_rev_s: [f64; 2],
    explained_share: f64,
}

/// `[[not_identified]]`: a harmonic left out, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
struct MissingRow {
    direction: &'static str,
    order: u32,
    reason: String,
}

fn pair(i: Interval95) -> [f64; 2] {
    [i.low, i.high]
}

impl RippleFile {
    /// The file of fit `f` of the motor named `motor` (the profile's name), on `axis` (`X` or
    /// `Y`), at `current_peak_a` (A, the current vector's peak).
    pub fn new(f: &RippleFit, motor: &str, axis: char, current_peak_a: f64) -> Self {
        let h = &f.head;
        RippleFile {
            motor: motor.into(),
            axis: axis.to_string(),
            current_peak_a,
            captures: f.captures,
            blocks: f.blocks,
            explained_share: f.explained_share,
            head: HeadSection {
                pulley_radius_m: f.axis.pulley_radius_m,
                total_inertia_kg_m2: h.total_inertia_kg_m2.value,
                total_inertia_95_kg_m2: pair(h.total_inertia_kg_m2),
                carriage_mass_kg: h.carriage_mass_kg.value,
                carriage_mass_95_kg: pair(h.carriage_mass_kg),
                belt_hz: h.belt_hz.value,
                belt_95_hz: pair(h.belt_hz),
                belt_damping_ratio: h.belt_damping_ratio.value,
                belt_damping_ratio_95: pair(h.belt_damping_ratio),
                belt_stiffness_n_per_m: h.belt_stiffness_n_per_m,
                rotor_damping_nm_s_per_rad: h.rotor_damping_nm_s_per_rad.value,
                rotor_damping_95_nm_s_per_rad: pair(h.rotor_damping_nm_s_per_rad),
                shift_delay_s: h.shift_delay_s.value,
                shift_delay_95_s: pair(h.shift_delay_s),
                sensor_gain: f.sensor_gain,
                sensor_sign_fitted: f.sensor_sign_fitted,
            },
            ripple: f
                .harmonics
                .iter()
                .map(|x| RippleRow {
                    direction: x.direction.name(),
                    order: x.order,
                    amplitude_nm: x.amplitude_nm.value,
                    amplitude_95_nm: pair(x.amplitude_nm),
                    phase_rad: x.phase_rad.value,
                    phase_95_rad: pair(x.phase_rad),
                    radius95_nm: x.radius95_nm,
                    blocks: x.blocks,
                    speeds_rev_s: [x.speeds_rev_s.0, x.speeds_rev_s.1],
                    explained_share: x.explained_share,
                })
                .collect(),
            not_identified: f
                .not_identified
                .iter()
                .map(|x| MissingRow { direction: x.direction.name(), order: x.order, reason: x.reason.clone() })
                .collect(),
        }
    }

    /// The file's text: the comment lines, then the keys.
    pub fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        Ok(format!("{HEADER}{}", toml::to_string(self)?))
    }
}
