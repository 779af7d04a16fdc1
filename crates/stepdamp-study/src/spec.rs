//! The study specification (TOML) and its validation.
//!
//! ```toml
//! motor = "patent-motor"      # preset or profile file (relative to the spec file)
//! variants = 1000
//! seed = 1
//! controller = "nominal"      # the controller's model: "nominal" (the profile above) or "plant"
//!
//! [sweep]                     # what each variant runs (all optional)
//! modes = ["open-loop"]
//! compensations = ["off", "patent", "estimated"]
//! orders = [4, 2, 1]          # resonances to measure (default: the profile's detent orders)
//! points = 3                  # speeds per resonance, evenly over ±span around it
//! span = 0.1                  # relative half-width of that window
//! duration_s = 1.0
//!
//! [plant]                     # distributions of the simulated motor's parameters
//! resistance_ohm = { scale = [0.9, 1.1] }
//! inertia_kg_m2 = { scale = [0.8, 1.5] }
//! detent_amplitude_nm = { scale = [0.8, 1.2] }   # each harmonic drawn on its own
//! detent_phase_rad = { add = [-0.2, 0.2] }
//! load_torque_nm = { uniform = [0.0, 0.01] }
//!
//! [controller_error]          # identification error of the controller's model, on top
//! detent_amplitude_nm = { scale = [0.95, 1.05] }
//! ```

use serde::{Deserialize, Serialize};
use std::path::Path;
use stepdamp_core::Mode;
use stepdamp_core::limits::Num;
use stepdamp_sim::options::MAX_SUBSTEPS;
use stepdamp_sim::{Compensation, Profile, check_substeps};

/// A distribution of one parameter. Uniform draws; `scale` multiplies the nominal value,
/// `add` adds to it, `uniform` replaces it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Dist {
    /// Nominal × U(lo, hi) (0 < lo ≤ hi).
    Scale([f64; 2]),
    /// Nominal + U(lo, hi) (lo ≤ hi), in the parameter's unit.
    Add([f64; 2]),
    /// U(lo, hi) (lo ≤ hi), in the parameter's unit, whatever the nominal value.
    Uniform([f64; 2]),
}

impl Dist {
    /// The value for nominal `x` and a uniform draw `u` in `[0, 1)`.
    pub fn apply(&self, x: f64, u: f64) -> f64 {
        let lerp = |[lo, hi]: [f64; 2]| lo + (hi - lo) * u;
        match *self {
            Dist::Scale(r) => x * lerp(r),
            Dist::Add(r) => x + lerp(r),
            Dist::Uniform(r) => lerp(r),
        }
    }

    fn check(&self, key: &str) -> Result<(), String> {
        let (name, [lo, hi]) = match *self {
            Dist::Scale(r) => ("scale", r),
            Dist::Add(r) => ("add", r),
            Dist::Uniform(r) => ("uniform", r),
        };
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return Err(format!(
                "{key} = {{ {name} = [{}, {}] }}: the bounds must be finite with lo ≤ hi",
                Num(lo),
                Num(hi)
            ));
        }
        if name == "scale" && lo <= 0.0 {
            return Err(format!("{key} = {{ scale = [{}, {}] }}: a scale factor must be > 0", Num(lo), Num(hi)));
        }
        Ok(())
    }
}

/// Distributions of the parameters a study varies (absent = held at the nominal value).
/// Keys are the profile's `[motor]` keys; `detent_*` apply to every harmonic, each drawn
/// on its own.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Variation {
    /// Phase resistance `R`, Ω.
    pub resistance_ohm: Option<Dist>,
    /// Phase inductance `L`, H.
    pub inductance_h: Option<Dist>,
    /// Torque constant `Km`, N·m/A.
    pub km_nm_per_a: Option<Dist>,
    /// Rotor + load inertia `J`, kg·m².
    pub inertia_kg_m2: Option<Dist>,
    /// Coulomb friction `Fs`, N·m.
    pub coulomb_friction_nm: Option<Dist>,
    /// Viscous friction `D`, N·m·s/rad.
    pub viscous_nm_s_per_rad: Option<Dist>,
    /// Each detent amplitude `A_k`, N·m.
    pub detent_amplitude_nm: Option<Dist>,
    /// Each detent phase `φ_k`, rad.
    pub detent_phase_rad: Option<Dist>,
    /// Constant load torque opposing the motion, N·m (plant only; nominal 0).
    pub load_torque_nm: Option<Dist>,
}

