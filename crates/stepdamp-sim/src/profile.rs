//! Motor profiles: the TOML format of design.md §6, the built-in presets of §7, and
//! validation that names the file, the key and the reason.

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use stepdamp_core::{MAX_HARMONIC_ORDER, Topology};

/// A motor profile: motor, drive, encoder, and optional servo settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Profile {
    /// Name of the motor.
    pub name: String,
    /// Motor and load.
    pub motor: MotorSection,
    /// Power stage and current loop.
    pub drive: DriveSection,
    /// Encoder.
    pub encoder: EncoderSection,
    /// Servo-mode settings (defaults when absent).
    #[serde(default)]
    pub servo: ServoSection,
}

/// `[motor]`: SI units, the key names carry them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotorSection {
    /// Torque constant `Km` in N·m/A.
    pub km_nm_per_a: f64,
    /// Rotor teeth / pole pairs `Nr`.
    pub pole_pairs: u16,
    /// Phase resistance in Ω.
    pub resistance_ohm: f64,
    /// Phase inductance in H.
    pub inductance_h: f64,
    /// Rotor + load inertia in kg·m².
    pub inertia_kg_m2: f64,
    /// Viscous friction `D` in N·m·s/rad.
    pub viscous_nm_s_per_rad: f64,
    /// Coulomb friction `Fs` in N·m.
    pub coulomb_friction_nm: f64,
    /// Detent harmonics: torque on the rotor `−Σ A sin(k·Nr·θ + φ)`.
    #[serde(default)]
    pub detent: Vec<DetentTerm>,
}

/// One `[[motor.detent]]` entry.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DetentTerm {
    /// Harmonic order `k` of the electrical angle.
    pub order: u16,
    /// Amplitude `A_k` in N·m.
    pub amplitude_nm: f64,
    /// Phase `φ_k` in rad.
    pub phase_rad: f64,
}

/// `[drive]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveSection {
    /// DC bus voltage in V.
    pub bus_voltage_v: f64,
    /// PWM and control frequency in Hz.
    pub pwm_hz: f64,
    /// Open-loop holding current in A.
    pub holding_current_a: f64,
    /// Current vector limit in A.
    pub current_limit_a: f64,
    /// Closed current-loop bandwidth in Hz.
    pub current_loop_bandwidth_hz: f64,
    /// Power stage: `"three-leg"` (the patent's, default) or `"two-h-bridge"`.
    #[serde(default)]
    pub topology: TopologyName,
    /// Periods between sampling and the new duties taking effect: 1 (default; the drive
    /// loads the PWM for the next period) or 0 (computed within the period). A current
    /// loop faster than about pwm/12 needs 0: with a period of delay its phase margin
    /// drops below 45°.
    #[serde(default = "default_delay")]
    pub computation_delay_periods: u8,
}

fn default_delay() -> u8 {
    1
}

/// Power stage names in profiles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TopologyName {
    /// Three legs with a common leg (patent eqs. 10–13).
    #[default]
    ThreeLeg,
    /// Two H-bridges.
    TwoHBridge,
}

impl TopologyName {
    /// The name as written in profiles.
    pub fn as_str(self) -> &'static str {
        match self {
            TopologyName::ThreeLeg => "three-leg",
            TopologyName::TwoHBridge => "two-h-bridge",
        }
    }
}

impl From<Topology> for TopologyName {
    fn from(t: Topology) -> TopologyName {
        match t {
            Topology::ThreeLeg => TopologyName::ThreeLeg,
            Topology::TwoHBridge => TopologyName::TwoHBridge,
        }
    }
}

impl From<TopologyName> for Topology {
    fn from(t: TopologyName) -> Topology {
        match t {
            TopologyName::ThreeLeg => Topology::ThreeLeg,
            TopologyName::TwoHBridge => Topology::TwoHBridge,
        }
    }
}

/// `[encoder]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EncoderSection {
    /// Counts per mechanical revolution (quadrature edges).
    pub counts_per_rev: u32,
}

