//! # stepdamp-profile
//!
//! The files every stepdamp tool reads: the motor profile (TOML) and the run log (CSV).
//!
//! A profile is read into [`ProfileData`] (every key, unchecked) and validated once into a
//! [`Profile`]: each key within the physical range of a real motor and drive
//! ([`stepdamp_core::limits`], the same ranges the controller enforces), the derived
//! quantities finite, and the controller willing to take it in every mode. The simulator,
//! identification and the command line take a `Profile` and do not check it again.
//! Errors name the file, the key, the value as written and the allowed range.
//!
//! A motor argument is a preset or a file ([`MotorRef::parse`]): a name with a `/` or
//! ending in `.toml` is a file, a bare name a preset, and a bare name that is both is an
//! error.
//!
//! ```
//! use stepdamp_profile::{Profile, ProfileError};
//!
//! let p = Profile::preset("patent-motor").unwrap();
//! assert!((p.resonance_speed_rad_s(4) - 4.22).abs() < 0.02);
//! let e = p.edited("m.toml", |d| d.motor.km_nm_per_a = 1e308).unwrap_err();
//! assert_eq!(e.to_string(), "m.toml: motor.km_nm_per_a = 1e308: must be in [1e-3, 50] N·m/A");
//! # let _: ProfileError = e;
//! ```
//!
//! No simulator, thread pool or random numbers: reading a real drive's files needs none.

pub mod data;
pub mod error;
pub mod figures;
pub mod flux;
pub mod load;
pub mod name;
pub mod profile;
pub mod ripple;
pub mod runlog;
mod validate;

pub use data::{DetentTerm, DriveSection, EncoderSection, MotorSection, ProfileData, ServoSection, TopologyName};
pub use error::ProfileError;
pub use figures::{MotorFigures, MotorShow, ResonanceSpeed};
pub use flux::{FluxHarmonic, FluxSection, FluxShape};
pub use load::{MAX_PROFILE_BYTES, MotorRef, PRESETS, preset_text};
pub use profile::{ControllerHarmonics, Profile, TYPICAL_DETENT_ORDERS};
pub use ripple::{Ripple, RippleError, RippleHarmonic, RippleParts, ripple, ripple_parts};
pub use runlog::LogRow;
pub use stepdamp_core::limits;

#[cfg(test)]
mod tests;