impl Variation {
    /// The distributions in draw order, with their keys (this order fixes what each
    /// variant's random numbers mean: never reorder).
    pub fn scalar_entries(&self) -> [(&'static str, Option<Dist>); 6] {
        [
            ("resistance_ohm", self.resistance_ohm),
            ("inductance_h", self.inductance_h),
            ("km_nm_per_a", self.km_nm_per_a),
            ("inertia_kg_m2", self.inertia_kg_m2),
            ("coulomb_friction_nm", self.coulomb_friction_nm),
            ("viscous_nm_s_per_rad", self.viscous_nm_s_per_rad),
        ]
    }

    /// True when nothing is varied.
    pub fn is_empty(&self) -> bool {
        self.scalar_entries().iter().all(|(_, d)| d.is_none())
            && self.detent_amplitude_nm.is_none()
            && self.detent_phase_rad.is_none()
            && self.load_torque_nm.is_none()
    }

    fn check(&self, section: &str) -> Result<(), String> {
        let all = self.scalar_entries().into_iter().chain([
            ("detent_amplitude_nm", self.detent_amplitude_nm),
            ("detent_phase_rad", self.detent_phase_rad),
            ("load_torque_nm", self.load_torque_nm),
        ]);
        for (key, d) in all {
            if let Some(d) = d {
                d.check(&format!("{section}.{key}"))?;
            }
        }
        Ok(())
    }
}

/// Which model the controller is given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ControllerModel {
    /// The nominal profile (a drive shipped with the datasheet motor's model).
    #[default]
    Nominal,
    /// The variant's own parameters (perfect identification), before `[controller_error]`.
    Plant,
}

/// `[sweep]`: the runs each variant needs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SweepSection {
    /// Control modes by the core's names ([`Mode::name`]: `open-loop`, `servo`).
    pub modes: Vec<String>,
    /// Compensations by the core's names ([`Compensation::name`]: `off`, `patent`,
    /// `estimated`, `angle`; `table` replays a table file, which a study has not, and is
    /// refused); `off` is the reference of every reduction and is always run.
    pub compensations: Vec<String>,
    /// Detent orders whose resonances are measured (default: the profile's detent orders,
    /// largest amplitude first).
    pub orders: Option<Vec<u16>>,
    /// Speeds per resonance (1..=50).
    pub points: usize,
    /// Relative half-width of the speed window around each resonance (0..0.5).
    pub span: f64,
    /// Simulated time per run in s (0.2..=100).
    pub duration_s: f64,
    /// RK4 steps per control period (1..=1000).
    pub substeps: u32,
    /// Current-sensor noise, standard deviation in A (≥ 0).
    pub current_noise_a: f64,
}

impl Default for SweepSection {
    fn default() -> Self {
        SweepSection {
            modes: vec!["open-loop".into()],
            compensations: vec!["off".into(), "patent".into(), "estimated".into()],
            orders: None,
            points: 3,
            span: 0.1,
            duration_s: 1.0,
            substeps: 2,
            current_noise_a: 0.0,
        }
    }
}

/// `[report]`: how the results are summarised.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReportSection {
    /// The reduction (peak-to-peak velocity error off / on) a variant must reach at every
    /// resonance to count as holding.
    pub threshold: f64,
    /// How many worst variants to list per mode and compensation.
    pub worst: usize,
}

impl Default for ReportSection {
    fn default() -> Self {
        ReportSection { threshold: 10.0, worst: 5 }
    }
}

/// The study file as written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudySpec {
    /// Preset name or profile file (relative paths are relative to the spec file).
    pub motor: String,
    /// Number of variants (1..=10 000 000).
    pub variants: u64,
    /// Study seed: variant `i` draws from `derived_seed(seed, i)`.
    #[serde(default = "one")]
    pub seed: u64,
    /// The controller's model.
    #[serde(default)]
    pub controller: ControllerModel,
    /// Runs per variant.
    #[serde(default)]
    pub sweep: SweepSection,
    /// Distributions of the simulated motor.
    #[serde(default)]
    pub plant: Variation,
    /// Identification error of the controller's model, applied to its parameters.
    #[serde(default)]
    pub controller_error: Variation,
    /// Summary settings.
    #[serde(default)]
    pub report: ReportSection,
}

fn one() -> u64 {
    1
}

/// Largest number of variants a study accepts.
pub const MAX_VARIANTS: u64 = 10_000_000;

