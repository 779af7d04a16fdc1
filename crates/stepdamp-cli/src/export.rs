//! `stepdamp export` and `stepdamp import`: a profile in the correction formats of other
//! drives (crate `stepdamp-export`), with the library's prediction printed.

use crate::Global;
use crate::common::{load_motor, write_atomic};
use anyhow::{Result, bail};
use std::path::{Path, PathBuf};
use stepdamp_core::{Compensation, Mode};
use stepdamp_export::{Correction, RunCurrent, c_header, predict, prusa, simplefoc, tmc};

/// Target format.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Prusa-Firmware-Buddy phase stepping (XL, iX, Core One, MK4): M970/M971 G-code for
    /// firmware >= 6.3.1 (M973 with --firmware 6.2) in FILE, and the binary correction files
    /// FILE.fwd.bin and FILE.bck.bin.
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
    /// Prusa-Firmware-Buddy phase stepping: the `M971 X F` / `M971 X B` read-back of firmware
    /// 6.3.1 and later (a terminal log with OctoPrint's `Recv: ` is fine), the 6.2 M972
    /// print, M973 lines or a 168-byte correction file.
    Prusa,
}

/// Prusa firmware generation of `--firmware`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrusaFirmware {
    /// 6.3.1 and later (v6.3.1, v6.3.2): M970/M971 per item, the fixed-point scale.
    #[value(name = "6.3.1", alias = "6.3")]
    V6_3_1,
    /// 6.2.x: one M973 line per direction, the float scale (4x the 6.3.1 magnitudes).
    #[value(name = "6.2")]
    V6_2,
}

impl From<PrusaFirmware> for prusa::Firmware {
    fn from(f: PrusaFirmware) -> Self {
        match f {
            PrusaFirmware::V6_3_1 => prusa::Firmware::V6_3_1,
            PrusaFirmware::V6_2 => prusa::Firmware::V6_2,
        }
    }
}

/// The run current, peak or RMS: exactly one of the two.
#[derive(clap::Args, Debug)]
#[group(required = true, multiple = false)]
pub struct CurrentArgs {
    /// Run current as the PEAK of the current vector, A: the amplitude of each phase's sine
    /// wave, the unit of the profile's holding_current_a. For a drive's RMS setting (Klipper
    /// run_current, Prusa's motor current) use --current-rms.
    #[arg(long)]
    pub current: Option<f64>,
    /// Run current as the RMS of each phase's current, A (peak = sqrt(2) x RMS): Klipper's
    /// run_current, Prusa's motor current settings.
    #[arg(long)]
    pub current_rms: Option<f64>,
}

impl CurrentArgs {
    /// The run current given.
    pub fn run_current(&self) -> Result<RunCurrent> {
        Ok(match (self.current, self.current_rms) {
            (Some(p), None) => RunCurrent::from_peak(p)?,
            (None, Some(r)) => RunCurrent::from_rms(r)?,
            _ => bail!("give exactly one of --current (peak) and --current-rms"),
        })
    }
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
    /// The run current the correction is computed for.
    #[command(flatten)]
    pub current: CurrentArgs,
    /// Prusa firmware the G-code is for (prusa only; default 6.3.1, which covers 6.3.x).
    #[arg(long, value_enum)]
    pub firmware: Option<PrusaFirmware>,
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
    /// The printer's output (M971 read-back, 6.2 M972 print, M973 lines) or a 168-byte
    /// correction file; at most 1 MiB.
    #[arg(long, visible_alias = "m972")]
    pub readback: PathBuf,
    /// The motor's base profile (everything but the detent model).
    #[arg(long)]
    pub motor: String,
    /// The run current the printer used.
    #[command(flatten)]
    pub current: CurrentArgs,
    /// Firmware scale of a 168-byte correction file (the text forms say their own).
    #[arg(long, value_enum, default_value = "6.3.1")]
    pub firmware: PrusaFirmware,
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
    let current = a.current.run_current()?;
    if a.firmware.is_some() && a.format != Format::Prusa {
        bail!("--firmware: only for export prusa");
    }
    let c = Correction::from_profile(&p, Some(current.peak_a()))?;
    outln!("run current {current}");
    // The simulation runs at the exported current.
    let scaled = p.edited(&a.motor, |d| d.drive.holding_current_a = c.holding_current_a)?;
    let (comp, table) = match a.format {
        Format::Prusa => {
            let axis = match a.axis.as_deref() {
                None | Some("X") | Some("x") => 'X',
                Some("Y") | Some("y") => 'Y',
                Some(o) => bail!("--axis {o:?}: Prusa phase stepping has axes X and Y"),
            };
            let table = export_prusa(&a, &p.name, &c, current, axis)?;
            (Compensation::Table, Some(table))
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

/// Writes the Prusa G-code and files; returns the table the written G-code makes, read back
/// from the text itself, for the prediction.
fn export_prusa(
    a: &ExportArgs,
    name: &str,
    c: &Correction,
    current: RunCurrent,
    axis: char,
) -> Result<stepdamp_core::CorrectionTable> {
    let fw: prusa::Firmware = a.firmware.unwrap_or(PrusaFirmware::V6_3_1).into();
    let fitted = prusa::fit(c, fw)?;
    let text = prusa::gcode::write(&fitted, axis, &prusa::gcode::Header { profile: name, current })?;
    let (written, _) = prusa::parse_text(&text, Some(axis), "the exported G-code")?;
    if written != fitted.correction {
        bail!("internal: the exported G-code reads back to another correction");
    }
    out!("{fitted}");
    write_atomic(&a.out, text.as_bytes())?;
    let (f, b) = (sibling(&a.out, ".fwd.bin"), sibling(&a.out, ".bck.bin"));
    write_atomic(&f, &prusa::encode_file(&written.forward))?;
    write_atomic(&b, &prusa::encode_file(&written.backward))?;
    let how = match fw {
        prusa::Firmware::V6_3_1 => format!("M970 {axis}0, M971 {axis} F|B x17, M970 {axis}1"),
        prusa::Firmware::V6_2 => format!("M973 {axis}F/{axis}B"),
    };
    outln!("wrote {} ({how}, firmware {}), {} and {}", a.out.display(), fw.label(), f.display(), b.display());
    Ok(written.table())
}

/// Runs `stepdamp import prusa`.
pub fn run_import(a: ImportArgs, _g: &Global) -> Result<()> {
    let base = load_motor(&a.motor)?;
    let current = a.current.run_current()?;
    let bytes = prusa::read::read_capped(&a.readback)?;
    let what = a.readback.display().to_string();
    let axis = match a.axis {
        None => None,
        Some('X' | 'x') => Some('X'),
        Some('Y' | 'y') => Some('Y'),
        Some(o) => bail!("--axis {o:?}: Prusa phase stepping has axes X and Y"),
    };
    let (pc, kind) = prusa::parse_bytes(&bytes, axis, &what, a.firmware.into())?;
    outln!("read {kind}; run current {current}");
    let (p, spread) = prusa::import_profile(&base, &pc, current.peak_a())?;
    write_atomic(&a.out, p.to_toml_string().as_bytes())?;
    for h in &p.motor.detent {
        outln!("order {:>2}: A = {:.5} N·m, φ = {:+.4} rad", h.order, h.amplitude_nm, h.phase_rad);
    }
    outln!("forward and backward corrections differ by up to {spread:.5} rad (averaged)");
    outln!("wrote {}", a.out.display());
    Ok(())
}
