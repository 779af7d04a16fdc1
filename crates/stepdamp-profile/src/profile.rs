//! The validated profile and the quantities derived from it.

use crate::data::ProfileData;
use crate::error::ProfileError;
use serde::Serialize;
use stepdamp_core::{
    Compensation, Config, ConfigError, CorrectionTable, CurrentRipple, DriveSettings, Harmonic, Mode, MotorModel,
    Params, ServoGains, Topology,
};

/// The detent orders of a typical hybrid stepper (1.8°, 50 teeth): the 4th harmonic of the
/// electrical angle (the reluctance detent of two phases), the 2nd and the 1st (stator and
/// rotor asymmetries). Identification fits them by default; a profile without detent has
/// its resonances at these orders.
pub const TYPICAL_DETENT_ORDERS: [u16; 3] = [1, 2, 4];

/// The ripple model a profile gives the controller ([`Profile::controller_harmonics`]), in
/// the detent's convention (torque on the rotor `−A·sin(k·θe + φ)`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ControllerHarmonics {
    /// The detent, N·m.
    pub detent: Vec<Harmonic>,
    /// The ripple per ampere of `i_d`, N·m/A (empty without `[motor.flux]`).
    pub per_amp_d: Vec<Harmonic>,
    /// The ripple per ampere of `i_q` without its mean, N·m/A (empty without `[motor.flux]`).
    pub per_amp_q: Vec<Harmonic>,
}

impl ControllerHarmonics {
    /// The current parts as the core takes them.
    pub fn current_ripple(&self) -> CurrentRipple<'_> {
        CurrentRipple { per_amp_d: &self.per_amp_d, per_amp_q: &self.per_amp_q }
    }
}

/// A motor profile whose every key is within its physical range
/// ([`stepdamp_core::limits`]) and whose derived quantities (natural frequency, resonance
/// speeds, servo gains, the controller's configuration in every mode) are finite. Only
/// [`ProfileData::validate`] makes one, so whoever takes a `Profile` need not check it
/// again. Its keys are read through `Deref` (`p.motor.km_nm_per_a`); to change one, take
/// the data ([`Profile::to_data`]), edit it and validate again.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(transparent)]
pub struct Profile {
    data: ProfileData,
}

/// Deserialising validates: a profile read from JSON or TOML is checked like a file.
impl<'de> serde::Deserialize<'de> for Profile {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let data = ProfileData::deserialize(d)?;
        data.validate("serialised profile").map_err(serde::de::Error::custom)
    }
}

impl std::ops::Deref for Profile {
    type Target = ProfileData;
    fn deref(&self) -> &ProfileData {
        &self.data
    }
}

impl ProfileData {
    /// Checks every key against its range and every derived quantity for finiteness;
    /// `origin` (file path or preset name) names the profile in the error, which also
    /// names the key, the value as written and the allowed range.
    pub fn validate(self, origin: &str) -> Result<Profile, ProfileError> {
        crate::validate::check(&self, origin)?;
        let p = Profile { data: self };
        crate::validate::check_derived(&p, origin)?;
        Ok(p)
    }
}

impl Profile {
    /// The keys, to edit and validate again.
    pub fn to_data(&self) -> ProfileData {
        self.data.clone()
    }

    /// The keys.
    pub fn into_data(self) -> ProfileData {
        self.data
    }

    /// A copy with `edit` applied, validated again (`origin` names it in errors).
    pub fn edited(&self, origin: &str, edit: impl FnOnce(&mut ProfileData)) -> Result<Profile, ProfileError> {
        let mut d = self.to_data();
        edit(&mut d);
        d.validate(origin)
    }

