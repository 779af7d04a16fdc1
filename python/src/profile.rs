//! `stepdamp.Profile`: a motor profile (the TOML format of the CLI), attributes named
//! with their units.

use crate::err;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use stepdamp_sim::Profile;
use stepdamp_sim::profile::{DetentTerm, ProfileData, TopologyName};

/// A motor profile: motor, drive, encoder and servo settings (SI units; attribute names
/// carry them). `Profile.preset(name)`, `Profile.load(path)`, `Profile.from_toml(text)`;
/// `.to_toml()` writes the CLI's format. Setting an attribute validates the whole profile.
#[pyclass(name = "Profile", module = "stepdamp._native", eq)]
#[derive(Clone, PartialEq)]
pub struct PyProfile {
    /// The Rust profile.
    pub inner: Profile,
}

impl PyProfile {
    /// Applies `f` to a copy of the keys and validates it again (the profile's name names
    /// it in errors); on error the profile is unchanged.
    fn set(&mut self, f: impl FnOnce(&mut ProfileData)) -> PyResult<()> {
        let origin = self.inner.name.clone();
        self.inner = self.inner.edited(&origin, f).map_err(err)?;
        Ok(())
    }
}

macro_rules! attributes {
    ($( $get:ident / $set:ident : $ty:ty = $($path:ident).+ , $doc:literal ;)*) => {
        #[pymethods]
        impl PyProfile {
            $(
                #[doc = $doc]
                #[getter]
                fn $get(&self) -> $ty {
                    self.inner.$($path).+
                }
                #[setter]
                fn $set(&mut self, value: $ty) -> PyResult<()> {
                    self.set(|p| p.$($path).+ = value)
                }
            )*
        }
    };
}

attributes! {
    km_nm_per_a / set_km_nm_per_a: f64 = motor.km_nm_per_a, "Torque constant Km, N·m/A.";
    pole_pairs / set_pole_pairs: u16 = motor.pole_pairs, "Rotor teeth / pole pairs Nr.";
    resistance_ohm / set_resistance_ohm: f64 = motor.resistance_ohm, "Phase resistance R, Ω.";
    inductance_h / set_inductance_h: f64 = motor.inductance_h, "Phase inductance L, H.";
    inertia_kg_m2 / set_inertia_kg_m2: f64 = motor.inertia_kg_m2, "Rotor + load inertia J, kg·m².";
    viscous_nm_s_per_rad / set_viscous_nm_s_per_rad: f64 = motor.viscous_nm_s_per_rad, "Viscous friction D, N·m·s/rad.";
    coulomb_friction_nm / set_coulomb_friction_nm: f64 = motor.coulomb_friction_nm, "Coulomb friction Fs, N·m.";
    bus_voltage_v / set_bus_voltage_v: f64 = drive.bus_voltage_v, "DC bus voltage, V.";
    pwm_hz / set_pwm_hz: f64 = drive.pwm_hz, "PWM and control frequency, Hz.";
    holding_current_a / set_holding_current_a: f64 = drive.holding_current_a, "Open-loop holding current, A.";
    current_limit_a / set_current_limit_a: f64 = drive.current_limit_a, "Current vector limit, A.";
    current_loop_bandwidth_hz / set_current_loop_bandwidth_hz: f64 = drive.current_loop_bandwidth_hz, "Closed current-loop bandwidth, Hz.";
    computation_delay_periods / set_computation_delay_periods: u8 = drive.computation_delay_periods, "Periods between sampling and the new duties taking effect (0 or 1).";
    counts_per_rev / set_counts_per_rev: u32 = encoder.counts_per_rev, "Encoder counts per mechanical revolution (quadrature edges).";
    servo_bandwidth_hz / set_servo_bandwidth_hz: f64 = servo.bandwidth_hz, "Servo position-loop natural frequency, Hz.";
    servo_velocity_filter_hz / set_servo_velocity_filter_hz: f64 = servo.velocity_filter_hz, "Corner of the encoder velocity low-pass filter, Hz.";
}

#[pymethods]
impl PyProfile {
    /// The ripple at rotor-frame currents `i_d_a`, `i_q_a` (A) as the JSON of the CLI's
    /// `motor ripple --format json` (the library's `stepdamp_profile::Ripple`); the Python
    /// package's `Profile.ripple` parses it.
    fn ripple_json(&self, i_d_a: f64, i_q_a: f64) -> PyResult<String> {
        let r = stepdamp_sim::profile::ripple(&self.inner, i_d_a, i_q_a).map_err(err)?;
        serde_json::to_string(&r).map_err(err)
    }

    /// A built-in preset by name (`stepdamp.PRESETS`).
    #[staticmethod]
    fn preset(name: &str) -> PyResult<Self> {
        Profile::preset(name)
            .map(|inner| PyProfile { inner })
            .ok_or_else(|| err(stepdamp_sim::ProfileError::Unknown { name: name.to_string(), file_exists: false }))
    }

