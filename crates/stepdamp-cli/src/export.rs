//! `stepdamp export` and `stepdamp import`: a profile in the correction formats of other
//! drives (crate `stepdamp-export`), with the library's prediction printed.

use crate::Global;
use crate::common::{load_motor, write_atomic};
use anyhow::{Context, Result, anyhow, bail};
use std::path::{Path, PathBuf};
use stepdamp_core::{Compensation, Mode};
use stepdamp_export::{Correction, c_header, predict, prusa, simplefoc, tmc};

/// Target format.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Prusa-Firmware-Buddy phase stepping: M973 lines (FILE) and the binary correction
    /// files FILE.fwd.bin and FILE.bck.bin.
    Prusa,
    /// A Klipper [tmc5160 …] block with a Trinamic microstep table.
    KlipperTmc,
    /// A C++ header for SimpleFOC's HybridStepperMotor feed_forward_current.q.
    Simplefoc,
    /// An sd_params initializer for stepdamp's C library (stepdamp.h).
    CHeader,
}

/// Source format of `stepdamp import`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImportFormat {
    /// Prusa-Firmware-Buddy phase stepping: M972 output, M973 lines or a 168-byte
    /// correction file.
    Prusa,
}

/// Arguments of `stepdamp export`.
#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    /// Format to write.
    #[arg(value_enum)]
    pub format: Format,
    /// Motor profile (identified TOML) or preset.
    #[arg(long)]
    pub motor: String,
    /// Holding (run) current in A the correction is scaled for (default: the profile's).
    #[arg(long)]
    pub current: Option<f64>,
    /// Output file.
    #[arg(long)]
    pub out: PathBuf,
    /// Prusa axis (X or Y) / Klipper section (e.g. "tmc5160 stepper_x").
    #[arg(long)]
    pub axis: Option<String>,
    /// Simulated time per prediction run, s (0 skips the prediction).
    #[arg(long, default_value_t = 1.0)]
    pub duration: f64,
}

/// Arguments of `stepdamp import prusa`.
#[derive(clap::Args, Debug)]
pub struct ImportArgs {
    /// Source format (only `prusa`).
    #[arg(value_enum)]
    pub format: ImportFormat,
    /// M972 output, M973 lines, or a 168-byte correction file.
    #[arg(long)]
    pub m972: PathBuf,
    /// The motor's base profile (everything but the detent model).
    #[arg(long)]
    pub motor: String,
    /// Run current in A the printer used.
    #[arg(long)]
    pub current: f64,
    /// Axis to read when the file holds several (X or Y).
    #[arg(long)]
    pub axis: Option<char>,
    /// Profile TOML to write.
    #[arg(long)]
    pub out: PathBuf,
}