impl StudySpec {
    /// Checks what sets the study's size: `variants` in 1..=[`MAX_VARIANTS`] and the sweep
    /// section (points, duration, substeps …); the error is the message.
    fn check_sizes(&self) -> Result<(), String> {
        if !(1..=MAX_VARIANTS).contains(&self.variants) {
            return Err(format!("variants = {}: must be in 1..={MAX_VARIANTS}", self.variants));
        }
        self.sweep.check()
    }
}

/// Why a study cannot run. Every message names the file and the key.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// The spec file could not be read.
    #[error("{path}: cannot read: {reason}")]
    Read {
        /// The file.
        path: String,
        /// Why (not a `source`: the message says it, and an error chain would say it twice).
        reason: std::io::Error,
    },
    /// Not valid TOML or not the spec's shape, or a value out of range.
    #[error("{origin}: {message}")]
    Spec {
        /// The file.
        origin: String,
        /// What is wrong.
        message: String,
    },
    /// The motor profile could not be loaded.
    #[error("{origin}: motor: {source}")]
    Motor {
        /// The spec file.
        origin: String,
        /// Why.
        source: stepdamp_sim::ProfileError,
    },
    /// A drawn variant is not a valid motor (the distribution reaches outside the
    /// physical range).
    #[error("variant {index}: {message}")]
    Variant {
        /// Variant index.
        index: u64,
        /// Why.
        message: String,
    },
    /// A results table does not belong to this study.
    #[error("results table: {0}")]
    Table(String),
}

/// A study ready to run: the spec, its nominal profile, and the parsed lists. Serialisable
/// (JSON) so that it can be shipped to workers with no access to the spec's files.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Study {
    /// The spec as written.
    pub spec: StudySpec,
    /// The nominal motor.
    pub nominal: Profile,
    /// Where the spec came from (for messages).
    pub origin: String,
    /// Resonance orders measured, in table order.
    pub orders: Vec<u16>,
}

/// Largest study spec read, in bytes: 1 MiB, a thousand times a real spec (the examples
/// are under 1 kB), so that a wrong path (`/dev/zero`, a log) is refused after reading that
/// much instead of filling the memory (docs/files.md#size-limits).
pub const MAX_SPEC_BYTES: u64 = 1 << 20;

impl Study {
    /// Reads and checks a spec file of at most [`MAX_SPEC_BYTES`] (read in one pass: a FIFO
    /// works, an endless input is refused).
    pub fn load(path: &Path) -> Result<Study, StudyError> {
        let text = stepdamp_out::input::read_to_string_bounded(path, MAX_SPEC_BYTES)
            .map_err(|reason| StudyError::Read { path: path.display().to_string(), reason })?;
        let dir = path.parent().unwrap_or(Path::new("."));
        Study::from_toml_str(&text, &path.display().to_string(), dir)
    }

    /// Parses and checks spec text; `origin` names it in errors and `base_dir` resolves a
    /// relative motor path.
    pub fn from_toml_str(text: &str, origin: &str, base_dir: &Path) -> Result<Study, StudyError> {
        let bad = |message: String| StudyError::Spec { origin: origin.to_string(), message };
        let spec: StudySpec = toml::from_str(text).map_err(|e| bad(one_line(&e.to_string())))?;
        let nominal = nominal_motor(&spec.motor, origin, base_dir)?;
        spec.check_sizes().map_err(bad)?;
        let orders = spec.sweep.orders_for(&nominal).map_err(bad)?;
        spec.plant.check("plant").map_err(bad)?;
        spec.controller_error.check("controller_error").map_err(bad)?;
        if spec.controller_error.load_torque_nm.is_some() {
            return Err(bad("controller_error.load_torque_nm: the load is not part of the controller's model".into()));
        }
        let r = &spec.report;
        if !(r.threshold.is_finite() && r.threshold > 0.0) {
            return Err(bad(format!("report.threshold = {}: must be > 0", r.threshold)));
        }
        if r.worst > 1000 {
            return Err(bad(format!("report.worst = {}: at most 1000", r.worst)));
        }
        let study = Study { spec, nominal, origin: origin.to_string(), orders };
        // The nominal motor itself must run: check its sweep set-up now, once.
        let v = study.variant(0)?;
        study
            .sweep_spec(&v)
            .validate(&v.plant, "plant", &v.controller, "controller")
            .map_err(|e| bad(e.to_string()))?;
        Ok(study)
    }

