//! The profile as written in TOML: every key, unchecked. [`ProfileData::validate`] turns it
//! into a [`crate::Profile`].

use serde::{Deserialize, Serialize};
use stepdamp_core::Topology;

/// A motor profile as read, not yet checked: motor, drive, encoder, and optional servo
/// settings. The ranges of every key are in [`stepdamp_core::limits`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProfileData {
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