/// `[servo]` (optional): the position loop of patent eq. 15.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ServoSection {
    /// Natural frequency of the position loop in Hz (gains from it and the inertia,
    /// damping 0.7, integral corner a tenth of it).
    pub bandwidth_hz: f64,
    /// Corner of the encoder velocity low-pass filter in Hz.
    pub velocity_filter_hz: f64,
}

impl Default for ServoSection {
    fn default() -> Self {
        ServoSection { bandwidth_hz: 40.0, velocity_filter_hz: 250.0 }
    }
}

/// Why a profile could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Not valid TOML or not the profile's shape (unknown or missing key, wrong type).
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// The parser's message (names the key and the line).
        message: String,
    },
    /// A key holds a value that makes no physical sense.
    #[error("{path}: {key} = {value}: {reason}")]
    Invalid {
        /// The file (or preset name).
        path: String,
        /// The key, e.g. `motor.resistance_ohm`.
        key: String,
        /// The value given.
        value: String,
        /// What it must be.
        reason: String,
    },
    /// Neither a preset nor an existing file.
    #[error("unknown motor '{0}': not a preset ({presets}) nor a readable .toml file", presets = PRESETS.join(", "))]
    Unknown(String),
}

/// Names of the built-in presets (design.md §7).
pub const PRESETS: [&str; 4] = ["patent-motor", "nema17-17hs4401", "nema23-57mm", "nema34-86mm"];

const PATENT_MOTOR: &str = include_str!("../presets/patent-motor.toml");
const NEMA17: &str = include_str!("../presets/nema17-17hs4401.toml");
const NEMA23: &str = include_str!("../presets/nema23-57mm.toml");
const NEMA34: &str = include_str!("../presets/nema34-86mm.toml");

impl Profile {
    /// A built-in preset by name.
    pub fn preset(name: &str) -> Option<Profile> {
        let text = match name {
            "patent-motor" => PATENT_MOTOR,
            "nema17-17hs4401" => NEMA17,
            "nema23-57mm" => NEMA23,
            "nema34-86mm" => NEMA34,
            _ => return None,
        };
        Some(Profile::from_toml_str(text, name).expect("built-in presets are valid (tested)"))
    }

    /// A preset name or the path of a TOML profile.
    pub fn load(name_or_path: &str) -> Result<Profile, ProfileError> {
        if let Some(p) = Profile::preset(name_or_path) {
            return Ok(p);
        }
        let path = Path::new(name_or_path);
        if !path.exists() {
            return Err(ProfileError::Unknown(name_or_path.to_string()));
        }
        Profile::from_file(path)
    }

    /// Reads and validates a TOML profile.
    pub fn from_file(path: &Path) -> Result<Profile, ProfileError> {
        let text =
            std::fs::read_to_string(path).map_err(|source| ProfileError::Read { path: path.to_path_buf(), source })?;
        Profile::from_toml_str(&text, &path.display().to_string())
    }

