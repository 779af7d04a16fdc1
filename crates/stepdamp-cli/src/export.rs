//! `stepdamp export` and `stepdamp import`: a profile in the correction formats of other
//! drives (crate `stepdamp-export`), with the library's prediction printed.

use crate::Global;
use crate::common::{load_motor, write_atomic};
use anyhow::{Context, Result, anyhow, bail};
use std::path::{Path, PathBuf};
use stepdamp_core::{Compensation, Mode};
use stepdamp_export::{Correction, c_header, escape, predict, prusa, simplefoc, tmc};

/// Target format.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Prusa-Firmware-Buddy phase stepping: M973 lines (FILE) and the binary correction
    /// files FILE.fwd.bin and FILE.bck.bin.
    Prusa,
    /// A Klipper [tmc2130|tmc2240|tmc5160 …] block with a Trinamic microstep table.
    KlipperTmc,
    /// A C++ header for SimpleFOC (>= 2.4.0) feed_forward_current.q.
    Simplefoc,
    /// An sd_params initializer for stepdamp's C library (stepdamp.h).
    CHeader,
}

impl Format {
    /// The subcommand's name as typed.
    fn name(self) -> &'static str {
        match self {
            Format::Prusa => "prusa",
            Format::KlipperTmc => "klipper-tmc",
            Format::Simplefoc => "simplefoc",
            Format::CHeader => "c-header",
        }
    }
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
    /// Prusa axis (X or Y) / Klipper section: tmc2130, tmc2240 or tmc5160 and the stepper
    /// (e.g. "tmc5160 stepper_x"; the other drivers have no wave table).
    #[arg(long)]
    pub axis: Option<String>,
    /// Simulated time per prediction run, s (0 skips the prediction and its check: nothing
    /// is claimed).
    #[arg(long, default_value_t = 1.0)]
    pub duration: f64,
    /// Write the files even when the prediction shows the correction makes the simulated
    /// motor worse, or not measurably better (by 1 dB at some resonance).
    #[arg(long)]
    pub force: bool,
    /// c-header: the stem of the C names (`<NAME>_PARAMS`, guard `STEPDAMP_<NAME>_H`);
    /// default: the --out file name up to its first dot.
    #[arg(long)]
    pub name: Option<String>,
    /// simplefoc: the loopFOC rate in Hz the prediction models (default 10000).
    #[arg(long)]
    pub loop_hz: Option<f64>,
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

/// Runs `stepdamp export`: builds the files, predicts what the correction does (unless
/// `--duration 0`), refuses a correction the simulation shows worse or not measurably
/// better (unless `--force`), then writes the files.
pub fn run_export(a: ExportArgs, _g: &Global) -> Result<()> {
    let p = load_motor(&a.motor)?;
    if !(a.duration.is_finite() && (a.duration == 0.0 || (0.5..=100.0).contains(&a.duration))) {
        bail!("--duration {}: 0 (no prediction) or 0.5..=100 s", a.duration);
    }
    refuse_unused_options(&a)?;
    let c = Correction::from_profile(&p, a.current)?;
    // The simulation runs at the exported current.
    let scaled = p.edited(&a.motor, |d| d.drive.holding_current_a = c.holding_current_a)?;
    let mut files: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    let mut wrote = String::new();
    let (comp, table) = match a.format {
        Format::Prusa => {
            let axis = match a.axis.as_deref() {
                None | Some("X") | Some("x") => 'X',
                Some("Y") | Some("y") => 'Y',
                Some(o) => bail!("--axis {}: Prusa phase stepping has axes X and Y", escape::line(o)),
            };
            let pc = prusa::PrusaCorrection::from_correction(&c)?;
            let (f, b) = (sibling(&a.out, ".fwd.bin"), sibling(&a.out, ".bck.bin"));
            wrote = format!("(M973 {axis}F/{axis}B), {} and {}", f.display(), b.display());
            files.push((a.out.clone(), pc.m973(axis).into_bytes()));
            files.push((f, prusa::encode_file(&pc.forward).to_vec()));
            files.push((b, prusa::encode_file(&pc.backward).to_vec()));
            (Compensation::Table, Some(pc.table()))
        }
        Format::KlipperTmc => {
            let e = tmc::export(&c)?;
            let section = a.axis.clone().unwrap_or_else(|| "tmc5160 stepper_x".to_string());
            files.push((a.out.clone(), tmc::klipper_block(&e, &section, &p.name)?.into_bytes()));
            out!("{e}");
            wrote = format!("([{section}])");
            (Compensation::Table, Some(tmc::table(&e.registers)))
        }
        Format::Simplefoc => {
            files.push((a.out.clone(), simplefoc::header(&c, "stepdamp_q_current")?.into_bytes()));
            (Compensation::Patent, None)
        }
        Format::CHeader => {
            let ident = c_header::ident_for(&a.out, a.name.as_deref())?;
            files.push((a.out.clone(), c_header::header(&scaled, &p.name, &a.motor, &ident)?.into_bytes()));
            wrote = format!("(sd_params {ident}_PARAMS)");
            (Compensation::Patent, None)
        }
    };
    if a.duration > 0.0 {
        let verdict = predict_export(&a, &scaled, comp, table.as_ref())?;
        if verdict != predict::Verdict::Better {
            if !a.force {
                bail!("{verdict}; nothing written (--force writes it anyway)");
            }
            outln!("{verdict}; writing it anyway (--force)");
        }
    }
    for (path, bytes) in &files {
        write_atomic(path, bytes)?;
    }
    outln!("wrote {}{}", a.out.display(), if wrote.is_empty() { String::new() } else { format!(" {wrote}") });
    Ok(())
}