    /// The study as JSON (to ship to workers).
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a study always serialises")
    }

    /// A study from [`Study::to_json`].
    /// Its sizes are checked again as for a spec file (the number of variants, the sweep
    /// section), so that JSON written by hand cannot ask for more than a spec can.
    pub fn from_json(text: &str) -> Result<Study, StudyError> {
        let bad = |message: String| StudyError::Spec { origin: "study JSON".into(), message };
        let study: Study = serde_json::from_str(text).map_err(|e| bad(one_line(&e.to_string())))?;
        study.spec.check_sizes().map_err(bad)?;
        Ok(study)
    }

    /// The modes run, in table order.
    pub fn modes(&self) -> Vec<Mode> {
        self.spec.sweep.modes.iter().filter_map(|m| m.parse().ok()).collect()
    }

    /// The compensations run, in table order: `off` first, then the spec's others.
    pub fn compensations(&self) -> Vec<Compensation> {
        let mut out = vec![Compensation::Off];
        for c in self.spec.sweep.compensations.iter().filter_map(|c| c.parse().ok()) {
            if !out.contains(&c) {
                out.push(c);
            }
        }
        out
    }
}

/// A parser message on one line.
fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The spec's `motor`: a preset name, or a profile file relative to `base_dir`.
fn nominal_motor(motor: &str, origin: &str, base_dir: &Path) -> Result<Profile, StudyError> {
    if let Some(p) = Profile::preset(motor) {
        return Ok(p);
    }
    let path = base_dir.join(motor);
    if !path.exists() {
        return Err(StudyError::Spec {
            origin: origin.to_string(),
            message: format!(
                "motor = '{motor}': not a preset ({}) nor a file ({})",
                stepdamp_sim::PRESETS.join(", "),
                path.display()
            ),
        });
    }
    Profile::from_file(&path).map_err(|source| StudyError::Motor { origin: origin.to_string(), source })
}

impl SweepSection {
    /// Checks the section's names and ranges; the error is the message (key, value, range).
    fn check(&self) -> Result<(), String> {
        let s = self;
        if s.modes.is_empty() {
            return Err("sweep.modes: the list is empty".into());
        }
        // The core's names (`Mode::name`, `Compensation::name`); its message lists them.
        for m in &s.modes {
            m.parse::<Mode>().map_err(|e| format!("sweep.modes: '{m}': {e}"))?;
        }
        for c in &s.compensations {
            c.parse::<Compensation>().map_err(|e| format!("sweep.compensations: '{c}': {e}"))?;
        }
        if !s.compensations.iter().any(|c| c != "off") {
            return Err("sweep.compensations: name at least one besides off (off is always run)".into());
        }
        if !(1..=50).contains(&s.points) {
            return Err(format!("sweep.points = {}: must be in 1..=50", s.points));
        }
        if !(s.span.is_finite() && (0.0..0.5).contains(&s.span)) {
            return Err(format!("sweep.span = {}: must be in [0, 0.5)", Num(s.span)));
        }
        if s.points > 1 && s.span == 0.0 {
            return Err(format!("sweep.span = 0 with sweep.points = {}: the points would coincide", s.points));
        }
        if !(s.duration_s.is_finite() && (0.2..=100.0).contains(&s.duration_s)) {
            return Err(format!("sweep.duration_s = {}: must be in 0.2..=100 s", Num(s.duration_s)));
        }
        if check_substeps(i64::from(s.substeps)).is_err() {
            return Err(format!("sweep.substeps = {}: must be in 1..={MAX_SUBSTEPS}", s.substeps));
        }
        if !(s.current_noise_a.is_finite() && s.current_noise_a >= 0.0) {
            return Err(format!("sweep.current_noise_a = {}: must be ≥ 0 A", Num(s.current_noise_a)));
        }
        Ok(())
    }

    /// The orders to sweep: the section's (distinct, ≥ 1), else the nominal motor's detent
    /// orders; the error is the message.
    fn orders_for(&self, nominal: &Profile) -> Result<Vec<u16>, String> {
        match &self.orders {
            Some(o) => {
                if o.is_empty() {
                    return Err("sweep.orders: the list is empty".into());
                }
                for (i, &k) in o.iter().enumerate() {
                    if k == 0 || o[..i].contains(&k) {
                        return Err(format!("sweep.orders: {k}: orders must be distinct and ≥ 1"));
                    }
                }
                Ok(o.clone())
            }
            None if nominal.motor.detent.is_empty() => {
                Err(format!("sweep.orders: {} has no detent harmonics; name the orders", nominal.name))
            }
            None => Ok(nominal.detent_orders()),
        }
    }
}