    /// Parses and validates TOML text; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Profile, ProfileError> {
        let p: Profile = toml::from_str(text)
            .map_err(|e| ProfileError::Parse { path: origin.to_string(), message: one_line(&e.to_string()) })?;
        p.validate(origin)?;
        Ok(p)
    }

    /// The profile as TOML text.
    pub fn to_toml_string(&self) -> String {
        toml::to_string_pretty(self).expect("a profile always serialises")
    }

    /// Checks every value; the error names the key and the reason.
    pub fn validate(&self, origin: &str) -> Result<(), ProfileError> {
        let bad = |key: &str, value: String, reason: &str| ProfileError::Invalid {
            path: origin.to_string(),
            key: key.to_string(),
            value,
            reason: reason.to_string(),
        };
        let pos = |key: &str, v: f64| {
            if v.is_finite() && v > 0.0 { Ok(()) } else { Err(bad(key, v.to_string(), "must be a finite number > 0")) }
        };
        let nonneg = |key: &str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(bad(key, v.to_string(), "must be a finite number ≥ 0"))
            }
        };
        if self.name.trim().is_empty() {
            return Err(bad("name", format!("{:?}", self.name), "must not be empty"));
        }
        let m = &self.motor;
        pos("motor.km_nm_per_a", m.km_nm_per_a)?;
        if m.pole_pairs == 0 || m.pole_pairs > 1024 {
            return Err(bad("motor.pole_pairs", m.pole_pairs.to_string(), "must be in 1..=1024"));
        }
        pos("motor.resistance_ohm", m.resistance_ohm)?;
        pos("motor.inductance_h", m.inductance_h)?;
        pos("motor.inertia_kg_m2", m.inertia_kg_m2)?;
        nonneg("motor.viscous_nm_s_per_rad", m.viscous_nm_s_per_rad)?;
        nonneg("motor.coulomb_friction_nm", m.coulomb_friction_nm)?;
        for (i, h) in m.detent.iter().enumerate() {
            let key = |f: &str| format!("motor.detent[{i}].{f}");
            if h.order == 0 || usize::from(h.order) > MAX_HARMONIC_ORDER {
                return Err(bad(&key("order"), h.order.to_string(), &format!("must be in 1..={MAX_HARMONIC_ORDER}")));
            }
            if m.detent[..i].iter().any(|o| o.order == h.order) {
                return Err(bad(&key("order"), h.order.to_string(), "this order is listed twice"));
            }
            nonneg(&key("amplitude_nm"), h.amplitude_nm)?;
            if !h.phase_rad.is_finite() {
                return Err(bad(&key("phase_rad"), h.phase_rad.to_string(), "must be a finite number"));
            }
        }
        let d = &self.drive;
        pos("drive.bus_voltage_v", d.bus_voltage_v)?;
        pos("drive.pwm_hz", d.pwm_hz)?;
        if d.pwm_hz > 0.0 && !(1_000.0..=200_000.0).contains(&d.pwm_hz) {
            return Err(bad("drive.pwm_hz", d.pwm_hz.to_string(), "must be in 1000..=200000"));
        }
        nonneg("drive.holding_current_a", d.holding_current_a)?;
        pos("drive.current_limit_a", d.current_limit_a)?;
        if d.holding_current_a > d.current_limit_a {
            return Err(bad(
                "drive.holding_current_a",
                d.holding_current_a.to_string(),
                "must not exceed drive.current_limit_a",
            ));
        }
        pos("drive.current_loop_bandwidth_hz", d.current_loop_bandwidth_hz)?;
        if d.computation_delay_periods > 1 {
            return Err(bad(
                "drive.computation_delay_periods",
                d.computation_delay_periods.to_string(),
                "must be 0 or 1",
            ));
        }
        if d.current_loop_bandwidth_hz > d.pwm_hz / 4.0 {
            return Err(bad(
                "drive.current_loop_bandwidth_hz",
                d.current_loop_bandwidth_hz.to_string(),
                "must be below a quarter of drive.pwm_hz",
            ));
        }
        if self.encoder.counts_per_rev == 0 || self.encoder.counts_per_rev > 1 << 20 {
            return Err(bad(
                "encoder.counts_per_rev",
                self.encoder.counts_per_rev.to_string(),
                "must be in 1..=1048576",
            ));
        }
        pos("servo.bandwidth_hz", self.servo.bandwidth_hz)?;
        pos("servo.velocity_filter_hz", self.servo.velocity_filter_hz)?;
        Ok(())
    }

    /// Holding stiffness `K = Nr·Km·I_hold` in N·m/rad.
    pub fn holding_stiffness_nm_per_rad(&self) -> f64 {
        f64::from(self.motor.pole_pairs) * self.motor.km_nm_per_a * self.drive.holding_current_a
    }

    /// Small-signal natural frequency `ω_n = sqrt(K/J)` in rad/s.
    pub fn natural_frequency_rad_s(&self) -> f64 {
        (self.holding_stiffness_nm_per_rad() / self.motor.inertia_kg_m2).sqrt()
    }

    /// Resonance speed of harmonic order `k`: `Ω_k = ω_n / (k·Nr)` in rad/s.
    pub fn resonance_speed_rad_s(&self, order: u16) -> f64 {
        self.natural_frequency_rad_s() / (f64::from(order) * f64::from(self.motor.pole_pairs))
    }

    /// Damping ratio of the open-loop rotor from viscous friction: `D / (2 J ω_n)`.
    pub fn damping_ratio(&self) -> f64 {
        self.motor.viscous_nm_s_per_rad / (2.0 * self.motor.inertia_kg_m2 * self.natural_frequency_rad_s())
    }

    /// Detent orders, largest amplitude first.
    pub fn detent_orders(&self) -> Vec<u16> {
        let mut d = self.motor.detent.clone();
        d.sort_by(|a, b| b.amplitude_nm.total_cmp(&a.amplitude_nm));
        d.iter().map(|h| h.order).collect()
    }
}