/// Options that would do nothing for the chosen format are refused, never ignored.
fn refuse_unused_options(a: &ExportArgs) -> Result<()> {
    let unused =
        |opt: &str, why: &str| -> Result<()> { bail!("{opt} does nothing for export {}: {why}", a.format.name()) };
    match a.format {
        Format::Simplefoc => {
            if a.current.is_some() {
                unused("--current", "the q-current feed-forward A_k/Km does not depend on the run current")?;
            }
            if a.axis.is_some() {
                unused("--axis", "the header is for the motor object you call it with")?;
            }
        }
        Format::CHeader if a.axis.is_some() => unused("--axis", "the header's names come from --out or --name")?,
        _ => {}
    }
    if a.name.is_some() && a.format != Format::CHeader {
        unused("--name", "it names the C header's identifiers (export c-header)")?;
    }
    if a.loop_hz.is_some() && a.format != Format::Simplefoc {
        unused("--loop-hz", "it is SimpleFOC's loopFOC rate (export simplefoc)")?;
    }
    Ok(())
}

/// Prints the prediction of the exported correction and returns the verdict on the first
/// (the one that models what is exported).
fn predict_export(
    a: &ExportArgs,
    scaled: &stepdamp_sim::Profile,
    comp: Compensation,
    table: Option<&stepdamp_core::CorrectionTable>,
) -> Result<predict::Verdict> {
    // SimpleFOC runs on its sensor: servo mode; the others microstep in open loop.
    let mode = if a.format == Format::Simplefoc { Mode::Servo } else { Mode::OpenLoop };
    let off = predict::config_in(scaled, mode, Compensation::Off, None)?;
    let mut comps: Vec<(String, predict::ConfigAt<'_>)> = Vec::new();
    match (a.format, comp) {
        (Format::Simplefoc, _) => {
            let timing = simplefoc::LoopTiming {
                loop_hz: a.loop_hz.unwrap_or(DEFAULT_LOOP_HZ),
                order: simplefoc::CallOrder::Documented,
            };
            timing.check()?;
            let name = format!(
                "servo, SimpleFOC loop at {} Hz with the header's call order, q-current feed-forward",
                timing.loop_hz
            );
            comps.push((
                name,
                Box::new(move |speed| {
                    predict::config_in(&timing.as_applied(scaled, speed)?, Mode::Servo, Compensation::Patent, None)
                }),
            ));
        }
        (_, Compensation::Table) => {
            let cfg = predict::config_in(scaled, mode, comp, table)?;
            comps.push(("open loop, table replay".into(), Box::new(move |_| Ok(cfg))));
        }
        _ => {
            let cfg = predict::config_in(scaled, mode, comp, table)?;
            comps.push(("open loop, patent q-current feed-forward".into(), Box::new(move |_| Ok(cfg))));
        }
    }
    if a.format == Format::KlipperTmc {
        // What the coverage report predicts: the continuous angle law carrying exactly
        // the part of the model the table can hold (the table's rounding aside).
        let covered = predict::config(&tmc::covered_profile(scaled)?, Compensation::Angle, None)?;
        comps.push(("open loop, angle law on the covered part only".to_string(), Box::new(move |_| Ok(covered))));
    }
    let pr = predict::predict_at(scaled, off, &comps, a.duration)?;
    for p in &pr {
        out!("{p}");
    }
    Ok(pr[0].verdict())
}

/// SimpleFOC loop rate the prediction assumes without `--loop-hz`, Hz.
const DEFAULT_LOOP_HZ: f64 = 10_000.0;

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
