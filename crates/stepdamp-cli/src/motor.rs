//! `stepdamp motor show|check` and `stepdamp resonance`.

use crate::Global;
use crate::common::{Format, load_motor, print_json};
use anyhow::Result;
use stepdamp_profile::{MotorFigures, MotorShow, PRESETS, Profile};

/// `stepdamp motor …`.
#[derive(clap::Subcommand, Debug)]
pub enum MotorCommand {
    /// Print a profile (preset or file) with derived figures.
    Show {
        /// Preset name or TOML file.
        motor: String,
        /// text (the TOML and its figures as comments) or json.
        #[arg(long, value_enum, default_value_t)]
        format: Format,
    },
    /// Check a profile; print the precise reason when it is invalid.
    Check {
        /// Preset name or TOML file.
        motor: String,
    },
    /// List the built-in presets.
    List,
}

/// Arguments of `stepdamp resonance`.
#[derive(clap::Args, Debug)]
pub struct ResonanceArgs {
    /// Motor: a preset name or a profile TOML file.
    #[arg(long, default_value = "patent-motor")]
    pub motor: String,
    /// text or json.
    #[arg(long, value_enum, default_value_t)]
    pub format: Format,
}

/// Runs `stepdamp motor …`.
pub fn run(c: MotorCommand, _g: &Global) -> Result<()> {
    match c {
        MotorCommand::Show { motor, format } => {
            let p = load_motor(&motor)?;
            let figures = MotorFigures::of(&p);
            if format == Format::Json {
                return print_json(&MotorShow { profile: p, figures });
            }
            out!("{}", p.to_toml_string());
            outln!("\n# derived");
            for line in figures.to_string().lines() {
                outln!("# {line}");
            }
        }
        MotorCommand::Check { motor } => {
            let p = load_motor(&motor)?;
            outln!("{motor}: ok ({})", p.name);
        }
        MotorCommand::List => {
            for name in PRESETS {
                let p = Profile::preset(name).expect("presets are valid");
                outln!(
                    "{name:<18} Km {:.3} N·m/A, I {:.1} A, J {:.1e} kg·m², resonances {}",
                    p.motor.km_nm_per_a,
                    p.drive.holding_current_a,
                    p.motor.inertia_kg_m2,
                    MotorFigures::of(&p)
                        .resonances
                        .iter()
                        .map(|r| format!("{:.2}", r.speed_rad_s))
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
        }
    }
    Ok(())
}

/// Runs `stepdamp resonance`.
pub fn resonance(a: ResonanceArgs, _g: &Global) -> Result<()> {
    let figures = MotorFigures::of(&load_motor(&a.motor)?);
    if a.format == Format::Json {
        return print_json(&figures);
    }
    outln!("{}", figures.name);
    out!("{figures}");
    Ok(())
}
