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
    /// `[motor.friction]` (optional): the law of the Coulomb part, Karnopp when absent.
    /// Simulator only: the controller's model is `coulomb_friction_nm`.
    #[serde(default, skip_serializing_if = "FrictionSection::is_default")]
    pub friction: FrictionSection,
    /// `[motor.flux]` (optional): the magnet flux linkage's harmonics and the phases'
    /// imbalance ([`crate::flux`]); a pure sine and equal phases when absent.
    #[serde(default, skip_serializing_if = "crate::flux::FluxSection::is_default")]
    pub flux: crate::flux::FluxSection,
}

/// `[motor.friction]`: which law the simulated plant's Coulomb friction `Fs`
/// (`motor.coulomb_friction_nm`) follows, and its extra parameters.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionSection {
    /// The law (default `"karnopp"`).
    #[serde(default)]
    pub law: FrictionLawName,
    /// Creep speed `ω_ε` in rad/s of the smooth sign `tanh(ω/ω_ε)` (smooth and stribeck).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub creep_speed_rad_s: Option<f64>,
    /// Break-away torque `Fs_static` in N·m (stribeck).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub static_nm: Option<f64>,
    /// Stribeck speed `ω_s` in rad/s over which the torque falls from `Fs_static` to `Fs`
    /// (stribeck).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stribeck_speed_rad_s: Option<f64>,
}

impl FrictionSection {
    /// Today's Karnopp friction with no other key (not written out).
    pub fn is_default(&self) -> bool {
        *self == FrictionSection::default()
    }
}

/// Friction law names in profiles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FrictionLawName {
    /// `Fs·sgn(ω)` when moving, sticking at rest while the other torques stay within `Fs`.
    #[default]
    Karnopp,
    /// `Fs·tanh(ω/ω_ε)`: no sticking, the rotor creeps below `Fs`.
    Smooth,
    /// `(Fs + (Fs_static − Fs)·exp(−(ω/ω_s)²))·tanh(ω/ω_ε)`.
    Stribeck,
}

impl FrictionLawName {
    /// The name as written in profiles.
    pub fn as_str(self) -> &'static str {
        match self {
            FrictionLawName::Karnopp => "karnopp",
            FrictionLawName::Smooth => "smooth",
            FrictionLawName::Stribeck => "stribeck",
        }
    }
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn is_zero2(v: &[f64; 2]) -> bool {
    *v == [0.0, 0.0]
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
    /// Current-sensor offsets of phases A and B in A (simulator only: what the drive reads
    /// is `(1 + gain error)·i + offset`); default `[0, 0]`.
    #[serde(default, skip_serializing_if = "is_zero2")]
    pub current_offset_a: [f64; 2],
    /// Current-sensor gain errors of phases A and B (the gain is `1 + ε`; simulator only);
    /// default `[0, 0]`.
    #[serde(default, skip_serializing_if = "is_zero2")]
    pub current_gain_error: [f64; 2],
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
    /// Code-disc eccentricity in rad (simulator only): the encoder reads
    /// `θ + e·sin(θ + φ_e)`, a once-per-revolution angle error; default 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub eccentricity_rad: f64,
    /// Phase `φ_e` of the eccentricity in rad; default 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub eccentricity_phase_rad: f64,
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

/// Ranges of the simulator-only keys (the plant's friction law and sensor errors; the
/// controller never reads them, so they live here and not in [`stepdamp_core::limits`]).
pub mod sim_limits {
    use stepdamp_core::limits::Limit;

    /// `motor.friction.creep_speed_rad_s`: a creep speed above 10 rad/s is no longer
    /// friction but a viscous law.
    pub const CREEP_SPEED_RAD_S: Limit = Limit {
        key: "motor.friction.creep_speed_rad_s",
        min: 0.0,
        min_exclusive: true,
        max: 10.0,
        unit: "rad/s",
        why: "above 10 rad/s the smooth sign is a viscous law, not friction",
    };
    /// `motor.friction.stribeck_speed_rad_s`.
    pub const STRIBECK_SPEED_RAD_S: Limit = Limit {
        key: "motor.friction.stribeck_speed_rad_s",
        min: 0.0,
        min_exclusive: true,
        max: 10.0,
        unit: "rad/s",
        why: "the Stribeck dip of lubricated contacts ends well below 10 rad/s",
    };
    /// `motor.friction.static_nm` as a multiple of `motor.coulomb_friction_nm`: `[1, 10]`.
    pub const STATIC_PER_COULOMB: Limit = Limit {
        key: "motor.friction.static_nm",
        min: 1.0,
        min_exclusive: false,
        max: 10.0,
        unit: "× motor.coulomb_friction_nm",
        why: "break-away friction is at least the sliding level and rarely twice it",
    };
    /// Each of `drive.current_offset_a` is within `±drive.current_limit_a` divided by this
    /// (10 %: a sensor further off than that fails the drive's own offset calibration).
    pub const CURRENT_LIMIT_PER_OFFSET: f64 = 10.0;
    /// Each of `drive.current_gain_error`.
    pub const CURRENT_GAIN_ERROR: Limit = Limit {
        key: "drive.current_gain_error",
        min: -0.2,
        min_exclusive: false,
        max: 0.2,
        unit: "",
        why: "a current sensor more than 20 % off is broken, not mismatched",
    };
    /// `encoder.eccentricity_rad` (0.01 rad is 6 counts of 4000).
    pub const ECCENTRICITY_RAD: Limit = Limit {
        key: "encoder.eccentricity_rad",
        min: 0.0,
        min_exclusive: false,
        max: 0.01,
        unit: "rad",
        why: "a disc off-centre by 1 % of its code radius",
    };
    /// `encoder.eccentricity_phase_rad`.
    pub const ECCENTRICITY_PHASE_RAD: Limit = Limit {
        key: "encoder.eccentricity_phase_rad",
        min: -std::f64::consts::PI,
        min_exclusive: false,
        max: std::f64::consts::PI,
        unit: "rad",
        why: "an angle",
    };
}