/// A parser message on one line: toml's "TOML parse error at line L, column C", its
/// source excerpt (`L | text`, caret lines dropped) and the reason become
/// "TOML parse error at line L, column C (`text`): reason".
fn one_line(s: &str) -> String {
    let mut head = Vec::new();
    let mut source = Vec::new();
    let mut rest = Vec::new();
    for line in s.lines().map(str::trim).filter(|l| !l.is_empty()) {
        match line.split_once('|') {
            Some((n, text)) if n.trim().chars().all(|c| c.is_ascii_digit()) => {
                let text = text.trim();
                // `|` alone and `| ^^^` carets carry no words.
                if !n.trim().is_empty() && !text.is_empty() {
                    source.push(format!("`{text}`"));
                }
            }
            _ if head.is_empty() && rest.is_empty() && line.starts_with("TOML parse error") => head.push(line),
            _ => rest.push(line),
        }
    }
    let mut out = head.join(" ");
    if !source.is_empty() {
        out += &format!(" ({})", source.join(" "));
    }
    if !rest.is_empty() {
        if !out.is_empty() {
            out += ": ";
        }
        out += &rest.join(" ");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn bad_values_are_rejected_with_file_key_and_reason() {
        let e = with(|s| *s = s.replace("resistance_ohm = 0.9", "resistance_ohm = -0.9")).unwrap_err().to_string();
        assert!(e.contains("m.toml") && e.contains("motor.resistance_ohm") && e.contains("> 0"), "{e}");
        let e = with(|s| *s = s.replace("inertia_kg_m2 = 4.0e-5", "inertia_kg_m2 = 0.0")).unwrap_err().to_string();
        assert!(e.contains("motor.inertia_kg_m2"), "{e}");
        let e = with(|s| *s = s.replace("inductance_h = 2.5e-3", "inductance_h = nan")).unwrap_err().to_string();
        assert!(e.contains("motor.inductance_h"), "{e}");
        let e = with(|s| *s = s.replace("order = 2", "order = 4")).unwrap_err().to_string();
        assert!(e.contains("motor.detent[1].order") && e.contains("twice"), "{e}");
    }

    #[test]
    fn unknown_and_missing_keys_are_rejected_by_name() {
        let e = with(|s| *s = s.replace("pole_pairs = 50", "pole_pairs = 50\nteeth = 3")).unwrap_err().to_string();
        assert!(e.contains("m.toml") && e.contains("teeth"), "{e}");
        let e = with(|s| *s = s.replace("km_nm_per_a = 0.3\n", "")).unwrap_err().to_string();
        assert!(e.contains("km_nm_per_a"), "{e}");
        let e = with(|s| *s = s.replace("counts_per_rev = 4000", "counts_per_rev = \"many\"")).unwrap_err().to_string();
        assert!(e.contains("counts_per_rev"), "{e}");
    }

    #[test]
    fn bad_toml_syntax_names_the_file_and_the_line_on_one_line() {
        let e = with(|s| *s = s.replace("[drive]", "[drive")).unwrap_err().to_string();
        assert!(e.starts_with("m.toml: TOML parse error at line ") && !e.contains('\n'), "{e}");
        assert!(e.contains("`[drive`") && !e.contains('^'), "{e}");
    }

    #[test]
    fn unknown_preset_lists_the_presets() {
        let e = Profile::load("no-such-motor").unwrap_err().to_string();
        assert!(e.contains("no-such-motor") && e.contains("patent-motor"), "{e}");
    }
}
