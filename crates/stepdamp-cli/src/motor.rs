//! `stepdamp motor show|check|list|ripple` and `stepdamp resonance`.

use crate::Global;
use crate::common::{Format, TableFormat, load_motor, print_json};
use anyhow::{Context, Result, anyhow};
use stepdamp_profile::ripple::RIPPLE_CSV_COLUMNS;
use stepdamp_profile::{MotorFigures, MotorShow, PRESETS, Profile, ripple};

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
    /// The total ripple torque at an operating point: detent plus the ripple that grows with
    /// current (docs/design.md#real-motors-flux-harmonics), as harmonics of the electrical
    /// angle in the profile's convention (torque on the rotor −A·sin(k·θe + φ)).
    Ripple(RippleArgs),
}

/// Arguments of `stepdamp motor ripple`.
#[derive(clap::Args, Debug)]
pub struct RippleArgs {
    /// Motor: a preset name or a profile TOML file.
    #[arg(long)]
    pub motor: String,
    /// d-axis current in A, in the rotor's frame (open loop at the holding current and no
    /// load: the holding current; under load angle δ: I·cos δ).
    #[arg(long, value_name = "A", allow_negative_numbers = true)]
    pub id: f64,
    /// q-axis current in A, in the rotor's frame (a servo at i_d = 0: its torque current;
    /// open loop under load angle δ: I·sin δ).
    #[arg(long, value_name = "A", allow_negative_numbers = true)]
    pub iq: f64,
    /// text, json or csv (one row per order; amplitudes in N·m, phases in rad).
    #[arg(long, value_enum, default_value_t)]
    pub format: TableFormat,
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
        MotorCommand::Ripple(a) => return print_ripple(&a),
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

/// `stepdamp motor ripple`: the library's [`stepdamp_profile::Ripple`], translated.
fn print_ripple(a: &RippleArgs) -> Result<()> {
    let p = load_motor(&a.motor)?;
    let r = ripple(&p, a.id, a.iq).map_err(|e| anyhow!("{e}"))?;
    match a.format {
        TableFormat::Text => out!("{r}"),
        TableFormat::Json => print_json(&r)?,
        TableFormat::Csv => {
            let mut w = csv::Writer::from_writer(Vec::new());
            w.write_record(RIPPLE_CSV_COLUMNS)?;
            for row in r.csv_rows() {
                w.write_record(row.iter().map(|v| v.to_string()))?;
            }
            let bytes = w.into_inner().context("cannot write the CSV")?;
            out!("{}", String::from_utf8(bytes).context("the CSV is not UTF-8")?);
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