fn sibling(out: &Path, suffix: &str) -> PathBuf {
    let mut s = out.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

/// Runs `stepdamp export`.
pub fn run_export(a: ExportArgs, _g: &Global) -> Result<()> {
    let p = load_motor(&a.motor)?;
    if !(a.duration.is_finite() && (a.duration == 0.0 || (0.5..=100.0).contains(&a.duration))) {
        bail!("--duration {}: 0 (no prediction) or 0.5..=100 s", a.duration);
    }
    let c = Correction::from_profile(&p, a.current)?;
    // The simulation runs at the exported current.
    let scaled = p.edited(&a.motor, |d| d.drive.holding_current_a = c.holding_current_a)?;
    let (comp, table) = match a.format {
        Format::Prusa => {
            let axis = match a.axis.as_deref() {
                None | Some("X") | Some("x") => 'X',
                Some("Y") | Some("y") => 'Y',
                Some(o) => bail!("--axis {o}: Prusa phase stepping has axes X and Y"),
            };
            let pc = prusa::PrusaCorrection::from_correction(&c)?;
            write_atomic(&a.out, pc.m973(axis).as_bytes())?;
            let (f, b) = (sibling(&a.out, ".fwd.bin"), sibling(&a.out, ".bck.bin"));
            write_atomic(&f, &prusa::encode_file(&pc.forward))?;
            write_atomic(&b, &prusa::encode_file(&pc.backward))?;
            outln!("wrote {} (M973 {axis}F/{axis}B), {} and {}", a.out.display(), f.display(), b.display());
            (Compensation::Table, Some(pc.table()))
        }
        Format::KlipperTmc => {
            let e = tmc::export(&c)?;
            let section = a.axis.clone().unwrap_or_else(|| "tmc5160 stepper_x".to_string());
            write_atomic(&a.out, tmc::klipper_block(&e, &section, &p.name).as_bytes())?;
            out!("{e}");
            outln!("wrote {} ([{section}])", a.out.display());
            (Compensation::Table, Some(tmc::table(&e.registers)))
        }
        Format::Simplefoc => {
            write_atomic(&a.out, simplefoc::header(&c, "stepdamp_q_current").as_bytes())?;
            outln!("wrote {}", a.out.display());
            (Compensation::Patent, None)
        }
        Format::CHeader => {
            write_atomic(&a.out, c_header::header(&scaled, &a.motor, "motor").as_bytes())?;
            outln!("wrote {}", a.out.display());
            (Compensation::Patent, None)
        }
    };
    if a.duration > 0.0 {
        // SimpleFOC runs on its sensor: servo mode; the others microstep in open loop.
        let (mode, name) = match (a.format, comp) {
            (Format::Simplefoc, _) => (Mode::Servo, "servo, patent q-current feed-forward"),
            (_, Compensation::Table) => (Mode::OpenLoop, "open loop, table replay"),
            _ => (Mode::OpenLoop, "open loop, patent q-current feed-forward"),
        };
        let off = predict::config_in(&scaled, mode, Compensation::Off, None)?;
        let cfg = predict::config_in(&scaled, mode, comp, table.as_ref())?;
        let mut comps = vec![(name.to_string(), cfg)];
        if a.format == Format::KlipperTmc {
            // What the coverage report predicts: the continuous angle law carrying exactly
            // the part of the model the table can hold (the table's rounding aside).
            let covered = predict::config(&tmc::covered_profile(&scaled)?, Compensation::Angle, None)?;
            comps.push(("open loop, angle law on the covered part only".to_string(), covered));
        }
        for p in predict::predict_against(&scaled, off, &comps, a.duration)? {
            out!("{p}");
        }
    }
    Ok(())
}

/// Runs `stepdamp import prusa`.
pub fn run_import(a: ImportArgs, _g: &Global) -> Result<()> {
    let base = load_motor(&a.motor)?;
    let bytes = std::fs::read(&a.m972).with_context(|| format!("reading {}", a.m972.display()))?;
    let what = a.m972.display().to_string();
    let pc = if bytes.len() == prusa::FILE_BYTES && bytes[..32].iter().all(|&b| b == 0) {
        let s = prusa::decode_file(&bytes, &what)?;
        prusa::PrusaCorrection { forward: s, backward: s }
    } else {
        let text =
            std::str::from_utf8(&bytes).map_err(|_| anyhow!("{what}: not text and not a 168-byte correction file"))?;
        if text.lines().any(|l| l.trim().starts_with("M973 ")) {
            prusa::parse_m973(text, a.axis, &what)?
        } else {
            prusa::parse_m972(text, a.axis, &what)?
        }
    };
    let (p, spread) = prusa::import_profile(&base, &pc, a.current)?;
    write_atomic(&a.out, p.to_toml_string().as_bytes())?;
    for h in &p.motor.detent {
        outln!("order {:>2}: A = {:.5} N·m, φ = {:+.4} rad", h.order, h.amplitude_nm, h.phase_rad);
    }
    outln!("forward and backward corrections differ by up to {spread:.5} rad (averaged)");
    outln!("wrote {}", a.out.display());
    Ok(())
}