    /// The profile as TOML text.
    pub fn to_toml_string(&self) -> String {
        toml::to_string_pretty(&self.data).expect("a profile always serialises")
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

    /// The orders whose resonance speeds matter: the profile's detent orders, highest first,
    /// or [`TYPICAL_DETENT_ORDERS`] when it lists no detent.
    pub fn resonance_orders(&self) -> Vec<u16> {
        let mut orders: Vec<u16> = self.motor.detent.iter().map(|h| h.order).collect();
        if orders.is_empty() {
            orders = TYPICAL_DETENT_ORDERS.to_vec();
        }
        orders.sort_unstable_by(|a, b| b.cmp(a));
        orders
    }

    /// Detent orders, largest amplitude first.
    pub fn detent_orders(&self) -> Vec<u16> {
        let mut d = self.motor.detent.clone();
        d.sort_by(|a, b| b.amplitude_nm.total_cmp(&a.amplitude_nm));
        d.iter().map(|h| h.order).collect()
    }

    /// The servo gains of patent eq. 15 from `[servo]` and the inertia
    /// ([`ServoGains::for_bandwidth`]).
    pub fn servo_gains(&self) -> ServoGains {
        ServoGains::for_bandwidth(
            self.motor.inertia_kg_m2 as f32,
            self.servo.bandwidth_hz as f32,
            self.servo.velocity_filter_hz as f32,
        )
    }

    /// The detent harmonics as the controller takes them (`f32`).
    pub fn harmonics(&self) -> Vec<Harmonic> {
        self.motor
            .detent
            .iter()
            .map(|h| Harmonic { order: h.order, amplitude_nm: h.amplitude_nm as f32, phase_rad: h.phase_rad as f32 })
            .collect()
    }

    /// The ripple model the controller is given (`f32`): the detent ([`Profile::harmonics`])
    /// and, from a `[motor.flux]` section, the ripple per ampere of `i_d` and of `i_q`
    /// ([`crate::ripple::ripple_parts`]; harmonics of zero amplitude left out). The core feeds
    /// it forward at the operating point of each law (open loop at `θ_cmd`: `(I_hold, 0)`;
    /// servo: `(0, i_q)` of its feedback; estimated angle: `(I_hold·cos δ̂, I_hold·sin δ̂)`;
    /// `stepdamp_core::ripple`, docs/design.md#real-motors-flux-harmonics). A profile
    /// without the section has empty current parts, and the controller runs the detent-only
    /// laws bit for bit.
    pub fn controller_harmonics(&self) -> ControllerHarmonics {
        let detent = self.harmonics();
        if self.motor.flux.is_default() {
            return ControllerHarmonics { detent, per_amp_d: Vec::new(), per_amp_q: Vec::new() };
        }
        let parts = crate::ripple::ripple_parts(self);
        let f32s = |h: &[crate::ripple::RippleHarmonic]| -> Vec<Harmonic> {
            h.iter()
                .filter(|h| h.amplitude_nm > 0.0)
                .map(|h| Harmonic {
                    order: h.order,
                    amplitude_nm: h.amplitude_nm as f32,
                    phase_rad: h.phase_rad as f32,
                })
                .collect()
        };
        ControllerHarmonics { detent, per_amp_d: f32s(&parts.per_amp_d), per_amp_q: f32s(&parts.per_amp_q) }
    }

    /// The controller's parameters for `mode` and `compensation`; `model` is
    /// [`Profile::controller_harmonics`] (borrowed by the result).
    pub fn params<'a>(&self, model: &'a ControllerHarmonics, mode: Mode, compensation: Compensation) -> Params<'a> {
        let (m, d) = (&self.motor, &self.drive);
        Params {
            motor: MotorModel {
                km_nm_per_a: m.km_nm_per_a as f32,
                pole_pairs: m.pole_pairs,
                resistance_ohm: m.resistance_ohm as f32,
                inductance_h: m.inductance_h as f32,
                coulomb_friction_nm: m.coulomb_friction_nm as f32,
                detent: &model.detent,
                current_ripple: model.current_ripple(),
            },
            drive: DriveSettings {
                bus_voltage_v: d.bus_voltage_v as f32,
                pwm_hz: d.pwm_hz as f32,
                holding_current_a: d.holding_current_a as f32,
                current_limit_a: d.current_limit_a as f32,
                current_loop_bandwidth_hz: d.current_loop_bandwidth_hz as f32,
                topology: Topology::from(d.topology),
                computation_delay_periods: d.computation_delay_periods,
            },
            encoder_counts_per_rev: self.encoder.counts_per_rev,
            servo: self.servo_gains(),
            mode,
            compensation,
        }
    }

    /// The controller's configuration for `mode` and `compensation`: the one mapping of a
    /// profile to the core's [`Config`]. `table` is the correction table that
    /// [`Compensation::Table`] replays ([`Config::with_table`]; other compensations ignore
    /// it); table compensation without one is a [`ConfigError`].
    pub fn controller_config(
        &self,
        mode: Mode,
        compensation: Compensation,
        table: Option<&CorrectionTable>,
    ) -> Result<Config, ConfigError> {
        let model = self.controller_harmonics();
        let params = self.params(&model, mode, compensation);
        match table {
            Some(t) => Config::with_table(&params, t),
            None => Config::new(&params),
        }
    }
}
