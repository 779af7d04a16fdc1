//! `stepdamp identify static`: the detent harmonics from a static torque-versus-angle
//! table by FFT, written into a profile.

use super::args::{Orders, check_output_dir, default_name, parse_orders};
use crate::common::{Format, choice_parser, load_motor, print_json, write_atomic};
use anyhow::{Result, anyhow, bail};
use std::path::PathBuf;
use stepdamp_identify::model::Model;
use stepdamp_identify::static_curve::{StaticReport, TorqueSign, analyse, read_table};

/// `stepdamp identify static`.
#[derive(clap::Args, Debug)]
pub(super) struct StaticArgs {
    /// Torque-versus-angle table: CSV with columns theta_rad (mechanical) and torque_nm,
    /// over a whole number of electrical periods.
    #[arg(long, value_name = "CSV")]
    pub(super) table: PathBuf,
    /// What the table holds: on-rotor (the detent torque on the rotor, −Σ A sin) or holding
    /// (the torque applied to hold the rotor, +Σ A sin).
    #[arg(long, value_parser = choice_parser(TorqueSign::ALL, TorqueSign::name))]
    pub(super) sign: TorqueSign,
    /// Base motor profile (preset or TOML).
    #[arg(long, value_name = "PRESET|FILE")]
    pub(super) motor: String,
    /// Where to write the profile with the detent replaced (friction kept).
    #[arg(long, value_name = "FILE")]
    pub(super) out: PathBuf,
    /// Harmonic orders to keep.
    #[arg(long, default_value = "1,2,4", value_parser = parse_orders)]
    pub(super) orders: Orders,
    /// Name of the new profile (default: base name + "-static").
    #[arg(long)]
    pub(super) name: Option<String>,
    /// text, or json: the analysis (stepdamp_identify::static_curve::StaticReport) as one
    /// line of JSON on stdout, nothing else (the profile is written the same).
    #[arg(long, value_enum, default_value_t)]
    pub(super) format: Format,
}

/// Runs `stepdamp identify static`.
pub(super) fn run_static_cmd(a: StaticArgs) -> Result<()> {
    let base = load_motor(&a.motor)?;
    let orders = a.orders.0.clone();
    let sign = a.sign;
    check_output_dir(&a.out)?;
    let pts = read_table(&a.table).map_err(|e| anyhow!("{e}"))?;
    let kmax = *orders.iter().max().expect("parse_orders gives at least one order");
    let src = a.table.display().to_string();
    let c = analyse(&pts, base.motor.pole_pairs, sign, kmax, &src).map_err(|e| anyhow!("{e}"))?;
    let report = StaticReport::new(&src, pts.len(), &c, &orders);
    let picked = &report.harmonics;
    if picked.len() < orders.len() {
        let missing: Vec<String> =
            orders.iter().filter(|&&k| picked.iter().all(|h| h.order != k)).map(u16::to_string).collect();
        bail!(
            "{src}: {} points over {} electrical periods cannot resolve order {} (order k needs more than 2·k points \
             per electrical period)",
            pts.len(),
            c.electrical_periods,
            missing.join(", ")
        );
    }
    let json = a.format == Format::Json;
    if !json {
        outln!("{report}");
    }
    let mut model = Model::of_profile(&base);
    model.detent = picked
        .iter()
        .map(|h| stepdamp_sim::profile::DetentTerm {
            order: h.order,
            amplitude_nm: h.amplitude_nm,
            phase_rad: h.phase_rad,
        })
        .collect();
    let name = a.name.clone().unwrap_or_else(|| default_name(&base, "static"));
    let out_s = a.out.display().to_string();
    let profile = model.apply_to(&base, Some(&name), &out_s).map_err(|e| anyhow!("{e}"))?;
    write_atomic(&a.out, profile.to_toml_string().as_bytes())?;
    if json {
        print_json(&report)?;
    } else {
        outln!("wrote {out_s} (friction kept from the base profile: a static table does not measure it)");
    }
    Ok(())
}
