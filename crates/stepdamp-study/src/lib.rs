//! # stepdamp-study
//!
//! Tolerance studies: does compensation hold across production tolerances? A study draws
//! `N` motor variants from distributions over the profile's parameters (R, L, Km, J, each
//! detent amplitude and phase, Fs, D, the load, and the error of the controller's model),
//! runs each variant's sweep around its own resonances with and without compensation, and
//! reports the distribution of the reduction (peak-to-peak velocity error off / on) at each
//! resonance.
//!
//! Deterministic: variant `i` is drawn and simulated from `derived_seed(seed, i)` only, so
//! a table does not depend on how the variants are split into chunks or threads. The CLI
//! (`stepdamp study`) and the Python package (`stepdamp.study`, which spreads chunks over
//! Dask workers) both run [`Study::run_range`] and [`Study::summarize`].
//!
//! ```
//! use stepdamp_study::Study;
//! let spec = r#"
//! motor = "patent-motor"
//! variants = 4
//! [sweep]
//! compensations = ["patent"]
//! orders = [4]
//! points = 1
//! duration_s = 0.4
//! [plant]
//! inertia_kg_m2 = { scale = [0.8, 1.5] }
//! "#;
//! let study = Study::from_toml_str(spec, "study.toml", std::path::Path::new("."))?;
//! let table = study.run_range(0, 4, &|| {})?;
//! let summary = study.summarize(&table)?;
//! assert_eq!(summary.variants, 4);
//! # Ok::<(), stepdamp_study::StudyError>(())
//! ```

pub mod run;
pub mod spec;
pub mod summary;

pub use run::{Table, Variant, reduction};
pub use spec::{ControllerModel, Dist, Study, StudyError, StudySpec, Variation};
pub use summary::{PairSummary, ResonanceStats, StudySummary, WorstVariant, percentile};

#[cfg(test)]
mod tests;
