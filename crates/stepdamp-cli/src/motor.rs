//! `stepdamp motor show|check` and `stepdamp resonance`.

use crate::Global;
use crate::common::load_motor;
use crate::sweep::resonance_markers;
use anyhow::Result;
use stepdamp_sim::{PRESETS, Profile};

/// `stepdamp motor …`.
#[derive(clap::Subcommand, Debug)]
pub enum MotorCommand {
    /// Print a profile (preset or file) with derived figures.
    Show {
        /// Preset name or TOML file.
        motor: String,
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
}

/// Derived figures of a profile, one per line.
pub fn derived(p: &Profile) -> String {
    let m = &p.motor;
    let d = &p.drive;
    let k = p.holding_stiffness_nm_per_rad();
    let wn = p.natural_frequency_rad_s();
    let mut s = String::new();
    s += &format!(
        "holding torque √2·Km·I      {:.4} N·m\n",
        std::f64::consts::SQRT_2 * m.km_nm_per_a * d.holding_current_a
    );
    s += &format!("holding stiffness Nr·Km·I   {k:.3} N·m/rad\n");
    s += &format!("natural frequency ω_n       {wn:.1} rad/s ({:.1} Hz)\n", wn / std::f64::consts::TAU);
    s += &format!("damping ratio D/(2Jω_n)     {:.4}\n", p.damping_ratio());
    s += &format!("electrical time constant    {:.2} ms\n", 1e3 * m.inductance_h / m.resistance_ohm);
    s += &format!("full step                   {:.3}°\n", 90.0 / f64::from(m.pole_pairs));
    for mk in resonance_markers(p) {
        s += &format!(
            "resonance {:<5}             {:.3} rad/s ({:.2} rev/s)\n",
            mk.label,
            mk.x,
            mk.x / std::f64::consts::TAU
        );
    }
    s
}

/// Runs `stepdamp motor …`.
pub fn run(c: MotorCommand, _g: &Global) -> Result<()> {
    match c {
        MotorCommand::Show { motor } => {
            let p = load_motor(&motor)?;
            out!("{}", p.to_toml_string());
            outln!("\n# derived");
            for line in derived(&p).lines() {
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
                    resonance_markers(&p).iter().map(|m| format!("{:.2}", m.x)).collect::<Vec<_>>().join(", ")
                );
            }
        }
    }
    Ok(())
}

/// Runs `stepdamp resonance`.
pub fn resonance(a: ResonanceArgs, _g: &Global) -> Result<()> {
    let p = load_motor(&a.motor)?;
    outln!("{}", p.name);
    out!("{}", derived(&p));
    Ok(())
}