    /// Reads and validates a TOML profile file, or a preset name, as the CLI's `--motor`: a
    /// name with a `/` or ending in `.toml` is a file, a bare name a preset.
    #[staticmethod]
    fn load(path: std::path::PathBuf) -> PyResult<Self> {
        let s = path.to_string_lossy().into_owned();
        Profile::load(&s).map(|inner| PyProfile { inner }).map_err(err)
    }

    /// Parses and validates TOML text; `origin` names it in errors.
    #[staticmethod]
    #[pyo3(signature = (text, origin = "<string>"))]
    fn from_toml(text: &str, origin: &str) -> PyResult<Self> {
        Profile::from_toml_str(text, origin).map(|inner| PyProfile { inner }).map_err(err)
    }

    /// The profile as TOML text (the CLI's format).
    fn to_toml(&self) -> String {
        self.inner.to_toml_string()
    }

    /// Name of the motor.
    #[getter]
    fn name(&self) -> String {
        self.inner.name.clone()
    }

    #[setter]
    fn set_name(&mut self, name: String) -> PyResult<()> {
        self.set(|p| p.name = name)
    }

    /// Power stage: `"three-leg"` or `"two-h-bridge"`.
    #[getter]
    fn topology(&self) -> &'static str {
        self.inner.drive.topology.as_str()
    }

    #[setter]
    fn set_topology(&mut self, name: &str) -> PyResult<()> {
        let t = match name {
            "three-leg" => TopologyName::ThreeLeg,
            "two-h-bridge" => TopologyName::TwoHBridge,
            _ => return Err(err(format!("topology '{name}': expected three-leg or two-h-bridge"))),
        };
        self.set(|p| p.drive.topology = t)
    }

    /// Detent harmonics: a list of dicts `{order, amplitude_nm, phase_rad}` (torque on the
    /// rotor `−Σ A sin(k·Nr·θ + φ)`). Assign a new list to change them.
    #[getter]
    fn detent<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let out = PyList::empty(py);
        for h in &self.inner.motor.detent {
            let d = PyDict::new(py);
            d.set_item("order", h.order)?;
            d.set_item("amplitude_nm", h.amplitude_nm)?;
            d.set_item("phase_rad", h.phase_rad)?;
            out.append(d)?;
        }
        Ok(out)
    }

    #[setter]
    fn set_detent(&mut self, terms: Vec<Bound<'_, PyDict>>) -> PyResult<()> {
        let mut detent = Vec::new();
        for d in terms {
            let get = |k: &str| -> PyResult<Bound<'_, PyAny>> {
                d.get_item(k)?.ok_or_else(|| err(format!("detent term: missing key '{k}'")))
            };
            detent.push(DetentTerm {
                order: get("order")?.extract()?,
                amplitude_nm: get("amplitude_nm")?.extract()?,
                phase_rad: get("phase_rad")?.extract()?,
            });
        }
        self.set(|p| p.motor.detent = detent)
    }

    /// Holding stiffness `Nr·Km·I_hold`, N·m/rad.
    fn holding_stiffness_nm_per_rad(&self) -> f64 {
        self.inner.holding_stiffness_nm_per_rad()
    }

    /// Small-signal natural frequency `ω_n = sqrt(K/J)`, rad/s.
    fn natural_frequency_rad_s(&self) -> f64 {
        self.inner.natural_frequency_rad_s()
    }

    /// Resonance speed of detent order `k`: `ω_n/(k·Nr)`, rad/s.
    fn resonance_speed_rad_s(&self, order: u16) -> f64 {
        self.inner.resonance_speed_rad_s(order)
    }

    /// Damping ratio `D/(2·J·ω_n)` of the open-loop rotor.
    fn damping_ratio(&self) -> f64 {
        self.inner.damping_ratio()
    }

    /// A copy.
    fn copy(&self) -> Self {
        self.clone()
    }

    fn __copy__(&self) -> Self {
        self.clone()
    }

    fn __deepcopy__(&self, _memo: Bound<'_, PyAny>) -> Self {
        self.clone()
    }

    /// Pickles through the TOML text (so profiles travel to Dask workers).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(Bound<'py, PyAny>, (String, String))> {
        let from_toml = slf.get_type().getattr("from_toml")?;
        let me = slf.borrow();
        Ok((from_toml, (me.inner.to_toml_string(), me.inner.name.clone())))
    }

    fn __repr__(&self) -> String {
        let m = &self.inner.motor;
        format!(
            "Profile('{}': R {} Ω, L {} H, Km {} N·m/A, J {} kg·m², Nr {}, {} detent terms)",
            self.inner.name,
            m.resistance_ohm,
            m.inductance_h,
            m.km_nm_per_a,
            m.inertia_kg_m2,
            m.pole_pairs,
            m.detent.len()
        )
    }
}
